// LiveStroke: a stroke cut while it is drawn, updated after every quad, on
// the tooth and the 1 mm head (../shared/data; skipped when absent) and the
// built-in phantom. A refusal of the blade's momentary end is retried at the
// next update; one that stays stops the stroke where its last accepted
// update left it. Either way the cut equals a
// from-scratch cut of the same mask, and the fused mesh is clean.
#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/LiveStroke.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"
#include "tests/TestStrokes.h"
#include "tests/TestUtil.h"
#include "tests/TestVolumes.h"
#include "vdb/Phantom.h"
#include "vdb/VolumeIO.h"

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

using namespace mtcut;
using namespace mtcut::cutter;

namespace {

bool sameMesh(const Mesh& a, const Mesh& b)
{
    return a.positions == b.positions && a.indices == b.indices && a.triangleVoxels == b.triangleVoxels;
}

/// The cut of `mask` from scratch equals the live one (`remesher`'s), and is clean.
void expectSameAsFromScratch(const vdb::Volume& vol, float iso, const Mesh& uncut, const CutMask& mask,
                             const CutRemesher& remesher)
{
    CutRemesher scratch(vol, iso, uncut);
    scratch.update(mask);
    const Mesh fused = remesher.fusedMesh();
    EXPECT_TRUE(sameMesh(scratch.fusedMesh(), fused)) << "the live cut differs from a from-scratch cut";
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
}

/// The volume at `path` (the tooth, the 1 mm head) at 400 with kerf w, its
/// strokes for `seed` (test_cut_props' randomStrokes; with `saw`, the saw
/// worked back and forth of bench_strokes --saw), filtered with `filter`
/// (default: the filter they were recorded with, recordedFilter()), the
/// strokes before `live` cut whole.
struct StrokeCut
{
    StrokeCut(const std::string& path, double kerf, uint32_t seed, size_t live, float isovalue = 400.0f,
              const SawMotion* saw = nullptr, const PathFilterOptions* filter = nullptr)
        : iso(isovalue), vol(vdb::readVolume(path)),
          uncut(extractIsosurface(vol, isovalue, IsosurfaceOptions{nullptr, false})), mask(frameOf(vol), kerf),
          remesher(vol, isovalue, uncut)
    {
        const PathFilterOptions options = filter ? *filter : mtcut::test::recordedFilter();
        const auto strokes = saw ? makeSawingStrokes(uncut.positions, seed, int(live) + 1, *saw)
                                 : makeRandomStrokes(mask.frame(), seed, int(live) + 1, 150 + 50 * int(seed % 5),
                                                     0.4 + 0.2 * (seed % 4), 20.0 + 10.0 * (seed % 4));
        for (size_t s = 0; s < live; ++s) {
            mask.beginStroke();
            for (const Quad& q : filterStroke(strokes[s], mask.frame(), options)) mask.addQuad(q);
            remesher.update(mask);
        }
        quads = filterStroke(strokes[live], mask.frame(), options);
    }
    /// The cut of the same mask from scratch equals the live one, and is clean.
    void expectSameAsFromScratch() const { ::expectSameAsFromScratch(vol, iso, uncut, mask, remesher); }
    float iso;
    vdb::Volume vol;
    Mesh uncut;
    CutMask mask;
    CutRemesher remesher;
    std::vector<Quad> quads; ///< the live stroke's
};

} // namespace

// A refusal of where the blade stops for a moment: the 2 mm head at 400,
// kerf 0, a saw slid along its blade, seed 75106, stroke 0. Its first nine
// quads are accepted one by one; with its tenth (quad 9) the update is
// refused, with the eleventh it goes through. (Until the fifty-fourth
// session this was the tooth's random stroke 8046, stroke 1, at its second
// quad: its cap region at the blade's end is now split where its two sides
// shared a diagonal, and no early quad of the tooth's random strokes 8000-
// 8250 is refused any more.) Updated after every quad, the stroke is
// deferred once and then accepted whole. Without patience (1), and not
// stepping round, it stops at its first refusal.
constexpr uint32_t kMomentarySeed = 75106;
constexpr size_t kMomentaryQuad = 9; ///< the update that adds it is refused; the next is not

TEST(LiveStroke, ARefusalOfTheBladesMomentaryEndIsRetriedAtTheNextUpdate)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    const SawMotion slide = SawMotion::Slide;
    for (int patience : {LiveStroke::kPatience, 1}) {
        SCOPED_TRACE("patience " + std::to_string(patience));
        StrokeCut cut(path, 0.0, kMomentarySeed, 0, 400.0f, &slide);
        ASSERT_GT(cut.quads.size(), kMomentaryQuad + 10);
        const uint32_t strokesBefore = cut.mask.strokeCount();
        LiveStroke live(cut.mask, cut.remesher, patience, false);
        size_t deferred = 0, accepted = 0;
        for (size_t q = 0; q < cut.quads.size(); ++q) {
            if (!live.add(cut.quads[q])) break;
            const LiveStroke::Result r = live.update();
            deferred += r.outcome == LiveStroke::Outcome::Deferred;
            accepted += r.outcome == LiveStroke::Outcome::Accepted;
            if (q == kMomentaryQuad) {
                ASSERT_NE(r.outcome, LiveStroke::Outcome::Accepted) << "the update that adds quad 9 is no longer refused";
                EXPECT_NE(r.refusal.find("remesh: "), std::string::npos) << r.refusal;
            }
        }
        const LiveStroke::Result end = live.finish();
        EXPECT_EQ(end.outcome, LiveStroke::Outcome::Unchanged) << "nothing was left to cut at the end";
        if (patience == 1) {
            EXPECT_TRUE(live.stopped());
            EXPECT_EQ(accepted, kMomentaryQuad);
            EXPECT_EQ(live.acceptedQuads(), kMomentaryQuad);
            EXPECT_EQ(cut.mask.strokeCount(), strokesBefore + 1);
            EXPECT_EQ(cut.mask.quadCount(cut.mask.strokeCount()), kMomentaryQuad)
                << "the stroke is cut back to its last accepted update";
            EXPECT_FALSE(live.add(cut.quads[kMomentaryQuad + 1])) << "a stopped stroke took a quad";
        } else {
            EXPECT_EQ(deferred, 1u);
            EXPECT_EQ(accepted, cut.quads.size() - 1);
            EXPECT_FALSE(live.stopped());
            EXPECT_EQ(live.acceptedQuads(), cut.quads.size());
            EXPECT_EQ(cut.mask.quadCount(cut.mask.strokeCount()), cut.quads.size());
        }
        cut.expectSameAsFromScratch();
    }
}

