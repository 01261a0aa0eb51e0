#include "cutter/Remesh.h"

#include "cutter/FloatRepair.h"
#include "cutter/Isosurface.h"
#include "cutter/PrismCover.h"
#include "cutter/RemeshKernel.h"
#include "vdb/Error.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace mtcut::cutter {

// ------------------------------------------------------------- vertex ids --

bool CutVertexId::operator==(const CutVertexId& o) const
{
    return dim == o.dim && planeCount == o.planeCount && tagCount == o.tagCount && feature == o.feature &&
           planes == o.planes && tags == o.tags;
}

bool CutVertexId::operator<(const CutVertexId& o) const
{
    if (dim != o.dim) return dim < o.dim;
    if (feature != o.feature) return feature < o.feature;
    if (planeCount != o.planeCount) return planeCount < o.planeCount;
    if (planes != o.planes) return planes < o.planes;
    if (tagCount != o.tagCount) return tagCount < o.tagCount;
    return tags < o.tags;
}

size_t CutVertexIdHash::operator()(const CutVertexId& v) const
{
    uint64_t h = 1469598103934665603ull ^ (uint64_t(v.dim) << 16 | uint64_t(v.planeCount) << 8 | v.tagCount);
    auto mix = [&](uint64_t x) {
        h ^= x + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
    };
    for (uint64_t f : v.feature) mix(f);
    for (int i = 0; i < v.planeCount; ++i) mix(v.planes[size_t(i)]);
    for (int i = 0; i < v.tagCount; ++i) mix(v.tags[size_t(i)]);
    return size_t(h);
}

uint64_t gridVertexId(int i, int j, int k)
{
    constexpr int64_t off = int64_t(1) << 20;
    return (uint64_t(int64_t(k) + off) << 42) | (uint64_t(int64_t(j) + off) << 21) | uint64_t(int64_t(i) + off);
}

openvdb::Coord gridVertexCoord(uint64_t id)
{
    constexpr int64_t off = int64_t(1) << 20;
    constexpr uint64_t m = (uint64_t(1) << 21) - 1;
    return openvdb::Coord(int(int64_t(id & m) - off), int(int64_t(id >> 21 & m) - off), int(int64_t(id >> 42 & m) - off));
}

using namespace remesh_detail;

// ---------------------------------------------------------- quad geometry --

namespace {

/// A prism folding back onto the previous one borrows its faces
/// (makePrismGeom) when their normals are within this of opposite
/// (radians) and its corners lie near the previous prism's mid-plane.
constexpr double kFoldMaxAngle = 1e-3;

/// Convex hull (CCW around n) of the quad's corners, as corner indices.
std::vector<int> hullOf(const Quad& q, const IndexFrame& frame, const dvec3& n)
{
    std::array<dvec3, 4> c;
    for (uint32_t i = 0; i < q.cornerCount; ++i) c[i] = frame.toIndex(q.corners[i]);
    return convexHullOrder(c.data(), q.cornerCount, n);
}

dvec3 indexNormal(const Quad& q, const IndexFrame& frame)
{
    return glm::normalize(q.normal * frame.spacing);
}

Plane quadPlane(const Quad& q, const IndexFrame& frame)
{
    Plane p;
    p.n = indexNormal(q, frame);
    double d = 0.0;
    for (uint32_t i = 0; i < q.cornerCount; ++i) d += glm::dot(p.n, frame.toIndex(q.corners[i]));
    p.d = d / double(q.cornerCount);
    return p;
}

/// Index of a hull edge of `other` with the same two world corners as (a, b), or -1.
bool sharesEdge(const Quad& other, const std::vector<int>& otherHull, const dvec3& a, const dvec3& b)
{
    const size_t m = otherHull.size();
    for (size_t i = 0; i < m; ++i) {
        const dvec3& c = other.corners[size_t(otherHull[i])];
        const dvec3& d = other.corners[size_t(otherHull[(i + 1) % m])];
        if ((c == a && d == b) || (c == b && d == a)) return true;
    }
    return false;
}

/// Is the corner of `q` at `corner` (a hull corner, world) too sharp for a
/// mitre that bends by `tanHalfBend` (tan of half the angle between the two
/// quads' normals)? The mitre meets the offset planes at most
/// delta = (w/2) tan(bend/2) past the stick, so at a corner of angle a it
/// reaches delta / sin(a) past the corner along the rim. cutRegion() grows the
/// hull by margin = (w/2) tan(kKerfMitreMaxBend/2) (or more) with the corner
/// clamped where 1 - cos(a) < kKerfMitreMinCornerGap: the clamped corner is
/// margin (1 - cos a) / kKerfMitreMinCornerGap off the stick's line, and the
/// reach is covered while delta stays within half of that. Past that the
/// prism gets a cap at the corner (makePrismGeom), and the joint keeps its
/// mitre all the same: without one, the two prisms' end planes leave a
/// notch w/2 deep and (w/2) bend wide at the stick, sub-micron for nearly
/// coplanar quads, whose walls cross once written in float (seed 1023 on
/// the 2 mm head; 11001, 11006, 11049 on it relabelled to 0.45 x 0.45 x
/// 1.25 mm voxels).
bool tooSharpForMitre(const Quad& q, const std::vector<int>& hull, const dvec3& corner, double tanHalfBend)
{
    const size_t m = hull.size();
    for (size_t k = 0; k < m; ++k) {
        if (q.corners[size_t(hull[k])] != corner) continue;
        const dvec3 a = q.corners[size_t(hull[(k + m - 1) % m])] - corner;
        const dvec3 b = q.corners[size_t(hull[(k + 1) % m])] - corner;
        const double la = glm::length(a), lb = glm::length(b);
        if (!(la > 0.0 && lb > 0.0)) return true;
        const double gap = 1.0 - glm::dot(a, b) / (la * lb);
        if (gap >= kKerfMitreMinCornerGap) return false;
        return !(tanHalfBend <= 0.5 * std::tan(0.5 * kKerfMitreMaxBend) * gap / kKerfMitreMinCornerGap);
    }
    return false;
}

bool lexLess(const dvec3& a, const dvec3& b)
{
    if (a.x != b.x) return a.x < b.x;
    if (a.y != b.y) return a.y < b.y;
    return a.z < b.z;
}

dvec3 centroidOf(const Quad& q, const IndexFrame& frame)
{
    dvec3 c(0.0);
    for (uint32_t i = 0; i < q.cornerCount; ++i) c += frame.toIndex(q.corners[i]);
    return c / double(q.cornerCount);
}

/// Is the hull edge (a, b) (world corners) of quad `ref` shared with the previous or next quad of its stroke?
bool isJunctionEdge(const CutMask& mask, const QuadRef& ref, const dvec3& a, const dvec3& b)
{
    for (int dq : {-1, 1}) {
        const int64_t oq = int64_t(ref.quad) + dq;
        if (oq < 0 || oq >= int64_t(mask.quadCount(ref.stroke))) continue;
        const Quad& o = mask.quad(QuadRef{ref.stroke, uint32_t(oq)});
        if (o.degenerate) continue;
        if (sharesEdge(o, hullOf(o, mask.frame(), indexNormal(o, mask.frame())), a, b)) return true;
    }
    return false;
}

/// The plane through the stick p0 -> p1 (index space) that bisects the angle
/// between the two quads meeting at it (centroids cl, cu, unit normals nl,
/// nu; lower quad first, so both quads get the same plane), whichever way
/// their normals point: each quad's direction away from the stick in its own
/// plane, a; the plane holds the stick and al + au, so its normal is along
/// al - au. Used where the plane bisecting the normals fails (a fold with the
/// normals agreeing, a straight stroke with them opposite). False when the
/// two directions agree to 1e-9 (one plane: no wedge between them).
bool foldMitre(const dvec3& cl, const dvec3& nl, const dvec3& cu, const dvec3& nu, const dvec3& p0, const dvec3& p1,
               Plane& mp)
{
    const dvec3 t = p1 - p0;
    auto away = [&](const dvec3& c, const dvec3& n) {
        dvec3 a = glm::cross(n, t);
        const double l = glm::length(a);
        if (!(l > 0.0)) return dvec3(0.0);
        a /= l;
        return glm::dot(a, c - p0) < 0.0 ? -a : a;
    };
    const dvec3 d = away(cl, nl) - away(cu, nu);
    const double len = glm::length(d);
    if (!(len > 1e-9)) return false;
    mp.n = d / len;
    mp.d = glm::dot(mp.n, p0);
    return true;
}

/// The rim side of quad `ref` through world corner p other than the edge (p, other), or 0.
uint64_t rimSideAt(const CutMask& mask, const QuadRef& ref, const dvec3& p, const dvec3& other)
{
    const Quad& q = mask.quad(ref);
    const std::vector<int> hull = hullOf(q, mask.frame(), indexNormal(q, mask.frame()));
    const size_t m = hull.size();
    for (size_t e = 0; e < m; ++e) {
        const dvec3& a = q.corners[size_t(hull[e])];
        const dvec3& b = q.corners[size_t(hull[(e + 1) % m])];
        const bool hasP = a == p || b == p;
        const bool isShared = (a == p && b == other) || (b == p && a == other);
        if (!hasP || isShared) continue;
        return isJunctionEdge(mask, ref, a, b) ? 0 : planeIdOf(ref.stroke, ref.quad, 1 + int(e));
    }
    return 0;
}

/// Geometry of quad `ref` of the mask (refs of the cell, to resolve partners).
QuadGeom makeQuadGeom(const CutMask& mask, const QuadRef& ref)
{
    const IndexFrame& frame = mask.frame();
    const Quad& q = mask.quad(ref);
    QuadGeom g;
    g.id = planeIdOf(ref.stroke, ref.quad, 0);
    g.pi = quadPlane(q, frame);
    const std::vector<int> hull = hullOf(q, frame, g.pi.n);
    const dvec3 centre = centroidOf(q, frame);
    const size_t m = hull.size();
    for (size_t e = 0; e < m; ++e) {
        const dvec3& wa = q.corners[size_t(hull[e])];
        const dvec3& wb = q.corners[size_t(hull[(e + 1) % m])];
        QuadGeom::Side side;
        bool junction = false;
        for (int dq : {-1, 1}) {
            const int64_t oq = int64_t(ref.quad) + dq;
            if (oq < 0 || oq >= int64_t(mask.quadCount(ref.stroke))) continue;
            const QuadRef oref{ref.stroke, uint32_t(oq)};
            const Quad& o = mask.quad(oref);
            if (o.degenerate) continue;
            const dvec3 on = indexNormal(o, frame);
            if (!sharesEdge(o, hullOf(o, frame, on), wa, wb)) continue;
            // The mitre: through the shared edge, bisecting the two quads' planes,
            // computed from the lower quad's data first so both quads get the same plane.
            const bool lower = dq > 0;
            const dvec3 nl = lower ? g.pi.n : on, nu = lower ? on : g.pi.n;
            dvec3 p0 = frame.toIndex(wa), p1 = frame.toIndex(wb);
            if (lexLess(p1, p0)) std::swap(p0, p1);
            const dvec3 mdir = glm::cross(nl + nu, p1 - p0);
            const double len = glm::length(mdir);
            Plane mp;
            const dvec3 oc = centroidOf(o, frame);
            double own = 0.0, other = 0.0;
            if (len > 1e-12) {
                mp.n = mdir / len;
                mp.d = glm::dot(mp.n, p0);
                own = mp.h(centre);
                other = mp.h(oc);
            }
            if (!(own * other < 0.0)) {
                // The normals agree where the quads fold back onto one side
                // of the stick (a zigzag's turn with the base sliding along
                // the blade, which orients the quads), or point opposite ways
                // along a straight stroke (their sum 0: no such plane). The
                // plane that bisects the angle between the quads parts them
                // instead; without it both would end in a rim there and the
                // wedge between them would touch the outside along the stick
                // (tooth, kerf 0, sharp turns, seed 74005: an edge used twice
                // each way in cell (32, 63, 105)).
                if (!foldMitre(lower ? centre : oc, nl, lower ? oc : centre, nu, p0, p1, mp)) continue;
                own = mp.h(centre);
                other = mp.h(oc);
                if (!(own * other < 0.0)) continue; // the quads in one plane: the kernel refuses them
                side.fold = true;
            }
            side.id = planeIdOf(ref.stroke, lower ? ref.quad : uint32_t(oq), kJunctionKind);
            side.plane = mp;
            side.orient = own > 0 ? 1.0 : -1.0;
            side.partnerId = planeIdOf(ref.stroke, uint32_t(oq), 0);
            for (int k = 0; k < 2; ++k) {
                const dvec3& pc = k == 0 ? wa : wb;
                const dvec3& po = k == 0 ? wb : wa;
                side.cornerSides[size_t(k)] = {rimSideAt(mask, ref, pc, po), rimSideAt(mask, oref, pc, po)};
            }
            junction = true;
            break;
        }
        if (!junction) {
            const dvec3 a = frame.toIndex(wa), b = frame.toIndex(wb);
            const dvec3 sdir = glm::cross(g.pi.n, b - a);
            const double len = glm::length(sdir);
            if (!(len > 0.0)) continue;
            side.id = planeIdOf(ref.stroke, ref.quad, 1 + int(e));
            side.plane.n = sdir / len;
            side.plane.d = glm::dot(side.plane.n, a);
            side.orient = side.plane.h(centre) >= 0 ? 1.0 : -1.0;
        }
        g.sides.push_back(side);
    }
    return g;
}

} // namespace

