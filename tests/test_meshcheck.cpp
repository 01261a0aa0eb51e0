// checkMesh counts each defect exactly; shells, volumes, areas; mesh files
// round-trip through OpenMesh; `mtcut mesh`.
#include "TestUtil.h"

#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/MeshIO.h"

#include <glm/common.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

using namespace mtcut;
using namespace mtcut::cutter;

namespace {

/// Axis-aligned box [lo, hi], 12 triangles, outward CCW (the bottom, z =
/// lo.z, first).
void addBox(Mesh& m, glm::vec3 lo, glm::vec3 hi, bool inward = false)
{
    const uint32_t base = uint32_t(m.positions.size());
    for (int c = 0; c < 8; ++c) m.positions.push_back(glm::mix(lo, hi, glm::vec3(c & 1, c >> 1 & 1, c >> 2 & 1)));
    const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) {
        uint32_t t[6] = {q[0], q[1], q[2], q[0], q[2], q[3]};
        if (inward) std::swap(t[1], t[2]), std::swap(t[4], t[5]);
        for (uint32_t v : t) m.indices.push_back(base + v);
    }
}

/// Axis-aligned cube [o, o+s]^3, 12 triangles, outward CCW.
void addCube(Mesh& m, glm::vec3 o, float s, bool inward = false) { addBox(m, o, o + glm::vec3(s), inward); }

} // namespace

TEST(MeshCheck, CubeIsValidWithExactVolumeAndArea)
{
    Mesh m;
    addCube(m, glm::vec3(10.0f), 2.0f);
    const MeshCheck c = checkMesh(m);
    EXPECT_TRUE(c.ok()) << c.report();
    EXPECT_EQ(c.shells, 1u);
    const auto shells = findShells(m);
    ASSERT_EQ(shells.size(), 1u);
    EXPECT_DOUBLE_EQ(shells[0].volume, 8.0);
    EXPECT_DOUBLE_EQ(shells[0].area, 24.0);
    EXPECT_EQ(shells[0].vertexCount, 8u);
    EXPECT_EQ(shells[0].boundsMin, glm::dvec3(10.0));
    EXPECT_EQ(shells[0].boundsMax, glm::dvec3(12.0));
}

TEST(MeshCheck, CountsEachDefect)
{
    {   // one triangle removed: 3 boundary edges
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        m.indices.resize(m.indices.size() - 3);
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.boundaryEdges, 3u);
        EXPECT_EQ(c.defects(), 3u) << c.report();
    }
    {   // one triangle flipped: its 3 edges run the same way as their neighbours'
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        std::swap(m.indices[1], m.indices[2]);
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.inconsistentEdges, 3u);
        EXPECT_EQ(c.boundaryEdges, 0u);
    }
    {   // inside-out cube: negative volume, not nested
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f, true);
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.negativeVolumeShells, 1u);
        EXPECT_EQ(c.defects(), 1u) << c.report();
    }
    {   // hollow cube: outer outward, inner inward = a cavity, valid
        Mesh m;
        addCube(m, glm::vec3(0.0f), 3.0f);
        addCube(m, glm::vec3(1.0f), 1.0f, true);
        const MeshCheck c = checkMesh(m);
        EXPECT_TRUE(c.ok()) << c.report();
        EXPECT_EQ(c.cavities, 1u);
        EXPECT_DOUBLE_EQ(meshVolume(m), 26.0);
        // the cavity facing the wrong way (outward) is a defect
        Mesh bad;
        addCube(bad, glm::vec3(0.0f), 3.0f);
        addCube(bad, glm::vec3(1.0f), 1.0f);
        EXPECT_EQ(checkMesh(bad).negativeVolumeShells, 1u);
    }
    {   // a third triangle on an edge: non-manifold edge
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        m.positions.push_back(glm::vec3(5.0f, 5.0f, 5.0f));
        m.indices.insert(m.indices.end(), {0, 2, 8});
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.nonManifoldEdges, 1u);
        EXPECT_EQ(c.boundaryEdges, 2u);
    }
    {   // two cubes sharing one vertex: a non-manifold vertex
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        addCube(m, glm::vec3(1.0f), 1.0f);
        for (uint32_t& i : m.indices) if (i == 8) i = 7; // corner (1,1,1) of both
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.nonManifoldVertices, 1u) << c.report();
        EXPECT_EQ(c.unusedVertices, 1u);
    }
    {   // degenerate, non-finite, bad index, malformed
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        m.positions.push_back(glm::vec3(7.0f));
        m.positions.push_back(glm::vec3(8.0f));
        m.positions.push_back(glm::vec3(9.0f)); // collinear
        m.positions.push_back(glm::vec3(std::nanf(""), 0.0f, 0.0f));
        m.indices.insert(m.indices.end(), {8, 9, 10, 8, 8, 9, 8, 9, 11, 0, 1, 99});
        m.triangleVoxels.resize(3);
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.degenerateTriangles, 2u);
        EXPECT_EQ(c.nonFiniteTriangles, 1u);
        EXPECT_EQ(c.badIndexTriangles, 1u);
        EXPECT_EQ(c.malformedArrays, 1u);
    }
}