// Tooth, kerf 0.5, seed 8004, stroke 0: a refusal that stays (two blade
// planes meet a cube edge a float step apart in a cell the later quads do not
// change; the whole stroke is refused too). Not stepping round it, the
// stroke stops after kPatience refused updates, cut back to its last
// accepted update, and takes no more quads.
TEST(LiveStroke, ARefusalThatStaysStopsTheStrokeAtItsLastAcceptedUpdate)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    StrokeCut cut(path, 0.5, 8004, 0);
    LiveStroke live(cut.mask, cut.remesher, LiveStroke::kPatience, false);
    size_t firstRefused = SIZE_MAX, updates = 0;
    LiveStroke::Result last;
    for (size_t q = 0; q < cut.quads.size() && live.add(cut.quads[q]); ++q) {
        last = live.update();
        ++updates;
        if (last.outcome != LiveStroke::Outcome::Accepted && firstRefused == SIZE_MAX) firstRefused = q;
        if (live.stopped()) break;
    }
    ASSERT_NE(firstRefused, SIZE_MAX) << "the stroke is no longer refused";
    ASSERT_TRUE(live.stopped());
    EXPECT_EQ(last.outcome, LiveStroke::Outcome::Stopped);
    EXPECT_NE(last.refusal.find("crosses or touches itself"), std::string::npos) << last.refusal;
    EXPECT_EQ(updates, firstRefused + size_t(LiveStroke::kPatience));
    EXPECT_EQ(live.acceptedQuads(), firstRefused);
    EXPECT_EQ(live.quads(), firstRefused);
    EXPECT_EQ(cut.mask.quadCount(cut.mask.strokeCount()), firstRefused);
    EXPECT_FALSE(live.add(cut.quads.back()));
    EXPECT_EQ(live.finish().outcome, LiveStroke::Outcome::Unchanged);
    cut.expectSameAsFromScratch();
}

// Not stepping round, a refusal at the stroke's last update stops it there,
// however patient; a stroke with nothing accepted leaves the mask; and an
// update with nothing new re-meshes nothing.
TEST(LiveStroke, TheLastUpdateDoesNotDeferAndAnEmptyUpdateDoesNothing)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    const SawMotion slide = SawMotion::Slide;
    StrokeCut cut(path, 0.0, kMomentarySeed, 0, 400.0f, &slide);
    const uint32_t strokesBefore = cut.mask.strokeCount();
    {
        LiveStroke live(cut.mask, cut.remesher, LiveStroke::kPatience, false);
        EXPECT_EQ(live.update().outcome, LiveStroke::Outcome::Unchanged);
        EXPECT_EQ(live.finish().outcome, LiveStroke::Outcome::Unchanged);
        EXPECT_FALSE(live.inMask());
        for (size_t q = 0; q < kMomentaryQuad; ++q) {
            ASSERT_TRUE(live.add(cut.quads[q]));
            ASSERT_EQ(live.update().outcome, LiveStroke::Outcome::Accepted) << "quad " << q;
        }
        ASSERT_TRUE(live.add(cut.quads[kMomentaryQuad]));
        EXPECT_EQ(live.update().outcome, LiveStroke::Outcome::Deferred);
        EXPECT_EQ(live.update().outcome, LiveStroke::Outcome::Unchanged) << "the same quads were tried again";
        EXPECT_EQ(live.quads(), kMomentaryQuad + 1);
        const LiveStroke::Result end = live.finish();
        EXPECT_EQ(end.outcome, LiveStroke::Outcome::Stopped);
        EXPECT_FALSE(end.refusal.empty());
        EXPECT_EQ(live.acceptedQuads(), kMomentaryQuad);
        EXPECT_EQ(cut.mask.quadCount(cut.mask.strokeCount()), kMomentaryQuad);
        cut.expectSameAsFromScratch();
    }
    ASSERT_TRUE(cut.mask.undoStroke());
    cut.remesher.update(cut.mask);
    {
        // Patience 1 and a refused first update: nothing of the stroke stays.
        LiveStroke live(cut.mask, cut.remesher, 1, false);
        for (size_t q = 0; q <= kMomentaryQuad; ++q) ASSERT_TRUE(live.add(cut.quads[q]));
        EXPECT_EQ(live.update().outcome, LiveStroke::Outcome::Stopped);
        EXPECT_FALSE(live.inMask());
        EXPECT_EQ(live.acceptedQuads(), 0u);
        EXPECT_EQ(cut.mask.strokeCount(), strokesBefore);
        cut.expectSameAsFromScratch();
    }
}

