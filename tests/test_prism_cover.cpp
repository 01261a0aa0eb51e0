// The prisms a cell's others cover (cutter/PrismCover.h): which ones the
// test finds, that it never calls one covered that sticks out of the
// others (random tilted slabs against sampling), and that leaving them out
// of a cell changes nothing of its surface (a saw worked back and forth on
// the 4 mm head: the same vertex names, the same triangle count, the
// positions on the cell's faces bit for bit and inside it within 1e-9
// voxel), while the kernel does far less.
#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/PrismCover.h"
#include "cutter/RemeshKernel.h"
#include "tests/TestUtil.h"
#include "vdb/VolumeIO.h"

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <map>
#include <random>
#include <vector>

using namespace mtcut;
using namespace mtcut::cutter;
using remesh_detail::coveredPrisms;
using remesh_detail::QuadGeom;
using glm::dvec3;
using openvdb::Coord;

namespace {

/// A slab between the planes n . x = lo and n . x = hi (index space),
/// bounded far outside the cell on the other axes.
QuadGeom slab(const dvec3& normal, double lo, double hi)
{
    QuadGeom g;
    const dvec3 n = glm::normalize(normal);
    auto side = [&](const dvec3& m, double d, double orient) {
        QuadGeom::Side s;
        s.plane.n = m;
        s.plane.d = d;
        s.orient = orient;
        g.sides.push_back(s);
    };
    side(n, lo, 1.0);  // n . x - lo >= 0
    side(n, hi, -1.0); // hi - n . x >= 0
    // Far ends on the two other directions (the cell is [0, 1]^3 or near).
    const dvec3 a = glm::normalize(glm::cross(n, std::abs(n.x) < 0.9 ? dvec3(1, 0, 0) : dvec3(0, 1, 0)));
    const dvec3 b = glm::cross(n, a);
    for (const dvec3& m : {a, b}) {
        side(m, -50.0, 1.0);
        side(m, 50.0, -1.0);
    }
    return g;
}

const dvec3 kX(1, 0, 0);

std::vector<char> covered(const std::vector<QuadGeom>& quads) { return coveredPrisms(Coord(0, 0, 0), quads); }

} // namespace

TEST(PrismCover, FindsTheSlabsInsideTheOthers)
{
    using V = std::vector<char>;
    // Two prisms: not tested.
    EXPECT_EQ(covered({slab(kX, 0.2, 0.8), slab(kX, 0.3, 0.7)}), (V{0, 0}));
    // Nested: the inner ones go, the outer stays.
    EXPECT_EQ(covered({slab(kX, 0.2, 0.8), slab(kX, 0.3, 0.7), slab(kX, 0.25, 0.75)}), (V{0, 1, 1}));
    // Covered only by two together (two pieces left after the first).
    EXPECT_EQ(covered({slab(kX, 0.1, 0.5), slab(kX, 0.4, 0.9), slab(kX, 0.2, 0.8)}), (V{0, 0, 1}));
    // Sticking out by less than the margin of the others: kept. Two equal
    // slabs: both kept (each reaches the other's faces); a third inside
    // them by more than the margin goes.
    EXPECT_EQ(covered({slab(kX, 0.2, 0.8), slab(kX, 0.2 + 1e-7, 0.8), slab(kX, 0.5, 0.6)}), (V{0, 0, 1}));
    EXPECT_EQ(covered({slab(kX, 0.2, 0.8), slab(kX, 0.2, 0.8), slab(kX, 0.2 + 1e-5, 0.8 - 1e-5)}), (V{0, 0, 1}));
    // Only touching the cell (its face x = 1) or outside it: kept whatever
    // covers it, since its planes may hold the surface on that face.
    EXPECT_EQ(covered({slab(kX, 1.0, 1.5), slab(kX, 0.5, 2.0), slab(kX, 0.6, 2.0)}), (V{0, 0, 1}));
    EXPECT_EQ(covered({slab(kX, 1.2, 1.5), slab(kX, 0.5, 2.0), slab(kX, 0.6, 2.0)}), (V{0, 0, 1}));
    // Crossing slabs (an X): neither covers the other; a third inside
    // their union near the crossing but out of it elsewhere stays.
    EXPECT_EQ(covered({slab(dvec3(1, 0.3, 0), 0.3, 0.6), slab(dvec3(1, -0.3, 0), 0.3, 0.6), slab(kX, 0.35, 0.55)}),
              (V{0, 0, 0}));
}