// A defect count alone says a mesh is broken; the sites say where, so the
// file can be opened there and the scan's voxel looked at.
TEST(MeshCheck, SaysWhereEachDefectIs)
{
    using Kind = DefectSite::Kind;
    {   // one triangle, (1, 7, 5) on the face x = 1, removed: its three edges are open
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        m.indices.resize(m.indices.size() - 3);
        for (int t = 0; t < 11; ++t) m.triangleVoxels.push_back(glm::ivec3(t, 20, 30));
        const MeshCheck c = checkMesh(m);
        ASSERT_EQ(c.sites.size(), 3u) << c.report();
        const glm::dvec3 middles[3] = {{1.0, 0.0, 0.5}, {1.0, 0.5, 0.5}, {1.0, 0.5, 1.0}}; // 1-5, 1-7, 5-7
        const uint64_t keys[3] = {uint64_t(1) << 32 | 5, uint64_t(1) << 32 | 7, uint64_t(5) << 32 | 7};
        const int triangles[3] = {4, 10, 2}; // the one triangle left on each: (0, 1, 5), (1, 3, 7), (4, 5, 7)
        for (int i = 0; i < 3; ++i) {
            const DefectSite& site = c.sites[size_t(i)];
            EXPECT_EQ(site.kind, Kind::BoundaryEdge);
            EXPECT_EQ(site.key, keys[i]);
            ASSERT_TRUE(site.hasPosition);
            EXPECT_EQ(site.position, middles[i]);
            ASSERT_TRUE(site.hasVoxel); // the voxel of the triangle that has the edge
            EXPECT_EQ(site.voxel, glm::ivec3(triangles[i], 20, 30));
        }
        EXPECT_EQ(c.sites[0].describe(), "boundary edge 1-5, in 1 triangle, at (1.0000, 0.0000, 0.5000) mm, voxel (4, 20, 30)");
        EXPECT_NE(c.report().find("where (the first 5 of each kind):\n  boundary edge 1-5"), std::string::npos) << c.report();
    }
    {   // a valid mesh has no sites, and its report no "where"
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        const MeshCheck c = checkMesh(m);
        EXPECT_TRUE(c.sites.empty());
        EXPECT_EQ(c.report().find("where"), std::string::npos);
    }
    {   // inside out, and a cavity facing outward: which shell, and why
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f, true);
        addCube(m, glm::vec3(10.0f), 3.0f);
        addCube(m, glm::vec3(11.0f), 1.0f);
        const MeshCheck c = checkMesh(m);
        ASSERT_EQ(c.sites.size(), 2u) << c.report();
        EXPECT_EQ(c.sites[0].kind, Kind::WrongWayShell);
        EXPECT_EQ(c.sites[0].key, 0u);
        EXPECT_NE(c.sites[0].what.find("12 triangles, volume -1 mm^3, faces inward (a cavity) but the other shells' "
                                       "winding number there is 0, not 1"),
                  std::string::npos)
            << c.sites[0].what;
        EXPECT_EQ(c.sites[1].key, 2u);
        EXPECT_NE(c.sites[1].what.find("faces outward but lies inside other solids (their winding number there is 1"),
                  std::string::npos)
            << c.sites[1].what;
        EXPECT_FALSE(c.sites[1].hasVoxel); // no triangleVoxels
        EXPECT_GE(c.sites[1].position.x, 11.0);
        EXPECT_LE(c.sites[1].position.x, 12.0);
    }
    {   // 40 triangles of no area: counted all, the first 5 placed; a bad index has no position
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        for (int i = 0; i < 40; ++i) {
            const uint32_t base = uint32_t(m.positions.size());
            for (int k = 0; k < 3; ++k) m.positions.push_back(glm::vec3(float(i), float(k), 0.0f));
            m.indices.insert(m.indices.end(), {base, base + 1, base + 2});
        }
        m.indices.insert(m.indices.end(), {0, 1, 999});
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.degenerateTriangles, 40u);
        size_t degenerate = 0;
        for (const DefectSite& site : c.sites) {
            if (site.kind == Kind::BadIndexTriangle) {
                EXPECT_EQ(site.key, 52u);
                EXPECT_FALSE(site.hasPosition);
                EXPECT_EQ(site.describe(), "bad-index triangle 52 (0, 1, 999): an index past the 128 vertices");
            }
            if (site.kind != Kind::DegenerateTriangle) continue;
            EXPECT_EQ(site.key, 12u + degenerate) << "the lowest triangles first";
            EXPECT_EQ(site.position, glm::dvec3(double(degenerate), 1.0, 0.0));
            ++degenerate;
        }
        EXPECT_EQ(degenerate, MeshCheck::kSitesPerKind);
        EXPECT_EQ(c.sites.front().kind, Kind::BadIndexTriangle) << "kinds in the order of the counts";
    }
    {   // two cubes sharing the corner (1, 1, 1)
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        addCube(m, glm::vec3(1.0f), 1.0f);
        for (uint32_t& i : m.indices) if (i == 8) i = 7;
        const MeshCheck c = checkMesh(m);
        ASSERT_EQ(c.sites.size(), 1u) << c.report();
        EXPECT_EQ(c.sites[0].kind, Kind::NonManifoldVertex);
        EXPECT_EQ(c.sites[0].position, glm::dvec3(1.0));
        EXPECT_EQ(c.sites[0].what, "7: its 12 triangles make 2 fans");
    }
}