TEST(LiveStroke, PatienceBelowOneIsRefused)
{
    const vdb::Volume vol = test::fieldVolume(openvdb::Coord(8), openvdb::Vec3d(1.0), openvdb::Vec3d(0.0),
                                              [](const openvdb::Vec3d& p) { return 3.0 - (p - openvdb::Vec3d(4.0)).length(); });
    const Mesh uncut = extractIsosurface(vol, 0.0f, IsosurfaceOptions{nullptr, false});
    CutMask mask(frameOf(vol), 0.0);
    CutRemesher remesher(vol, 0.0f, uncut);
    EXPECT_THROW(LiveStroke(mask, remesher, 0), std::invalid_argument);
    EXPECT_NO_THROW(LiveStroke(mask, remesher, 1));
}

/// The live stroke `stroke` of `seed` on `path` at 400 with kerf w (the
/// strokes before it cut whole), updated after each of its first `quads`
/// quads (all when 0): every update accepted, and the cut then equals a
/// from-scratch cut of the same mask. `strokeQuads`, when given, pins the
/// stroke's whole length (the stroke the test was written for).
void expectEveryUpdateAccepted(const std::string& path, uint32_t seed, size_t stroke, size_t quads = 0,
                               size_t strokeQuads = 0, float iso = 400.0f)
{
    SCOPED_TRACE("seed " + std::to_string(seed) + " stroke " + std::to_string(stroke));
    StrokeCut cut(path, 0.5, seed, stroke, iso);
    if (strokeQuads != 0) {
        ASSERT_EQ(cut.quads.size(), strokeQuads);
    }
    if (quads == 0) quads = cut.quads.size();
    ASSERT_LE(quads, cut.quads.size());
    LiveStroke live(cut.mask, cut.remesher);
    size_t notAccepted = 0;
    for (size_t q = 0; q < quads; ++q) {
        ASSERT_TRUE(live.add(cut.quads[q])) << "stopped before quad " << q;
        const LiveStroke::Result r = live.update();
        if (r.outcome != LiveStroke::Outcome::Accepted && notAccepted++ == 0) ADD_FAILURE() << "quad " << q << ": " << r.refusal;
    }
    EXPECT_EQ(notAccepted, 0u);
    EXPECT_EQ(live.finish().outcome, LiveStroke::Outcome::Unchanged);
    EXPECT_EQ(cut.mask.quadCount(cut.mask.strokeCount()), quads);
    cut.expectSameAsFromScratch();
}

// The 1 mm head, kerf 0.5, seed 9065, stroke 0: at its 50th quad the
// isosurface's line on a kerf plane crossed faces z = 1053 and x = 212 of
// cell (212, 198, 53) 1.6e-5 mm apart beside their cube edge; both rounded
// onto the edge, the sliver of isosurface between them lay flat in face
// z = 1053 and the cap triangle below ran into it. Every later update was
// refused, and the stroke stopped with 49 of its 109 quads. Snap rounding
// now joins the two (FloatFolds.OnlyVerticesOfTwoFacesRoundACubeEdge...).
// Seeds 9103 (stroke 1, at quad 282 of 293) and 9239 (stroke 3, at quad 6
// of 335): two offset faces' line, one of its points a float step off the
// cube edge once rounded (y = 248.999985 mm beside y = 249).
TEST(LiveStroke, ASliverOfIsosurfaceRoundACubeEdgeDoesNotStopTheStroke)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectEveryUpdateAccepted(dir, 9065, 0, 0, 109);
    expectEveryUpdateAccepted(dir, 9239, 3, 20);
    expectEveryUpdateAccepted(dir, 9103, 1);
}

// The 1 mm head, kerf 0.5, seed 9202, stroke 0, from its 192nd quad: in
// cell (205, 295, 134) a tent of three triangles over a triangle of the
// face z = 1135 mm (bounded by the isosurface's line, a kerf plane's line
// and the face's diagonal), its apex 6.1e-5 mm below the face, rounded flat
// into it and overlapping itself; the float repair could not move the apex
// without laying a triangle into the face. When a cell's own triangles
// cross, it now may (FloatFolds.ATentOverAFaceTriangle...). At its 202nd
// quad it then stopped in another cell (two vertices of one face at one
// float position with no edge between them) until a face vertex rounded
// across an edge of the face was put back (FloatFolds.AFaceVertexRounded...):
// the whole stroke now runs.
TEST(LiveStroke, ATentRoundedIntoACellFaceIsFlattenedThere)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectEveryUpdateAccepted(dir, 9202, 0);
}

// Tooth, kerf 0.5, seed 9124, stroke 0: from its 6th quad on, quad 4's
// mitre face held a strip of cap between its lines with quad 4's and
// quad 5's offset faces, 1e-10 voxel wide and 0.08 long (the two offset
// faces nearly one plane), in cell (60, 73, 122); its one loop was too thin
// to count as an outline, and the kernel refused the cell ("region without
// outer loop"), so the stroke stopped at its 5th quad of 189 (seed 9159
// likewise). Such a loop is now the region's outline, fanned; rounded to
// float, the strip's triangles collapse.
TEST(LiveStroke, AStripOfCapThinnerThanDoubleDoesNotStopTheStroke)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectEveryUpdateAccepted(path, 9124, 0, 0, 189);
}

