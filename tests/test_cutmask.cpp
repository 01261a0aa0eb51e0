// CutMask: exact contents against an independent reference, undo/redo equal
// to a rebuild from scratch, the input -> geometry hand-off, no depth limit.
#include "cutter/CutMask.h"
#include "cutter/PathFile.h"
#include "vdb/Error.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <thread>
#include <tuple>

using namespace mtcut::cutter;
using glm::dvec3;
using glm::ivec3;

namespace {

using Key = std::tuple<int, int, int>;
Key key(const openvdb::Coord& c) { return {c.x(), c.y(), c.z()}; }

IndexFrame smallFrame()
{
    IndexFrame f;
    f.origin = dvec3(-12.0, 7.5, -30.0);
    f.spacing = dvec3(0.5, 0.5, 2.0);
    f.dims = ivec3(48, 48, 20);
    return f;
}

std::map<Key, int32_t> gridValues(const CutMask& m)
{
    std::map<Key, int32_t> out;
    for (auto it = m.grid()->cbeginValueOn(); it; ++it) out[key(it.getCoord())] = *it;
    return out;
}

void expectSameMask(const CutMask& a, const CutMask& b)
{
    ASSERT_EQ(a.strokeCount(), b.strokeCount());
    for (uint32_t s = 1; s <= a.strokeCount(); ++s) ASSERT_EQ(a.quadCount(s), b.quadCount(s));
    ASSERT_EQ(a.cutCellCount(), b.cutCellCount());
    ASSERT_EQ(gridValues(a), gridValues(b));
    ASSERT_EQ(a.grid()->activeVoxelCount(), openvdb::Index64(a.cutCellCount()));
    a.forEachCutCell([&](const openvdb::Coord& c, const std::vector<QuadRef>& list) {
        const std::vector<QuadRef>* other = b.quadsAt(c);
        ASSERT_NE(other, nullptr);
        ASSERT_EQ(list, *other);
    });
}

/// Independent reference: per cell, the (stroke, quad) list from the
/// voxelisation of each quad in order, first stroke = front of the list.
void expectMatchesReference(const CutMask& m, const std::vector<std::vector<Quad>>& strokes)
{
    std::map<Key, std::vector<QuadRef>> ref;
    for (size_t s = 0; s < strokes.size(); ++s)
        for (size_t q = 0; q < strokes[s].size(); ++q) {
            std::vector<ivec3> cells;
            voxelizeCut(strokes[s][q], m.kerf(), m.frame(), cells);
            for (const ivec3& c : cells) ref[{c.x, c.y, c.z}].push_back({uint32_t(s + 1), uint32_t(q)});
        }
    ASSERT_EQ(m.cutCellCount(), ref.size());
    const auto values = gridValues(m);
    ASSERT_EQ(values.size(), ref.size());
    for (const auto& [k, list] : ref) {
        const openvdb::Coord c(std::get<0>(k), std::get<1>(k), std::get<2>(k));
        const std::vector<QuadRef>* got = m.quadsAt(c);
        ASSERT_NE(got, nullptr);
        ASSERT_EQ(*got, list);
        ASSERT_EQ(values.at(k), int32_t(list.front().stroke));
    }
}

CutMask rebuild(const IndexFrame& f, double kerf, const std::vector<std::vector<Quad>>& strokes)
{
    CutMask m(f, kerf);
    for (const auto& s : strokes) {
        m.beginStroke();
        for (const Quad& q : s) m.addQuad(q);
    }
    return m;
}

} // namespace