// Two unit cubes stacked, touching over the face z = 1 with vertices of
// their own: the two sides of a zero-width cut (kerf 0). The lower cube's
// first triangle lies in that face, so the nesting ray from its centroid
// starts on the upper cube's bottom face: counted by rounding, that once
// made the lower cube "inside" the upper one (a cut piece of the tooth scan,
// random strokes seed 7003 at kerf 0, was reported as facing the wrong
// way). Such a ray is ambiguous and another triangle's is taken.
TEST(MeshCheck, ShellsTouchingOverAFaceAreNotNestedByTheirCommonFace)
{
    for (const bool lowerFirst : {true, false}) {
        Mesh m;
        if (!lowerFirst) addCube(m, glm::vec3(0.0f, 0.0f, 1.0f), 1.0f);
        const size_t at = m.indices.size();
        addCube(m, glm::vec3(0.0f), 1.0f);
        // The lower cube's top face (its second quad) first.
        std::rotate(m.indices.begin() + std::ptrdiff_t(at), m.indices.begin() + std::ptrdiff_t(at + 6),
                    m.indices.begin() + std::ptrdiff_t(at + 12));
        if (lowerFirst) addCube(m, glm::vec3(0.0f, 0.0f, 1.0f), 1.0f);
        ASSERT_EQ(m.positions[m.indices[at]].z, 1.0f);
        const MeshCheck c = checkMesh(m);
        EXPECT_TRUE(c.ok()) << c.report();
        EXPECT_EQ(c.shells, 2u);
        EXPECT_EQ(c.cavities, 0u);
        const auto shells = findShells(m);
        EXPECT_EQ(enclosingShells(m, shells), std::vector<int>(2, -1));
    }
    // Still found: the upper cube inside out on the lower one.
    Mesh bad;
    addCube(bad, glm::vec3(0.0f), 1.0f);
    addCube(bad, glm::vec3(0.0f, 0.0f, 1.0f), 1.0f, true);
    EXPECT_EQ(checkMesh(bad).negativeVolumeShells, 1u);
}