// Tooth, kerf 0.5, seed 9074, stroke 2: at its fifth quad, quad 3's rim line
// poked 2.2e-5 mm through quad 4's offset face in the face z = 10 of cell
// (69, 69, 9), so the face's section ran out to the rim line's point and
// back, the spike's base 9e-7 mm wide: one float point once written, and
// the two triangles at the spike lay on each other. Every update after was
// refused and the stroke stopped at its 4th quad of 300. Both cells of the
// face now close such a spike (FloatFolds.ASpikeOfAFacesSection...). Seeds
// 9082 (stroke 2, stopped at quad 18 of 211: a spike 3e-4 mm long in face
// y = 41) and 9160 (stroke 1, at quad 35 of 79) likewise, and 9099 (stroke
// 2, at quad 27 of 329), whose spike's base lies on the face's diagonal.
TEST(LiveStroke, ASpikeOfAFacesSectionThinnerThanAFloatStepDoesNotStopTheStroke)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectEveryUpdateAccepted(path, 9074, 2, 30, 300);
    expectEveryUpdateAccepted(path, 9082, 2, 40, 211);
    expectEveryUpdateAccepted(path, 9160, 1, 0, 79);
    expectEveryUpdateAccepted(path, 9099, 2, 40, 329);
}

// Tooth, kerf 0.5, seed 9127, stroke 0: from its 10th quad, a vertex inside
// a tet of cell (78, 24, 160), 3e-6 mm above the face z = 160 mm, rounded
// into the face; its triangle with two vertices of the face lay in the face
// and the cell below's triangle with an edge there ran through it, so the
// stroke stopped with 9 of its 245 quads. Seed 9065, stroke 2 (15 of 101,
// cell (50, 74, 159)) likewise. Such a vertex is now put a float step inside
// its cell (FloatFolds.APrivateVertexRoundedIntoItsCellsFace...).
TEST(LiveStroke, AVertexRoundedIntoItsCellsFaceDoesNotStopTheStroke)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectEveryUpdateAccepted(path, 9127, 0, 30, 245);
    expectEveryUpdateAccepted(path, 9065, 2, 30, 101);
}

// The 2 mm head at -300 (the skin), kerf 0.5, seed 9037, stroke 0: the
// blade pivots on its base corner, and the path filter splits the turn into
// two triangles, so three prisms meet round that corner. In face y = 278 mm
// of cells (82, 71, 30) and (82, 72, 30) the corner line of one prism passes
// 1.25e-5 mm beside the edge of another's section, and rounded to float (a
// step is 1.2e-4 mm at z = 1061 mm) it landed on that edge: the triangles
// crossed, and the stroke stopped with 61 of its 101 quads (7 updates
// deferred before). Both cells now write that vertex a float step over
// (FloatFolds.AFaceVertexRoundedAcrossAnEdgeOfTheFaceIsPutBackInBothCells).
// The tooth's seed 9033 (stroke 0 stopped at its 27th quad of 211: three
// blade lines within 2.7e-5 mm of each other in face z = 49) likewise.
TEST(LiveStroke, AFaceVertexRoundedAcrossAnEdgeOfTheFaceDoesNotStopTheStroke)
{
    MTCUT_REQUIRE_DATA(skin, "vhm_head_2mm.nhdr");
    expectEveryUpdateAccepted(skin, 9037, 0, 0, 101, -300.0f);
    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    expectEveryUpdateAccepted(tooth, 9033, 0, 40, 211);
}

// The 1 mm head, kerf 0.5, seed 9355, stroke 1: at its 124th quad, quad
// 123's corner line (its offset face's and its end face's line) met the
// isosurface 1.1e-4 mm below face z = 1209 of cells (307, 223, 208) and
// (307, 223, 209), 3e-4 mm beside where it crosses the face. Rounded, that
// notch closed in both cells onto the iso line's segment between the two
// faces' lines, which each cell's iso and cap triangles then used once each
// way: an edge used four times, and the stroke stopped with 123 of its 139
// quads. Snap rounding now joins its ends, leaving a pinch that fusion
// splits (FloatFolds.OnlyTwoVerticesOfATetFaceAFewFloatStepsApartJoinAtAPinch).
// The tooth's seed 9273 (stroke 1, stopped at its 29th quad of 211): an
// offset face crossed a tet face of cell (39, 81, 99) 8e-6 mm beside the
// isosurface's vertex on the cell's face diagonal, and the edge between
// them was used twice each way in that one cell.
TEST(LiveStroke, APinchInAFaceLeftByTheFloatRepairDoesNotStopTheStroke)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectEveryUpdateAccepted(dir, 9355, 1, 0, 139);
    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    expectEveryUpdateAccepted(tooth, 9273, 1, 40, 211);
}

/// A NRRD header in a fresh temporary folder of its own (so tests run in
/// parallel never share it) for the 2 mm head's data (`raw`) relabelled with
/// voxels of sx x sy x sz mm (its spacing only): anisotropic CT from the
/// cubic-voxel data. Removed, with its folder, when this goes.
struct RelabelledHead2mm
{
    RelabelledHead2mm(const std::string& raw, double sx, double sy, double sz)
        : path(dir.file("head_2mm.nhdr"))
    {
        std::ofstream h(path);
        h << "NRRD0004\ntype: int16\ndimension: 3\nspace: left-posterior-superior\nsizes: 192 176 122\n"
          << "space directions: (" << sx << ",0,0) (0," << sy << ",0) (0,0," << sz << ")\n"
          << "space origin: (74,134,1000)\nkinds: domain domain domain\nendian: little\nencoding: gzip\n"
          << "data file: " << raw << "\n";
    }
    RelabelledHead2mm(const RelabelledHead2mm&) = delete;
    RelabelledHead2mm& operator=(const RelabelledHead2mm&) = delete;
    test::TempDir dir;
    std::string path;
};