// Random nearly parallel slabs through the cell, tilted a little, as a saw's
// passes are: every prism called covered has no sample point of its part
// of the cell outside the prisms kept (the test is conservative), and the
// kept ones cover every sample the dropped ones held.
TEST(PrismCover, NeverDropsAPrismThatSticksOut)
{
    std::mt19937 rng(20261204);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    size_t droppedAll = 0, tested = 0;
    for (int trial = 0; trial < 300; ++trial) {
        const int k = 3 + int(rng() % 8);
        std::vector<QuadGeom> quads;
        for (int i = 0; i < k; ++i) {
            const dvec3 n = glm::normalize(dvec3(1.0, 0.02 * (u(rng) - 0.5), 0.02 * (u(rng) - 0.5)));
            const double centre = 0.5 + 0.06 * (u(rng) - 0.5), halfWidth = trial % 3 == 0 ? 0.05 : 0.25;
            quads.push_back(slab(n, centre - halfWidth, centre + halfWidth));
        }
        const std::vector<char> cov = covered(quads);
        auto in = [](const QuadGeom& g, const dvec3& x) {
            for (const auto& s : g.sides)
                if (!(s.orient * s.plane.h(x) >= 0)) return false;
            return true;
        };
        for (int sample = 0; sample < 4000; ++sample) {
            const dvec3 x(u(rng), u(rng), u(rng));
            bool inDropped = false, inKept = false;
            for (size_t i = 0; i < size_t(k); ++i)
                if (in(quads[i], x)) (cov[i] ? inDropped : inKept) = true;
            ASSERT_FALSE(inDropped && !inKept) << "trial " << trial << ": a dropped prism holds (" << x.x << ", " << x.y
                                               << ", " << x.z << "), which no kept one does";
        }
        for (char c : cov) droppedAll += size_t(c);
        tested += size_t(k);
    }
    // And it does find them: most of a pile of passes is covered.
    std::printf("random slabs: %zu of %zu prisms covered\n", droppedAll, tested);
    EXPECT_GT(droppedAll, tested / 3);
}

// A saw worked back and forth on the 4 mm head at kerf 0.5 (the sawing
// tests' eight seeds, default retrace tolerance, every quad of four strokes
// in the mask): in each cell with covered prisms, the kernel's output with
// them and without has the same vertex names, the same number of
// triangles, the vertices on the cell's faces bit for bit, and those
// inside a tet within 1e-9 voxel (the arrangement's intermediate points
// differ, so the last bits of a point inside a tet can, and a region's
// diagonals may be chosen otherwise; measured: 1.3e-10). The cells lose
// about half their prisms and the kernel more than half its time there.
TEST(PrismCover, LeavingThemOutChangesNoSurface)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    remesh_detail::CellKernel kernel(vol, 400.0f);
    size_t cutCells = 0, withCovered = 0, prisms = 0, kept = 0, bitForBit = 0;
    double maxMove = 0.0, withMs = 0.0, withoutMs = 0.0;
    for (uint32_t seed : {102u, 104u, 105u, 106u, 108u, 111u, 115u, 117u}) {
    CutMask mask(frameOf(vol), 0.5);
    for (const std::vector<Pose>& poses : makeSawingStrokes(uncut.positions, seed, 4, SawMotion::Both)) {
        mask.beginStroke();
        for (const Quad& q : filterStroke(poses, mask.frame())) mask.addQuad(q);
    }
    std::vector<Coord> cells;
    mask.forEachCutCell([&](const Coord& c, const std::vector<QuadRef>&) { cells.push_back(c); });
    cutCells += cells.size();
    for (const Coord& c : cells) {
        remesh_detail::dropCoveredPrismsForTesting(false);
        const std::vector<QuadGeom> all = remesh_detail::kernelQuadsOf(mask, c);
        remesh_detail::dropCoveredPrismsForTesting(true);
        const std::vector<QuadGeom> some = remesh_detail::kernelQuadsOf(mask, c);
        ASSERT_LE(some.size(), all.size());
        if (some.size() == all.size()) continue;
        ++withCovered;
        prisms += all.size();
        kept += some.size();
        CutCellGeometry a, b;
        auto t0 = std::chrono::steady_clock::now();
        kernel.remesh(c, all, true, a);
        auto t1 = std::chrono::steady_clock::now();
        kernel.remesh(c, some, true, b);
        auto t2 = std::chrono::steady_clock::now();
        withMs += std::chrono::duration<double, std::milli>(t1 - t0).count();
        withoutMs += std::chrono::duration<double, std::milli>(t2 - t1).count();
        SCOPED_TRACE("cell (" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ", " + std::to_string(c.z()) + ")");
        ASSERT_EQ(a.indices.size(), b.indices.size());
        std::map<CutVertexId, dvec3> names;
        for (size_t v = 0; v < a.vertexIds.size(); ++v) names[a.vertexIds[v]] = a.indexPositions[v];
        ASSERT_EQ(names.size(), a.vertexIds.size());
        ASSERT_EQ(b.vertexIds.size(), a.vertexIds.size());
        for (size_t v = 0; v < b.vertexIds.size(); ++v) {
            auto it = names.find(b.vertexIds[v]);
            ASSERT_NE(it, names.end()) << "a vertex name only without the covered prisms";
            const double move = glm::length(it->second - b.indexPositions[v]);
            if (b.vertexIds[v].dim < 3) {
                ASSERT_EQ(move, 0.0) << "a vertex on the cell's faces moved (dim " << int(b.vertexIds[v].dim) << ")";
            }
            maxMove = std::max(maxMove, move);
        }
        bitForBit += a.vertexIds == b.vertexIds && a.indexPositions == b.indexPositions && a.indices == b.indices;
    }
    }
    std::printf("4 mm head, eight sawing seeds, kerf 0.5: %zu of %zu cut cells have covered prisms; %zu of their %zu "
                "prisms kept; %zu cells bit for bit the same; positions within %.3g voxel; kernel %.0f ms with them, "
                "%.0f without\n",
                withCovered, cutCells, kept, prisms, bitForBit, maxMove, withMs, withoutMs);
    EXPECT_LT(maxMove, 1e-9);
    EXPECT_GT(withCovered, 300u);
    EXPECT_LT(5 * kept, 3 * prisms);
    EXPECT_LT(2 * withoutMs, withMs);
}
