// Mask coding (DESIGN "GPU passes"): the sparse cut mask tiled for the GPU.
// For seeded random masks - one taller than 1024 slices, one with more than
// 2048 leaves, cells at negative indices - the atlas written by the GPU
// (points, OR logic-op into 4 integer attachments) equals the atlas built on
// the CPU from the leaf masks, bit for bit, and both decode to exactly the
// mask's cells; the shader lookup answers the same for set and unset cells.
#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "render/MaskAtlas.h"
#include "render/MaskTiling.h"
#include "tests/TestVolumes.h"
#include "tests/test_render_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <random>
#include <set>

using namespace mtcut;
using namespace mtcut::render;
using openvdb::Coord;

namespace {

/// `count` random cells in [lo, hi] (seeded), plus a few dense blobs so that
/// whole tiles and tile borders are exercised.
openvdb::MaskGrid::Ptr randomMask(uint32_t seed, Coord lo, Coord hi, size_t count, int blobs)
{
    std::mt19937 rng(seed);
    auto uniform = [&](int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); };
    openvdb::MaskGrid::Ptr g = openvdb::MaskGrid::create();
    auto acc = g->getAccessor();
    for (size_t n = 0; n < count; ++n) acc.setValueOn(Coord(uniform(lo.x(), hi.x()), uniform(lo.y(), hi.y()), uniform(lo.z(), hi.z())));
    for (int b = 0; b < blobs; ++b) {
        const Coord c(uniform(lo.x(), hi.x()), uniform(lo.y(), hi.y()), uniform(lo.z(), hi.z()));
        const int r = uniform(1, 6);
        for (int x = -r; x <= r; ++x)
            for (int y = -r; y <= r; ++y)
                for (int z = -r; z <= r; ++z) {
                    const Coord p = c + Coord(x, y, z);
                    if (x * x + y * y + z * z <= r * r && p.x() >= lo.x() && p.y() >= lo.y() && p.z() >= lo.z() &&
                        p.x() <= hi.x() && p.y() <= hi.y() && p.z() <= hi.z()) {
                        acc.setValueOn(p);
                    }
                }
    }
    return g;
}

std::vector<Coord> activeCells(const openvdb::MaskGrid& g)
{
    std::vector<Coord> out;
    for (auto it = g.tree().cbeginValueOn(); it; ++it) out.push_back(it.getCoord());
    std::sort(out.begin(), out.end());
    return out;
}

/// The whole chain for one mask: CPU tiling, GPU coding, CPU upload, lookups.
void checkMask(const openvdb::MaskGrid& grid, const Coord& lo, const Coord& hi, uint32_t seed, const std::string& what)
{
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<Coord> cells = activeCells(grid);
    const MaskTiling tiling = tileMask(grid.tree());
    ASSERT_EQ(tiling.slotCount(), grid.tree().leafCount()) << what;
    // CPU tiles decode to exactly the mask's cells.
    std::vector<Coord> decoded = tiling.cells();
    std::sort(decoded.begin(), decoded.end());
    ASSERT_EQ(decoded, cells) << what;

    MaskAtlas atlas(tiling);
    // GPU coding, cells in a shuffled order (OR makes the order irrelevant).
    std::vector<Coord> shuffled = cells;
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(seed));
    atlas.writeCells(shuffled);
    const std::vector<uint32_t> gpuWords = atlas.readWords();
    ASSERT_EQ(gpuWords.size(), tiling.words.size()) << what;
    size_t differing = 0;
    for (size_t i = 0; i < gpuWords.size(); ++i) differing += gpuWords[i] != tiling.words[i];
    EXPECT_EQ(differing, 0u) << what << ": GPU-coded words differ from the CPU tiles";

    // Lookups in the shader: every set cell, and as many unset ones (random,
    // in and around the box, half of them in tiles that exist).
    std::vector<Coord> queries = cells;
    std::mt19937 rng(seed + 1);
    auto uniform = [&](int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); };
    std::vector<uint8_t> expected(cells.size(), 1);
    for (size_t n = 0; n < cells.size(); ++n) {
        Coord q;
        if (n % 2) {
            q = cells[size_t(uniform(0, int(cells.size()) - 1))] + Coord(uniform(-2, 2), uniform(-2, 2), uniform(-2, 2));
        } else {
            q = Coord(uniform(lo.x() - 9, hi.x() + 9), uniform(lo.y() - 9, hi.y() + 9), uniform(lo.z() - 9, hi.z() + 9));
        }
        queries.push_back(q);
        expected.push_back(uint8_t(grid.tree().isValueOn(q)));
        EXPECT_EQ(tiling.isSet(q), bool(expected.back()));
    }
    EXPECT_EQ(atlas.queryCells(queries), expected) << what << ": GPU lookup (GPU-coded atlas)";

    // CPU fallback: the same words, the same answers.
    atlas.uploadTiles(tiling);
    EXPECT_EQ(atlas.readWords(), tiling.words) << what;
    EXPECT_EQ(atlas.queryCells(queries), expected) << what << ": GPU lookup (uploaded atlas)";
    std::printf("%s: %zu cells, %zu tiles (atlas %dx%d), leaf box %dx%dx%d, %.0f ms\n", what.c_str(), cells.size(),
                tiling.slotCount(), atlas.atlasWidth(), atlas.atlasHeight(), tiling.leafExtent.x(),
                tiling.leafExtent.y(), tiling.leafExtent.z(),
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
}

} // namespace