// The 2 mm head relabelled 0.8 x 0.8 x 2.4 mm (its header's spacing only),
// kerf 0.5, seed 10054, stroke 3: at its 26th quad a sideways step folds
// the stroke (quad 23 stands about 90 degrees off its neighbours), and
// quads 23-25 pivot on one point inside tet 4 of cell (55, 63, 82), leaving
// a tetrahedron of bone 2e-3 voxel thin between their rims and the
// isosurface. The float repair collapsed its short edge, and its other two
// faces lay on each other facing opposite ways: a self-contact, and the
// stroke stopped with 25 of its 335 quads. The tetrahedron now goes as a
// whole (FloatFolds.ATetrahedronWithAnEdgeBelowAFloatStepGoesAsAWhole).
TEST(LiveStroke, ASpikeOfBoneBetweenPivotingPrismsThinnerThanAFloatStepGoes)
{
    MTCUT_REQUIRE_DATA(raw, "vhm_head_2mm.raw.gz");
    const RelabelledHead2mm head(raw, 0.8, 0.8, 2.4);
    expectEveryUpdateAccepted(head.path, 10054, 3, 40, 335);
}

// The same 0.8 x 0.8 x 2.4 mm voxels, the skin at -300, kerf 0.5, seed
// 10023, stroke 3: at its 18th quad an offset plane crossed grid edge
// (92, 145, 21)-(92, 145, 22) 2.3e-3 mm from the isosurface's vertex, and
// the line where the two meet passed the edge a float step away. In each
// of the four cells round the edge the float repair's face rule merged that
// line's point in a face into the plane's vertex, joining it to the iso
// vertex along the edge: used twice each way, and the stroke stopped with
// 17 of its 296 quads. The face rule makes no new edge along a cube edge now
// (FloatFolds.TheFaceRuleMakesNoNewEdgeAlongACubeEdge).
TEST(LiveStroke, AFaceRuleMergeDoesNotJoinTwoVerticesOfACubeEdge)
{
    MTCUT_REQUIRE_DATA(raw, "vhm_head_2mm.raw.gz");
    const RelabelledHead2mm head(raw, 0.8, 0.8, 2.4);
    expectEveryUpdateAccepted(head.path, 10023, 3, 40, 296, -300.0f);
}

// The 2 mm head relabelled 0.45 x 0.45 x 1.25 mm (a clinical head CT's
// voxels), the skin at -300, kerf 0.5, seed 11033, stroke 1: at its 17th
// quad an offset face nearly parallel to the skin crossed the face diagonal
// (48, 147, 25)-(49, 147, 26) 2e-3 voxel from the isosurface's vertex
// there, and in each of the two cells of that face the float repair
// collapsed a short edge from a vertex of its own inner tet face onto the
// plane's vertex on the diagonal, which joined the two diagonal vertices by
// an edge in both cells: used twice each way, and the stroke stopped with
// 16 of its 304 quads (seed 11039, stroke 0, with 57 of 335, likewise). A
// collapse no longer makes an edge in a cell face that the cell did not
// have (FloatFolds.ACollapseMakesNoNewEdgeInACellFace).
TEST(LiveStroke, ACollapseOnBothSidesOfAFaceDoesNotJoinTwoVerticesOfItsDiagonal)
{
    MTCUT_REQUIRE_DATA(raw, "vhm_head_2mm.raw.gz");
    const RelabelledHead2mm head(raw, 0.45, 0.45, 1.25);
    expectEveryUpdateAccepted(head.path, 11033, 1, 40, 304, -300.0f);
    expectEveryUpdateAccepted(head.path, 11039, 0, 80, 335, -300.0f);
}

// The same clinical voxels and skin, kerf 0.5, seed 11001, stroke 1: the
// blade pivots on its tip, and consecutive quads bend by 2-5 degrees at a
// stick whose corner at the tip is sharper than the mitre's reach allows
// (tooSharpForMitre). Each prism then ended on its own end plane through
// the stick, which left a notch of skin between them on the outer side of
// the bend, thinner than a float step near the stick; its walls crossed
// grid edges a float step apart and touched once written, in cell (67, 51,
// 82), and the stroke stopped with 47 of its 183 quads (seed 11006, stroke
// 0, with 31 of 196; seed 11049, stroke 1, with 10 of 352). Such a joint is
// now mitred and the mitre capped at the sharp corner (makePrismGeom).
TEST(LiveStroke, AJointWithASharpCornerIsMitredAndCappedNotNotched)
{
    MTCUT_REQUIRE_DATA(raw, "vhm_head_2mm.raw.gz");
    const RelabelledHead2mm head(raw, 0.45, 0.45, 1.25);
    expectEveryUpdateAccepted(head.path, 11001, 1, 55, 183, -300.0f);
    expectEveryUpdateAccepted(head.path, 11006, 0, 40, 196, -300.0f);
    expectEveryUpdateAccepted(head.path, 11049, 1, 20, 352, -300.0f);
}

// The same clinical voxels and skin, kerf 0.5, seed 11042, stroke 0: the
// stroke folds back and forth, and at its 44th quad three end planes cross
// face y = 32 of cell (84, 31, 88) within 2e-5 voxel of each other. The
// float repair's face rule merged two of their points in the cell above
// the face and not in this one, where a triangle of its own lies in the
// face; the seam opened and the stroke stopped with 43 of its 254 quads.
// Both cells now merge them
// (FloatFolds.AFaceRuleCollapseThroughATriangleInTheFaceIsMadeAsAcrossTheFace).
TEST(LiveStroke, AFaceRuleMergeIsMadeOnBothSidesOfTheFaceOfAFoldingStroke)
{
    MTCUT_REQUIRE_DATA(raw, "vhm_head_2mm.raw.gz");
    const RelabelledHead2mm head(raw, 0.45, 0.45, 1.25);
    expectEveryUpdateAccepted(head.path, 11042, 0, 50, 254, -300.0f);
}