/// Rim planes of kerf > 0 prisms, per quad: (world corner, side id, plane)
/// for each rim side through that corner. Quads of a stroke only append, so a
/// quad's entry depends on its own corners and its predecessor's entry.
struct RimEntry
{
    struct Rim
    {
        glm::dvec3 corner; ///< world
        uint64_t id;
        glm::dvec3 n; ///< the plane n.x = d, index space
        double d;
    };
    std::array<double, 12> signature{};
    std::vector<Rim> rims;
    std::array<QuadGeom::Side, 2> faces{}; ///< the prism's offset faces as built (+normal side first), borrowed or its own
    bool borrowed = false; ///< its faces are the previous prism's (a fold back, makePrismGeom)
    uint64_t serial = 0; ///< which build of an entry this is (PrismCache::serial)
};
struct PrismCache
{
    std::unordered_map<uint64_t, RimEntry> entries;
    /// Each quad's prism as makePrismGeom last built it, with what it was
    /// built from: the quad and its stroke neighbours, kerf and frame
    /// (prismGeomKey), and the build of the previous quad's rim entry.
    struct Geom
    {
        std::array<double, 3 * 17 + 7> key;
        uint64_t previousSerial = 0;
        QuadGeom geom;
    };
    std::unordered_map<uint64_t, Geom> geoms;
    uint64_t serial = 0;
};