TEST(CutMask, MatchesReferenceAndUndoEqualsRebuild)
{
    const IndexFrame f = smallFrame();
    std::mt19937_64 rng(4242);
    for (double kerf : {0.0, 0.6}) {
        const auto poseStrokes = makeRandomStrokes(f, 11, 8, 120, 0.4, 6.0);
        std::vector<std::vector<Quad>> all;
        for (const auto& ps : poseStrokes) all.push_back(filterStroke(ps, f));

        CutMask mask(f, kerf);
        std::vector<std::vector<Quad>> model; // the path the mask should hold
        std::vector<std::vector<Quad>> redo;  // model of the redo stack (quads per entry)
        std::vector<uint32_t> redoStroke;
        size_t next = 0;
        int ops = 0;
        while (ops < 150) {
            const int op = int(rng() % 5);
            if (op <= 1 && next < all.size()) { // add a stroke, quad by quad
                mask.beginStroke();
                model.emplace_back();
                redo.clear();
                redoStroke.clear();
                for (const Quad& q : all[next]) {
                    // lastNewCells = this quad's cells not cut before.
                    std::vector<ivec3> cells;
                    voxelizeCut(q, kerf, f, cells);
                    size_t fresh = 0;
                    for (const ivec3& c : cells) fresh += mask.isCut({c.x, c.y, c.z}) ? 0 : 1;
                    mask.addQuad(q);
                    ASSERT_EQ(mask.lastNewCells().size(), fresh);
                    model.back().push_back(q);
                }
                ++next;
            } else if (op == 2) {
                if (mask.undoStroke()) {
                    redo.push_back(model.back());
                    redoStroke.push_back(uint32_t(model.size()));
                    model.pop_back();
                } else {
                    ASSERT_TRUE(model.empty());
                }
            } else if (op == 3 && !model.empty()) { // back to an earlier stick
                const uint32_t n = uint32_t(rng() % (model.back().size() + 1));
                if (n < model.back().size()) {
                    redo.emplace_back(model.back().begin() + n, model.back().end());
                    redoStroke.push_back(uint32_t(model.size()));
                    model.back().resize(n);
                }
                mask.undoToQuad(n);
            } else if (op == 4) {
                const bool did = mask.redoStroke();
                ASSERT_EQ(did, !redo.empty());
                if (did) {
                    if (redoStroke.back() == model.size() + 1) model.emplace_back();
                    model.back().insert(model.back().end(), redo.back().begin(), redo.back().end());
                    redo.pop_back();
                    redoStroke.pop_back();
                }
            } else {
                continue;
            }
            ++ops;
            const CutMask fresh = rebuild(f, kerf, model);
            expectSameMask(mask, fresh);
            if (HasFatalFailure()) return;
            if (ops % 10 == 0) expectMatchesReference(mask, model);
            if (HasFatalFailure()) return;
        }
        // Undo everything: empty mask, pruned grid.
        while (mask.undoStroke()) {
        }
        EXPECT_EQ(mask.cutCellCount(), 0u);
        EXPECT_EQ(mask.grid()->activeVoxelCount(), 0u);
        EXPECT_EQ(mask.grid()->tree().leafCount(), 0u);
    }
}

TEST(CutMask, NoDepthLimit)
{
    // A tall scan (3000 slices): a vertical stroke through all of it.
    IndexFrame f;
    f.spacing = dvec3(0.5, 0.5, 0.5);
    f.dims = ivec3(64, 64, 3000);
    CutMask mask(f, 0.0);
    std::vector<Pose> poses;
    for (int i = 0; i < 40; ++i) {
        Pose p;
        p.time = i * 0.001;
        p.base = dvec3(5.0 + 0.5 * i + 0.25, 16.25, 1499.0);
        p.direction = dvec3(0, 0, -1);
        p.length = 1498.0;
        poses.push_back(p);
    }
    for (const Quad& q : filterStroke(poses, f)) mask.addQuad(q);
    // Cells reach from k = 2 (z = 1.0 mm) up to the top cell below z = 1499.
    const openvdb::CoordBBox box = mask.grid()->evalActiveVoxelBoundingBox();
    EXPECT_EQ(box.min().z(), 1);
    EXPECT_EQ(box.max().z(), 2998); // the base lies on grid plane 2998: both layers
    // x index 10.5..49.5 -> cells 10..49; y index 32.5 -> row 32; k 1..2998.
    EXPECT_EQ(mask.cutCellCount(), 40u * 2998u);
}

TEST(CutMask, InputThreadToGeometryThreadEqualsDirectBuild)
{
    const IndexFrame f = smallFrame();
    const auto strokes = makeRandomStrokes(f, 3, 6, 400, 0.3, 8.0);
    std::vector<std::string> lines = {"# test", "t,x,y,z,dx,dy,dz,length"};
    for (size_t s = 0; s < strokes.size(); ++s) {
        if (s) lines.push_back(s % 2 ? "stroke" : "");
        for (size_t i = 0; i < strokes[s].size(); ++i) {
            lines.push_back(formatPoseLine(strokes[s][i]));
            if (i == 100) lines.push_back("1,2,3"); // truncated line: an error item, stream goes on
        }
    }
    const double kerf = 0.4;
    for (bool voxelizeOnInput : {true, false}) {
        InputThreadOptions opt;
        opt.kerfMm = kerf;
        opt.voxelize = voxelizeOnInput;
        InputThread input(std::make_unique<MemoryLineSource>(lines), f, opt);
        CutMask mask(f, kerf);
        std::vector<std::string> errors;
        size_t applied = 0;
        std::thread geometry([&] {
            while (true) {
                const bool closed = input.queue().closed();
                applied += drainCutInfo(input.queue(), mask, &errors);
                if (closed) break;
                std::this_thread::yield();
            }
        });
        input.start();
        input.join();
        geometry.join();
        EXPECT_EQ(errors.size(), strokes.size());
        if (!errors.empty()) {
            EXPECT_NE(errors[0].find("memory:"), std::string::npos) << errors[0];
        }
        EXPECT_EQ(input.posesRead(), strokes.size() * 400);
        EXPECT_EQ(applied, input.quadsMade());
        std::vector<std::vector<Quad>> direct;
        for (const auto& s : strokes) direct.push_back(filterStroke(s, f));
        expectSameMask(mask, rebuild(f, kerf, direct));
    }
}