// Anisotropic voxels, as most CT has (the built-in phantom's are 0.47 x 0.47
// x 1 mm; at 128 x 128 x 64 here, 1.875 x 1.875 x 4): random strokes at kerf
// 0.5 and 1.5, updated after every quad, are all accepted. A prism's rim
// sides stood at right angles to its quad in index space, which leans up to
// about 30 degrees off the quad's world normal there; at a sharp corner of a
// quad the prism then reached out of the cells the mask cut (cutRegion),
// and its cap crossed into a cell nobody re-meshed: an open edge. Before the
// sides stood upright in world mm, these 80 strokes stopped 5 times and
// waited out 45 refused updates (seeds 5, 6, 9, 14 and 19 stopped); the
// full-size phantom of the README's main command stopped 9 of its first 36
// random strokes (seeds 10000-10008).
TEST(LiveStroke, RandomKerfStrokesOnTheAnisotropicPhantomAreAcceptedAtEveryQuad)
{
    vdb::PhantomOptions options;
    options.dims = openvdb::Coord(128, 128, 64);
    const vdb::Volume vol = vdb::makePhantom(options);
    ASSERT_NE(vol.spacing()[0], vol.spacing()[2]);
    const float iso = 700.0f;
    const Mesh uncut = extractIsosurface(vol, iso, IsosurfaceOptions{nullptr, false});
    size_t strokes = 0, updates = 0, notAccepted = 0;
    for (uint32_t seed = 1; seed <= 20; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        CutMask mask(frameOf(vol), seed % 2 ? 0.5 : 1.5);
        CutRemesher remesher(vol, iso, uncut);
        const auto all = makeRandomStrokes(mask.frame(), seed, 4, 150 + 50 * int(seed % 5), 0.4 + 0.2 * (seed % 4),
                                           20.0 + 10.0 * (seed % 4));
        for (const std::vector<Pose>& poses : all) {
            LiveStroke live(mask, remesher);
            for (const Quad& q : filterStroke(poses, mask.frame())) {
                if (!live.add(q)) break;
                const LiveStroke::Result r = live.update();
                ++updates;
                if (r.outcome != LiveStroke::Outcome::Accepted && notAccepted++ == 0)
                    ADD_FAILURE() << "stroke " << strokes << ": " << r.refusal;
            }
            EXPECT_EQ(live.finish().outcome, LiveStroke::Outcome::Unchanged);
            EXPECT_FALSE(live.stopped());
            ++strokes;
        }
        expectSameAsFromScratch(vol, iso, uncut, mask, remesher);
    }
    std::printf("anisotropic phantom: %zu strokes, %zu updates, %zu not accepted\n", strokes, updates, notAccepted);
    EXPECT_EQ(strokes, 80u);
    EXPECT_GT(updates, 5000u);
    EXPECT_EQ(notAccepted, 0u);
}

namespace {

/// Seed `seed`'s stroke `stroke` on `path` cut live (kerf, iso), a refusal
/// in it that stays (it stops when not stepping round): stepping round it,
/// the stroke goes through whole, its blade moved by no more than
/// kStepRoundMostVoxels, and the cut is what a from-scratch cut
/// of the mask gives, clean.
/// Returns the steps the stroke took (LiveStroke::steppedRound()).
uint32_t expectSteppedRound(const std::string& path, double kerf, uint32_t seed, size_t stroke, float iso,
                            const SawMotion* saw = nullptr)
{
    SCOPED_TRACE("seed " + std::to_string(seed) + " stroke " + std::to_string(stroke));
    uint32_t steps = 0;
    for (bool stepRound : {false, true}) {
        StrokeCut cut(path, kerf, seed, stroke, iso, saw);
        LiveStroke live(cut.mask, cut.remesher, LiveStroke::kPatience, stepRound);
        size_t stepped = 0;
        for (size_t q = 0; q < cut.quads.size() && live.add(cut.quads[q]); ++q) {
            const LiveStroke::Result r = q + 1 < cut.quads.size() ? live.update() : live.finish();
            if (r.steppedRound) {
                ++stepped;
                EXPECT_EQ(r.outcome, LiveStroke::Outcome::Accepted);
                EXPECT_NE(r.refusal.find("remesh: "), std::string::npos) << r.refusal;
            }
        }
        if (!stepRound) {
            EXPECT_TRUE(live.stopped()) << "the stroke no longer stops: take another";
            EXPECT_EQ(stepped, 0u);
            continue;
        }
        EXPECT_FALSE(live.stopped());
        EXPECT_GE(stepped, 1u);
        EXPECT_GE(live.steppedRound(), stepped); // an update may step round more than one refusal
        steps = live.steppedRound();
        EXPECT_EQ(live.acceptedQuads(), cut.quads.size());
        EXPECT_EQ(live.quads(), cut.quads.size());
        // Every corner of the stroke in the mask is one of the blade's or
        // stepped round from one, by at most the largest step; some moved.
        const glm::dvec3 sp = cut.mask.frame().spacing;
        const double most = LiveStroke::kStepRoundMostVoxels * std::min({sp.x, sp.y, sp.z});
        const uint32_t id = cut.mask.strokeCount();
        EXPECT_GE(cut.mask.quadCount(id), cut.quads.size());
        size_t moved = 0;
        for (uint32_t k = 0; k < cut.mask.quadCount(id); ++k) {
            const Quad& m = cut.mask.quad({id, k});
            for (uint32_t i = 0; i < m.cornerCount; ++i) {
                double nearest = 1e300;
                for (const Quad& q : cut.quads)
                    for (uint32_t j = 0; j < q.cornerCount; ++j)
                        nearest = std::min(nearest, glm::length(m.corners[i] - q.corners[j]));
                EXPECT_LE(nearest, most * (1.0 + 1e-9));
                moved += nearest > 0.0;
            }
        }
        EXPECT_GT(moved, 0u);
        cut.expectSameAsFromScratch();
    }
    return steps;
}

} // namespace

