// The discard pass and the surface frames (DESIGN "GPU passes"): the uncut
// isosurface drawn with its cut cells discarded by primitive id, plus the cut
// cells' geometry, gives the frame of the CPU-fused mesh.
//
// Oracle tolerance. Both frames draw the same triangles in the same order
// (fusedMesh keeps the uncut triangles outside the cut cells in order, then
// appends the cut cells' triangles, cells ascending; the discard frame draws
// the uncut mesh, dropping the cut cells' triangles, then the cut geometry in
// the same order). What may differ is rounding: the cut geometry's
// marching-tetrahedra vertices come from the re-mesher's double arithmetic
// (the fused mesh reuses the uncut floats) and their normals are recomputed
// from the volume, so positions and normals can differ in the last float
// bits. That moves colours by far less than 1/255 except where a pixel
// centre lies within ~1e-6 pixel of a triangle edge and changes owner.
// Bound: fewer than 0.1 % of covered pixels differ by more than 2/255 in any
// colour channel, or in fragment id; measured differences are printed.
// This holds for the cut geometry with the fused mesh's normals
// (CutNormals::Fused). With the shading normals mtcut render uses
// (CutNormals::Shading: gradient normals on isosurface pieces, the blade's on
// caps) only the shading of the cut geometry's own pixels may change: depth
// and fragment ids stay bit for bit those of the fused frame, and every pixel
// whose colour differs is one the cut geometry covers.
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"
#include "render/CutGeometry.h"
#include "render/MaskTiling.h"
#include "render/SurfaceRenderer.h"
#include "tests/TestStrokes.h"
#include "tests/TestUtil.h"
#include "tests/TestVolumes.h"
#include "tests/test_render_util.h"
#include "vdb/VolumeIO.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <set>

using namespace mtcut;
using namespace mtcut::render;
using mtcut::test::straightStroke;
using openvdb::Coord;

namespace {


struct Comparison
{
    size_t covered = 0;          ///< pixels covered in either frame
    size_t colourOver2 = 0;      ///< covered pixels with a channel differing by > 2/255
    size_t fragmentDiffer = 0;   ///< covered pixels with another fragment id
    int maxColourDiff = 0;
    size_t sameBits = 0;         ///< pixels with identical colour bytes
};

Comparison compare(const Frame& a, const Frame& b)
{
    Comparison c;
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.height, b.height);
    for (size_t p = 0; p < a.pixelCount(); ++p) {
        const bool covered = a.fragments[p] != 0 || b.fragments[p] != 0;
        int d = 0;
        for (int ch = 0; ch < 4; ++ch) d = std::max(d, std::abs(int(a.rgba[4 * p + size_t(ch)]) - int(b.rgba[4 * p + size_t(ch)])));
        c.sameBits += d == 0;
        if (!covered) continue;
        ++c.covered;
        c.maxColourDiff = std::max(c.maxColourDiff, d);
        c.colourOver2 += d > 2;
        c.fragmentDiffer += a.fragments[p] != b.fragments[p];
    }
    return c;
}

