// Cuts of a given size for the benchmarks: straight strokes (of the caller's
// kerf) through bone whose cut-cell counts are close to a target (the paper's
// Table 1 uses 419, 3,638 and 11,716 cut voxels). bench_cut and bench_render
// both take their strokes from here, so they cut the same strokes.
//
// The stroke: in a horizontal plane (half a voxel off the grid planes), the
// base sweeping along +x in front of the face (3 mm in front of the first
// bone at the centre), the blade pointing posterior (+y) with length B, the
// sweep 1.5 B long; B binary-searched for the target count (cut cells = the
// mask's cells, air included). Poses every 0.25 voxel at 1 kHz ->
// filterStroke -> quads, as mtcut cut does. When the re-mesher refuses a
// stroke (it throws for some configurations), variants are tried in order
// (see StrokeKind): shifted and turned ("tip"), ones whose tip line holds no
// bone surface ("air"), then through-cuts.
#pragma once

#include "benchmarks/BenchUtil.h"
#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "cutter/Mesh.h"
#include "cutter/Remesh.h"
#include "vdb/Volume.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace mtcut::bench {

/// A volume with its isosurface and where the strokes go. Build with
/// locateCutPlane(). `vol` and `uncut` must outlive it.
struct CutScene
{
    std::string name;
    const vdb::Volume* vol = nullptr;
    float iso = 400.0f;
    const cutter::Mesh* uncut = nullptr;
    cutter::IndexFrame frame;
    double planeZ = 0.0;  ///< world z of the cut plane (half a voxel off the grid planes)
    double xCentre = 0.0; ///< world x of the centre of the bone in that plane
    double yFront = 0.0;  ///< world y of the first bone in front, near xCentre
};

/// Fills scene.frame and the stroke's plane at index height planeIndexZ.
/// Throws std::runtime_error when that plane holds no bone.
inline void locateCutPlane(CutScene& sc, double planeIndexZ)
{
    sc.frame = cutter::frameOf(*sc.vol);
    const cutter::IndexFrame& f = sc.frame;
    const int kz = std::clamp(int(std::floor(planeIndexZ)), 0, f.dims.z - 2);
    sc.planeZ = f.toWorld(glm::dvec3(0, 0, double(kz) + 0.5)).z;
    auto acc = sc.vol->grid->getConstAccessor();
    int xMin = f.dims.x, xMax = -1;
    for (int j = 0; j < f.dims.y; ++j)
        for (int i = 0; i < f.dims.x; ++i)
            if (acc.getValue(openvdb::Coord(i, j, kz)) >= sc.iso) {
                xMin = std::min(xMin, i);
                xMax = std::max(xMax, i);
            }
    if (xMax < 0) throw std::runtime_error(sc.name + ": no bone in the cut plane");
    const double xc = 0.5 * (xMin + xMax);
    sc.xCentre = f.toWorld(glm::dvec3(xc, 0, 0)).x;
    const int half = int(std::ceil(20.0 / f.spacing.x));
    int yFirst = f.dims.y;
    for (int i = std::max(0, int(xc) - half); i <= std::min(f.dims.x - 1, int(xc) + half); ++i)
        for (int j = 0; j < yFirst; ++j)
            if (acc.getValue(openvdb::Coord(i, j, kz)) >= sc.iso) {
                yFirst = j;
                break;
            }
    sc.yFront = f.toWorld(glm::dvec3(0, double(yFirst), 0)).y;
}

/// Stroke variants, tried in order while the re-mesher refuses them:
///   0..3   "tip": the blade's tip stops inside the head (a partial-depth
///          cut); blade length s and sweep 1.5 s, s binary-searched;
///   4..7   "air": the axis-aligned stroke with the blade length moved off the
///          searched one until no cell along its tip line holds bone surface
///          (the re-mesher refuses tips inside bone often, see RESULTS.md),
///          sweep length chosen to keep the cut's area;
///   8..11  "through": the tip beyond the scan box, sweep length searched.
/// Within a kind, variant v' > 0 shifts the stroke (base, plane height) and,
/// for tip and through, turns it: blade pitched down 2v' degrees, sweep
/// yawed 1.5v' degrees.
enum class StrokeKind { Tip, Air, Through };
constexpr int kStrokesPerKind = 4;
constexpr int kStrokeVariants = 3 * kStrokesPerKind;
constexpr double kSweepAspect = 1.5; ///< sweep length / blade length

inline StrokeKind strokeKindOf(int variant)
{
    return variant < kStrokesPerKind ? StrokeKind::Tip : variant < 2 * kStrokesPerKind ? StrokeKind::Air : StrokeKind::Through;
}
inline const char* strokeKindName(int variant)
{
    const StrokeKind k = strokeKindOf(variant);
    return k == StrokeKind::Tip ? "tip" : k == StrokeKind::Air ? "air" : "through";
}

inline double strokeFrontY(const CutScene& sc, int v) { return sc.yFront - 3.0 - 0.37 * v; }