// Refusals that stay, each a coincidence below a float step, and each
// stepped round: the tooth, kerf 0.5, seed 8004, stroke 0 (two blade planes
// meet a cube edge a float step apart); the 2 mm head at 400, kerf 0.5,
// seed 12052, stroke 1 (five vertices of three quads' planes and the
// isosurface within 2e-5 mm of face y = 210 mm, at its 15th quad of 79);
// at kerf 0, a saw slid along its blade, seed 75103, stroke 1 (at its quad
// 37 of 110 the sheets of two slits' sides share an edge between two
// points of face y = 100 1.1e-3 mm apart: used twice each way); on
// clinical voxels (0.45 x 0.45 x 1.25 mm), their skin at -300, kerf 0.5,
// seed 13043, stroke 1 (an open edge beside the stick the waiting quad
// turns about: it goes through only turned 1e-2 voxel the other way).
// (The kerf-0 case was the clinical voxels' seed 11118, stroke 0, a stick
// crossing a face within a float step; since the float repair joins points
// on one side of a slit it goes through without a step.)
TEST(LiveStroke, ARefusalThatStaysIsSteppedRound)
{
    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    expectSteppedRound(tooth, 0.5, 8004, 0, 400.0f);
    MTCUT_REQUIRE_DATA(head2, "vhm_head_2mm.nhdr");
    expectSteppedRound(head2, 0.5, 12052, 1, 400.0f);
    const SawMotion slide = SawMotion::Slide;
    expectSteppedRound(head2, 0.0, 75103, 1, 400.0f, &slide);
    MTCUT_REQUIRE_DATA(raw, "vhm_head_2mm.raw.gz");
    const RelabelledHead2mm head(raw, 0.45, 0.45, 1.25);
    expectSteppedRound(head.path, 0.5, 13043, 1, -300.0f);
}

// A second refusal among the waiting quads: the 1 mm head at 400, kerf 3,
// seed 14123, stroke 3. Its quad 158 is refused (a side plane and the
// mitre of quad 157 cross grid edge (205, 187, 194)-(205, 187, 195) at one
// float point) and waits; stepped round, the quads that waited meet a
// second coincidence, the mitre of quads 164 and 165 a few float steps from
// face z = 1199 mm, which stopped the stroke (at 158 of 289 quads) while
// every quad waiting was stepped round at once. Stepped round one refusal
// at a time, it goes through whole, in two steps.
TEST(LiveStroke, ASecondRefusalAmongTheWaitingQuadsIsSteppedRoundInItsTurn)
{
    MTCUT_REQUIRE_DATA(head, "vhm-head-dicom");
    EXPECT_EQ(expectSteppedRound(head, 3.0, 14123, 3, 400.0f), 2u);
}

namespace {

/// The 2 mm head at 400, kerf 0, sawing strokes along the blade for `seed`
/// (makeSawingStrokes, as bench_strokes --saw slide): the strokes before
/// `stroke` cut whole, then that one updated after every quad, which must
/// neither stop nor step round: accepted whole, equal to the cut from
/// scratch and clean.
void expectSlidingSawAcceptedWhole(uint32_t seed, size_t stroke, size_t quadsInStroke)
{
    SCOPED_TRACE("seed " + std::to_string(seed) + " stroke " + std::to_string(stroke));
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    const SawMotion slide = SawMotion::Slide;
    StrokeCut cut(path, 0.0, seed, stroke, 400.0f, &slide);
    ASSERT_EQ(cut.quads.size(), quadsInStroke);
    LiveStroke live(cut.mask, cut.remesher);
    for (size_t q = 0; q < cut.quads.size(); ++q) {
        ASSERT_TRUE(live.add(cut.quads[q])) << "stopped before quad " << q;
        const LiveStroke::Result r = q + 1 < cut.quads.size() ? live.update() : live.finish();
        ASSERT_NE(r.outcome, LiveStroke::Outcome::Stopped) << "quad " << q << ": " << r.refusal;
        EXPECT_FALSE(r.steppedRound) << "quad " << q << ": " << r.refusal;
    }
    EXPECT_FALSE(live.stopped());
    EXPECT_EQ(cut.mask.quadCount(cut.mask.strokeCount()), cut.quads.size());
    cut.expectSameAsFromScratch();
}

/// The same on `name` (in the shared data) at 400, kerf 0: the sliding
/// saw's strokes before `stroke` cut whole, then that stroke's quads before
/// `step` in one update and quad `step` alone in the next (the update a live
/// stroke makes for it); both accepted, the result as from scratch, clean.
void expectSlidingSawStepAccepted(const char* name, uint32_t seed, size_t stroke, size_t quadsInStroke, size_t step)
{
    SCOPED_TRACE(std::string(name) + " seed " + std::to_string(seed) + " stroke " + std::to_string(stroke));
    MTCUT_REQUIRE_DATA(path, name);
    const SawMotion slide = SawMotion::Slide;
    StrokeCut cut(path, 0.0, seed, stroke, 400.0f, &slide);
    ASSERT_EQ(cut.quads.size(), quadsInStroke);
    cut.mask.beginStroke();
    for (size_t q = 0; q < step; ++q) cut.mask.addQuad(cut.quads[q]);
    ASSERT_NO_THROW(cut.remesher.update(cut.mask)) << "the quads before " << step;
    cut.mask.addQuad(cut.quads[step]);
    try {
        cut.remesher.update(cut.mask);
    } catch (const std::exception& e) {
        FAIL() << "quad " << step << " refused: " << e.what();
    }
    cut.expectSameAsFromScratch();
}

} // namespace