namespace {

std::array<double, 12> cornerSignature(const Quad& q)
{
    std::array<double, 12> s{};
    for (int i = 0; i < 4; ++i)
        for (int a = 0; a < 3; ++a) s[size_t(3 * i + a)] = q.corners[size_t(i)][a];
    return s;
}

/// Geometry of quad `ref` as a kerf > 0 removed region (DESIGN invariant 7):
/// a closed convex prism, every bounding plane a side (the offset planes have
/// kinds kPlusKind and kMinusKind), so "inside" is inExtentClosed. Built from
/// the quad's world geometry and mapped to index space.
///
/// - Offsets: the quad's plane shifted by +-w/2 (world).
/// - A hull edge shared with the previous or next quad of the stroke, bending
///   by less than kKerfMitreMaxBend: the mitre, one plane object for both
///   quads (the lower quad's data first) through the stick and
///   u = (w/2)(n_q + n_o)/(1 + n_q.n_o), the world bisector, on which the two
///   quads' offset planes meet exactly (also with anisotropic spacing). At a
///   corner of the stick too sharp for that bend (tooSharpForMitre), the
///   mitre would reach along the rim past what cutRegion() covers: a cap
///   there, the plane through the corner at right angles to the stick
///   (world), again one plane object for both quads (kCapKinds).
/// - Any other edge (rims, unjoined stick ends): the plane through it
///   perpendicular to the quad in world mm; but a rim that continues the previous quad's
///   rim through a corner of their shared stick, mitred or not (both its
///   corners within 1e-4 voxel of that plane, normals within 1.4e-4 rad),
///   uses that very plane object, so the two prisms meet the mitre in the
///   same rim line and leave no sub-micron sliver there, and coplanar faces
///   across an unmitred turn are one surface in remeshTet.
/// The mask voxelises cutRegion(), which covers the mitre joints.
QuadGeom makePrismGeom(const CutMask& mask, const QuadRef& ref, PrismCache& cache);

/// The guard of a fold's borrowed faces (makePrismGeom): does the mask cut, by quad
/// `ref` or the one before it, every cell that `ref`'s quad would reach with
/// its corners moved onto the plane `mid` (index space, normal `n`)? Its
/// region, cutRegion() of the moved quad, has the previous prism's faces
/// (the same plane and offset) and, for ends, the quad's own moved by at
/// most the fold's tolerance, inside the region's growth. Only these two
/// quads count, so the answer stays the same while they stand, however the
/// stroke goes on or is undone after them.
bool maskHoldsFold(const CutMask& mask, const QuadRef& ref, const Quad& q, const dvec3& n, double mid)
{
    const IndexFrame& frame = mask.frame();
    std::array<dvec3, 4> corners{};
    for (uint32_t k = 0; k < q.cornerCount; ++k) {
        const dvec3 p = frame.toIndex(q.corners[k]);
        corners[k] = frame.toWorld(p - (glm::dot(n, p) - mid) * n);
    }
    const Quad moved = makeQuad(corners.data(), q.cornerCount, q.stick);
    if (moved.degenerate) return false;
    std::vector<glm::ivec3> cells;
    voxelizeCut(moved, mask.kerf(), frame, cells);
    const QuadRef before{ref.stroke, ref.quad - 1};
    for (const glm::ivec3& c : cells) {
        const std::vector<QuadRef>* list = mask.quadsAt(openvdb::Coord(c.x, c.y, c.z));
        if (!list || (std::find(list->begin(), list->end(), ref) == list->end() &&
                      std::find(list->begin(), list->end(), before) == list->end()))
            return false;
    }
    return true;
}
std::array<double, 3 * 17 + 7> prismGeomKey(const CutMask& mask, const QuadRef& r);

const RimEntry& rimEntry(const CutMask& mask, const QuadRef& ref, PrismCache& cache)
{
    const uint64_t key = uint64_t(ref.stroke) << 32 | ref.quad;
    // Walk back to the first quad whose entry is missing or stale, then build forward.
    std::vector<uint32_t> todo;
    for (int64_t i = ref.quad; i >= 0; --i) {
        const QuadRef r{ref.stroke, uint32_t(i)};
        auto it = cache.entries.find(uint64_t(ref.stroke) << 32 | uint32_t(i));
        if (it != cache.entries.end() && it->second.signature == cornerSignature(mask.quad(r))) break;
        todo.push_back(uint32_t(i));
    }
    for (auto it = todo.rbegin(); it != todo.rend(); ++it) makePrismGeom(mask, QuadRef{ref.stroke, *it}, cache);
    return cache.entries.at(key);
}

QuadGeom makePrismGeom(const CutMask& mask, const QuadRef& ref, PrismCache& cache)
{
    const IndexFrame& frame = mask.frame();
    const Quad& q = mask.quad(ref);
    QuadGeom g;
    g.id = planeIdOf(ref.stroke, ref.quad, 0);
    g.pi = quadPlane(q, frame);
    const double halfW = 0.5 * mask.kerf();
    const double hw = halfW / glm::length(q.normal * frame.spacing);
    const std::vector<int> hull = hullOf(q, frame, g.pi.n);
    const dvec3 centre = centroidOf(q, frame);
    for (int k = 0; k < 2; ++k) {
        QuadGeom::Side side;
        side.id = planeIdOf(ref.stroke, ref.quad, k == 0 ? kPlusKind : kMinusKind);
        side.plane.n = g.pi.n;
        side.plane.d = g.pi.d + (k == 0 ? hw : -hw);
        side.orient = k == 0 ? -1.0 : 1.0;
        g.sides.push_back(side);
    }
    RimEntry entry;
    entry.signature = cornerSignature(q);
    const RimEntry* previous = nullptr;
    if (ref.quad > 0 && !q.degenerate) {
        const QuadRef pref{ref.stroke, ref.quad - 1};
        auto it = cache.entries.find(uint64_t(pref.stroke) << 32 | pref.quad);
        if (it == cache.entries.end() || it->second.signature != cornerSignature(mask.quad(pref)))
            previous = &rimEntry(mask, pref, cache);
        else
            previous = &it->second;
    }
    const size_t m = hull.size();
    // The quad's world normal as an index-space direction: the sides stand
    // on the quad at right angles in world mm, as the saw's do. (The index
    // normal g.pi.n is that direction only when the spacing is isotropic;
    // with 0.47 x 0.47 x 1 mm voxels it leans up to about 30 degrees, so a
    // side through a rim edge leaned out of the region the mask voxelises,
    // cutRegion(): along a straight rim by about a tenth of a voxel at the
    // offset planes, farther at a sharp corner of the quad, and the cap
    // there crossed into a cell the mask did not cut: an open edge.)
    const bool isotropic = frame.spacing.x == frame.spacing.y && frame.spacing.y == frame.spacing.z;
    const dvec3 upright = isotropic ? g.pi.n : glm::normalize(q.normal / frame.spacing);
    // A fold back onto the previous quad: the blade went back over it,
    // nearly in its plane (a saw reversing at the end of a pass, its passes
    // joined by the path filter). The two prisms overlap, their faces and
    // their ends at the stick a few 1e-4 rad apart: planes that nearly
    // coincide, whose crossings inside a cell the kernel names apart
    // where they are one point (4 mm head, kerf 0.5, sawing seeds 103 and
    // 108 with a retrace tolerance of a voxel or half: a region's loop
    // passing one edge twice, "triangulation failed"). When the normals are
    // within kFoldMaxAngle (1e-3 rad) of opposite and every corner lies
    // within 1e-3 voxel (and a tenth of the half-width) of the previous
    // prism's mid-plane, the prism borrows the previous prism's plane
    // objects: its faces, swapped, and (pass 2) its end at the stick. (The
    // bound was first a continued rim's 1.4e-4 rad; the 1 mm head's sawing
    // seed 302 at a voxel's tolerance folded by 1.43e-4 rad, its corners
    // 4e-4 mm off, and stopped the same way. The corners' distance is what
    // makes the planes nearly coincide in the cells; the angle only keeps
    // the fold a fold.)
    // - It is not mitred to the next quad (pass 1; the next one sees
    //   RimEntry::borrowed): the kernel names a mitred pair's offset planes
    //   by their quads' ids (a point on the mitre and one offset plane is on
    //   the partner's too), which borrowed faces are not, and a mitre
    //   bisecting borrowed faces and the next quad's own would not hold the
    //   stick. The two meet on their own end planes instead. (With the
    //   mitre kept and the fold left unborrowed, the pass after a fold was
    //   refused: 4 mm head seeds 113 at the default tolerance, 185 and 223
    //   at a voxel's.)
    // - maskHoldsFold: the mask voxelises the quad itself, and a face moved
    //   across a grid plane would reach a cell no quad cut.
    // The decision depends on the quad and the previous one only, so a live
    // stroke and the stroke re-meshed from scratch agree.
    bool foldedBack = false;
    if (previous) {
        const Quad& o = mask.quad(QuadRef{ref.stroke, ref.quad - 1});
        if (!o.degenerate && glm::dot(q.normal, o.normal) < -std::cos(kFoldMaxAngle)) {
            const std::vector<int> oHull = hullOf(o, frame, indexNormal(o, frame));
            for (size_t e = 0; e < m && !foldedBack; ++e)
                foldedBack = sharesEdge(o, oHull, q.corners[size_t(hull[e])], q.corners[size_t(hull[(e + 1) % m])]);
            const Plane& f0 = previous->faces[0].plane;
            const double mid = 0.5 * (previous->faces[0].plane.d + previous->faces[1].plane.d);
            const double tolerance = std::min(1e-3, 0.1 * hw);
            for (uint32_t k = 0; k < q.cornerCount; ++k)
                foldedBack = foldedBack && std::abs(glm::dot(f0.n, frame.toIndex(q.corners[k])) - mid) <= tolerance;
            foldedBack = foldedBack && maskHoldsFold(mask, ref, q, f0.n, mid);
        }
    }
    // Pass 1: mitre joints per hull edge.
    std::vector<QuadGeom::Side> joint(m);
    std::vector<char> isJoint(m, 0);
    std::vector<QuadGeom::Side> caps; // sharp corners of a mitred joint
    dvec3 prevA(0.0), prevB(0.0); // world corners of the joint with the previous quad
    bool joinedPrevious = false;
    for (size_t e = 0; e < m; ++e) {
        const dvec3& wa = q.corners[size_t(hull[e])];
        const dvec3& wb = q.corners[size_t(hull[(e + 1) % m])];
        for (int dq : {-1, 1}) {
            const int64_t oq = int64_t(ref.quad) + dq;
            if (oq < 0 || oq >= int64_t(mask.quadCount(ref.stroke))) continue;
            const Quad& o = mask.quad(QuadRef{ref.stroke, uint32_t(oq)});
            if (o.degenerate) continue;
            const std::vector<int> oHull = hullOf(o, frame, indexNormal(o, frame));
            if (!sharesEdge(o, oHull, wa, wb)) continue;
            if (dq < 0) { // joined to the previous quad, with or without a mitre
                joinedPrevious = true;
                prevA = wa;
                prevB = wb;
            }
            const bool lower = dq > 0;
            const dvec3 nl = lower ? q.normal : o.normal, nu = lower ? o.normal : q.normal; // world
            const double c = glm::dot(nl, nu);
            if (!(c > std::cos(kKerfMitreMaxBend))) break;
            if (lower ? foldedBack : previous && previous->borrowed) break; // a borrowing prism: its own ends
            // Both quads' corners at the joint (the decision is the same from
            // either side): a sharp one would put the mitre outside the mask.
            const double tanHalfBend = std::sqrt(std::max(0.0, 1.0 - c) / (1.0 + c));
            // A corner of this quad at the joint too sharp for the mitre
            // gets a cap (below); the partner caps its own.
            const bool sharpA = tooSharpForMitre(q, hull, wa, tanHalfBend), sharpB = tooSharpForMitre(q, hull, wb, tanHalfBend);
            dvec3 w0 = wa, w1 = wb;
            if (lexLess(w1, w0)) std::swap(w0, w1);
            const dvec3 p0 = frame.toIndex(w0), p1 = frame.toIndex(w1);
            const dvec3 u = (halfW * (nl + nu) / (1.0 + c)) / frame.spacing;
            const dvec3 mdir = glm::cross(u, p1 - p0);
            const double mlen = glm::length(mdir);
            if (!(mlen > 0.0)) break;
            QuadGeom::Side side;
            side.plane.n = mdir / mlen;
            side.plane.d = glm::dot(side.plane.n, p0);
            const double own = side.plane.h(centre), other = side.plane.h(centroidOf(o, frame));
            if (!(own * other < 0.0)) break; // folded back: keep the own end plane
            side.id = planeIdOf(ref.stroke, lower ? ref.quad : uint32_t(oq), kJunctionKind);
            side.partnerId = planeIdOf(ref.stroke, uint32_t(oq), 0);
            side.orient = own > 0 ? 1.0 : -1.0;
            joint[e] = side;
            isJoint[e] = 1;
            // The mitre reaches past the stick by (w/2) tan(bend/2), and at a
            // corner of angle a along the rim by that over sin a, out of
            // the cells the mask cut round a sharp corner (cutRegion clamps
            // its growth there). A cap through the corner at right angles
            // to the stick (world) stops it there: the quad lies within its
            // angle a < 90 degrees at the corner and the offset planes are
            // parallel to the stick, so the cap takes none of the prism but
            // what the mitre added beyond the corner. Without the mitre, the two
            // prisms' own end planes both hold the stick and leave a notch
            // of solid between them on the outer side of the bend, thinner
            // than a float step near the stick, whose walls then cross grid
            // edges a float step apart and touch once written (0.45 x 0.45 x
            // 1.25 mm voxels, the skin, random strokes seeds 11001, 11006,
            // 11049: bends of 2-5 degrees at a pivot).
            for (int k = 0; k < 2; ++k) {
                if (!(k == 0 ? sharpA : sharpB)) continue;
                const dvec3& X = k == 0 ? wa : wb;
                const dvec3& Y = k == 0 ? wb : wa;
                const dvec3 nw = glm::normalize(X - Y);
                const dvec3 xi = frame.toIndex(X);
                QuadGeom::Side cap;
                cap.plane.n = glm::normalize(nw * frame.spacing);
                cap.plane.d = glm::dot(cap.plane.n, xi);
                // One plane object for both quads, as the mitre: named by
                // the lower quad and the corner's place on the stick.
                cap.id = planeIdOf(ref.stroke, lower ? ref.quad : uint32_t(oq), kCapKinds[X == w0 ? 0 : 1]);
                cap.orient = cap.plane.h(frame.toIndex(Y)) > 0 ? 1.0 : -1.0;
                caps.push_back(cap);
            }
            break;
        }
    }
    if (foldedBack) {
        g.sides[0] = previous->faces[1];
        g.sides[1] = previous->faces[0];
    }
    // Pass 2: the sides.
    for (size_t e = 0; e < m; ++e) {
        if (isJoint[e]) {
            g.sides.push_back(joint[e]);
            continue;
        }
        const dvec3& wa = q.corners[size_t(hull[e])];
        const dvec3& wb = q.corners[size_t(hull[(e + 1) % m])];
        const dvec3 a = frame.toIndex(wa), b = frame.toIndex(wb);
        const dvec3 sdir = glm::cross(upright, b - a);
        const double len = glm::length(sdir);
        if (!(len > 0.0)) continue;
        QuadGeom::Side side;
        side.id = planeIdOf(ref.stroke, ref.quad, 1 + int(e));
        side.plane.n = sdir / len;
        side.plane.d = glm::dot(side.plane.n, a);
        const bool stick = (wa == prevA && wb == prevB) || (wa == prevB && wb == prevA);
        if (foldedBack && stick) {
            // The previous prism's own end at the stick: its rim through both corners.
            for (const auto& r : previous->rims) {
                Plane pp;
                pp.n = r.n;
                pp.d = r.d;
                if ((r.corner == wa || r.corner == wb) && std::abs(pp.h(a)) <= 1e-4 && std::abs(pp.h(b)) <= 1e-4) {
                    side.id = r.id;
                    side.plane = pp;
                    break;
                }
            }
        } else if (previous && joinedPrevious) {
            // A rim continuing the previous quad's rim through a corner of their joint.
            for (const auto& r : previous->rims) {
                const bool atJoint = r.corner == prevA || r.corner == prevB;
                if (!atJoint || !(r.corner == wa || r.corner == wb)) continue;
                Plane pp;
                pp.n = r.n;
                pp.d = r.d;
                if (std::abs(pp.h(a)) <= 1e-4 && std::abs(pp.h(b)) <= 1e-4 &&
                    std::abs(glm::dot(pp.n, side.plane.n)) > 1.0 - 1e-8) {
                    side.id = r.id;
                    side.plane = pp;
                }
                break;
            }
        }
        entry.rims.push_back({wa, side.id, side.plane.n, side.plane.d});
        entry.rims.push_back({wb, side.id, side.plane.n, side.plane.d});
        side.orient = side.plane.h(centre) >= 0 ? 1.0 : -1.0;
        g.sides.push_back(side);
    }
    for (const auto& cap : caps) g.sides.push_back(cap);
    entry.faces = {g.sides[0], g.sides[1]};
    entry.borrowed = foldedBack;
    entry.serial = ++cache.serial;
    const uint64_t key = uint64_t(ref.stroke) << 32 | ref.quad;
    PrismCache::Geom& memo = cache.geoms[key];
    memo.key = prismGeomKey(mask, ref);
    memo.previousSerial = previous ? previous->serial : 0;
    memo.geom = g;
    cache.entries[key] = std::move(entry);
    return g;
}

} // namespace