// The input thread's sticksKept counts every stick its filter kept: a pose's
// own, a held slide placed before the pose that left the blade's line (rule
// 2c), a retrace restart's (2b), and the last pose placed at a stroke's end;
// not the poses push() kept. On sliding saws (most poses held back) it equals
// the filter's own count, and exceeds the poses it reports kept.
TEST(CutMask, InputThreadCountsTheSticksItsFilterKept)
{
    const IndexFrame f = smallFrame();
    std::vector<std::string> lines = {"t,x,y,z,dx,dy,dz,length"};
    size_t sticks = 0, kept = 0, quads = 0;
    for (uint32_t seed = 0; seed < 4; ++seed) {
        SawingOptions o;
        o.poses = 300;
        o.slide = true;
        o.amplitudeMm = 3.0;
        o.feedMm = 0.02;
        const std::vector<Pose> stroke = makeSawingStroke(dvec3(0.0, 19.5, -10.0), seed, o);
        if (seed) lines.push_back("");
        PathFilter filter(f);
        std::vector<Quad> made;
        for (const Pose& p : stroke) {
            lines.push_back(formatPoseLine(p));
            kept += filter.push(p, made);
        }
        sticks += filter.sticks().size();
        const std::vector<Quad> last = filter.endStroke();
        sticks += last.empty() ? 0 : 1;
        quads += made.size() + last.size();
    }
    InputThreadOptions opt;
    opt.voxelize = false;
    InputThread input(std::make_unique<MemoryLineSource>(lines), f, opt);
    input.start();
    input.join(); // the queue grows without bound: nothing need drain it
    EXPECT_EQ(input.posesRead(), 4u * 300u);
    EXPECT_EQ(input.quadsMade(), quads);
    EXPECT_EQ(input.sticksKept(), sticks);
    EXPECT_GT(input.sticksKept(), kept) << "held slides placed before the pose that left the line";
    EXPECT_LT(input.sticksKept() * 4, input.posesRead()) << "most sliding poses are held back";
}

// quadSerial: one per quad as added, through undo and redo and into copies;
// the same quad added again gets a new one.
TEST(CutMask, QuadSerialsTellQuadsApartAndSurviveUndoRedo)
{
    const IndexFrame f = smallFrame();
    std::vector<Pose> poses;
    for (int i = 0; i < 6; ++i) {
        Pose p;
        p.time = i * 0.001;
        p.base = dvec3(-6.0 + 1.1 * i, 14.2, -2.0);
        p.direction = dvec3(0, 0, -1);
        p.length = 20.0;
        poses.push_back(p);
    }
    const std::vector<Quad> quads = filterStroke(poses, f);
    ASSERT_GE(quads.size(), 3u);
    CutMask mask(f, 0.0);
    mask.beginStroke();
    for (const Quad& q : quads) mask.addQuad(q);
    std::vector<uint64_t> serials;
    for (uint32_t q = 0; q < mask.quadCount(1); ++q) serials.push_back(mask.quadSerial({1, q}));
    for (size_t i = 0; i < serials.size(); ++i) {
        EXPECT_NE(serials[i], 0u);
        for (size_t j = 0; j < i; ++j) EXPECT_NE(serials[i], serials[j]);
    }
    // Undo to the first quad and redo: the same records, the same serials.
    mask.undoToQuad(1);
    ASSERT_TRUE(mask.redoStroke());
    for (uint32_t q = 0; q < mask.quadCount(1); ++q) EXPECT_EQ(mask.quadSerial({1, q}), serials[q]);
    const CutMask copy = mask;
    EXPECT_EQ(copy.quadSerial({1, 0}), serials[0]);
    // The same quad added again (after undo, or in another mask): a new serial.
    mask.undoToQuad(uint32_t(quads.size()) - 1);
    mask.addQuad(quads.back());
    EXPECT_NE(mask.quadSerial({1, uint32_t(quads.size()) - 1}), serials.back());
    CutMask other(f, 0.0);
    other.addQuad(quads.front());
    EXPECT_NE(other.quadSerial({1, 0}), serials.front());
}