// A slab 0.01 thick between two unit cubes, touching both over its whole top
// and bottom (at kerf 0, a piece cut out between two passes of the blade that
// run side by side: 2 mm head, random strokes seed 18002 with sharp turns,
// a piece 1-4 um thick). Its faces are 32 x 32 squares, so every triangle the
// nesting test tries lies on a face the other shell touches: a ray from any
// of them starts on a cube's triangle. It is taken from just inside the slab,
// and crosses that triangle only when it leaves through the slab's face
// there. Before, each start counted as ambiguous and the first ray was used
// as it was: from the top face, the upper cube's bottom at the start was
// left out and the slab counted as inside it (facing the wrong way).
TEST(MeshCheck, ASlabTouchingCubesOnBothFacesIsNestedInNeither)
{
    constexpr int n = 32;
    const float zb = 1.0f, zt = 1.01f;
    for (const bool topFirst : {true, false}) {
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        addCube(m, glm::vec3(0.0f, 0.0f, zt), 1.0f);
        const uint32_t base = uint32_t(m.positions.size());
        auto at = [&](int i, int j, int k) { return base + uint32_t(2 * ((n + 1) * j + i) + k); }; // k: 0 bottom, 1 top
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i)
                for (const float z : {zb, zt}) m.positions.push_back(glm::vec3(float(i) / n, float(j) / n, z));
        auto tri = [&](uint32_t a, uint32_t b, uint32_t c) {
            for (uint32_t v : {a, b, c}) m.indices.push_back(v);
        };
        auto face = [&](int k) { // k = 1: the top, facing +z; 0: the bottom
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) {
                    const uint32_t a = at(i, j, k), b = at(i + 1, j, k), c = at(i + 1, j + 1, k), d = at(i, j + 1, k);
                    if (k) tri(a, b, c), tri(a, c, d);
                    else tri(a, c, b), tri(a, d, c);
                }
        };
        face(topFirst ? 1 : 0);
        face(topFirst ? 0 : 1);
        for (int i = 0; i < n; ++i) { // the sides, outward
            tri(at(i, 0, 0), at(i + 1, 0, 0), at(i + 1, 0, 1)), tri(at(i, 0, 0), at(i + 1, 0, 1), at(i, 0, 1));
            tri(at(i + 1, n, 0), at(i, n, 0), at(i, n, 1)), tri(at(i + 1, n, 0), at(i, n, 1), at(i + 1, n, 1));
            tri(at(0, i + 1, 0), at(0, i, 0), at(0, i, 1)), tri(at(0, i + 1, 0), at(0, i, 1), at(0, i + 1, 1));
            tri(at(n, i, 0), at(n, i + 1, 0), at(n, i + 1, 1)), tri(at(n, i, 0), at(n, i + 1, 1), at(n, i, 1));
        }
        const MeshCheck c = checkMesh(m);
        EXPECT_TRUE(c.ok()) << (topFirst ? "top first" : "bottom first") << c.report();
        EXPECT_EQ(c.shells, 3u);
        EXPECT_EQ(c.cavities, 0u);
        const auto shells = findShells(m);
        ASSERT_EQ(shells.size(), 3u);
        EXPECT_NEAR(shells[2].volume, 0.01, 1e-6);
        EXPECT_EQ(enclosingShells(m, shells), std::vector<int>(3, -1));
    }
}