// ============================================================ front end ====

/// One re-meshing kernel per thread for CutRemesher::update().
struct KernelPool : tbb::enumerable_thread_specific<CellKernel>
{
    KernelPool(const vdb::Volume& volume, float iso) : tbb::enumerable_thread_specific<CellKernel>(std::cref(volume), iso) {}
};

/// Zero kerf: each quad's QuadGeom (makeQuadGeom), built once per quad. It
/// depends on the quad and the two quads either side of it in its stroke
/// (junctions with the neighbours; the rim sides at a junction's ends look at
/// the neighbour's other neighbour), so it is kept with those five quads'
/// data and rebuilt when any of it changes. One mask frame (CutRemesher
/// clears it when the frame or kerf changes).
struct QuadGeomCache
{
    static constexpr size_t kPerQuad = 17; // corners, normal, cornerCount, degenerate
    using Key = std::array<double, 5 * kPerQuad>;
    struct Entry
    {
        Key key;
        QuadGeom geom;
    };
    std::unordered_map<uint64_t, Entry> entries;
};

namespace {

/// The data (QuadGeomCache::kPerQuad doubles each) of quads r-reach..r+reach
/// of r's stroke, 1e308 where there is none.
void putQuads(const CutMask& mask, const QuadRef& r, int reach, double* out)
{
    const int64_t count = int64_t(mask.quadCount(r.stroke));
    for (int d = 0; d <= 2 * reach; ++d) {
        double* o = out + QuadGeomCache::kPerQuad * size_t(d);
        std::fill(o, o + QuadGeomCache::kPerQuad, 1e308);
        const int64_t qi = int64_t(r.quad) + d - reach;
        if (qi < 0 || qi >= count) continue;
        const Quad& q = mask.quad(QuadRef{r.stroke, uint32_t(qi)});
        for (int i = 0; i < 4; ++i)
            for (int a = 0; a < 3; ++a) o[3 * i + a] = q.corners[size_t(i)][a];
        for (int a = 0; a < 3; ++a) o[12 + a] = q.normal[a];
        o[15] = double(q.cornerCount);
        o[16] = q.degenerate ? 1.0 : 0.0;
    }
}

QuadGeomCache::Key quadGeomKey(const CutMask& mask, const QuadRef& r)
{
    QuadGeomCache::Key k;
    putQuads(mask, r, 2, k.data());
    return k;
}

std::array<double, 3 * 17 + 7> prismGeomKey(const CutMask& mask, const QuadRef& r)
{
    static_assert(QuadGeomCache::kPerQuad == 17, "key layout");
    std::array<double, 3 * 17 + 7> k;
    putQuads(mask, r, 1, k.data());
    const IndexFrame& f = mask.frame();
    double* o = k.data() + 3 * 17;
    o[0] = mask.kerf();
    for (int a = 0; a < 3; ++a) {
        o[1 + a] = f.origin[a];
        o[4 + a] = f.spacing[a];
    }
    return k;
}

/// makePrismGeom(mask, ref, cache), reusing the quad's last build when it was
/// made from the same data and the same build of the previous quad's rim entry.
const QuadGeom& cachedPrismGeom(const CutMask& mask, const QuadRef& ref, PrismCache& cache)
{
    const uint64_t key = uint64_t(ref.stroke) << 32 | ref.quad;
    auto rebuilt = [&]() -> const QuadGeom& {
        makePrismGeom(mask, ref, cache); // stores it in cache.geoms
        return cache.geoms.at(key).geom;
    };
    auto it = cache.geoms.find(key);
    if (it == cache.geoms.end() || !(it->second.key == prismGeomKey(mask, ref))) return rebuilt();
    uint64_t previousSerial = 0;
    if (ref.quad > 0 && !mask.quad(ref).degenerate) {
        // The entry makePrismGeom would take (it rebuilds a missing or stale one).
        auto p = cache.entries.find(key - 1);
        if (p == cache.entries.end() || p->second.signature != cornerSignature(mask.quad(QuadRef{ref.stroke, ref.quad - 1})))
            return rebuilt();
        previousSerial = p->second.serial;
    }
    if (previousSerial != it->second.previousSerial) return rebuilt();
    return it->second.geom;
}

const QuadGeom& cachedQuadGeom(const CutMask& mask, const QuadRef& r, QuadGeomCache& cache)
{
    const QuadGeomCache::Key key = quadGeomKey(mask, r);
    QuadGeomCache::Entry& e = cache.entries[uint64_t(r.stroke) << 32 | r.quad];
    if (!(e.key == key)) {
        e.geom = makeQuadGeom(mask, r);
        e.key = key;
    }
    return e.geom;
}

using VolumeAccessor = CutRemesher::VolumeAccessor;

} // namespace