/// Renders `views` of the cut two ways (discard + cut geometry; fused mesh)
/// and checks the bound. Returns the discard frames.
std::vector<Frame> checkOracle(const vdb::Volume& vol, float iso, const cutter::Mesh& uncut, const cutter::CutMask& mask,
                               const std::vector<std::string>& views, int size, const std::string& what,
                               size_t expectFragments)
{
    cutter::CutRemesher remesher(vol, iso, uncut);
    remesher.update(mask);
    std::vector<uint32_t> source;
    const cutter::Mesh fused = remesher.fusedMesh(&source);
    const CutGeometry cut = cutGeometryOf(remesher, vol, iso, CutNormals::Fused);
    const CutGeometry shadedCut = cutGeometryOf(remesher, vol, iso, CutNormals::Shading);
    EXPECT_EQ(shadedCut.mesh.indices.size(), cut.mesh.indices.size());
    EXPECT_EQ(shadedCut.triangleIsCap, cut.triangleIsCap);
    if (!remesher.cells().empty()) { // a cell without one cap flag per triangle is refused, not read past
        cutter::CutCellGeometry extraFlag = remesher.cells().begin()->second;
        extraFlag.cap.push_back(1);
        EXPECT_THROW(cutGeometryOfCells({{remesher.cells().begin()->first, &extraFlag}}, vol, iso, CutNormals::Shading),
                     std::invalid_argument);
    }
    std::vector<uint32_t> uncutIds, cutIds;
    discardFragmentIds(remesher, fused, source, uncutIds, cutIds);
    const std::vector<uint32_t> fusedIds = fragmentIdsOf(fused);
    const uint32_t fragments = *std::max_element(fusedIds.begin(), fusedIds.end());
    if (expectFragments) {
        EXPECT_EQ(fragments, expectFragments) << what;
    }

    SurfaceRenderer discard(size, size), shaded(size, size), oracle(size, size);
    const MaskTiling cells = tileMask(remeshedCellGrid(remesher)->tree());
    discard.setSurface(uncut, uncutIds);
    discard.setCutCells(cells);
    discard.setCutGeometry(cut.mesh, cutIds, cut.triangleIsCap);
    shaded.setSurface(uncut, uncutIds);
    shaded.setCutCells(cells);
    shaded.setCutGeometry(shadedCut.mesh, cutIds, shadedCut.triangleIsCap);
    oracle.setSurface(fused, fusedIds);
    std::vector<Frame> frames;
    for (const std::string& view : views) {
        const Camera camera = cameraFor(view, discard.bounds(), 1.0);
        RenderStyle style;
        discard.render(camera, style);
        oracle.render(camera, style);
        const Frame a = discard.readFrame(), b = oracle.readFrame();
        const Comparison c = compare(a, b);
        std::printf("%s, view %s: %zu covered pixels, %zu identical colour pixels of %zu, %zu differ by > 2/255 "
                    "(max %d/255), %zu in fragment id; cut cells %zu, fragments %u\n",
                    what.c_str(), view.c_str(), c.covered, c.sameBits, a.pixelCount(), c.colourOver2, c.maxColourDiff,
                    c.fragmentDiffer, remesher.cutCellCount(), fragments);
        EXPECT_GT(c.covered, a.pixelCount() / 10) << what << " " << view << ": the surface should fill the frame";
        EXPECT_LT(double(c.colourOver2), 1e-3 * double(c.covered)) << what << " " << view;
        EXPECT_LT(double(c.fragmentDiffer), 1e-3 * double(c.covered)) << what << " " << view;
        // Every fragment of the cut is seen in some view (ids are exactly 0..fragments).
        for (uint32_t id : a.fragments) EXPECT_LE(id, fragments);

        // Shading normals: same coverage, depth and ids; colour changes only
        // on the cut geometry's pixels (those the highlight recolours).
        shaded.render(camera, style);
        const Frame s = shaded.readFrame();
        RenderStyle lit = style;
        lit.highlight = true;
        shaded.render(camera, lit);
        const Frame h = shaded.readFrame();
        EXPECT_EQ(s.fragments, b.fragments) << what << " " << view;
        EXPECT_EQ(s.depth, b.depth) << what << " " << view;
        size_t cutPixels = 0, recoloured = 0, outside = 0;
        for (size_t p = 0; p < s.pixelCount(); ++p) {
            const bool onCut = !std::equal(&s.rgba[4 * p], &s.rgba[4 * p + 4], &h.rgba[4 * p]);
            const bool differs = !std::equal(&s.rgba[4 * p], &s.rgba[4 * p + 4], &b.rgba[4 * p]);
            cutPixels += onCut;
            recoloured += differs;
            outside += differs && !onCut;
        }
        EXPECT_EQ(outside, 0u) << what << " " << view << ": shading changed pixels outside the cut geometry";
        std::printf("  shading normals: %zu cut-geometry pixels, %zu of them shaded differently\n", cutPixels, recoloured);
        frames.push_back(a);
    }
    return frames;
}

} // namespace

// The discard pass alone drops exactly the cut cells' triangles: its frame is
// bit for bit the frame of a mesh holding only the uncut triangles outside
// the cut cells (same vertex buffer, same order). GPU-coded and CPU-uploaded
// masks give the same frame.
TEST(RenderFrame, DiscardDropsExactlyTheCutCellsTriangles)
{
    MTCUT_REQUIRE_GL();
    const vdb::Volume vol = test::sphereVolume();
    const cutter::Mesh uncut = cutter::extractIsosurface(vol, 0.0f);
    cutter::CutMask mask(cutter::frameOf(vol), 0.0);
    test::addStroke(mask, test::slantedStroke(45.0));
    const MaskTiling tiling = tileMask(cutCellGrid(mask)->tree());

    // The expected survivors: uncut triangles whose cell is not cut.
    std::vector<uint32_t> kept;
    for (uint32_t t = 0; t < uncut.triangleCount(); ++t) {
        const glm::ivec3 c = uncut.triangleVoxels[t];
        if (!mask.isCut(Coord(c.x, c.y, c.z))) kept.push_back(t);
    }
    ASSERT_LT(kept.size(), uncut.triangleCount());
    cutter::Mesh survivors = uncut; // same vertices, fewer triangles
    survivors.indices.clear();
    survivors.triangleVoxels.clear();
    for (uint32_t t : kept) {
        survivors.indices.insert(survivors.indices.end(), uncut.indices.begin() + 3 * t, uncut.indices.begin() + 3 * t + 3);
        survivors.triangleVoxels.push_back(uncut.triangleVoxels[t]);
    }

    SurfaceRenderer r(200, 150);
    size_t holes = 0;
    for (const char* view : {"front", "iso", "top", "-40,-30,25:0,0,0:0,0,1:35"}) {
        const Camera camera = cameraFor(view, Bounds{glm::dvec3(-16), glm::dvec3(16)}, 200.0 / 150.0);
        RenderStyle style;
        r.setSurface(survivors);
        r.render(camera, style);
        const Frame expected = r.readFrame();
        r.setSurface(uncut);
        r.setCutCells(tiling, true);
        r.render(camera, style);
        const Frame gpu = r.readFrame();
        r.setCutCells(tiling, false);
        r.render(camera, style);
        const Frame cpu = r.readFrame();
        r.clearCut();
        r.render(camera, style);
        const Frame whole = r.readFrame();
        EXPECT_EQ(gpu.rgba, expected.rgba) << view;
        EXPECT_EQ(gpu.depth, expected.depth) << view;
        EXPECT_EQ(gpu.fragments, expected.fragments) << view;
        EXPECT_EQ(cpu.rgba, gpu.rgba) << view;
        // Holes where the uncut surface was (the band of cut cells is behind
        // the silhouette from the front, so counted over all views).
        for (size_t p = 0; p < whole.pixelCount(); ++p) holes += whole.fragments[p] != 0 && gpu.fragments[p] == 0;
    }
    EXPECT_GT(holes, 500u);
}

