// Re-meshing of cut cells and fusion (DESIGN invariants 2, 5-10): zero
// checkMesh defects, the right shells, volumes against the uncut surface,
// nothing changed outside the cut cells, exact undo.
#include "cutter/CutMask.h"
#include "cutter/Fusion.h"
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"
#include "tests/TestUtil.h"
#include "vdb/VolumeIO.h"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <tuple>

using namespace mtcut;
using namespace mtcut::cutter;
using glm::dvec3;
using openvdb::Coord;
using openvdb::Vec3d;

namespace {

/// A volume sampling f (world mm) at voxel centres, nothing pruned.
template <typename F>
vdb::Volume fieldVolume(Coord dims, Vec3d spacing, Vec3d origin, F f)
{
    vdb::DenseScan scan;
    scan.geometry.dims = dims;
    scan.geometry.spacing = spacing;
    scan.geometry.origin = origin;
    scan.values.resize(size_t(dims.x()) * dims.y() * dims.z());
    float lo = 1e30f;
    size_t n = 0;
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j)
            for (int i = 0; i < dims.x(); ++i) {
                const Vec3d p = origin + Vec3d(i, j, k) * spacing;
                scan.values[n] = float(f(p));
                lo = std::min(lo, scan.values[n++]);
            }
    scan.units = "mm";
    vdb::SparseOptions sparse;
    sparse.airThreshold = lo - 1.0f;
    return vdb::makeVolume(std::move(scan), "field", sparse);
}

/// A straight stroke: the base moves from `from` to `to` in `steps` poses,
/// the blade pointing along `dir` with length `len` (world mm).
std::vector<Pose> straightStroke(dvec3 from, dvec3 to, dvec3 dir, double len, int steps)
{
    std::vector<Pose> poses;
    for (int i = 0; i <= steps; ++i) {
        Pose p;
        p.time = 0.001 * i;
        p.base = from + (to - from) * (double(i) / steps);
        p.direction = dir;
        p.length = len;
        poses.push_back(p);
    }
    return poses;
}

void addStroke(CutMask& mask, const std::vector<Pose>& poses)
{
    const std::vector<Quad> quads = filterStroke(poses, mask.frame());
    mask.beginStroke();
    for (const Quad& q : quads) mask.addQuad(q);
}

using TriKey = std::array<std::tuple<float, float, float>, 3>;
/// Triangles as position triples, rotated to start at the smallest corner (orientation kept).
std::multiset<TriKey> triangleSet(const Mesh& m, const std::function<bool(const glm::ivec3&)>& keep)
{
    std::multiset<TriKey> s;
    for (size_t t = 0; t < m.triangleCount(); ++t) {
        if (!keep(m.triangleVoxels[t])) continue;
        TriKey k;
        for (int j = 0; j < 3; ++j) {
            const glm::vec3& p = m.positions[m.indices[3 * t + size_t(j)]];
            k[size_t(j)] = {p.x, p.y, p.z};
        }
        const int r = int(std::min_element(k.begin(), k.end()) - k.begin());
        std::rotate(k.begin(), k.begin() + r, k.end());
        s.insert(k);
    }
    return s;
}

[[maybe_unused]] bool sameMesh(const Mesh& a, const Mesh& b)
{
    return a.positions == b.positions && a.indices == b.indices && a.triangleVoxels == b.triangleVoxels;
}

struct CutResult
{
    Mesh fused;
    MeshCheck check;
    std::vector<Fragment> fragments;
};

CutResult cutAndCheck(const CutRemesher& r)
{
    CutResult c;
    c.fused = r.fusedMesh();
    c.check = checkMesh(c.fused);
    c.fragments = fragmentsOf(c.fused);
    return c;
}

/// Invariant 9: outside the cut cells, the fused triangles are the uncut ones.
void expectUntouchedOutside(const Mesh& uncut, const Mesh& fused, const CutMask& mask)
{
    auto outside = [&](const glm::ivec3& c) { return !mask.isCut(Coord(c.x, c.y, c.z)); };
    EXPECT_EQ(triangleSet(uncut, outside), triangleSet(fused, outside));
}

} // namespace