// A piece lying on a solid and reaching two float steps into it (at kerf 0,
// where two passes of the blade cross, each side's vertices rounded to float:
// the tooth's pivoting fan left pieces 10-100 um across inside the main body
// by 1-10 um at some of their triangles) is judged from the middle of a
// chord through it, not from just behind a triangle: the first tried here,
// its bottom, lies inside the cube. Before, that ray was clear and counted
// the piece inside the cube (facing the wrong way). One reaching half way
// into the cube is still found.
TEST(MeshCheck, APieceReachingAFloatStepIntoAnotherIsJudgedFromItsMiddle)
{
    const float below = std::nextafter(std::nextafter(1.0f, 0.0f), 0.0f);
    for (const float bottom : {below, 0.5f}) {
        Mesh m;
        addCube(m, glm::vec3(0.0f), 1.0f);
        addBox(m, glm::vec3(0.25f, 0.25f, bottom), glm::vec3(0.75f, 0.75f, 1.01f));
        const auto shells = findShells(m);
        ASSERT_EQ(shells.size(), 2u);
        ASSERT_EQ(m.positions[m.indices[shells[1].triangles[0] * 3]].z, bottom);
        const MeshCheck c = checkMesh(m);
        EXPECT_EQ(c.negativeVolumeShells, bottom == below ? 0u : 1u) << "bottom " << bottom << "\n" << c.report();
        EXPECT_EQ(c.cavities, 0u);
    }
}

// A crack: both sides of a zero-width cut that ends inside the solid, a
// closed shell of zero volume (here a square in z = 1.5, split along one
// diagonal on top and the other below). Its volume's sign is rounding noise
// (here exactly 0), so it is judged flat: a cavity where the solid encloses
// it, which checkMesh accepts and fragments keep with their solid; a defect
// on its own. Before Shell::flat a crack counted by its sign: a cut that
// re-triangulated its caps turned the blade-inside-the-ball test red.
TEST(MeshCheck, AFlatShellInsideTheSolidIsACrackNotADefect)
{
    const auto addCrack = [](Mesh& m) {
        const uint32_t b = uint32_t(m.positions.size());
        for (const glm::vec3 p : {glm::vec3(1.1f, 1.2f, 1.5f), glm::vec3(1.9f, 1.3f, 1.5f), glm::vec3(1.8f, 1.7f, 1.5f),
                                  glm::vec3(1.2f, 1.9f, 1.5f)})
            m.positions.push_back(p);
        // top (+z) along the diagonal 0-2, bottom (-z) along 1-3
        for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u, 1u, 0u, 3u, 1u, 3u, 2u}) m.indices.push_back(b + i);
    };
    Mesh m;
    addCube(m, glm::vec3(0.0f), 3.0f);
    addCrack(m);
    const MeshCheck c = checkMesh(m);
    EXPECT_TRUE(c.ok()) << c.report();
    EXPECT_EQ(c.cavities, 1u);
    const std::vector<Shell> shells = findShells(m);
    ASSERT_EQ(shells.size(), 2u);
    EXPECT_FALSE(shells[0].flat);
    EXPECT_TRUE(shells[1].flat);
    EXPECT_EQ(shells[1].volume, 0.0);
    EXPECT_NEAR(shells[1].area, 2 * 0.385, 1e-6); // both sides of the square (shoelace: 0.385 mm^2)
    EXPECT_EQ(enclosingShells(m, shells), (std::vector<int>{-1, 0}));

    Mesh alone; // the same crack with no solid round it
    addCrack(alone);
    EXPECT_EQ(checkMesh(alone).negativeVolumeShells, 1u);
}