/// Kerf > 0: reads a cell's solid for coveredPrisms (a prism that meets the
/// cell's air alone needs no cover).
struct remesh_detail::CellSolidReader
{
    const vdb::Volume& volume;
    float iso;
    VolumeAccessor acc;
    CellSolidReader(const vdb::Volume& v, float i) : volume(v), iso(i), acc(v.grid->tree()) {}

    /// The cell's CellSolid, its corners read as the kernel reads them
    /// (RemeshKernel::loadTet: outside the scan box, the background and
    /// outside); false when every corner is inside (its box holds only solid).
    bool read(const Coord& cell, CellSolid& out)
    {
        std::array<float, 8> values;
        uint8_t inside = 0;
        const float background = volume.grid->background();
        for (int c = 0; c < 8; ++c) {
            const Coord g = cell + Coord(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            const bool inBox = g.x() >= 0 && g.y() >= 0 && g.z() >= 0 && g.x() < volume.dims.x() &&
                               g.y() < volume.dims.y() && g.z() < volume.dims.z();
            values[size_t(c)] = inBox ? acc.getValue(g) : background;
            if (inBox && values[size_t(c)] >= iso) inside |= uint8_t(1 << c);
        }
        if (inside == 0xff) return false;
        out = cellSolid(cell, values, inside, iso);
        return true;
    }
};

namespace {

/// quadCache: optional; when given, each quad's geometry is built once
/// (zero kerf: in quadCache; kerf > 0: in `cache`) instead of once per cell.
/// Into `quads` (its elements' storage is reused: no allocation per cell
/// once it has grown).
/// Kerf > 0: the prisms the others cover in the cell (coveredPrisms) are
/// left out; the kernel, the GPU cut pass and removedVoxels all take a
/// cell's quads from here. solidAt: the cell's solid (the kernel and the
/// GPU cut pass), so that a prism needs cover only where it meets it;
/// null (removedVoxels): wherever it meets the cell.
void cellQuads(const CutMask& mask, const Coord& cell, const std::vector<QuadRef>& refs, PrismCache& cache,
               QuadGeomCache* quadCache, std::vector<QuadGeom>& quads, CellSolidReader* solidAt)
{
    size_t n = 0;
    auto put = [&](const QuadGeom& g) {
        if (n < quads.size()) quads[n] = g;
        else quads.push_back(g);
        ++n;
    };
    for (const QuadRef& r : refs) {
        if (mask.quad(r).degenerate) continue; // zero area: removes nothing (the mask gives it no kerf either)
        if (mask.kerf() > 0) put(quadCache ? cachedPrismGeom(mask, r, cache) : makePrismGeom(mask, r, cache));
        else if (quadCache) put(cachedQuadGeom(mask, r, *quadCache));
        else put(makeQuadGeom(mask, r));
    }
    quads.resize(n);
    if (mask.kerf() > 0 && n >= kCoverMinPrisms && dropCoveredPrisms()) {
        CellSolid solid;
        const bool air = solidAt && solidAt->read(cell, solid);
        const std::vector<char> covered = coveredPrisms(cell, quads, air ? &solid : nullptr);
        size_t kept = 0;
        for (size_t i = 0; i < n; ++i)
            if (!covered[i]) {
                if (kept != i) quads[kept] = std::move(quads[i]);
                ++kept;
            }
        quads.resize(kept);
    }
    for (QuadGeom& q : quads)
        for (auto& s : q.sides) {
            if (s.partnerId == 0) continue;
            for (size_t i = 0; i < quads.size(); ++i)
                if (quads[i].id == s.partnerId) s.partner = int(i);
            if (s.partner < 0) s.partner = int(quads.size()); // partner exists, not in this cell
        }
}

/// What a cell's geometry depends on per quad: its corners and those of the
/// previous and next quad of its stroke (junctions and mitres, rim sharing),
/// 1e308 where there is none. A quad added or undone next to a quad thus
/// re-meshes every cell of that quad, not only the cells the new quad cuts.
std::array<double, 36> quadSignature(const CutMask& mask, const QuadRef& r)
{
    std::array<double, 36> s;
    s.fill(1e308);
    for (int k = 0; k < 3; ++k) {
        const int64_t qi = int64_t(r.quad) + k - 1;
        if (qi < 0 || qi >= int64_t(mask.quadCount(r.stroke))) continue;
        const std::array<double, 12> own = cornerSignature(mask.quad(QuadRef{r.stroke, uint32_t(qi)}));
        std::copy(own.begin(), own.end(), s.begin() + 12 * k);
    }
    return s;
}

/// What the kernel's output for `cell` depends on besides the volume, hashed
/// (two independent 64-bit hashes): the kind of cut, and per quad of the
/// cell that can reach one of its tets (in the kernel's order) its plane and
/// id, and each side in full unless the cell's closed box lies strictly on
/// one side of it (every corner more than kFar voxel inside, or outside).
/// Such a side decides nothing in the cell: no point there lies on it (the
/// kernel's tie is 1e-13 (1 + |x|)), every side test gives the same answer
/// for all points, so its id, partner and corner sides are never read; only
/// inside/outside remains. A quad with the box strictly outside one of its
/// sides reaches none of the cell's tets (gatherQuads passes it over in
/// each; the kernel reads a partner only among the quads a tet gathered, and
/// a partner's place in the list only for its sign), so it is left out.
/// When a stroke neighbour of a quad comes or goes, the quad's far side
/// changes (rim <-> junction); the cells that side does not reach keep this
/// digest. So do the cells the mask lists a new quad in that it reaches in
/// no tet (kerf > 0: the cut region is grown round the mitre, and pulls in
/// cells behind the prism). update() keeps their geometry instead of
/// re-meshing it.
std::array<uint64_t, 2> kernelInputDigest(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism)
{
    constexpr double kFar = 1e-6;
    std::array<uint64_t, 2> h{0x9e3779b97f4a7c15ull, 0xc2b2ae3d27d4eb4full};
    auto put = [&](uint64_t w) {
        h[0] = mixBits(h[0] ^ w) + 0x632be59bd9b4e019ull;
        h[1] = mixBits((h[1] + w) * 0xff51afd7ed558ccdull) ^ (h[1] >> 17);
    };
    auto putD = [&](double d) {
        uint64_t w;
        std::memcpy(&w, &d, sizeof w);
        put(w);
    };
    auto putPlane = [&](const Plane& p) {
        putD(p.n.x);
        putD(p.n.y);
        putD(p.n.z);
        putD(p.d);
    };
    // Each side against the cell's closed box: strictly inside at every
    // corner (1), strictly outside (2), or neither (3). A quad with a side
    // of kind 2 reaches none of the cell's tets: no corner of any is inside
    // that side or within the kernel's tie of it, so gatherQuads passes the
    // quad over in every one.
    auto kindOf = [&](const QuadGeom::Side& s) {
        double lo = std::numeric_limits<double>::infinity(), hi = -lo;
        for (int k = 0; k < 8; ++k) {
            const dvec3 x(cell.x() + (k & 1), cell.y() + ((k >> 1) & 1), cell.z() + ((k >> 2) & 1));
            const double v = s.orient * s.plane.h(x);
            lo = std::min(lo, v);
            hi = std::max(hi, v);
        }
        return lo > kFar ? 1 : hi < -kFar ? 2 : 3;
    };
    put(prism ? 2 : 1);
    std::vector<int> kinds; // of the quad's sides
    for (const QuadGeom& q : quads) {
        kinds.clear();
        bool reaches = true;
        for (const auto& s : q.sides) {
            kinds.push_back(kindOf(s));
            if (kinds.back() == 2) {
                reaches = false;
                break;
            }
        }
        if (!reaches) continue;
        put(q.id);
        putPlane(q.pi);
        put(q.sides.size());
        for (size_t i = 0; i < q.sides.size(); ++i) {
            const QuadGeom::Side& s = q.sides[i];
            put(uint64_t(kinds[i]));
            if (kinds[i] == 1) continue; // strictly inside over the whole cell
            put(s.id);
            putPlane(s.plane);
            putD(s.orient);
            put(uint64_t(int64_t(s.partner)) ^ (s.fold ? uint64_t(1) << 62 : 0));
            put(s.partnerId);
            for (const auto& cs : s.cornerSides) {
                put(cs.first);
                put(cs.second);
            }
        }
    }
    return h;
}

} // namespace

openvdb::MaskGrid::Ptr removedVoxels(const CutMask& mask)
{
    auto removed = openvdb::MaskGrid::create(false);
    if (!(mask.kerf() > 0)) return removed;
    auto acc = removed->getAccessor();
    PrismCache cache;
    std::vector<QuadGeom> quads;
    mask.forEachCutCell([&](const Coord& c, const std::vector<QuadRef>& list) {
        cellQuads(mask, c, list, cache, nullptr, quads, nullptr);
        for (int k = 0; k < 8; ++k) {
            const Coord g = c + Coord(k & 1, (k >> 1) & 1, (k >> 2) & 1);
            if (acc.isValueOn(g)) continue;
            const dvec3 x(g.x(), g.y(), g.z());
            for (const QuadGeom& q : quads) {
                bool in = true;
                for (const auto& sd : q.sides) in = in && sd.orient * sd.plane.h(x) >= 0.0;
                if (in) {
                    acc.setValueOn(g);
                    break;
                }
            }
        }
    });
    return removed;
}

std::vector<QuadGeom> remesh_detail::kernelQuadsOf(const CutMask& mask, const Coord& cell, const vdb::Volume* volume,
                                                   float iso)
{
    std::vector<QuadGeom> quads;
    const std::vector<QuadRef>* refs = mask.quadsAt(cell);
    if (!refs) return quads;
    PrismCache cache;
    std::unique_ptr<CellSolidReader> solid = volume ? std::make_unique<CellSolidReader>(*volume, iso) : nullptr;
    cellQuads(mask, cell, *refs, cache, nullptr, quads, solid.get());
    return quads;
}

remesh_detail::KernelQuads::KernelQuads(const CutMask& mask, const vdb::Volume& volume, float iso)
    : mMask(mask), mPrisms(std::make_unique<PrismCache>()), mQuadGeoms(std::make_unique<QuadGeomCache>()),
      mSolid(std::make_unique<CellSolidReader>(volume, iso))
{
}

remesh_detail::KernelQuads::~KernelQuads() = default;

std::vector<QuadGeom> remesh_detail::KernelQuads::of(const Coord& cell)
{
    std::vector<QuadGeom> quads;
    const std::vector<QuadRef>* refs = mMask.quadsAt(cell);
    if (!refs) return quads;
    cellQuads(mMask, cell, *refs, *mPrisms, mQuadGeoms.get(), quads, mSolid.get());
    return quads;
}

void remeshCell(const vdb::Volume& volume, float isovalue, const CutMask& mask, const openvdb::Coord& cell,
                CutCellGeometry& out)
{
    out.clear();
    const std::vector<QuadRef>* refs = mask.quadsAt(cell);
    if (!refs) return;
    CellKernel kernel(volume, isovalue);
    PrismCache cache;
    std::vector<QuadGeom> quads;
    CellSolidReader solid(volume, isovalue);
    cellQuads(mask, cell, *refs, cache, nullptr, quads, &solid);
    kernel.remesh(cell, quads, mask.kerf() > 0, out);
}

CutRemesher::CutRemesher(const vdb::Volume& volume, float isovalue, const Mesh& uncut)
    : mKernels(std::make_unique<KernelPool>(volume, isovalue)), mPrismCache(std::make_unique<PrismCache>()),
      mQuadCache(std::make_unique<QuadGeomCache>()), mVolume(&volume), mIso(isovalue), mUncut(uncut)
{
    const size_t nt = mUncut.triangleCount();
    if (nt > size_t(std::numeric_limits<int32_t>::max()))
        throw std::length_error("remesh: more than 2^31 - 1 triangles in the uncut mesh");
    {
        openvdb::tree::ValueAccessor<openvdb::Int32Tree, false> acc(mUncutFirst);
        for (size_t t = 0; t < nt;) {
            const glm::ivec3 c = mUncut.triangleVoxels[t];
            size_t e = t + 1;
            while (e < nt && mUncut.triangleVoxels[e] == c) ++e;
            acc.setValueOn(Coord(c.x, c.y, c.z), int32_t(t));
            t = e;
        }
    }
    // Snap rounding candidates (fusedMesh): the ends of zero-length uncut edges, and their triangles.
    std::vector<char> snapVertex;
    for (size_t t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = mUncut.indices[3 * t + size_t(k)], b = mUncut.indices[3 * t + size_t((k + 1) % 3)];
            if (a == b || !(mUncut.positions[a] == mUncut.positions[b])) continue;
            if (snapVertex.empty()) snapVertex.assign(mUncut.positions.size(), 0);
            snapVertex[a] = snapVertex[b] = 1;
        }
    if (!snapVertex.empty())
        for (size_t t = 0; t < nt; ++t)
            if (snapVertex[mUncut.indices[3 * t]] || snapVertex[mUncut.indices[3 * t + 1]] || snapVertex[mUncut.indices[3 * t + 2]])
                mSnapTriangles.push_back(uint32_t(t));
}

CutRemesher::~CutRemesher() = default;

void remesh_detail::sortUniqueCells(std::vector<Coord>& cells, const std::vector<size_t>& runs)
{
    constexpr int64_t kBias = 1 << 20, kSpan = int64_t(1) << 21;
    const bool packable = std::all_of(cells.begin(), cells.end(), [&](const Coord& c) {
        for (int a = 0; a < 3; ++a)
            if (int64_t(c[a]) + kBias < 0 || int64_t(c[a]) + kBias >= kSpan) return false;
        return true;
    });
    if (!packable) {
        std::sort(cells.begin(), cells.end());
        cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
        return;
    }
    std::vector<uint64_t> keys(cells.size());
    for (size_t i = 0; i < cells.size(); ++i) {
        const Coord& c = cells[i];
        keys[i] = uint64_t(c.x() + kBias) << 42 | uint64_t(c.y() + kBias) << 21 | uint64_t(c.z() + kBias);
    }
    std::vector<size_t> bounds(runs.begin(), runs.end());
    if (bounds.empty() || bounds.front() != 0) bounds.insert(bounds.begin(), 0);
    bounds.push_back(keys.size());
    for (size_t r = 0; r + 1 < bounds.size(); ++r) {
        const auto b = keys.begin() + std::ptrdiff_t(bounds[r]), e = keys.begin() + std::ptrdiff_t(bounds[r + 1]);
        if (!std::is_sorted(b, e)) std::sort(b, e);
        if (r > 0) std::inplace_merge(keys.begin(), b, e);
    }
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    cells.resize(keys.size());
    constexpr uint64_t kMask = uint64_t(kSpan - 1);
    for (size_t i = 0; i < keys.size(); ++i)
        cells[i] = Coord(int(int64_t(keys[i] >> 42) - kBias), int(int64_t(keys[i] >> 21 & kMask) - kBias),
                         int(int64_t(keys[i] & kMask) - kBias));
}

namespace {

/// map.lower_bound(c), given `from`, the lower bound of a key below c (or
/// begin()): a few steps forward from it, else the tree's search.
template <typename Map>
typename Map::iterator lowerBoundFrom(Map& map, typename Map::iterator from, const Coord& c)
{
    for (int k = 0; k < 8 && from != map.end(); ++k, ++from)
        if (!(from->first < c)) return from;
    return map.lower_bound(c);
}

/// The corners of `cell` inside the solid, bit c for corner (c & 1, c >> 1 & 1,
/// c >> 2 & 1), by the kernel's and the isosurface's rule: in the scan box and
/// at least the isovalue. 0: an air cell.
uint8_t insideCorners(const vdb::Volume& volume, float iso, VolumeAccessor& acc, const Coord& cell)
{
    const openvdb::CoordBBox box = volume.indexBox();
    using Leaf = openvdb::FloatTree::LeafNodeType;
    constexpr int kLast = int(Leaf::DIM) - 1;
    if ((cell.x() & kLast) != kLast && (cell.y() & kLast) != kLast && (cell.z() & kLast) != kLast &&
        box.isInside(cell) && box.isInside(cell + Coord(1))) {
        // The eight corners lie in one leaf's block (and in the box): read
        // that leaf once, or, where the block is a tile, its one value.
        if (const Leaf* leaf = acc.probeConstLeaf(cell)) {
            const openvdb::Index at = Leaf::coordToOffset(cell);
            constexpr openvdb::Index dx = Leaf::DIM * Leaf::DIM, dy = Leaf::DIM;
            const openvdb::Index step[8] = {0, dx, dy, dx + dy, 1, dx + 1, dy + 1, dx + dy + 1};
            uint8_t inside = 0;
            for (int c = 0; c < 8; ++c)
                if (leaf->getValue(at + step[c]) >= iso) inside |= uint8_t(1 << c);
            return inside;
        }
        return acc.getValue(cell) >= iso ? uint8_t(0xff) : uint8_t(0);
    }
    uint8_t inside = 0;
    for (int c = 0; c < 8; ++c) {
        const Coord g = cell + Coord(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        if (box.isInside(g) && acc.getValue(g) >= iso) inside |= uint8_t(1 << c);
    }
    return inside;
}

} // namespace

std::pair<uint32_t, uint32_t> CutRemesher::uncutRun(UncutAccessor& acc, const Coord& cell) const
{
    const int32_t first = acc.getValue(cell);
    if (first < 0) return {0u, 0u};
    const glm::ivec3 c(cell.x(), cell.y(), cell.z());
    size_t e = size_t(first) + 1;
    while (e < mUncut.triangleVoxels.size() && mUncut.triangleVoxels[e] == c) ++e;
    return {uint32_t(first), uint32_t(e - size_t(first))};
}

void CutRemesher::uncutCornerEdges(VolumeAccessor& acc, const Coord& cell, std::pair<uint32_t, uint32_t> run,
                                   std::vector<std::pair<uint64_t, uint64_t>>& out) const
{
    out.clear();
    if (run.second == 0) return;
    const uint8_t inside = insideCorners(*mVolume, mIso, acc, cell);
    const int parity = cellParity(cell.x(), cell.y(), cell.z());
    const CellCase& cc = cellCase(parity, inside);
    const auto& edges = cellEdges(parity);
    if (cc.triangleCount != run.second)
        throw std::logic_error("fusion: the uncut mesh does not match the volume at a cut cell");
    for (int k = 0; k < 3 * cc.triangleCount; ++k) {
        const CellEdge e = edges[cc.edges[size_t(k)]];
        const Coord a = cell + Coord(e.lo & 1, (e.lo >> 1) & 1, (e.lo >> 2) & 1);
        const Coord b = cell + Coord(e.hi & 1, (e.hi >> 1) & 1, (e.hi >> 2) & 1);
        uint64_t ia = gridVertexId(a.x(), a.y(), a.z()), ib = gridVertexId(b.x(), b.y(), b.z());
        if (ib < ia) std::swap(ia, ib);
        out.push_back({ia, ib});
    }
}

bool isBladePlaneId(uint64_t planeId)
{
    // planeIdOf: (stroke << 36) | (quad << 4) | kind, strokes from 1;
    // tet-local planes have kBoundaryLabel set. Kind 0 is the quad's plane,
    // 1..4 the sides, kJunctionKind the junction or mitre, kPlusKind and
    // kMinusKind the offset planes, kCapKinds (5, 6) the caps at a mitred
    // joint's sharp corners. With w = 0 sides and junctions bound the
    // quad but carry no surface, so no triangle has all three vertices on one.
    if (planeId < (uint64_t(1) << 36) || (planeId & kBoundaryLabel) != 0) return false;
    return (planeId & 15u) <= uint64_t(kMinusKind);
}

uint64_t capPlaneOf(const CutVertexId& a, const CutVertexId& b, const CutVertexId& c)
{
    auto on = [](const CutVertexId& v, uint64_t p) {
        return std::find(v.planes.begin(), v.planes.begin() + v.planeCount, p) != v.planes.begin() + v.planeCount;
    };
    for (int i = 0; i < a.planeCount; ++i) {
        const uint64_t p = a.planes[size_t(i)];
        if (isBladePlaneId(p) && on(b, p) && on(c, p)) return p;
    }
    return 0;
}

glm::vec3 worldPosition(const vdb::Volume& volume, const glm::dvec3& p)
{
    return glm::vec3(exactWorldPosition(volume.origin(), volume.spacing(), p));
}

size_t CutRemesher::update(const CutMask& mask, Interrupter* interrupter)
{
    // The cells a cut can reach (IndexFrame::cutCellLo/Hi): the box's and the
    // ring outside it where the isosurface closes (the kernel reads the
    // background there, below any bone isovalue, as extraction's "outside").
    const Coord last = mVolume->dims - Coord(1);
    auto inBox = [&](const Coord& c) {
        return c.x() >= -1 && c.y() >= -1 && c.z() >= -1 && c.x() <= last.x() && c.y() <= last.y() && c.z() <= last.z();
    };
    // The quads that changed since the last update (added, undone, replaced,
    // or all of them when the kerf or frame changed), compared with what it saw.
    const IndexFrame& frame = mask.frame();
    const bool sameSetting = mSeenKerf == mask.kerf() && mSeenFrame.origin == frame.origin &&
                             mSeenFrame.spacing == frame.spacing && mSeenFrame.dims == frame.dims;
    if (!sameSetting) mQuadCache.reset(new QuadGeomCache);
    // (The same serial is the same quad and cells: O(1) for the quads that
    // did not change, which are nearly all of a long cut's.)
    auto sameQuad = [&](const SeenQuad& s, const QuadRef& ref) {
        if (s.serial == mask.quadSerial(ref)) return true;
        const Quad& q = mask.quad(ref);
        return s.corners == cornerSignature(q) && s.normal == q.normal && s.cornerCount == q.cornerCount &&
               s.degenerate == q.degenerate && s.cells == mask.cellsOf(ref);
    };
    const uint32_t strokes = std::max<uint32_t>(mask.strokeCount(), uint32_t(mSeen.size()));
    std::vector<std::vector<char>> changedQuad(strokes);
    bool anyQuad = false;
    for (uint32_t s = 1; s <= strokes; ++s) {
        const uint32_t now = mask.quadCount(s);
        const uint32_t seen = s <= mSeen.size() ? uint32_t(mSeen[s - 1].size()) : 0u;
        std::vector<char>& flags = changedQuad[s - 1];
        flags.assign(std::max(now, seen), 1);
        for (uint32_t q = 0; q < std::min(now, seen) && sameSetting; ++q) {
            const QuadRef ref{s, q};
            flags[q] = !sameQuad(mSeen[s - 1][q], ref);
        }
        for (char f : flags) anyQuad = anyQuad || f;
    }
    // The cells to look at: those of the changed quads (before and now) and of
    // their stroke neighbours (their junction sides change), plus the cells
    // just outside the scan box next to any of them (the isosurface closes
    // there: a quad of a border cell that touches such a cell re-meshes it).
    std::vector<Coord> dirty;
    std::vector<size_t> dirtyRuns; // where each quad's list starts in `dirty`
    for (uint32_t s = 1; s <= strokes && anyQuad; ++s) {
        const std::vector<char>& flags = changedQuad[s - 1];
        const uint32_t now = mask.quadCount(s);
        for (uint32_t q = 0; q < flags.size(); ++q) {
            const bool neighbourChanged = (q > 0 && flags[q - 1]) || (q + 1 < flags.size() && flags[q + 1]);
            if (flags[q]) {
                if (s <= mSeen.size() && q < mSeen[s - 1].size()) {
                    const std::vector<Coord>& cells = mSeen[s - 1][q].cells;
                    dirtyRuns.push_back(dirty.size());
                    dirty.insert(dirty.end(), cells.begin(), cells.end());
                }
            }
            if (q < now && (flags[q] || neighbourChanged)) {
                const std::vector<Coord>& cells = mask.cellsOf(QuadRef{s, q});
                dirtyRuns.push_back(dirty.size());
                dirty.insert(dirty.end(), cells.begin(), cells.end());
            }
        }
    }
    sortUniqueCells(dirty, dirtyRuns);
    {
        const size_t inside = dirty.size();
        for (size_t i = 0; i < inside; ++i) {
            const Coord c = dirty[i];
            const bool border = c.x() == 0 || c.y() == 0 || c.z() == 0 || c.x() == last.x() || c.y() == last.y() ||
                                c.z() == last.z();
            if (!border) continue;
            for (int dx = -1; dx <= 1; ++dx)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dz = -1; dz <= 1; ++dz) {
                        const Coord n = c + Coord(dx, dy, dz);
                        bool outside = false, valid = true;
                        for (int a = 0; a < 3; ++a) {
                            outside |= n[a] < 0 || n[a] > last[a];
                            valid &= n[a] >= -1 && n[a] <= last[a] + 1;
                        }
                        if (outside && valid) dirty.push_back(n);
                    }
        }
        if (dirty.size() > inside) sortUniqueCells(dirty);
    }
    // A cell's quad list: the mask's; for a cell just outside the box, the
    // quads of its cut neighbours inside the box that touch it, sorted.
    std::map<std::pair<uint32_t, uint32_t>, CutRegion> regions;
    std::vector<QuadRef> outsideList;
    auto listOf = [&](const Coord& c) -> const std::vector<QuadRef>* {
        if (inBox(c)) return mask.quadsAt(c);
        outsideList.clear();
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const Coord b = c + Coord(dx, dy, dz);
                    if (!inBox(b)) continue;
                    const std::vector<QuadRef>* list = mask.quadsAt(b);
                    if (!list) continue;
                    for (const QuadRef& r : *list) {
                        auto it = regions.find({r.stroke, r.quad});
                        if (it == regions.end())
                            it = regions.emplace(std::make_pair(r.stroke, r.quad), cutRegion(mask.quad(r), mask.kerf(), mask.frame())).first;
                        if (it->second.touchesCell(glm::ivec3(c.x(), c.y(), c.z()))) outsideList.push_back(r);
                    }
                }
        if (outsideList.empty()) return nullptr;
        std::sort(outsideList.begin(), outsideList.end(), [](const QuadRef& a, const QuadRef& b) {
            return a.stroke != b.stroke ? a.stroke < b.stroke : a.quad < b.quad;
        });
        outsideList.erase(std::unique(outsideList.begin(), outsideList.end()), outsideList.end());
        return &outsideList;
    };
    // Every change is saved first, so a throw leaves the remesher as it was.
    struct Saved
    {
        Coord cell;
        bool had = false;
        CutCellGeometry geometry;
        CellRecord record;
    };
    std::vector<Saved> saved;
    saved.reserve(dirty.size());
    std::vector<Coord> changedCells;
    // `changed`: the cell's triangles can differ (every cell but an air cell).
    auto save = [&](const Coord& c, bool changed = true) {
        Saved sv;
        sv.cell = c;
        auto r = mRecords.find(c);
        if (r != mRecords.end()) {
            sv.had = true;
            sv.record = std::move(r->second);
            auto g = mCells.find(c);
            if (g != mCells.end()) sv.geometry = std::move(g->second);
        }
        saved.push_back(std::move(sv));
        if (changed) changedCells.push_back(c);
    };
    // An air cell: all eight corners outside the solid (as the kernel and the
    // isosurface decide it: in the scan box and at least the isovalue is
    // inside). None of its tets holds solid, so it has no uncut triangle and
    // the kernel makes none whatever quads cut it: its geometry is empty
    // once and for all. Most cells of a cut through a head are air (the
    // LeFort stroke on the 1 mm head: 2,995 of 47,880 meet the solid); they
    // are recorded as cut without their quads, meshing, checking or an entry
    // in cells() (a node of that map for each new air cell was a third of a
    // step on the 1 mm head's 11,748-cell cut), and their record says so (the
    // volume and isovalue never change), so a step reads the corners of its
    // new cells only.
    VolumeAccessor volumeAcc(mVolume->grid->tree());
    CellSolidReader solidAt(*mVolume, mIso);
    auto airCell = [&](const Coord& c) { return insideCorners(*mVolume, mIso, volumeAcc, c) == 0; };
    // Cells kept as they are (same kernel input) with their old quad lists
    // (empty when the list stayed) and signatures.
    struct Resigned
    {
        Coord cell;
        std::vector<QuadRef> quads;
        std::vector<std::array<double, 36>> signatures;
    };
    std::vector<Resigned> resigned;
    auto restore = [&] {
        for (Resigned& r : resigned) {
            CellRecord& rec = mRecords[r.cell];
            if (!r.quads.empty()) rec.quads = std::move(r.quads);
            rec.quadCorners = std::move(r.signatures);
        }
        for (auto it = saved.rbegin(); it != saved.rend(); ++it) {
            if (it->had) {
                if (it->record.air) mCells.erase(it->cell); // (an air cell has no geometry)
                else mCells[it->cell] = std::move(it->geometry);
                mRecords[it->cell] = std::move(it->record);
            } else {
                mRecords.erase(it->cell);
                mCells.erase(it->cell);
            }
        }
    };
    // Forget cells that are no longer cut (before any re-meshing, as the
    // cells' geometry does not depend on each other).
    std::vector<const std::vector<QuadRef>*> lists(dirty.size());
    std::vector<std::vector<QuadRef>> outsideLists;
    outsideLists.reserve(dirty.size());
    for (size_t i = 0; i < dirty.size(); ++i) {
        const std::vector<QuadRef>* list = listOf(dirty[i]);
        if (list == &outsideList) {
            outsideLists.push_back(outsideList);
            list = &outsideLists.back();
        }
        lists[i] = list;
        if (list) continue;
        auto it = mRecords.find(dirty[i]);
        if (it == mRecords.end()) continue;
        save(dirty[i], !it->second.air);
        mCells.erase(dirty[i]);
        mRecords.erase(it);
    }
    size_t count = 0, keptCells = 0, sourcedCells = 0;
    std::vector<QuadGeom> quads; // the cell's quads (storage reused)
    struct CellJob
    {
        Coord cell;
        std::vector<QuadGeom> quads;
        CutCellGeometry* out;
        std::exception_ptr error;
    };
    std::vector<CellJob> jobs;
    const bool prism = mask.kerf() > 0;
    try {
        // `dirty` ascends, so the records' lower bound for the next cell lies
        // a few nodes past the last one's (nearly all of a long cut's steps
        // are air cells, each a lookup into the records of every cut cell).
        auto recordHint = mRecords.begin();
        for (size_t i = 0; i < dirty.size(); ++i) {
            if (!lists[i]) continue;
            const Coord& c = dirty[i];
            const std::vector<QuadRef>& list = *lists[i];
            auto it = recordHint = lowerBoundFrom(mRecords, recordHint, c);
            const bool recorded = it != mRecords.end() && it->first == c;
            if (recorded ? it->second.air : airCell(c)) {
                if (!recorded) {
                    Saved fresh; // a new cell: nothing to keep but that it was not cut
                    fresh.cell = c;
                    saved.push_back(std::move(fresh));
                    CellRecord air;
                    air.air = true;
                    recordHint = mRecords.emplace_hint(it, c, std::move(air)); // no geometry: not in cells()
                }
                continue;
            }
            if (!recorded) it = mRecords.end();
            const bool newList = it == mRecords.end() || !(it->second.quads == list);
            std::vector<std::array<double, 36>> signatures;
            signatures.reserve(list.size());
            for (const QuadRef& r : list) signatures.push_back(quadSignature(mask, r));
            if (!newList && it->second.quadCorners == signatures) continue;
            cellQuads(mask, c, list, *mPrismCache, mQuadCache.get(), quads, &solidAt);
            const std::array<uint64_t, 2> input = kernelInputDigest(c, quads, prism);
            if (it != mRecords.end() && it->second.input == input) {
                // A neighbour quad's side changed where this cell does not
                // reach, or a quad came or went that reaches none of its
                // tets (kernelInputDigest): the kernel would make the same
                // geometry. Keep it; remember the new list and signatures.
                if (mVerifyKept) {
                    CutCellGeometry again;
                    mKernels->local().remesh(c, quads, prism, again);
                    const CutCellGeometry& kept = mCells.at(c);
                    if (!(again.vertexIds == kept.vertexIds && again.indexPositions == kept.indexPositions &&
                          again.indices == kept.indices && again.cap == kept.cap))
                        throw std::logic_error("remesh: kept geometry differs from a re-mesh in cell " + cellText(c));
                }
                resigned.push_back({c, newList ? std::move(it->second.quads) : std::vector<QuadRef>(),
                                    std::move(it->second.quadCorners)});
                if (newList) it->second.quads = list;
                it->second.quadCorners = std::move(signatures);
                ++keptCells;
                continue;
            }
            CellRecord rec;
            rec.quads = list;
            rec.quadCorners = std::move(signatures);
            rec.input = input;
            save(c);
            mRecords[c] = std::move(rec);
            jobs.push_back({c, std::move(quads), &mCells[c], nullptr}); // map nodes: the pointer stays valid
            quads.clear(); // moved from: rebuilt for the next cell
        }
        // The kernel over the cells to re-mesh, in parallel (each cell's
        // geometry is a function of the cell, its quads and the volume; one
        // kernel per thread). A refusal is reported for the lowest such cell,
        // as a serial loop would.
        // With an interrupter: polled after every cell (a cell is 10-400 us;
        // a pathological one, many quads pivoting through it, much more),
        // with the share of cells done; once it asks to stop, the remaining
        // cells are skipped and Cancelled is thrown below.
        InterrupterScope scope(interrupter, "re-meshing the cut cells");
        std::atomic<size_t> done{0}, sourced{0};
        std::atomic<bool> cancelled{false};
        tbb::parallel_for(tbb::blocked_range<size_t>(0, jobs.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
            CellKernel& kernel = mKernels->local();
            for (size_t j = range.begin(); j != range.end(); ++j) {
                if (cancelled.load(std::memory_order_relaxed)) return;
                try {
                    if (mCellSource && mCellSource(jobs[j].cell, *jobs[j].out)) {
                        const CutCellGeometry& g = *jobs[j].out;
                        if (g.cap.size() != g.indices.size() / 3)
                            throw std::invalid_argument("CutRemesher::update: the cell source gave cell " +
                                                        remesh_detail::cellText(jobs[j].cell) +
                                                        " without one cap flag per triangle");
                        sourced.fetch_add(1, std::memory_order_relaxed);
                    } else
                        kernel.remesh(jobs[j].cell, jobs[j].quads, prism, *jobs[j].out);
                } catch (...) {
                    jobs[j].error = std::current_exception();
                }
                const size_t n = done.fetch_add(1, std::memory_order_relaxed) + 1;
                if (interrupter && interrupter->wasInterrupted(int(100 * n / jobs.size())))
                    cancelled.store(true, std::memory_order_relaxed);
            }
        });
        if (cancelled) throw Cancelled();
        sourcedCells = sourced.load();
        for (CellJob& job : jobs) {
            if (job.error) std::rethrow_exception(job.error);
            if (!mCellHook) continue;
            mCellHook(job.cell, *job.out);
            job.out->crossFree = false; // (what the hook did, the float repair did not judge)
        }
        count = jobs.size();
        std::sort(changedCells.begin(), changedCells.end());
        checkLocally(changedCells, prism);
    } catch (...) {
        restore();
        throw;
    }
    // Success: remember the quads as they are now.
    mSeenKerf = mask.kerf();
    mSeenFrame = frame;
    mSeen.resize(mask.strokeCount());
    for (uint32_t s = 1; s <= mask.strokeCount(); ++s) {
        std::vector<SeenQuad>& seen = mSeen[s - 1];
        const uint32_t now = mask.quadCount(s);
        seen.resize(now);
        for (uint32_t q = 0; q < now; ++q) {
            if (!changedQuad[s - 1][q]) continue;
            const QuadRef ref{s, q};
            const Quad& quad = mask.quad(ref);
            SeenQuad& sq = seen[q];
            sq.corners = cornerSignature(quad);
            sq.normal = quad.normal;
            sq.cornerCount = quad.cornerCount;
            sq.degenerate = quad.degenerate;
            sq.cells = mask.cellsOf(ref);
            sq.serial = mask.quadSerial(ref);
        }
    }
    mLastChanged = std::move(changedCells);
    mLastKept = keptCells;
    mLastSourced = sourcedCells;
    return count;
}

std::string refusalOf(CutRemesher& remesher, const CutMask& mask)
{
    try {
        remesher.update(mask);
    } catch (const InputError&) {
        throw;
    } catch (const Cancelled&) {
        throw;
    } catch (const std::runtime_error& e) { // (std::logic_error is not one: it goes on)
        return e.what();
    }
    return {};
}

} // namespace mtcut::cutter