inline double throughBladeLength(const CutScene& sc)
{
    const double yBox = sc.frame.toWorld(glm::dvec3(sc.frame.dims) - 1.0).y;
    return (yBox - strokeFrontY(sc, 0)) * 1.2 + 10.0;
}

/// The straight stroke of blade length B and sweep length L (world mm).
inline std::vector<cutter::Pose> makeCutStroke(const CutScene& sc, double B, double L, int variant)
{
    const cutter::IndexFrame& f = sc.frame;
    const StrokeKind kind = strokeKindOf(variant);
    const int v = kind == StrokeKind::Air ? 0 : variant % kStrokesPerKind;
    const double y0 = strokeFrontY(sc, v);
    const double deg = M_PI / 180.0;
    const double pitch = 2.0 * v * deg, yaw = 1.5 * v * deg;
    const glm::dvec3 dir(0.0, std::cos(pitch), -std::sin(pitch));
    const glm::dvec3 sweep(std::cos(yaw), std::sin(yaw), 0.0);
    const glm::dvec3 centre(sc.xCentre + 0.37 * v * f.spacing.x, y0,
                            sc.planeZ + 0.07 * v * f.spacing.z + (kind == StrokeKind::Tip ? 0.5 * B * std::sin(pitch) : 0.0));
    const int steps = std::max(1, int(std::ceil(L / (0.25 * f.spacing.x))));
    std::vector<cutter::Pose> poses;
    for (int i = 0; i <= steps; ++i) {
        cutter::Pose p;
        p.time = 0.001 * i;
        p.base = centre + (L * (double(i) / steps - 0.5) + 0.37 * f.spacing.x) * sweep;
        p.direction = dir;
        p.length = B;
        poses.push_back(p);
    }
    return poses;
}

/// Blade and sweep length for size parameter s of a tip or through variant.
inline std::pair<double, double> strokeSize(const CutScene& sc, double s, int variant)
{
    return strokeKindOf(variant) == StrokeKind::Through ? std::make_pair(throughBladeLength(sc), s)
                                                        : std::make_pair(s, kSweepAspect * s);
}

inline size_t cutCellsOf(const CutScene& sc, const std::vector<cutter::Quad>& quads, double kerf)
{
    cutter::CutMask mask(sc.frame, kerf);
    mask.beginStroke();
    for (const cutter::Quad& q : quads) mask.addQuad(q);
    return mask.cutCellCount();
}

/// Size parameter (blade length, or sweep length for through-cuts) whose
/// stroke cuts closest to `target` cells (*cells: that count).
inline double searchStrokeSize(const CutScene& sc, size_t target, int variant, double kerf, size_t* cells)
{
    double lo = 2.0 * sc.frame.spacing.y, hi = 400.0;
    double best = lo;
    size_t bestCells = 0;
    const auto dist = [&](size_t c) { return c > target ? c - target : target - c; };
    for (int it = 0; it < 40 && hi - lo > 1e-3; ++it) {
        const double mid = 0.5 * (lo + hi);
        const auto [B, L] = strokeSize(sc, mid, variant);
        const size_t n = cutCellsOf(sc, cutter::filterStroke(makeCutStroke(sc, B, L, variant), sc.frame), kerf);
        if (bestCells == 0 || dist(n) < dist(bestCells)) {
            best = mid;
            bestCells = n;
        }
        (n < target ? lo : hi) = mid;
    }
    *cells = bestCells;
    return best;
}

/// Cells along the tip line of the axis-aligned stroke (B, L) (and the rows
/// either side of it) whose corners straddle the isovalue.
inline size_t tipSurfaceCells(const CutScene& sc, double B, double L)
{
    const cutter::IndexFrame& f = sc.frame;
    const double y0 = strokeFrontY(sc, 0);
    const double x0 = sc.xCentre - 0.5 * L + 0.37 * f.spacing.x;
    const glm::dvec3 a = f.toIndex(glm::dvec3(x0, y0 + B, sc.planeZ));
    const glm::dvec3 b = f.toIndex(glm::dvec3(x0 + L, y0 + B, sc.planeZ));
    auto acc = sc.vol->grid->getConstAccessor();
    const openvdb::CoordBBox box = sc.vol->indexBox();
    size_t n = 0;
    const int cz = int(std::floor(a.z)), cy0 = int(std::floor(a.y));
    for (int cx = int(std::floor(a.x)) - 1; cx <= int(std::floor(b.x)) + 1; ++cx)
        for (int cy = cy0 - 1; cy <= cy0 + 1; ++cy) {
            int inside = 0;
            for (int c = 0; c < 8; ++c) {
                const openvdb::Coord g(cx + (c & 1), cy + ((c >> 1) & 1), cz + ((c >> 2) & 1));
                inside += box.isInside(g) && acc.getValue(g) >= sc.iso;
            }
            n += inside != 0 && inside != 8;
        }
    return n;
}