// Sphere cut through by a slanted plane: two fragments; the discard frame
// with the cut geometry matches the fused mesh's frame within the bound.
TEST(RenderFrame, DiscardPlusCutGeometryMatchesFusedMeshOnASphere)
{
    MTCUT_REQUIRE_GL();
    const vdb::Volume vol = test::sphereVolume();
    const cutter::Mesh uncut = cutter::extractIsosurface(vol, 0.0f);
    cutter::CutMask mask(cutter::frameOf(vol), 0.0);
    test::addStroke(mask, test::slantedStroke(45.0));
    const std::vector<Frame> frames =
        checkOracle(vol, 0.0f, uncut, mask, {"front", "side", "top", "iso", "-30,-35,10:0,0,0:0,0,1:40"}, 192,
                    "sphere 40^3", 2);
    // Both fragments are seen from the side (the cut plane is close to y = 0).
    std::set<uint32_t> seen(frames[1].fragments.begin(), frames[1].fragments.end());
    EXPECT_EQ(seen, (std::set<uint32_t>{0, 1, 2}));
}

// The blade stops inside: one fragment; and a turning two-stroke cut.
TEST(RenderFrame, DiscardPlusCutGeometryMatchesFusedMeshOnPartialAndCrossingCuts)
{
    MTCUT_REQUIRE_GL();
    const vdb::Volume vol = test::sphereVolume();
    const cutter::Mesh uncut = cutter::extractIsosurface(vol, 0.0f);
    {
        cutter::CutMask mask(cutter::frameOf(vol), 0.0);
        test::addStroke(mask, straightStroke({-25, 0.37, 22}, {0.3, 0.37, 22}, glm::dvec3(0, 0, -1), 45.0, 100));
        checkOracle(vol, 0.0f, uncut, mask, {"front", "iso"}, 160, "sphere, blade stops inside", 1);
    }
    {
        cutter::CutMask mask(cutter::frameOf(vol), 0.0);
        for (const auto& stroke : {straightStroke({-25, 0.37, 22}, {25, 0.37, 22}, glm::dvec3(0, 0, -1), 45.0, 200),
                                   straightStroke({3.3, -25, 22}, {3.3, 25, 22}, glm::dvec3(0, 0, -1), 45.0, 200)}) {
            test::addStroke(mask, stroke);
        }
        checkOracle(vol, 0.0f, uncut, mask, {"top", "iso"}, 160, "sphere, crossing strokes", 4);
    }
}

// The real head at 4 mm (skipped when the shared data is absent): a straight
// horizontal stroke through the skull.
TEST(RenderFrame, DiscardPlusCutGeometryMatchesFusedMeshOnTheHead)
{
    MTCUT_REQUIRE_GL();
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    const auto t0 = std::chrono::steady_clock::now();
    const vdb::Volume vol = vdb::readVolume(path);
    const float iso = 400.0f;
    const cutter::Mesh uncut = cutter::extractIsosurface(vol, iso);
    ASSERT_FALSE(uncut.empty());
    const cutter::IndexFrame frame = cutter::frameOf(vol);
    const glm::dvec3 lo = frame.toWorld(glm::dvec3(0.0));
    const glm::dvec3 hi = frame.toWorld(glm::dvec3(frame.dims - glm::ivec3(1)));
    const glm::dvec3 mid = 0.5 * (lo + hi);
    cutter::CutMask mask(frame, 0.0);
    // From the patient's right to left, 40% up the scan, the blade pointing posterior.
    const double z = lo.z + 0.4 * (hi.z - lo.z) + 0.37;
    test::addStroke(mask, straightStroke({lo.x - 10, lo.y - 10, z}, {hi.x + 10, lo.y - 10, z},
                                         glm::normalize(glm::dvec3(0, 1, 0.05)), hi.y - lo.y + 20, 300));
    (void)mid;
    try {
        checkOracle(vol, iso, uncut, mask, {"front", "side", "iso"}, 256, "head 4 mm", 0 /* printed */);
    } catch (const std::runtime_error& e) {
        FAIL() << "the re-mesher refused the stroke: " << e.what();
    }
    std::printf("head test: %.1f s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}