// A sphere of radius 15 mm cut by the plane y = c through it, zero kerf:
// two shells whose volumes add up to the uncut surface's volume (the caps
// are coincident and opposite), each close to its analytic spherical cap.
TEST(Remesh, SphereCutThroughByAPlaneGivesTwoShells)
{
    const double R = 15.0;
    for (double yCut : {0.37, -4.0, 0.0, 7.25}) {
        const vdb::Volume vol = fieldVolume(Coord(40), Vec3d(1.0), Vec3d(-19.5), [&](const Vec3d& p) { return R - p.length(); });
        const Mesh uncut = extractIsosurface(vol, 0.0f);
        ASSERT_TRUE(checkMesh(uncut).ok());
        CutMask mask(frameOf(vol), 0.0);
        addStroke(mask, straightStroke(dvec3(-25, yCut, 22), dvec3(25, yCut, 22), dvec3(0, 0, -1), 45.0, 200));
        CutRemesher remesher(vol, 0.0f, uncut);
        remesher.update(mask);
        const CutResult c = cutAndCheck(remesher);
        EXPECT_TRUE(c.check.ok()) << "y = " << yCut << "\n" << c.check.report();
        ASSERT_EQ(c.fragments.size(), 2u) << "y = " << yCut;
        const double v0 = meshVolume(uncut);
        const double sum = c.fragments[0].volume + c.fragments[1].volume;
        EXPECT_NEAR(sum, v0, 1e-5 * v0);
        // Analytic caps; bound: the isosurface error plus one tet per cut cell.
        const double capSmall = std::abs(yCut) < 1e-12 ? 0.5 * (4.0 / 3.0) * M_PI * R * R * R
                                                       : M_PI * (R - std::abs(yCut)) * (R - std::abs(yCut)) *
                                                             (3 * R - (R - std::abs(yCut))) / 3.0;
        const double sphere = 4.0 / 3.0 * M_PI * R * R * R;
        const double bound = std::abs(v0 - sphere) + double(mask.cutCellCount()) / 6.0;
        EXPECT_NEAR(c.fragments[1].volume, capSmall, bound) << "y = " << yCut;
        std::printf("y=%g: cut cells %zu, triangles %zu, volumes %.3f + %.3f (uncut %.3f), small cap error %.4f (bound %.3f)\n",
                    yCut, mask.cutCellCount(), c.fused.triangleCount(), c.fragments[0].volume, c.fragments[1].volume, v0,
                    c.fragments[1].volume - capSmall, bound);
        expectUntouchedOutside(uncut, c.fused, mask);
    }
}

// The blade stops inside the sphere: one shell, still closed and manifold;
// a blade wholly inside leaves a closed zero-volume crack (a cavity shell).
TEST(Remesh, BladeStoppingInsideKeepsOneClosedShell)
{
    const double R = 15.0;
    const vdb::Volume vol = fieldVolume(Coord(40), Vec3d(1.0), Vec3d(-19.5), [&](const Vec3d& p) { return R - p.length(); });
    const Mesh uncut = extractIsosurface(vol, 0.0f);
    const double v0 = meshVolume(uncut);
    // Stops half way along x; and a short blade whose tip stays inside.
    const std::vector<std::vector<Pose>> strokes = {
        straightStroke(dvec3(-25, 0.37, 22), dvec3(0.3, 0.37, 22), dvec3(0, 0, -1), 45.0, 100),
        straightStroke(dvec3(-25, 0.37, 22), dvec3(25, 0.37, 22), dvec3(0, 0, -1), 20.0, 200),
        straightStroke(dvec3(-3.3, -2.1, 1.7), dvec3(4.1, 2.2, -1.3), glm::normalize(dvec3(0.2, -0.3, 1)), 6.0, 60),
    };
    for (size_t s = 0; s < strokes.size(); ++s) {
        CutMask mask(frameOf(vol), 0.0);
        addStroke(mask, strokes[s]);
        CutRemesher remesher(vol, 0.0f, uncut);
        remesher.update(mask);
        const CutResult c = cutAndCheck(remesher);
        EXPECT_TRUE(c.check.ok()) << "stroke " << s << "\n" << c.check.report();
        if (s < 2) {
            EXPECT_EQ(c.fragments.size(), 1u) << "stroke " << s;
        } else { // a slit entirely inside the solid: a zero-volume cavity
            ASSERT_EQ(c.fragments.size(), 2u);
            EXPECT_EQ(c.check.cavities, 1u);
            EXPECT_NEAR(c.fragments[1].volume, 0.0, 1e-9 * v0);
            EXPECT_GT(c.fragments[1].area, 2 * 20.0); // two caps of the 6 mm blade over ~8 mm
        }
        EXPECT_NEAR(meshVolume(c.fused), v0, 1e-5 * v0);
        expectUntouchedOutside(uncut, c.fused, mask);
    }
}