/// The k-th "air" stroke: blade length moved off `bestB` (the tip search's)
/// in half-voxel steps, alternately longer and shorter, up to 35%, until the
/// tip line holds no bone surface; the sweep keeps the area (1.5 bestB^2).
inline bool airStrokeSize(const CutScene& sc, double bestB, int k, double* B, double* L)
{
    const double h = 0.5 * sc.frame.spacing.y;
    int found = 0;
    for (int i = 0; i * h <= 0.35 * bestB; ++i)
        for (int sign : {1, -1}) {
            if (i == 0 && sign < 0) continue;
            const double b = bestB + sign * i * h;
            const double l = kSweepAspect * bestB * bestB / b;
            if (tipSurfaceCells(sc, b, l) != 0) continue;
            if (found++ == k) {
                *B = b;
                *L = l;
                return true;
            }
        }
    return false;
}

/// One stroke variant near a target cut-cell count, ready for a re-mesher.
struct CandidateStroke
{
    int variant = 0;
    double blade = 0.0; ///< blade length, mm
    std::vector<cutter::Pose> poses;
    std::vector<cutter::Quad> quads;       ///< filterStroke of the poses
    std::unique_ptr<cutter::CutMask> mask; ///< the quads, as one stroke
    /// The base's travel from the first pose to the last, mm.
    double sweep() const { return glm::length(poses.back().base - poses.front().base); }
};

/// Builds the stroke variants near `target` cut cells in order (see
/// StrokeKind; an air variant is skipped when no blade length clears its tip
/// line) and hands each to `tryStroke` until it returns true: it accepted the
/// stroke (it may move what it keeps out of the candidate) or gives up.
/// Returns false when no call returned true. `firstVariant` > 0 starts
/// there (the tip variants 1..3 are pitched and yawed: not along the grid).
inline bool forEachCutStroke(const CutScene& sc, size_t target, double kerf,
                             const std::function<bool(CandidateStroke&)>& tryStroke, int firstVariant = 0)
{
    double tipBlade = 0.0; // variant 0's blade length
    if (firstVariant >= kStrokesPerKind) { // an air variant sizes itself from the tip's blade
        size_t cells = 0;
        tipBlade = strokeSize(sc, searchStrokeSize(sc, target, 0, kerf, &cells), 0).first;
    }
    for (int variant = firstVariant; variant < kStrokeVariants; ++variant) {
        size_t cells = 0;
        double B = 0.0, L = 0.0;
        if (strokeKindOf(variant) == StrokeKind::Air) {
            if (!airStrokeSize(sc, tipBlade, variant - kStrokesPerKind, &B, &L)) continue;
        } else {
            std::tie(B, L) = strokeSize(sc, searchStrokeSize(sc, target, variant, kerf, &cells), variant);
            if (variant == 0) tipBlade = B;
        }
        CandidateStroke c;
        c.variant = variant;
        c.blade = B;
        c.poses = makeCutStroke(sc, B, L, variant);
        c.quads = cutter::filterStroke(c.poses, sc.frame);
        c.mask = std::make_unique<cutter::CutMask>(sc.frame, kerf);
        c.mask->beginStroke();
        for (const cutter::Quad& q : c.quads) c.mask->addQuad(q);
        if (tryStroke(c)) return true;
    }
    return false;
}

/// A cut the re-mesher accepted, with its mask and updated re-mesher.
struct SizedCut
{
    bool ok = false;
    size_t target = 0, cells = 0;
    int variant = 0, refused = 0;
    double blade = 0.0, sweep = 0.0; ///< mm
    double remeshMs = 0.0;           ///< the accepted stroke's CutRemesher::update from scratch, wall ms
    std::vector<cutter::Pose> poses;
    std::vector<cutter::Quad> quads;
    std::unique_ptr<cutter::CutMask> mask;
    std::unique_ptr<cutter::CutRemesher> remesher;
    std::string note; ///< why not ok
};

/// The first stroke variant (see StrokeKind) near `target` cut cells that
/// the re-mesher accepts on the scene. `onRefused` (may be empty) hears of
/// each refused variant. Runs on the calling thread's TBB arena (limit it
/// with tbb::global_control as the caller likes).
inline SizedCut chooseCut(const CutScene& sc, size_t target, double kerf,
                          const std::function<void(int variant, const std::string& why)>& onRefused = {},
                          int firstVariant = 0)
{
    SizedCut cut;
    cut.target = target;
    const bool ok = forEachCutStroke(sc, target, kerf, [&](CandidateStroke& c) {
        try {
            auto remesher = std::make_unique<cutter::CutRemesher>(*sc.vol, sc.iso, *sc.uncut);
            const auto t0 = Clock::now();
            remesher->update(*c.mask);
            cut.remeshMs = msSince(t0);
            cut.ok = true;
            cut.variant = c.variant;
            cut.cells = c.mask->cutCellCount();
            cut.blade = c.blade;
            cut.sweep = c.sweep();
            cut.poses = std::move(c.poses);
            cut.quads = std::move(c.quads);
            cut.mask = std::move(c.mask);
            cut.remesher = std::move(remesher);
            return true;
        } catch (const std::exception& e) {
            ++cut.refused;
            if (onRefused) onRefused(c.variant, e.what());
            return false;
        }
    }, firstVariant);
    if (!ok) cut.note = "every stroke refused";
    return cut;
}

} // namespace mtcut::bench