TEST(MeshCheck, ShellsSplitInFirstTriangleOrder)
{
    Mesh m;
    addCube(m, glm::vec3(5.0f), 1.0f);
    addCube(m, glm::vec3(0.0f), 2.0f);
    const std::vector<Mesh> parts = splitShells(m);
    ASSERT_EQ(parts.size(), 2u);
    EXPECT_DOUBLE_EQ(meshVolume(parts[0]), 1.0);
    EXPECT_DOUBLE_EQ(meshVolume(parts[1]), 8.0);
    EXPECT_EQ(parts[1].positions[0], glm::vec3(0.0f));
    EXPECT_EQ(parts[1].indices.size(), 36u);
}

TEST(MeshIO, RoundTripsEveryFormat)
{
    mtcut::test::TempDir dir;
    Mesh m;
    addCube(m, glm::vec3(1.5f, -2.25f, 3.0f), 2.0f);
    for (const char* ext : {"stl", "obj", "ply", "off", "STL"}) {
        const std::string path = dir.file(std::string("cube.") + ext);
        writeMesh(m, path);
        const Mesh back = readMesh(path);
        EXPECT_EQ(back.triangleCount(), 12u) << ext;
        EXPECT_EQ(back.vertexCount(), 8u) << ext;
        EXPECT_DOUBLE_EQ(meshVolume(back), 8.0) << ext;
        EXPECT_TRUE(checkMesh(back).ok()) << ext << checkMesh(back).report();
    }
    EXPECT_THROW(writeMesh(m, dir.file("cube.xyz")), InputError);
    EXPECT_THROW(readMesh(dir.file("none.stl")), InputError);
    // nothing but the five files: no temporary left behind
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 5);
}

TEST(MeshIO, WritesOneFilePerShell)
{
    mtcut::test::TempDir dir;
    Mesh m;
    addCube(m, glm::vec3(5.0f), 1.0f);
    addCube(m, glm::vec3(0.0f), 2.0f);
    const auto paths = writeShells(m, dir.file("parts.ply"));
    ASSERT_EQ(paths.size(), 2u);
    EXPECT_EQ(paths[0], dir.file("parts_shell001.ply"));
    EXPECT_DOUBLE_EQ(meshVolume(readMesh(paths[1])), 8.0);
}

TEST(MeshCli, MeshesTheHeadWithZeroDefects)
{
    MTCUT_REQUIRE_DATA(head, "vhm_head_4mm.nhdr");
    mtcut::test::TempDir dir;
    const auto r = mtcut::test::runMtcut("mesh " + head + " --iso 400 -o " + dir.file("head.stl") + " --check");
    EXPECT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("defects:                0 (valid)"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("isosurface: 92028 triangles"), std::string::npos) << r.output;
    const Mesh back = readMesh(dir.file("head.stl"));
    EXPECT_EQ(back.triangleCount(), 92028u);

    const auto shells = mtcut::test::runMtcut("mesh " + head + " --iso 400 -o " + dir.file("s.obj") + " --shells");
    EXPECT_EQ(shells.exitCode, 0) << shells.output;
    EXPECT_TRUE(std::filesystem::exists(dir.file("s_shell001.obj")));
    EXPECT_TRUE(std::filesystem::exists(dir.file("s_shell100.obj")));
    EXPECT_FALSE(std::filesystem::exists(dir.file("s_shell101.obj")));

    const auto empty = mtcut::test::runMtcut("mesh " + head + " --iso 99999 -o " + dir.file("e.stl"));
    EXPECT_EQ(empty.exitCode, 0) << empty.output;
    EXPECT_NE(empty.output.find("warning: isovalue 99999 is outside"), std::string::npos) << empty.output;

    const auto bad = mtcut::test::runMtcut("mesh " + head + " --iso 400 -o " + dir.file("x.abc"));
    EXPECT_EQ(bad.exitCode, 1);
    EXPECT_NE(bad.output.find("unknown mesh format"), std::string::npos) << bad.output;
}