// Two chords of one quad's slit that share an end: the 2 mm head at 400,
// kerf 0, a saw slid along its blade (seed 75101, stroke 0). In cell (104,
// 74, 115), tet 3, quad 62's cap holds the chords 59-60 and 60-65, ends
// that differ only in the kind of one plane (quad 64's plane, its rim
// side). A chord's Steiner midpoint is named by a word for each end, a hash
// of the end's name; the words were CutVertexIdHash shifted right by two,
// which for such ends differs only in the bits shifted out: one name, one
// vertex for both midpoints, a cap piece folded over itself ("open boundary
// loop"), and the stroke stopped at 64 of its 148 quads. Each word now
// mixes all of the name (midpointWord).
TEST(LiveStroke, TwoChordsOfAQuadThatShareAnEndHaveTwoMidpoints)
{
    expectSlidingSawAcceptedWhole(75101, 0, 148);
}

// A saw slid along its blade turns it a little about a point of itself
// between two kept poses: the 2 mm head at 400, kerf 0, seed 75101, stroke
// 2. The two sticks of its quad 57 cross (the blade slid 1.6 mm along itself
// and turned by 6e-4 rad): the outline crossed itself, and the hull the
// re-mesher cuts had neither stick as an edge, so quad 57 joined neither
// neighbour. Quad 58, 8e-4 rad from it, lay over it: a piece of quad 57's
// cap had all three corners on quad 58's plane (two of them one point named
// twice), and the stroke stopped at quad 58 with "coplanar overlapping
// quads" in cell (69, 17, 97), taken until now for a stroke doubling back in
// its own plane. With the path filter turning such a stick to the last one's
// direction (rule 3 (a'), PathFilterOptions::turnCrossingSticks, off by
// default), the stroke is cut whole, live, never deferred.
TEST(LiveStroke, ASawTurnedAboutAPointOfItsBladeIsCutWhole)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    const SawMotion slide = SawMotion::Slide;
    for (bool turn : {false, true}) {
        SCOPED_TRACE(turn ? "crossing sticks turned" : "crossing sticks kept");
        PathFilterOptions filter = mtcut::test::recordedFilter();
        filter.turnCrossingSticks = turn;
        StrokeCut cut(path, 0.0, 75101, 2, 400.0f, &slide, &filter);
        LiveStroke live(cut.mask, cut.remesher);
        size_t deferred = 0;
        std::string refusal;
        for (size_t q = 0; q < cut.quads.size() && live.add(cut.quads[q]); ++q) {
            const LiveStroke::Result r = q + 1 < cut.quads.size() ? live.update() : live.finish();
            deferred += r.outcome == LiveStroke::Outcome::Deferred;
            EXPECT_FALSE(r.steppedRound) << "quad " << q << ": " << r.refusal;
            if (!r.refusal.empty() && refusal.empty()) refusal = r.refusal;
        }
        if (!turn) {
            EXPECT_TRUE(live.stopped()) << "the stroke no longer stops with its sticks crossing: take another";
            EXPECT_NE(refusal.find("coplanar overlapping quads"), std::string::npos) << refusal;
            continue;
        }
        EXPECT_FALSE(live.stopped()) << refusal;
        EXPECT_EQ(deferred, 0u) << refusal;
        EXPECT_EQ(live.acceptedQuads(), cut.quads.size());
        EXPECT_EQ(cut.mask.quadCount(cut.mask.strokeCount()), cut.quads.size());
        cut.expectSameAsFromScratch();
    }
}

// A chord whose walk passes a point placed off its line by the tie: the 2 mm
// head, kerf 0, sawing along the blade, seed 75120, stroke 2. At its quad
// 35, quad 26's chord in face x = 82 between cells (81, 16, 54) and (82, 16,
// 54) crosses quad 28's rim sides in cell (82, ...) only (quad 28 does not
// reach the other); the point on 28's side 1 lies 3e-12 voxel off the chord
// (the two planes are nearly parallel), the walk (splitChord) took it for
// another line and stopped, so cell (82, ...) gave the chord no midpoint and
// cell (81, ...) did: an open edge, stepped round. The walk now allows two
// ties off the line.
TEST(LiveStroke, AChordsWalkPassesAPointOffItsLineByTheTie)
{
    expectSlidingSawAcceptedWhole(75120, 2, 74);
}

// A zero-area triangle of three points on one side of a slit: the tooth at
// 400, kerf 0, sawing along the blade, seed 75409, stroke 1. At its quad 62,
// in cell (95, 62, 37), tet 4, a slit chord's midpoint on quad 54's minus
// side, the junction point of quads 54 and 55 and a point of quad 55's
// plane lay within 1.5e-5 mm (two float steps there): their triangle had no
// area once written, and the float repair joined no two of them because
// their side tags differed ({54-}, {54-, 55+}, {}). It now joins points
// whose tags differ on no slit's side (FloatRepair.cpp, sidesAgree); the
// update stepped round before.
TEST(LiveStroke, PointsOnOneSideOfASlitAFloatStepApartAreJoined)
{
    expectSlidingSawStepAccepted("tooth.nhdr", 75409, 1, 251, 62);
}
