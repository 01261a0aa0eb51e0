#include "cutter/Remesh.h"

#include "cutter/Isosurface.h"
#include "cutter/RemeshKernel.h"
#include "cutter/TriangleIntersect.h"
#include "vdb/Error.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <set>
#include <sstream>
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
/// reach is covered while delta stays within half of that. So a sharp corner
/// (a blade pivoting about its tip) still takes a mitre when the quads are
/// nearly coplanar: without it the two prisms' end planes leave a notch w/2
/// deep and (w/2) bend wide at the stick, sub-micron for such quads, whose
/// walls cross once written in float (seed 1023 on the 2 mm head).
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
            if (!(len > 1e-12)) continue;
            Plane mp;
            mp.n = mdir / len;
            mp.d = glm::dot(mp.n, p0);
            const double own = mp.h(centre), other = mp.h(centroidOf(o, frame));
            if (!(own * other < 0.0)) continue; // folded back onto itself: keep as rim
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
///   by less than kKerfMitreMaxBend, with no corner of either quad at it too
///   sharp for that bend (tooSharpForMitre): the mitre, one plane object for both
///   quads (the lower quad's data first) through the stick and
///   u = (w/2)(n_q + n_o)/(1 + n_q.n_o), the world bisector, on which the two
///   quads' offset planes meet exactly (also with anisotropic spacing).
/// - Any other edge (rims, unjoined stick ends): the plane through it
///   perpendicular to the quad; but a rim that continues the previous quad's
///   rim through a corner of their shared stick, mitred or not (both its
///   corners within 1e-4 voxel of that plane, normals within 1.4e-4 rad),
///   uses that very plane object, so the two prisms meet the mitre in the
///   same rim line and leave no sub-micron sliver there, and coplanar faces
///   across an unmitred turn are one surface in remeshTet.
/// The mask voxelises cutRegion(), which covers the mitre joints.
QuadGeom makePrismGeom(const CutMask& mask, const QuadRef& ref, PrismCache& cache);
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
    // Pass 1: mitre joints per hull edge.
    std::vector<QuadGeom::Side> joint(m);
    std::vector<char> isJoint(m, 0);
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
            // Both quads' corners at the joint (the decision is the same from
            // either side): a sharp one would put the mitre outside the mask.
            const double tanHalfBend = std::sqrt(std::max(0.0, 1.0 - c) / (1.0 + c));
            if (tooSharpForMitre(q, hull, wa, tanHalfBend) || tooSharpForMitre(q, hull, wb, tanHalfBend) ||
                tooSharpForMitre(o, oHull, wa, tanHalfBend) || tooSharpForMitre(o, oHull, wb, tanHalfBend))
                break;
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
            break;
        }
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
        const dvec3 sdir = glm::cross(g.pi.n, b - a);
        const double len = glm::length(sdir);
        if (!(len > 0.0)) continue;
        QuadGeom::Side side;
        side.id = planeIdOf(ref.stroke, ref.quad, 1 + int(e));
        side.plane.n = sdir / len;
        side.plane.d = glm::dot(side.plane.n, a);
        if (previous && joinedPrevious) {
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

/// quadCache: optional; when given, each quad's geometry is built once
/// (zero kerf: in quadCache; kerf > 0: in `cache`) instead of once per cell.
/// Into `quads` (its elements' storage is reused: no allocation per cell
/// once it has grown).
void cellQuads(const CutMask& mask, const std::vector<QuadRef>& refs, PrismCache& cache, QuadGeomCache* quadCache,
               std::vector<QuadGeom>& quads)
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
/// cell (in the kernel's order) its plane and id, and each side in full
/// unless the cell's closed box lies strictly on one side of it (every
/// corner more than kFar voxel inside, or outside). Such a side decides
/// nothing in the cell: no point there lies on it (the kernel's tie is
/// 1e-13 (1 + |x|)), every side test gives the same answer for all points,
/// so its id, partner and corner sides are never read; only inside/outside
/// remains (a quad outside one of its sides reaches none of the cell's
/// tets). When a stroke neighbour of a quad comes or goes, the quad's far
/// side changes (rim <-> junction); the cells that side does not reach keep
/// this digest, and update() keeps their geometry instead of re-meshing it.
std::array<uint64_t, 2> kernelInputDigest(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism)
{
    constexpr double kFar = 1e-6;
    std::array<uint64_t, 2> h{0x9e3779b97f4a7c15ull, 0xc2b2ae3d27d4eb4full};
    auto mix = [](uint64_t x) {
        x ^= x >> 30;
        x *= 0xbf58476d1ce4e5b9ull;
        x ^= x >> 27;
        x *= 0x94d049bb133111ebull;
        return x ^ (x >> 31);
    };
    auto put = [&](uint64_t w) {
        h[0] = mix(h[0] ^ w) + 0x632be59bd9b4e019ull;
        h[1] = mix((h[1] + w) * 0xff51afd7ed558ccdull) ^ (h[1] >> 17);
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
    put(prism ? 2 : 1);
    put(quads.size());
    for (const QuadGeom& q : quads) {
        put(q.id);
        putPlane(q.pi);
        put(q.sides.size());
        for (const auto& s : q.sides) {
            double lo = std::numeric_limits<double>::infinity(), hi = -lo;
            for (int k = 0; k < 8; ++k) {
                const dvec3 x(cell.x() + (k & 1), cell.y() + ((k >> 1) & 1), cell.z() + ((k >> 2) & 1));
                const double v = s.orient * s.plane.h(x);
                lo = std::min(lo, v);
                hi = std::max(hi, v);
            }
            if (lo > kFar) {
                put(1); // strictly inside over the whole cell
                continue;
            }
            if (hi < -kFar) {
                put(2); // strictly outside
                continue;
            }
            put(3);
            put(s.id);
            putPlane(s.plane);
            putD(s.orient);
            put(uint64_t(int64_t(s.partner)));
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
        cellQuads(mask, list, cache, nullptr, quads);
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

void remeshCell(const vdb::Volume& volume, float isovalue, const CutMask& mask, const openvdb::Coord& cell,
                CutCellGeometry& out)
{
    out.clear();
    const std::vector<QuadRef>* refs = mask.quadsAt(cell);
    if (!refs) return;
    CellKernel kernel(volume, isovalue);
    PrismCache cache;
    std::vector<QuadGeom> quads;
    cellQuads(mask, *refs, cache, nullptr, quads);
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

std::pair<uint32_t, uint32_t> CutRemesher::uncutRun(UncutAccessor& acc, const Coord& cell) const
{
    const int32_t first = acc.getValue(cell);
    if (first < 0) return {0u, 0u};
    const glm::ivec3 c(cell.x(), cell.y(), cell.z());
    size_t e = size_t(first) + 1;
    while (e < mUncut.triangleVoxels.size() && mUncut.triangleVoxels[e] == c) ++e;
    return {uint32_t(first), uint32_t(e - size_t(first))};
}

void CutRemesher::uncutCornerEdges(const Coord& cell, std::pair<uint32_t, uint32_t> run,
                                   std::vector<std::pair<uint64_t, uint64_t>>& out) const
{
    out.clear();
    if (run.second == 0) return;
    openvdb::tree::ValueAccessor<const openvdb::FloatTree, false> acc(mVolume->grid->tree());
    uint8_t inside = 0;
    for (int c = 0; c < 8; ++c) {
        const Coord g = cell + Coord(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        const bool inBox = mVolume->indexBox().isInside(g);
        if (inBox && acc.getValue(g) >= mIso) inside |= uint8_t(1 << c);
    }
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

namespace {

/// The cells whose closed box holds vertex v: [lo, hi] per axis.
void cellsHolding(const CutVertexId& v, Coord& lo, Coord& hi)
{
    if (v.dim == 3) {
        lo = hi = gridVertexCoord(v.feature[0]);
        return;
    }
    lo = Coord(std::numeric_limits<int>::min());
    hi = Coord(std::numeric_limits<int>::max());
    for (int i = 0; i <= int(v.dim); ++i) {
        const Coord g = gridVertexCoord(v.feature[size_t(i)]);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::max(lo[a], g[a] - 1);
            hi[a] = std::min(hi[a], g[a]);
        }
    }
}

CutVertexId isoEdgeVertex(const std::pair<uint64_t, uint64_t>& e)
{
    CutVertexId id;
    id.dim = 1;
    id.planeCount = 1;
    id.planes[0] = 1;
    id.feature = {e.first, e.second, 0};
    return id;
}

} // namespace

bool isBladePlaneId(uint64_t planeId)
{
    // planeIdOf: (stroke << 36) | (quad << 4) | kind, strokes from 1;
    // tet-local planes have kBoundaryLabel set. Kind 0 is the quad's plane,
    // 1..4 the sides, kJunctionKind the junction or mitre, kPlusKind and
    // kMinusKind the offset planes. With w = 0 sides and junctions bound the
    // quad but carry no surface, so no triangle has all three vertices on one.
    if (planeId < (uint64_t(1) << 36) || (planeId & kBoundaryLabel) != 0) return false;
    const uint64_t kind = planeId & 15u;
    return kind <= 4 || kind == uint64_t(kJunctionKind) || kind == uint64_t(kPlusKind) || kind == uint64_t(kMinusKind);
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

// Marks a bitmap over the box when it is compact (a haptic step's cells),
// else sorts packed integer keys (the 27 copies sorted as Coord were a
// quarter of a step).
std::vector<Coord> dilatedCells(const std::vector<Coord>& cells)
{
    std::vector<Coord> out;
    if (cells.empty()) return out;
    Coord lo = cells.front(), hi = cells.front();
    for (const Coord& c : cells) {
        lo.minComponent(c);
        hi.maxComponent(c);
    }
    lo -= Coord(1);
    hi += Coord(1);
    const uint64_t nx = uint64_t(hi.x() - lo.x() + 1), ny = uint64_t(hi.y() - lo.y() + 1), nz = uint64_t(hi.z() - lo.z() + 1);
    const uint64_t boxCells = nx * ny * nz;
    if (boxCells <= 256 * uint64_t(cells.size())) {
        std::vector<char> in(boxCells, 0);
        for (const Coord& c : cells) {
            const Coord b = c - lo;
            for (int dx = -1; dx <= 1; ++dx)
                for (int dy = -1; dy <= 1; ++dy) {
                    char* row = &in[(uint64_t(b.x() + dx) * ny + uint64_t(b.y() + dy)) * nz + uint64_t(b.z() - 1)];
                    row[0] = row[1] = row[2] = 1;
                }
        }
        for (uint64_t x = 0; x < nx; ++x)
            for (uint64_t y = 0; y < ny; ++y) {
                const char* row = &in[(x * ny + y) * nz];
                for (uint64_t z = 0; z < nz; ++z)
                    if (row[z]) out.push_back(lo + Coord(int(x), int(y), int(z)));
            }
        return out;
    }
    // Sorted as packed integers (offsets in the box, x major as Coord's order).
    std::vector<uint64_t> keys;
    keys.reserve(27 * cells.size());
    for (const Coord& c : cells) {
        const Coord b = c - lo;
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz)
                    keys.push_back((uint64_t(b.x() + dx) * ny + uint64_t(b.y() + dy)) * nz + uint64_t(b.z() + dz));
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    out.reserve(keys.size());
    for (uint64_t k : keys) out.push_back(lo + Coord(int(k / (ny * nz)), int(k / nz % ny), int(k % nz)));
    return out;
}

namespace {

/// A triangle of the local check's region, over the region's vertex names.
struct RegionTriangle
{
    uint32_t v[3];
    Coord cell;
    bool cut; ///< a cut cell's (new geometry), else an uncut cell's
};

/// `contact` (of trianglesIntersect) unless the two share no vertex and
/// meet only at one corner of each that rounded to the same float position
/// (an iso point and a kerf plane's point on one grid edge 1e-6 mm apart at
/// z = 1227 mm: 1 mm head, kerf 0.5, random strokes seed 2011): a surface
/// touching itself at one point, as at a pinch (Remesh.h), not crossing.
Contact unlessPointContact(const std::array<glm::vec3, 3>& pa, const std::array<uint32_t, 3>& ia,
                           const std::array<glm::vec3, 3>& pb, std::array<uint32_t, 3> ib, Contact contact)
{
    int same = 0, ka = -1, kb = -1;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            if (ia[size_t(i)] == ib[size_t(j)]) return contact; // a vertex in common: judged as it is
            if (pa[size_t(i)] == pb[size_t(j)]) {
                ++same;
                ka = i;
                kb = j;
            }
        }
    if (same != 1) return contact;
    ib[size_t(kb)] = ia[size_t(ka)]; // as if one vertex: do they meet anywhere else?
    return trianglesIntersect(pa, ia, pb, ib) == Contact::None ? Contact::None : contact;
}

/// The local check's last step when the cut has a width (DESIGN invariant
/// 7): no triangle of a changed cell may cross or touch another triangle,
/// in float world mm as written, decided exactly (TriangleIntersect.h) with
/// CGAL's adjacency rules over the names (after snap rounding), except that
/// the copies of a pinch vertex (Remesh.h, kerf > 0: the same name plus a
/// pinch tag) count as one vertex, so the fans of a pinch may touch there,
/// as the exact shape does, and two triangles may touch at one corner of
/// each at one float position (unlessPointContact; the tests' CGAL check
/// counts both as pinch contacts, not intersections). Pairs of uncut
/// triangles are the isosurface's and are not asked. A triangle lies in its
/// cell's closed box (up to rounding), so only the 27 cells around a
/// changed cell's triangle are searched, and of those only triangles whose
/// float boxes overlap its.
/// `tris` are in `region` order. Throws std::runtime_error("remesh: the
/// surface crosses or touches itself ...") naming the changed cell.
void refuseSelfContact(const vdb::Volume& volume, const std::vector<Coord>& region, const std::vector<Coord>& changed,
                       const std::vector<RegionTriangle>& tris, const std::vector<CutVertexId>& ids,
                       const std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash>& names,
                       const std::vector<glm::vec3>& world, const std::vector<char>& known,
                       const std::function<void(uint32_t)>& describe)
{
    // Pinch copies -> the plain vertex of their name (or the first copy).
    std::vector<uint32_t> vertex(ids.size());
    std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash> copies;
    for (uint32_t v = 0; v < uint32_t(ids.size()); ++v) {
        vertex[v] = v;
        const CutVertexId& id = ids[v];
        auto pinch = [](uint64_t t) { return (t & kPinchTag) != 0; };
        if (std::none_of(id.tags.begin(), id.tags.begin() + id.tagCount, pinch)) continue;
        CutVertexId plain = id;
        plain.tagCount = 0;
        plain.tags = {};
        for (int k = 0; k < id.tagCount; ++k)
            if (!pinch(id.tags[size_t(k)])) plain.tags[plain.tagCount++] = id.tags[size_t(k)];
        auto it = names.find(plain);
        vertex[v] = it != names.end() ? it->second : copies.emplace(plain, v).first->second;
    }
    // Triangles per region cell (tris are in region order), and float boxes.
    std::vector<size_t> start(region.size() + 1, 0);
    for (size_t t = 0, r = 0; r < region.size(); ++r) {
        while (t < tris.size() && tris[t].cell == region[r]) ++t;
        start[r + 1] = t;
    }
    if (start.back() != tris.size()) throw std::logic_error("remesh: local check triangles out of region order");
    struct Box
    {
        glm::vec3 lo, hi;
        bool usable; ///< positions known
    };
    std::vector<Box> box(tris.size());
    for (size_t t = 0; t < tris.size(); ++t) {
        const RegionTriangle& tr = tris[t];
        Box& b = box[t];
        b.usable = known[tr.v[0]] && known[tr.v[1]] && known[tr.v[2]];
        if (!b.usable) continue;
        b.lo = glm::min(world[tr.v[0]], glm::min(world[tr.v[1]], world[tr.v[2]]));
        b.hi = glm::max(world[tr.v[0]], glm::max(world[tr.v[1]], world[tr.v[2]]));
    }
    auto isChanged = [&](const Coord& c) { return std::binary_search(changed.begin(), changed.end(), c); };
    // A triangle lies in its cell's closed box, rounded to float as the
    // vertices are (rounding is monotone), so a neighbour's triangles can
    // meet it only where its box reaches the common face, edge or corner:
    // within kSlack float steps of it, for the double rounding of points
    // computed on a cell face.
    constexpr int kSlack = 4;
    auto inward = [](glm::vec3 x, float to) { // kSlack float steps towards `to`, per axis
        for (int k = 0; k < 3; ++k)
            for (int i = 0; i < kSlack; ++i) x[k] = std::nextafter(x[k], to);
        return x;
    };
    struct Neighbour
    {
        size_t region;
        Coord offset;
        bool changed;
    };
    std::vector<Neighbour> around;
    for (size_t r = 0; r < region.size(); ++r) {
        const Coord& c = region[r];
        if (!isChanged(c) || start[r] == start[r + 1]) continue;
        around.clear();
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    const Coord n = c + Coord(dx, dy, dz);
                    auto it = std::lower_bound(region.begin(), region.end(), n);
                    if (it != region.end() && *it == n)
                        around.push_back({size_t(it - region.begin()), Coord(dx, dy, dz), isChanged(n)});
                }
        // The cell's faces, a few float steps inside.
        const glm::vec3 lo = worldPosition(volume, glm::dvec3(c.x(), c.y(), c.z()));
        const glm::vec3 hi = worldPosition(volume, glm::dvec3(c.x() + 1, c.y() + 1, c.z() + 1));
        const glm::vec3 nearLo = inward(lo, std::numeric_limits<float>::infinity());
        const glm::vec3 nearHi = inward(hi, -std::numeric_limits<float>::infinity());
        for (size_t t = start[r]; t < start[r + 1]; ++t) {
            const Box& bt = box[t];
            if (!bt.usable) continue;
            const RegionTriangle& a = tris[t];
            bool reach[3][2]; // axis, (low, high) face
            for (int k = 0; k < 3; ++k) {
                reach[k][0] = bt.lo[k] <= nearLo[k];
                reach[k][1] = bt.hi[k] >= nearHi[k];
            }
            std::array<glm::vec3, 3> pa{world[a.v[0]], world[a.v[1]], world[a.v[2]]};
            std::array<uint32_t, 3> ia{vertex[a.v[0]], vertex[a.v[1]], vertex[a.v[2]]};
            for (const Neighbour& n : around) {
                bool needed = true;
                for (int k = 0; k < 3 && needed; ++k)
                    needed = n.offset[k] == 0 || reach[k][n.offset[k] > 0 ? 1 : 0];
                if (!needed) continue;
                for (size_t u = start[n.region]; u < start[n.region + 1]; ++u) {
                    if (n.changed && u <= t) continue; // a pair of changed cells' triangles once
                    const Box& bu = box[u];
                    if (!bu.usable || (!a.cut && !tris[u].cut)) continue;
                    if (bt.hi.x < bu.lo.x || bu.hi.x < bt.lo.x || bt.hi.y < bu.lo.y || bu.hi.y < bt.lo.y ||
                        bt.hi.z < bu.lo.z || bu.hi.z < bt.lo.z)
                        continue;
                    const RegionTriangle& b = tris[u];
                    const std::array<glm::vec3, 3> pb{world[b.v[0]], world[b.v[1]], world[b.v[2]]};
                    const std::array<uint32_t, 3> ib{vertex[b.v[0]], vertex[b.v[1]], vertex[b.v[2]]};
                    Contact contact = trianglesIntersect(pa, ia, pb, ib);
                    if (contact != Contact::None) contact = unlessPointContact(pa, ia, pb, ib, contact);
                    if (contact == Contact::None) continue;
                    if (describe) {
                        std::fprintf(stderr, "self-contact (%s), cells (%d,%d,%d) and (%d,%d,%d):\n",
                                     contact == Contact::Intersect ? "exact" : "undecided", a.cell.x(), a.cell.y(),
                                     a.cell.z(), b.cell.x(), b.cell.y(), b.cell.z());
                        for (uint32_t v : a.v) describe(v);
                        for (uint32_t v : b.v) describe(v);
                    }
                    throw std::runtime_error(
                        std::string("remesh: the surface crosses or touches itself (two triangles meet in float mm") +
                        (contact == Contact::Undecided ? ", or the exact test cannot decide" : "") +
                        "; the cut has a width) in cell " + cellText(c));
                }
            }
        }
    }
}

} // namespace

void CutRemesher::checkLocally(const std::vector<Coord>& changed, bool kerf) const
{
    if (changed.empty()) return;
    // The triangles of the changed cells and of their 26 neighbours, over
    // vertex names (the fused mesh's identity: iso edge vertices by edge).
    const std::vector<Coord> region = dilatedCells(changed);
    // Plain marching-tetrahedra vertices (most of them) by their grid edge,
    // the others by their whole name; one numbering, in order of first use.
    struct EdgeHash
    {
        size_t operator()(const std::pair<uint64_t, uint64_t>& e) const
        {
            uint64_t x = e.first * 0x9e3779b97f4a7c15ull ^ (e.second + 0x632be59bd9b4e019ull);
            x ^= x >> 31;
            x *= 0xbf58476d1ce4e5b9ull;
            return size_t(x ^ (x >> 29));
        }
    };
    std::unordered_map<std::pair<uint64_t, uint64_t>, uint32_t, EdgeHash> edgeNames;
    std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash> names;
    std::vector<CutVertexId> ids;
    auto edgeNameOf = [&](const std::pair<uint64_t, uint64_t>& e) {
        auto [it, added] = edgeNames.emplace(e, uint32_t(ids.size()));
        if (added) ids.push_back(isoEdgeVertex(e));
        return it->second;
    };
    auto nameOf = [&](const CutVertexId& id) {
        if (id.isIsoEdgeVertex()) return edgeNameOf({id.feature[0], id.feature[1]});
        auto [it, added] = names.emplace(id, uint32_t(ids.size()));
        if (added) ids.push_back(id);
        return it->second;
    };
    using Tri = RegionTriangle;
    std::vector<Tri> tris;
    // Per region cell: its cut geometry (or null), its uncut triangles' run
    // and their corners' grid edges (cornerStart[i] .. cornerStart[i + 1]).
    std::vector<const CutCellGeometry*> cutOf(region.size(), nullptr);
    std::vector<std::pair<uint32_t, uint32_t>> runOf(region.size());
    std::vector<size_t> cornerStart(region.size() + 1, 0);
    std::vector<std::pair<uint64_t, uint64_t>> corners, cellCorners;
    {
        UncutAccessor uncutAcc(mUncutFirst);
        for (size_t i = 0; i < region.size(); ++i) {
            const Coord& c = region[i];
            auto cut = mCells.find(c);
            if (cut != mCells.end()) cutOf[i] = &cut->second;
            runOf[i] = uncutRun(uncutAcc, c);
            uncutCornerEdges(c, runOf[i], cellCorners);
            corners.insert(corners.end(), cellCorners.begin(), cellCorners.end());
            cornerStart[i + 1] = corners.size();
        }
    }
    // The names of each cut cell's vertices: localNames[localStart[i] ..].
    std::vector<uint32_t> localNames;
    std::vector<size_t> localStart(region.size() + 1, 0);
    for (size_t i = 0; i < region.size(); ++i) {
        const Coord& c = region[i];
        if (cutOf[i]) {
            const CutCellGeometry& g = *cutOf[i];
            const size_t base = localNames.size();
            for (const CutVertexId& id : g.vertexIds) localNames.push_back(nameOf(id));
            const uint32_t* local = localNames.data() + base;
            for (size_t k = 0; k + 2 < g.indices.size(); k += 3)
                tris.push_back({{local[g.indices[k]], local[g.indices[k + 1]], local[g.indices[k + 2]]}, c, true});
        } else {
            for (size_t k = cornerStart[i]; k + 2 < cornerStart[i + 1]; k += 3)
                tris.push_back({{edgeNameOf(corners[k]), edgeNameOf(corners[k + 1]), edgeNameOf(corners[k + 2])}, c, false});
        }
        localStart[i + 1] = localNames.size();
    }
    auto isChanged = [&](const Coord& c) { return std::binary_search(changed.begin(), changed.end(), c); };
    auto fail = [&](const std::string& what, const Coord& c) {
        throw std::runtime_error("remesh: open or inconsistent surface (" + what + ") in cell " + cellText(c));
    };
    for (const Tri& tr : tris)
        if (isChanged(tr.cell) && (tr.v[0] == tr.v[1] || tr.v[1] == tr.v[2] || tr.v[0] == tr.v[2]))
            fail("a triangle repeats a vertex", tr.cell);
    // Float world positions as fusedMesh() gives them (iso edge vertices: the
    // uncut mesh's; a new vertex: from the first cell, ascending, that makes
    // it), and its snap rounding: names joined by an edge at one float
    // position are one vertex, and the triangles that collapse are dropped.
    // Held as float, as written: GCC 12.2's SLP vectoriser folded the
    // round trip double(float(x)) of two lanes away when these were
    // dvec3(vec3(float(..), ..)), so the check judged unrounded positions
    // and let two float-degenerate triangles through (seed 1021).
    std::vector<glm::vec3> world(ids.size(), glm::vec3(std::numeric_limits<float>::quiet_NaN()));
    std::vector<char> known(ids.size(), 0);
    for (size_t i = 0; i < region.size(); ++i) {
        for (size_t k = cornerStart[i]; k < cornerStart[i + 1]; ++k) {
            const uint32_t vertex = mUncut.indices[3 * size_t(runOf[i].first) + (k - cornerStart[i])];
            auto it = edgeNames.find(corners[k]);
            if (it != edgeNames.end() && !known[it->second]) {
                world[it->second] = mUncut.positions[vertex];
                known[it->second] = 1;
            }
        }
        if (!cutOf[i]) continue;
        const CutCellGeometry& g = *cutOf[i];
        for (size_t v = 0; v < g.vertexIds.size(); ++v) {
            const uint32_t name = localNames[localStart[i] + v];
            if (known[name] || g.vertexIds[v].isIsoEdgeVertex()) continue;
            world[name] = worldPosition(*mVolume, g.indexPositions[v]);
            known[name] = 1;
        }
    }
    {
        std::vector<uint32_t> rep(ids.size());
        for (size_t v = 0; v < rep.size(); ++v) rep[v] = uint32_t(v);
        auto find = [&](uint32_t x) {
            uint32_t r = x;
            while (rep[r] != r) r = rep[r];
            while (rep[x] != r) x = std::exchange(rep[x], r);
            return r;
        };
        for (const Tri& tr : tris)
            for (int k = 0; k < 3; ++k) {
                const uint32_t a = tr.v[k], b = tr.v[(k + 1) % 3];
                if (a == b || !known[a] || !known[b] || !(world[a] == world[b])) continue;
                const uint32_t ra = find(a), rb = find(b);
                if (ra != rb) rep[std::max(ra, rb)] = std::min(ra, rb);
            }
        std::vector<Tri> kept;
        for (Tri tr : tris) {
            for (uint32_t& v : tr.v) v = find(v);
            if (tr.v[0] == tr.v[1] || tr.v[1] == tr.v[2] || tr.v[0] == tr.v[2]) continue;
            kept.push_back(tr);
        }
        tris.swap(kept);
    }
    // MTCUT_REMESH_DEBUG (Remesh.h): a vertex's name and float position on
    // stderr, planes as s<stroke>:q<quad>:k<kind>, tags as q<quad>+/-.
    const bool debug = std::getenv("MTCUT_REMESH_DEBUG") != nullptr;
    auto desc = [&](uint32_t v) {
        using ull = unsigned long long;
        const CutVertexId& id = ids[v];
        std::fprintf(stderr, "  v%u dim %d at", v, id.dim);
        for (int i = 0; i <= std::min<int>(id.dim, 2); ++i) {
            if (id.dim == 3 && i == 1) {
                std::fprintf(stderr, " tet %llu", ull(id.feature[1]));
                break;
            }
            const Coord g = gridVertexCoord(id.feature[size_t(i)]);
            std::fprintf(stderr, " (%d,%d,%d)", g.x(), g.y(), g.z());
        }
        std::fprintf(stderr, " planes");
        for (int i = 0; i < id.planeCount; ++i) {
            const uint64_t p = id.planes[size_t(i)];
            if (p < 16) std::fprintf(stderr, " %llu", ull(p));
            else std::fprintf(stderr, " s%llu:q%llu:k%llu", ull(p >> 36), ull((p >> 4) & 0xffffffff), ull(p & 15));
        }
        std::fprintf(stderr, " tags");
        for (int i = 0; i < id.tagCount; ++i) {
            const uint64_t t = id.tags[size_t(i)];
            std::fprintf(stderr, " q%llu%c", ull((t >> 5) & 0xffffffff), t & 1 ? '-' : '+');
        }
        std::fprintf(stderr, " world %.6f %.6f %.6f\n", world[v].x, world[v].y, world[v].z);
    };
    // Directed edge uses; an edge matters when a changed cell's closed box holds it
    // (then every triangle that can use it is in the region).
    auto matters = [&](uint32_t a, uint32_t b, const Coord& cell) {
        if (isChanged(cell)) return true;
        Coord la, ha, lb, hb;
        cellsHolding(ids[a], la, ha);
        cellsHolding(ids[b], lb, hb);
        Coord lo, hi;
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::max(la[k], lb[k]);
            hi[k] = std::min(ha[k], hb[k]);
            if (lo[k] > hi[k]) return false;
        }
        for (int x = lo.x(); x <= hi.x(); ++x)
            for (int y = lo.y(); y <= hi.y(); ++y)
                for (int z = lo.z(); z <= hi.z(); ++z)
                    if (isChanged(Coord(x, y, z))) return true;
        return false;
    };
    // Per use that matters: (undirected edge, direction, triangle, index in
    // triangle order), sorted, so an edge's uses are one run, each
    // direction's in triangle order. An edge is fine when it is used once
    // each way; the one reported is the failing edge used first in triangle
    // order, as a walk over the uses in that order would find it.
    struct Use
    {
        uint64_t edge;  ///< min vertex << 32 | max vertex
        uint32_t dir;   ///< 0: from the lower vertex to the higher, 1: back
        uint32_t tri;
        uint32_t order; ///< index of the use in triangle order
        bool operator<(const Use& o) const
        {
            return edge != o.edge ? edge < o.edge : dir != o.dir ? dir < o.dir : tri < o.tri;
        }
    };
    std::vector<Use> uses;
    for (size_t t = 0; t < tris.size(); ++t) {
        const Tri& tr = tris[t];
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = tr.v[k], b = tr.v[(k + 1) % 3];
            if (!matters(a, b, tr.cell)) continue;
            const uint64_t edge = uint64_t(std::min(a, b)) << 32 | std::max(a, b);
            uses.push_back({edge, a < b ? 0u : 1u, uint32_t(t), uint32_t(uses.size())});
        }
    }
    std::sort(uses.begin(), uses.end());
    struct Uses
    {
        uint32_t count = 0, triangle = 0; ///< uses, and the first one's triangle
    };
    size_t failOrder = SIZE_MAX, failAt = 0; // the failing edge's first use: its order, and its run
    for (size_t begin = 0, end = 0; begin < uses.size(); begin = end) {
        uint32_t count[2] = {0, 0}, first = UINT32_MAX;
        for (end = begin; end < uses.size() && uses[end].edge == uses[begin].edge; ++end) {
            ++count[uses[end].dir];
            first = std::min(first, uses[end].order);
        }
        if (count[0] == 1 && count[1] == 1) continue;
        if (first < failOrder) {
            failOrder = first;
            failAt = begin;
        }
    }
    if (failOrder != SIZE_MAX) {
        // The first use's direction is "one way"; each direction's count and first triangle.
        Uses way[2];
        uint32_t firstDir = 0;
        for (size_t i = failAt; i < uses.size() && uses[i].edge == uses[failAt].edge; ++i) {
            Uses& w = way[uses[i].dir];
            if (w.count++ == 0) w.triangle = uses[i].tri;
            if (uses[i].order == failOrder) firstDir = uses[i].dir;
        }
        const Uses u = way[firstDir], r = way[1 - firstDir];
        const uint32_t lo = uint32_t(uses[failAt].edge >> 32), hi = uint32_t(uses[failAt].edge);
        const uint64_t key = firstDir == 0 ? uint64_t(lo) << 32 | hi : uint64_t(hi) << 32 | lo;
        const uint32_t back = r.count;
        // Name a changed cell: the triangle's own, else a changed cell holding the edge.
        Coord cell = tris[u.triangle].cell;
        if (!isChanged(cell) && r.count && isChanged(tris[r.triangle].cell)) cell = tris[r.triangle].cell;
        if (!isChanged(cell)) {
            Coord la, ha, lb, hb;
            cellsHolding(ids[uint32_t(key >> 32)], la, ha);
            cellsHolding(ids[uint32_t(key)], lb, hb);
            for (const Coord& c : changed) {
                bool in = true;
                for (int k = 0; k < 3; ++k) in = in && std::max(la[k], lb[k]) <= c[k] && c[k] <= std::min(ha[k], hb[k]);
                if (in) {
                    cell = c;
                    break;
                }
            }
        }
        if (debug) {
            std::fprintf(stderr, "open edge, triangle cell (%d,%d,%d):\n", tris[u.triangle].cell.x(), tris[u.triangle].cell.y(), tris[u.triangle].cell.z());
            desc(uint32_t(key >> 32));
            desc(uint32_t(key));
            std::set<uint32_t> around; // the vertices of the triangles at either end
            for (const Tri& tr : tris) {
                if (std::none_of(tr.v, tr.v + 3, [&](uint32_t v) { return v == uint32_t(key >> 32) || v == uint32_t(key); }))
                    continue;
                std::fprintf(stderr, "   tri cell (%d,%d,%d): %u %u %u\n", tr.cell.x(), tr.cell.y(), tr.cell.z(), tr.v[0],
                             tr.v[1], tr.v[2]);
                around.insert(tr.v, tr.v + 3);
            }
            for (uint32_t v : around) desc(v);
        }
        std::ostringstream os;
        os << "an edge used " << u.count << " time(s) one way and " << back << " the other";
        fail(os.str(), cell);
    }
    // Every vertex of a changed cell's triangles has one fan (a disc): all the
    // triangles that can use it are in the region.
    // Links (the edge opposite each corner), per vertex ascending, each in
    // triangle order.
    std::vector<char> ofChanged(ids.size(), 0);
    for (const Tri& tr : tris)
        if (isChanged(tr.cell))
            for (uint32_t v : tr.v) ofChanged[v] = 1;
    // (A counting sort by vertex: names are dense, and it keeps triangle order.)
    std::vector<uint32_t> linkStart(ids.size() + 1, 0);
    for (const Tri& tr : tris)
        for (uint32_t v : tr.v)
            if (ofChanged[v]) ++linkStart[v + 1];
    for (size_t v = 0; v < ids.size(); ++v) linkStart[v + 1] += linkStart[v];
    std::vector<std::pair<uint32_t, uint32_t>> linkEdges(linkStart.back());
    {
        std::vector<uint32_t> fill(linkStart.begin(), linkStart.end() - 1);
        for (const Tri& tr : tris)
            for (int k = 0; k < 3; ++k)
                if (ofChanged[tr.v[k]]) linkEdges[fill[tr.v[k]]++] = {tr.v[(k + 1) % 3], tr.v[(k + 2) % 3]};
    }
    std::vector<std::pair<uint32_t, uint32_t>> link;
    for (uint32_t v = 0; v < uint32_t(ids.size()); ++v) {
        if (linkStart[v] == linkStart[v + 1]) continue;
        link.assign(linkEdges.begin() + linkStart[v], linkEdges.begin() + linkStart[v + 1]);
        size_t steps = 0;
        uint32_t at = link[0].second;
        while (steps < link.size()) {
            auto next = std::find_if(link.begin(), link.end(), [&](const auto& e) { return e.first == at; });
            if (next == link.end()) break;
            at = next->second;
            ++steps;
            if (at == link[0].second) break;
        }
        if (steps == link.size()) continue;
        Coord lo, hi;
        cellsHolding(ids[v], lo, hi);
        Coord cell = changed.front();
        for (const Coord& c : changed)
            if (lo.x() <= c.x() && c.x() <= hi.x() && lo.y() <= c.y() && c.y() <= hi.y() && lo.z() <= c.z() &&
                c.z() <= hi.z()) {
                cell = c;
                break;
            }
        if (debug) {
            std::fprintf(stderr, "pinch at:\n");
            desc(v);
            std::set<uint32_t> seen;
            for (const auto& e : link) {
                std::fprintf(stderr, "   link edge %u -> %u\n", e.first, e.second);
                for (uint32_t u : {e.first, e.second})
                    if (seen.insert(u).second) desc(u);
            }
        }
        fail("a vertex where the surface pinches: not a 2-manifold", cell);
    }
    // No triangle of a changed cell is degenerate in float world mm.
    for (const Tri& tr : tris) {
        if (!isChanged(tr.cell) || !tr.cut) continue;
        if (!known[tr.v[0]] || !known[tr.v[1]] || !known[tr.v[2]]) continue;
        const glm::dvec3 a(world[tr.v[0]]), b(world[tr.v[1]]), c(world[tr.v[2]]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        if (n.x == 0.0 && n.y == 0.0 && n.z == 0.0) {
            if (debug) {
                std::fprintf(stderr, "zero-area triangle, cell (%d,%d,%d):\n", tr.cell.x(), tr.cell.y(), tr.cell.z());
                for (uint32_t v : tr.v) desc(v);
                for (const Tri& o : tris) {
                    int shared = 0;
                    for (uint32_t v : o.v) shared += v == tr.v[0] || v == tr.v[1] || v == tr.v[2];
                    if (shared >= 2) std::fprintf(stderr, "   neighbour cell (%d,%d,%d): %u %u %u\n", o.cell.x(), o.cell.y(), o.cell.z(), o.v[0], o.v[1], o.v[2]);
                }
            }
            fail("a triangle of zero area in float mm", tr.cell);
        }
    }
    // With kerf the surface neither crosses nor touches itself (two triangles
    // on the same three float points, where a removed sliver thinner than a
    // float step rounded its two faces onto each other: 1 mm head, kerf 1,
    // random strokes seed 3015; two sheets 4e-6 mm apart that cross once
    // rounded: the tooth, kerf 2, seed 3016). At kerf 0 the two sides of the
    // cut lie on each other by design.
    if (!kerf) return;
    refuseSelfContact(*mVolume, region, changed, tris, ids, names, world, known,
                      debug ? std::function<void(uint32_t)>(desc) : nullptr);
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
    for (uint32_t s = 1; s <= strokes && anyQuad; ++s) {
        const std::vector<char>& flags = changedQuad[s - 1];
        const uint32_t now = mask.quadCount(s);
        for (uint32_t q = 0; q < flags.size(); ++q) {
            const bool neighbourChanged = (q > 0 && flags[q - 1]) || (q + 1 < flags.size() && flags[q + 1]);
            if (flags[q]) {
                if (s <= mSeen.size() && q < mSeen[s - 1].size()) {
                    const std::vector<Coord>& cells = mSeen[s - 1][q].cells;
                    dirty.insert(dirty.end(), cells.begin(), cells.end());
                }
            }
            if (q < now && (flags[q] || neighbourChanged)) {
                const std::vector<Coord>& cells = mask.cellsOf(QuadRef{s, q});
                dirty.insert(dirty.end(), cells.begin(), cells.end());
            }
        }
    }
    std::sort(dirty.begin(), dirty.end());
    dirty.erase(std::unique(dirty.begin(), dirty.end()), dirty.end());
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
        if (dirty.size() > inside) {
            std::sort(dirty.begin(), dirty.end());
            dirty.erase(std::unique(dirty.begin(), dirty.end()), dirty.end());
        }
    }
    // A cell's quad list: the mask's; for a cell just outside the box, the
    // quads of its cut neighbours inside the box that touch it, sorted.
    std::map<std::pair<uint32_t, uint32_t>, QuadRegion> regions;
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
    std::vector<Coord> changedCells;
    auto save = [&](const Coord& c) {
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
        changedCells.push_back(c);
    };
    // Cells kept as they are (same kernel input) with their old signatures.
    std::vector<std::pair<Coord, std::vector<std::array<double, 36>>>> resigned;
    auto restore = [&] {
        for (auto& [cell, signatures] : resigned) mRecords[cell].quadCorners = std::move(signatures);
        for (auto it = saved.rbegin(); it != saved.rend(); ++it) {
            if (it->had) {
                mRecords[it->cell] = std::move(it->record);
                mCells[it->cell] = std::move(it->geometry);
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
        save(dirty[i]);
        mCells.erase(dirty[i]);
        mRecords.erase(it);
    }
    size_t count = 0, keptCells = 0;
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
        for (size_t i = 0; i < dirty.size(); ++i) {
            if (!lists[i]) continue;
            const Coord& c = dirty[i];
            const std::vector<QuadRef>& list = *lists[i];
            auto it = mRecords.find(c);
            const bool newList = it == mRecords.end() || !(it->second.quads == list);
            std::vector<std::array<double, 36>> signatures;
            signatures.reserve(list.size());
            for (const QuadRef& r : list) signatures.push_back(quadSignature(mask, r));
            if (!newList && it->second.quadCorners == signatures) continue;
            cellQuads(mask, list, *mPrismCache, mQuadCache.get(), quads);
            const std::array<uint64_t, 2> input = kernelInputDigest(c, quads, prism);
            if (!newList && it->second.input == input) {
                // A neighbour quad's side changed where this cell does not
                // reach (kernelInputDigest): the kernel would make the same
                // geometry. Keep it; remember the new signatures.
                if (mVerifyKept) {
                    CutCellGeometry again;
                    mKernels->local().remesh(c, quads, prism, again);
                    const CutCellGeometry& kept = mCells.at(c);
                    if (!(again.vertexIds == kept.vertexIds && again.indexPositions == kept.indexPositions &&
                          again.indices == kept.indices))
                        throw std::logic_error("remesh: kept geometry differs from a re-mesh in cell " + cellText(c));
                }
                resigned.emplace_back(c, std::move(it->second.quadCorners));
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
        std::atomic<size_t> done{0};
        std::atomic<bool> cancelled{false};
        tbb::parallel_for(tbb::blocked_range<size_t>(0, jobs.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
            CellKernel& kernel = mKernels->local();
            for (size_t j = range.begin(); j != range.end(); ++j) {
                if (cancelled.load(std::memory_order_relaxed)) return;
                try {
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
        for (CellJob& job : jobs) {
            if (job.error) std::rethrow_exception(job.error);
            if (mCellHook) mCellHook(job.cell, *job.out);
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
    return count;
}

} // namespace mtcut::cutter