TEST(RenderMask, TilingOfAnEmptyMaskIsEmpty)
{
    const MaskTiling t = tileMask(openvdb::MaskGrid::create()->tree());
    EXPECT_TRUE(t.empty());
    EXPECT_FALSE(t.isSet(Coord(0)));
    MTCUT_REQUIRE_GL();
    MaskAtlas atlas(t);
    atlas.writeCells({Coord(1, 2, 3)}); // in no tile: ignored
    EXPECT_TRUE(atlas.readWords().empty());
    EXPECT_EQ(atlas.queryCells({Coord(1, 2, 3), Coord(0)}), (std::vector<uint8_t>{0, 0}));
}

TEST(RenderMask, TileBitsAreOpenVdbLeafOrder)
{
    openvdb::MaskGrid::Ptr g = openvdb::MaskGrid::create();
    g->tree().setValueOn(Coord(-1, 9, 2)); // leaf (-8, 8, 0), local (7, 1, 2)
    const MaskTiling t = tileMask(g->tree());
    ASSERT_EQ(t.slotCount(), 1u);
    EXPECT_EQ(t.leafOrigins[0], Coord(-8, 8, 0));
    EXPECT_EQ(t.leafMin, Coord(-1, 1, 0));
    EXPECT_EQ(t.leafExtent, Coord(1));
    const int n = 7 * 64 + 1 * 8 + 2;
    EXPECT_EQ(tileBitOf(Coord(-1, 9, 2)), n);
    for (int w = 0; w < kTileWords; ++w) EXPECT_EQ(t.words[size_t(w)], w == n / 32 ? 1u << (n % 32) : 0u) << w;
    EXPECT_TRUE(t.isSet(Coord(-1, 9, 2)));
    EXPECT_FALSE(t.isSet(Coord(-1, 9, 3)));
}

TEST(RenderMask, GpuCodingEqualsCpuTilesOnRandomMasks)
{
    MTCUT_REQUIRE_GL();
    for (uint32_t seed : {1u, 2u, 3u}) {
        const Coord lo(0), hi(63, 47, 39);
        checkMask(*randomMask(seed, lo, hi, 1500, 6), lo, hi, seed, "64x48x40 seed " + std::to_string(seed));
    }
}

TEST(RenderMask, TallVolumeOver1024Slices)
{
    MTCUT_REQUIRE_GL();
    const Coord lo(0), hi(15, 15, 1499); // a 16x16x1500 index box
    checkMask(*randomMask(7, lo, hi, 20000, 40), lo, hi, 7, "16x16x1500");
}

TEST(RenderMask, MoreThan2048TilesAndNegativeCells)
{
    MTCUT_REQUIRE_GL();
    const Coord lo(-1, -1, -1), hi(95, 95, 1099); // border cells at -1, as the remesher's
    const openvdb::MaskGrid::Ptr g = randomMask(11, lo, hi, 30000, 20);
    ASSERT_GT(g->tree().leafCount(), 2048u);
    checkMask(*g, lo, hi, 11, "97x97x1101 from -1");
}

TEST(RenderMask, CutMaskOfAStrokeCodesExactly)
{
    MTCUT_REQUIRE_GL();
    const vdb::Volume vol = test::fieldVolume(Coord(40, 40, 1100), openvdb::Vec3d(1.0), openvdb::Vec3d(-19.5, -19.5, 0),
                                              [](const openvdb::Vec3d& p) { return 15.0 - std::hypot(p.x(), p.y()); });
    cutter::CutMask mask(cutter::frameOf(vol), 0.0);
    std::vector<cutter::Pose> poses;
    for (int i = 0; i <= 400; ++i) { // a slanted stroke down the tall cylinder
        cutter::Pose p;
        p.time = 0.001 * i;
        p.base = glm::dvec3(-25.0 + 50.0 * i / 400.0, 0.3 + 0.1 * i / 400.0, 1090.0);
        p.direction = glm::dvec3(0.05, 0.0, -1.0);
        p.length = 1085.0;
        poses.push_back(p);
    }
    const std::vector<cutter::Quad> quads = cutter::filterStroke(poses, mask.frame());
    mask.beginStroke();
    for (const cutter::Quad& q : quads) mask.addQuad(q);
    ASSERT_GT(mask.cutCellCount(), 1000u);
    const openvdb::MaskGrid::Ptr g = cutCellGrid(mask);
    ASSERT_EQ(g->tree().activeVoxelCount(), mask.cutCellCount());
    mask.forEachCutCell([&](const Coord& c, const auto&) { ASSERT_TRUE(g->tree().isValueOn(c)); });
    checkMask(*g, Coord(0), Coord(38, 38, 1098), 5, "cut mask of a stroke");
}