// Vertices at one position: only where the surface touches itself.
TEST(MeshIO, CountsVerticesThatShareAPosition)
{
    Mesh m;
    addCube(m, glm::vec3(0.0f), 1.0f);
    EXPECT_EQ(coincidentVertices(m), 0u);
    addCube(m, glm::vec3(0.0f, 0.0f, 1.0f), 1.0f); // on the first one's top, with vertices of its own
    EXPECT_EQ(coincidentVertices(m), 8u);          // the four corners of the common face, twice
    m.positions.push_back(glm::vec3(std::nanf(""), 0.0f, 0.0f));
    m.positions.push_back(glm::vec3(std::nanf(""), 0.0f, 0.0f));
    EXPECT_EQ(coincidentVertices(m), 8u) << "a NaN is not a position";
}

// `mtcut check`: any mesh file, or a folder of them; exit 1 on a defect and
// say where it is; bad arguments named.
TEST(CheckCli, ChecksFilesAndFoldersAndSaysWhereADefectIs)
{
    mtcut::test::TempDir dir;
    std::filesystem::create_directories(dir.file("good"));
    Mesh cube;
    addCube(cube, glm::vec3(2.0f), 2.0f);
    writeMesh(cube, dir.file("good/a.obj"));
    writeMesh(cube, dir.file("good/b.stl"));
    const auto good = mtcut::test::runMtcut("check " + dir.file("good"));
    EXPECT_EQ(good.exitCode, 0) << good.output;
    EXPECT_NE(good.output.find("a.obj: 12 triangles, 1 shells (0 cavities), volume 8.000 mm^3, area 24.000 mm^2: valid"),
              std::string::npos)
        << good.output;
    EXPECT_NE(good.output.find("2 of 2 files valid"), std::string::npos) << good.output;
    EXPECT_EQ(good.output.find("boundary edges:"), std::string::npos) << "counts only with --report";
    const auto report = mtcut::test::runMtcut("check " + dir.file("good/a.obj") + " --report");
    EXPECT_EQ(report.exitCode, 0) << report.output;
    EXPECT_NE(report.output.find("defects:                0 (valid)"), std::string::npos) << report.output;

    Mesh holed = cube;
    holed.indices.resize(holed.indices.size() - 3); // (1, 7, 5): x = 4, open along its three edges
    writeMesh(holed, dir.file("holed.off"));
    const auto bad = mtcut::test::runMtcut("check " + dir.file("good/a.obj") + " " + dir.file("holed.off"));
    EXPECT_EQ(bad.exitCode, 1) << bad.output;
    EXPECT_NE(bad.output.find("holed.off: 11 triangles, 1 shells (0 cavities)"), std::string::npos) << bad.output;
    EXPECT_NE(bad.output.find("boundary edges:         3"), std::string::npos) << bad.output;
    EXPECT_NE(bad.output.find(", in 1 triangle, at (4.0000, 2.0000, 3.0000) mm"), std::string::npos) << bad.output;
    EXPECT_NE(bad.output.find("1 of 2 files valid"), std::string::npos) << bad.output;

    for (const std::string& wrong : {dir.file("none.stl"), dir.file("holed.txt"), dir.file("empty")}) {
        std::filesystem::create_directories(dir.file("empty"));
        std::ofstream(dir.file("holed.txt")) << "not a mesh\n";
        const auto r = mtcut::test::runMtcut("check " + wrong);
        EXPECT_EQ(r.exitCode, 1) << r.output;
        EXPECT_NE(r.output.find("mtcut: error: " + wrong), std::string::npos) << r.output;
    }
    const auto none = mtcut::test::runMtcut("check");
    EXPECT_EQ(none.exitCode, 1) << none.output;
    EXPECT_NE(none.output.find("usage: mtcut check"), std::string::npos) << none.output;
}
