#include "cutter/Remesh.h"

#include "cutter/Isosurface.h"
#include "cutter/Polygon2.h"
#include "vdb/Error.h"

#include <glm/geometric.hpp>

#include <boost/container/small_vector.hpp>

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

namespace {

using glm::dvec3;
using openvdb::Coord;

constexpr uint64_t kIso = 1, kIsoA = 2, kIsoB = 3;
constexpr uint64_t kMid = 4;      ///< marks a Steiner midpoint of a slit chord between two rim points
constexpr uint64_t kCentroid = 5; ///< marks the Steiner centre of a cap region
constexpr uint64_t kBoundaryLabel = uint64_t(1) << 63; ///< | mask of tet-local vertices of the tet face/edge
constexpr int kJunctionKind = 7;
/// Kerf > 0: the tag (CutVertexId::tags) of the k-th copy (k >= 1) of a
/// vertex inside a tet where the removed region's boundary pinches.
constexpr uint64_t kPinchTag = uint64_t(1) << 63;
/// Kerf > 0: where the removed region's boundary has several fans at one
/// vertex inside a tet (the union of the prisms, or the solid left between
/// them, touches itself at that point: a blade pivoting on a corner), every
/// fan but the first gets its own copy of the vertex, so the surface is a
/// 2-manifold that touches itself there.
void splitPinches(const openvdb::Coord& cell, CutCellGeometry& out);
constexpr int kPlusKind = 8, kMinusKind = 9; ///< kerf > 0: the prism's offset planes
constexpr double kMaxMitreBend = 0.35; ///< kerf > 0: consecutive prisms bending less than this (rad) meet on a mitre

uint64_t planeIdOf(uint32_t stroke, uint32_t quad, int kind)
{
    return (uint64_t(stroke) << 36) | (uint64_t(quad) << 4) | uint64_t(kind);
}

struct Plane
{
    dvec3 n{0.0};
    double d = 0.0;
    double h(const dvec3& x) const { return glm::dot(n, x) - d; }
};

inline double epsAt(const dvec3& x)
{
    return 1e-13 * (1.0 + std::max({std::abs(x.x), std::abs(x.y), std::abs(x.z)}));
}

std::string cellText(const Coord& c)
{
    std::ostringstream os;
    os << "(" << c.x() << ", " << c.y() << ", " << c.z() << ")";
    return os.str();
}

// ---------------------------------------------------------- quad geometry --

/// A quad's zero-kerf removed region in index space: its plane and its sides
/// (each a plane through a hull edge; the junction with the previous/next
/// quad of the stroke is one shared mitre plane, so the strip is one surface).
struct QuadGeom
{
    uint64_t id = 0; ///< plane id of the quad's plane (kind 0)
    Plane pi;
    struct Side
    {
        uint64_t id = 0;
        Plane plane;
        double orient = 1.0; ///< inside the quad: orient * h >= 0
        int partner = -1;    ///< junction: the other quad's index in the cell's quad list (-1: rim)
        uint64_t partnerId = 0;
        /// Junction: at each end of the shared edge, this quad's rim side there and
        /// the partner's (0 when none); a point on both is one corner of the strip.
        std::array<std::pair<uint64_t, uint64_t>, 2> cornerSides{};
    };
    std::vector<Side> sides;
};

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
///   by less than kKerfMitreMaxBend: the mitre, one plane object for both
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
            if (!sharesEdge(o, hullOf(o, frame, indexNormal(o, frame)), wa, wb)) continue;
            if (dq < 0) { // joined to the previous quad, with or without a mitre
                joinedPrevious = true;
                prevA = wa;
                prevB = wb;
            }
            const bool lower = dq > 0;
            const dvec3 nl = lower ? q.normal : o.normal, nu = lower ? o.normal : q.normal; // world
            const double c = glm::dot(nl, nu);
            if (!(c > std::cos(kKerfMitreMaxBend))) break;
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

// ================================================================ kernel ====

using poly2::bestTriangulation;
using poly2::bridgeHoles;
using poly2::cross2;
using poly2::earClip;
using poly2::signedArea;
using poly2::Vec2;

/// Inline-storage vectors for the kernel's short per-vertex and per-polygon
/// lists (a few entries each), so building them allocates nothing.
template <class T, size_t N> using SmallVector = boost::container::small_vector<T, N>;
using PlaneList = SmallVector<uint64_t, 8>;

class RemeshKernel
{
public:
    RemeshKernel(const vdb::Volume& volume, float iso)
        : mAcc(volume.grid->tree()), mIso(iso), mDims(volume.dims), mBackground(volume.grid->background())
    {
    }

    /// prism: the quads are kerf > 0 prisms (makePrismGeom), else zero-kerf quads.
    void remesh(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out);

private:
    // ---- per tet state
    struct Vert
    {
        CutVertexId key; // planes only, no tags
        dvec3 pos;
        uint8_t support = 0; // tet-local vertices of the smallest simplex holding it
        SmallVector<std::pair<uint64_t, int8_t>, 8> signs;
        int8_t member = 2; // P membership cache (2 = unknown)
        bool steiner = false; // a Steiner point: always a corner
    };
    struct Poly
    {
        SmallVector<int, 8> v;
        SmallVector<uint64_t, 8> lab; // lab[i]: edge v[i] -> v[i+1]
    };
    struct Support
    {
        dvec3 p[4];
        uint64_t id[4];
        float value[4];
        bool inside[4];
    };

    float value(const Coord& c) { return mAcc.getValue(c); }

    // Tet-level data.
    Coord mCell;
    int mTet = 0;
    Support mT;
    std::vector<Vert> mVerts;
    /// CutVertexIdHash of each mVerts[i].key: makeVertex's search for an
    /// existing name compares these first (a cell where many quads pivot has
    /// thousands of vertices per tet; comparing whole keys was most of its time).
    std::vector<uint64_t> mVertHash;
    /// Past kIndexFrom vertices, an index over mVertHash: per hash the first
    /// and last vertex holding it, chained in ascending order through
    /// mNextSameHash, so findVertex still returns the lowest match.
    static constexpr size_t kIndexFrom = 64;
    std::unordered_map<uint64_t, std::pair<int, int>> mHashChain;
    std::vector<int> mNextSameHash;
    bool mHashIndexed = false;
    /// Also past kIndexFrom: the tet-inside, non-Steiner vertices by position,
    /// in buckets of kNearCell voxels (far above mergeTolerance), for
    /// makeVertex's merge of one point made by different planes.
    static constexpr double kNearCell = 1e-5;
    std::unordered_map<uint64_t, SmallVector<int, 2>> mNear;
    static uint64_t nearKey(int64_t x, int64_t y, int64_t z)
    {
        uint64_t h = uint64_t(x) * 0x9e3779b97f4a7c15ull;
        h ^= uint64_t(y) * 0xc2b2ae3d27d4eb4full + (h << 6) + (h >> 2);
        h ^= uint64_t(z) * 0x165667b19e3779f9ull + (h << 6) + (h >> 2);
        return h;
    }
    static double mergeTolerance(const dvec3& p)
    {
        return 1e-11 * (1.0 + std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}));
    }
    /// The lowest tet-inside, non-Steiner vertex with this feature within
    /// mergeTolerance of `p`, or -1.
    int mergeCandidate(const std::array<uint64_t, 3>& feature, const dvec3& p) const
    {
        auto fits = [&](const Vert& o) {
            return o.key.dim == 3 && !o.steiner && o.key.feature == feature && glm::length(o.pos - p) <= mergeTolerance(p);
        };
        if (!mHashIndexed) {
            for (size_t i = 0; i < mVerts.size(); ++i)
                if (fits(mVerts[i])) return int(i);
            return -1;
        }
        const int64_t bx = int64_t(std::floor(p.x / kNearCell)), by = int64_t(std::floor(p.y / kNearCell)),
                      bz = int64_t(std::floor(p.z / kNearCell));
        int best = -1;
        for (int64_t dx = -1; dx <= 1; ++dx)
            for (int64_t dy = -1; dy <= 1; ++dy)
                for (int64_t dz = -1; dz <= 1; ++dz) {
                    auto it = mNear.find(nearKey(bx + dx, by + dy, bz + dz));
                    if (it == mNear.end()) continue;
                    for (int i : it->second)
                        if ((best < 0 || i < best) && fits(mVerts[size_t(i)])) best = i;
                }
        return best;
    }
    void indexVertex(int i)
    {
        const Vert& v = mVerts[size_t(i)];
        if (v.key.dim == 3 && !v.steiner)
            mNear[nearKey(int64_t(std::floor(v.pos.x / kNearCell)), int64_t(std::floor(v.pos.y / kNearCell)),
                          int64_t(std::floor(v.pos.z / kNearCell)))]
                .push_back(i);
        mNextSameHash.push_back(-1);
        auto [it, fresh] = mHashChain.try_emplace(mVertHash[size_t(i)], i, i);
        if (!fresh) {
            mNextSameHash[size_t(it->second.second)] = i;
            it->second.second = i;
        }
    }
    void rebuildHashIndex()
    {
        mHashChain.clear();
        mNextSameHash.clear();
        mNear.clear();
        for (size_t i = 0; i < mVerts.size(); ++i) indexVertex(int(i));
        mHashIndexed = true;
    }
    /// The lowest vertex named `key` (hash: its CutVertexIdHash), or -1.
    int findVertex(const CutVertexId& key, uint64_t hash) const
    {
        if (!mHashIndexed) {
            for (size_t i = 0; i < mVerts.size(); ++i)
                if (mVertHash[i] == hash && mVerts[i].key == key) return int(i);
            return -1;
        }
        auto it = mHashChain.find(hash);
        for (int i = it == mHashChain.end() ? -1 : it->second.first; i >= 0; i = mNextSameHash[size_t(i)])
            if (mVerts[size_t(i)].key == key) return i;
        return -1;
    }
    void pushVertex(Vert&& v, uint64_t hash)
    {
        mVerts.push_back(std::move(v));
        mVertHash.push_back(hash);
        if (mHashIndexed) indexVertex(int(mVerts.size() - 1));
        else if (mVerts.size() >= kIndexFrom) rebuildHashIndex();
    }
    /// sign() memo, one column per plane of mPlanes (a plane's signs over
    /// the vertices are contiguous: splitting pieces asks one plane about many
    /// nearby vertices): entry pidx * mSignCap + vi; 2 = not yet known. Ids
    /// not in mPlanes use Vert::signs. Reset per tet.
    std::vector<int8_t> mSignTab;
    size_t mSignStride = 0; ///< mPlanes.size() once mPlanes is final; 0 before
    size_t mSignCap = 0;    ///< vertices per column
    int8_t& signSlot(size_t vi, size_t pidx)
    {
        if (vi >= mSignCap) {
            size_t cap = std::max<size_t>(64, mSignCap);
            while (cap <= vi) cap *= 2;
            std::vector<int8_t> grown(mSignStride * cap, int8_t(2));
            for (size_t p = 0; p < mSignStride && mSignCap; ++p)
                std::copy_n(mSignTab.begin() + std::ptrdiff_t(p * mSignCap), mSignCap, grown.begin() + std::ptrdiff_t(p * cap));
            mSignTab.swap(grown);
            mSignCap = cap;
        }
        return mSignTab[pidx * mSignCap + vi];
    }
    void forgetSigns(size_t vi)
    {
        mVerts[vi].signs.clear();
        if (vi < mSignCap)
            for (size_t p = 0; p < mSignStride; ++p) mSignTab[p * mSignCap + vi] = 2;
    }
    // remeshTet's scratch, kept between tets for its capacity.
    std::vector<int> mNodeHead, mNodeNext, mParent, mEdgeOrder;
    std::vector<Poly> mPieces, mNextPieces;
    std::vector<int> mOnLine;
    using Tags = SmallVector<uint64_t, 4>;
    struct Node // a vertex of a region loop: the vertex and its side tags
    {
        int vert;
        Tags tags;
    };
    std::vector<Node> mNodes;
    std::vector<Vec2> mTriangulatePts;
    std::vector<int> mTriangulateNodes;
    std::vector<std::array<int, 4>> mEdgeUses, mEdgeSorted;
    std::vector<std::vector<std::array<int64_t, 3>>> mRegionEdges;
    std::vector<std::pair<int, int>> mBoundaryKeys;
    std::vector<const QuadGeom*> mQuads;             // quads crossing this tet
    std::vector<std::pair<uint64_t, Plane>> mPlanes; // sorted by id: ISO_A, ISO_B, quad planes and sides
    int mTriCount = 0;
    Plane mTriPlane[2];
    std::vector<int> mTriVerts[2];
    int mFaceTri[4];      // which iso triangle has its edge on tet face f (opposite vertex f), -1 none
    std::vector<uint8_t> mTriEdgeMasks[2]; // tet-local vertex masks of the grid edges of each iso triangle's corners
    /// Does iso triangle k (kIsoA + k) hold the MT geometry of the face or edge `support`?
    bool triOwns(int k, uint8_t support) const
    {
        if (mTriCount < 2) return true;
        if (bits(support) == 3) {
            int f = 0;
            while (support >> f & 1) ++f;
            return mFaceTri[f] == k;
        }
        return std::find(mTriEdgeMasks[k].begin(), mTriEdgeMasks[k].end(), support) != mTriEdgeMasks[k].end();
    }
    bool mFoldConvex = true;
    bool mPrism = false; ///< kerf > 0: quads are closed prisms, no slits, tags or Steiner points

    const Plane* planeById(uint64_t id) const
    {
        if (mSignStride) {
            const size_t i = planeIndex(id);
            return i == SIZE_MAX ? nullptr : &mPlanes[i].second;
        }
        auto it = std::lower_bound(mPlanes.begin(), mPlanes.end(), id,
                                   [](const std::pair<uint64_t, Plane>& a, uint64_t b) { return a.first < b; });
        return it != mPlanes.end() && it->first == id ? &it->second : nullptr;
    }
    /// Once mPlanes is final: an open-addressing table id -> index in mPlanes
    /// (sign() and planeById() ask it millions of times in a cell where many
    /// quads pivot; a binary search over mPlanes was half of sign()).
    std::vector<std::pair<uint64_t, uint32_t>> mPlaneSlots; ///< (id, index); index UINT32_MAX = empty
    static size_t slotHash(uint64_t id) { return size_t((id * 0x9e3779b97f4a7c15ull) >> 32); }
    void buildPlaneSlots()
    {
        size_t n = 16;
        while (n < 2 * mPlanes.size()) n *= 2;
        mPlaneSlots.assign(n, {0, UINT32_MAX});
        for (size_t i = 0; i < mPlanes.size(); ++i) {
            size_t h = slotHash(mPlanes[i].first) & (n - 1);
            while (mPlaneSlots[h].second != UINT32_MAX) h = (h + 1) & (n - 1);
            mPlaneSlots[h] = {mPlanes[i].first, uint32_t(i)};
        }
    }
    /// Index of plane `id` in mPlanes once it is final; SIZE_MAX when absent or before.
    size_t planeIndex(uint64_t id) const
    {
        if (!mSignStride) return SIZE_MAX;
        const size_t mask = mPlaneSlots.size() - 1;
        for (size_t h = slotHash(id) & mask;; h = (h + 1) & mask) {
            const auto& s = mPlaneSlots[h];
            if (s.second == UINT32_MAX) return SIZE_MAX;
            if (s.first == id) return s.second;
        }
    }

    static int bits(uint8_t m) { return (m & 1) + (m >> 1 & 1) + (m >> 2 & 1) + (m >> 3 & 1); }

    // Grid data for features.
    dvec3 mtPoint(int a, int b) const // tet-local vertices, MT crossing point
    {
        int lo = a, hi = b;
        if (mT.id[hi] < mT.id[lo]) std::swap(lo, hi);
        const double t = edgeCrossing(mT.value[lo], mT.value[hi], mIso);
        return mT.p[lo] + t * (mT.p[hi] - mT.p[lo]);
    }
    /// Face (tet-local vertex mask, 3 bits): canonical iso line p1, p2 and inside sign; false when not crossed.
    bool faceIsoLine(uint8_t mask, dvec3& p1, dvec3& p2, dvec3& normal, double& inSign) const
    {
        int v[3], n = 0;
        for (int i = 0; i < 4; ++i)
            if (mask >> i & 1) v[n++] = i;
        std::sort(v, v + 3, [&](int a, int b) { return mT.id[a] < mT.id[b]; });
        const int ni = int(mT.inside[v[0]]) + int(mT.inside[v[1]]) + int(mT.inside[v[2]]);
        if (ni == 0 || ni == 3) return false;
        const int ends[3][2] = {{v[0], v[1]}, {v[0], v[2]}, {v[1], v[2]}};
        int k = 0;
        dvec3 pts[2];
        for (const auto& e : ends)
            if (mT.inside[e[0]] != mT.inside[e[1]]) pts[k++] = mtPoint(e[0], e[1]);
        p1 = pts[0];
        p2 = pts[1];
        normal = glm::cross(mT.p[v[1]] - mT.p[v[0]], mT.p[v[2]] - mT.p[v[0]]);
        const int in = mT.inside[v[0]] ? v[0] : mT.inside[v[1]] ? v[1] : v[2];
        inSign = glm::dot(glm::cross(p2 - p1, mT.p[in] - p1), normal) > 0 ? 1.0 : -1.0;
        return true;
    }
    /// Signed in-plane distance to the face's iso line (+ inside), or +-1e300 when uncrossed.
    double faceIsoDistance(uint8_t mask, const dvec3& x) const
    {
        dvec3 p1, p2, nrm;
        double s;
        if (!faceIsoLine(mask, p1, p2, nrm, s)) {
            int any = 0;
            while (!(mask >> any & 1)) ++any;
            return mT.inside[any] ? 1e300 : -1e300;
        }
        const double l = glm::length(p2 - p1) * glm::length(nrm);
        return s * glm::dot(glm::cross(p2 - p1, x - p1), nrm) / l;
    }
    double edgeIsoDistance(uint8_t mask, const dvec3& x) const
    {
        int a = -1, b = -1;
        for (int i = 0; i < 4; ++i)
            if (mask >> i & 1) (a < 0 ? a : b) = i;
        if (mT.id[b] < mT.id[a]) std::swap(a, b);
        if (mT.inside[a] == mT.inside[b]) return mT.inside[a] ? 1e300 : -1e300;
        const dvec3 e = mT.p[b] - mT.p[a];
        const double len = glm::length(e);
        const double t = glm::dot(x - mT.p[a], e) / (len * len);
        const double ti = edgeCrossing(mT.value[a], mT.value[b], mIso);
        return (mT.inside[a] ? (ti - t) : (t - ti)) * len;
    }

    CutVertexId featureKey(uint8_t support) const
    {
        CutVertexId k;
        const int n = bits(support);
        k.dim = uint8_t(n - 1);
        if (n == 4) {
            k.feature = {gridVertexId(mCell.x(), mCell.y(), mCell.z()), uint64_t(mTet), 0};
            return k;
        }
        int m = 0;
        for (int i = 0; i < 4; ++i)
            if (support >> i & 1) k.feature[size_t(m++)] = mT.id[i];
        std::sort(k.feature.begin(), k.feature.begin() + n);
        return k;
    }

    dvec3 canonicalPosition(const CutVertexId& key, uint8_t support, const dvec3& pos0) const;
    int makeVertex(uint8_t support, PlaneList defining, const dvec3& pos0);
    /// The first of `planes` (in order; those with a plane in this tet)
    /// whose normals are independent, at most three: three fix one point.
    PlaneList independentPlanes(const PlaneList& planes) const
    {
        PlaneList chosen;
        dvec3 n0(0.0), n1(0.0);
        for (uint64_t id : planes) {
            const Plane* pl = planeById(id);
            if (!pl) continue;
            const dvec3& n = pl->n;
            const bool independent = chosen.empty()       ? glm::length(n) > 0.5
                                     : chosen.size() == 1 ? glm::length(glm::cross(n0, n)) > 1e-6
                                                          : std::abs(glm::dot(glm::cross(n0, n1), n)) > 1e-6;
            if (!independent) continue;
            (chosen.empty() ? n0 : n1) = n;
            chosen.push_back(id);
            if (chosen.size() == 3) break;
        }
        return chosen;
    }
    int makeSteiner(uint8_t support, PlaneList planes, const dvec3& pos);
    /// A slit chord of quad r between two rim points on different rim lines:
    /// the two sides of the slit need a tagged vertex on it.
    bool needsMidpoint(int u, int v, const QuadGeom& r)
    {
        if (mPrism) return false;
        if (sign(u, r.id) != 0 || sign(v, r.id) != 0) return false;
        if (!inExtentClosed(u, r) || !inExtentClosed(v, r) || (inSlitOpen(u, r) && !onStripRim(u, r)) || (inSlitOpen(v, r) && !onStripRim(v, r))) return false;
        for (const auto& sd : r.sides)
            if (sd.partner < 0 && sign(u, sd.id) == 0 && sign(v, sd.id) == 0) return false;
        return true;
    }
    /// Side of vertex v on plane planeId: 1, -1, or 0 on it (by name, or
    /// within the tie rule); memoised.
    int sign(int v, uint64_t planeId)
    {
        const size_t pidx = planeIndex(planeId);
        if (pidx != SIZE_MAX && size_t(v) < mSignCap) {
            const int8_t known = mSignTab[pidx * mSignCap + size_t(v)];
            if (known != 2) return known;
        }
        return signSlow(v, planeId, pidx);
    }
    int signSlow(int v, uint64_t planeId, size_t pidx);
    int member(int v);
    bool inExtentClosed(int v, const QuadGeom& q)
    {
        for (const auto& s : q.sides)
            if (s.orient * sign(v, s.id) < 0) return false;
        return true;
    }
    bool inSlitOpen(int v, const QuadGeom& q)
    {
        for (const auto& s : q.sides) {
            const double o = s.orient * sign(v, s.id);
            if (s.partner >= 0 ? o < 0 : o <= 0) return false;
        }
        return true;
    }
    /// On the rim of a neighbouring quad of r's strip (a strip corner that r
    /// touches only at a point)? Then the point is rim for r too.
    bool onStripRim(int v, const QuadGeom& r)
    {
        for (const QuadGeom* o : mQuads) {
            if (o == &r || (o->id >> 36) != (r.id >> 36)) continue;
            const int64_t dq = int64_t((o->id >> 4) & 0xffffffff) - int64_t((r.id >> 4) & 0xffffffff);
            if (dq < -2 || dq > 2 || sign(v, o->id) != 0 || !inExtentClosed(v, *o)) continue;
            for (const auto& sd : o->sides)
                if (sd.partner < 0 && sign(v, sd.id) == 0) return true;
        }
        return false;
    }
    const QuadGeom* quadById(uint64_t id) const
    {
        for (const QuadGeom* q : mQuads)
            if (q->id == id) return q;
        return nullptr;
    }

    /// Appends the pieces of `in` on either side of plane p to `out` (`in`
    /// itself, moved, when p does not cross it).
    void splitPoly(Poly&& in, uint64_t polyPlane, uint64_t p, std::vector<Poly>& out);
    /// Appends `o` to `out`, split into simple loops where it visits a vertex twice.
    void pushSimple(Poly o, std::vector<Poly>& out);
    void remeshTet(CutCellGeometry& out, std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash>& cellIndex);

    openvdb::tree::ValueAccessor<const openvdb::FloatTree> mAcc;
    float mIso;
    Coord mDims;
    float mBackground;
    const std::vector<QuadGeom>* mCellQuads = nullptr;
};

dvec3 RemeshKernel::canonicalPosition(const CutVertexId& key, uint8_t support, const dvec3& pos0) const
{
    if (key.dim == 0) {
        for (int i = 0; i < 4; ++i)
            if (support >> i & 1) return mT.p[i];
    }
    if (key.dim == 3) return pos0;
    for (int i = 0; i < key.planeCount; ++i)
        if (key.planes[size_t(i)] == kMid || key.planes[size_t(i)] == kCentroid) return pos0;
    auto planeOf = [&](uint64_t id) -> const Plane* { return planeById(id); };
    if (key.dim == 1) {
        int a = -1, b = -1;
        for (int i = 0; i < 4; ++i)
            if (support >> i & 1) (a < 0 ? a : b) = i;
        if (mT.id[b] < mT.id[a]) std::swap(a, b);
        if (key.planes[0] == kIso) return mtPoint(a, b);
        for (int i = 0; i < key.planeCount; ++i) {
            const Plane* p = planeOf(key.planes[size_t(i)]);
            if (!p) continue;
            const double ha = p->h(mT.p[a]), hb = p->h(mT.p[b]);
            if (!(std::abs(ha - hb) > 1e-12)) continue;
            const double t = std::clamp(ha / (ha - hb), 0.0, 1.0);
            return mT.p[a] + t * (mT.p[b] - mT.p[a]);
        }
        return pos0;
    }
    // dim 2: a face.
    if (key.planes[0] == kIso) {
        dvec3 p1, p2, nrm;
        double s;
        if (faceIsoLine(support, p1, p2, nrm, s)) {
            const double len = glm::length(p2 - p1);
            for (int i = 1; i < key.planeCount; ++i) {
                const Plane* p = planeOf(key.planes[size_t(i)]);
                if (!p) continue;
                const double h1 = p->h(p1), h2 = p->h(p2);
                if (!(std::abs(h1 - h2) > 1e-9 * len)) continue;
                const double u = h1 / (h1 - h2);
                return p1 + u * (p2 - p1);
            }
        }
        return pos0;
    }
    int v[3], n = 0;
    for (int i = 0; i < 4; ++i)
        if (support >> i & 1) v[n++] = i;
    std::sort(v, v + 3, [&](int a, int b) { return mT.id[a] < mT.id[b]; });
    const dvec3 A = mT.p[v[0]], e1 = mT.p[v[1]] - A, e2 = mT.p[v[2]] - A;
    for (int i = 0; i < key.planeCount; ++i)
        for (int j = i + 1; j < key.planeCount; ++j) {
            const Plane* p = planeOf(key.planes[size_t(i)]);
            const Plane* q = planeOf(key.planes[size_t(j)]);
            if (!p || !q) continue;
            const double a11 = glm::dot(p->n, e1), a12 = glm::dot(p->n, e2), b1 = -p->h(A);
            const double a21 = glm::dot(q->n, e1), a22 = glm::dot(q->n, e2), b2 = -q->h(A);
            const double det = a11 * a22 - a12 * a21;
            if (!(std::abs(det) > 1e-9)) continue;
            const double s = (b1 * a22 - a12 * b2) / det, t = (a11 * b2 - b1 * a21) / det;
            return A + s * e1 + t * e2;
        }
    return pos0;
}

int RemeshKernel::makeVertex(uint8_t support, PlaneList defining, const dvec3& pos0)
{
    CutVertexId key = featureKey(support);
    const double eps = epsAt(pos0);
    // The name is the set of ACTIVE planes through the point (the iso surface,
    // quads holding it); the planes that happened to make it (in this tet's
    // arrangement) are used only when the active ones do not fix the point.
    PlaneList planes;
    for (uint64_t& p : defining) {
        // An iso triangle's plane is the iso surface only on the faces and
        // edges that hold that triangle's MT geometry; elsewhere (a fold's
        // plane extended over the other triangle's face) it is a tet-local plane.
        if (key.dim < 3 && (p == kIsoA || p == kIsoB) && triOwns(int(p - kIsoA), support)) p = kIso;
        if (p <= kIsoB) planes.push_back(p);
    }
    if (key.dim < 3) {
        if (key.dim == 2 && std::abs(faceIsoDistance(support, pos0)) <= eps) planes.push_back(kIso);
        if (key.dim == 1 && std::abs(edgeIsoDistance(support, pos0)) <= eps) planes.push_back(kIso);
    }
    // Active quad planes: on the plane and in the closed quad; sides on which it lies.
    // Prisms (kerf > 0): on the closed prism's boundary, every bounding plane it lies on.
    for (const QuadGeom* q : mQuads) {
        if (!mPrism) continue;
        bool in = true, onAny = false;
        for (const auto& s : q->sides) {
            const double h = s.orient * s.plane.h(pos0);
            in = in && h >= -eps;
            onAny = onAny || std::abs(h) <= eps;
        }
        if (!in || !onAny) continue;
        for (const auto& s : q->sides)
            if (std::abs(s.plane.h(pos0)) <= eps) planes.push_back(s.id);
    }
    for (const QuadGeom* q : mQuads) {
        if (mPrism) break;
        if (!(std::abs(q->pi.h(pos0)) <= eps)) continue;
        bool in = true;
        for (const auto& s : q->sides) in = in && s.orient * s.plane.h(pos0) >= -eps;
        if (!in) continue;
        planes.push_back(q->id);
        for (const auto& s : q->sides)
            if (std::abs(s.plane.h(pos0)) <= eps) planes.push_back(s.id);
    }
    // Junctions: a point on a junction plane and on either quad's plane is on
    // both (the three meet in one line, the stick, whether or not the point is
    // inside the quads); at the ends of the shared edge, on either rim side is
    // on both. `on`: the planes the point lies on (made by them, or within eps).
    std::sort(planes.begin(), planes.end());
    planes.erase(std::unique(planes.begin(), planes.end()), planes.end());
    PlaneList on(defining.begin(), defining.end());
    for (const auto& pl : mPlanes)
        if (pl.first > kIsoB && std::abs(pl.second.h(pos0)) <= eps) on.push_back(pl.first);
    on.insert(on.end(), planes.begin(), planes.end());
    std::sort(on.begin(), on.end());
    on.erase(std::unique(on.begin(), on.end()), on.end());
    // Prisms: the offset planes of two quads meet on their mitre (it bisects
    // them), so a point on the mitre and on one quad's offset plane is on the
    // partner's same-side offset plane too.
    for (const QuadGeom* q : mQuads) {
        if (!mPrism) break;
        auto has = [&](uint64_t id) { return std::binary_search(on.begin(), on.end(), id); };
        for (const auto& sd : q->sides) {
            if (sd.partnerId == 0 || !has(sd.id)) continue;
            for (int kind : {kPlusKind, kMinusKind}) {
                const uint64_t mine = (q->id & ~uint64_t(15)) | uint64_t(kind);
                const uint64_t theirs = (sd.partnerId & ~uint64_t(15)) | uint64_t(kind);
                if (has(mine) || has(theirs)) {
                    planes.push_back(sd.id);
                    planes.push_back(mine);
                    planes.push_back(theirs);
                }
            }
        }
    }
    if (mPrism) {
        std::sort(planes.begin(), planes.end());
        planes.erase(std::unique(planes.begin(), planes.end()), planes.end());
    }
    for (int round = 0; round < 4 && !mPrism; ++round) {
        PlaneList add;
        auto has = [&](uint64_t id) { return std::binary_search(on.begin(), on.end(), id); };
        for (const QuadGeom* q : mQuads) {
            for (const auto& s : q->sides) {
                if (s.partner < 0 || !has(s.id) || !(has(q->id) || has(s.partnerId)) || !quadById(s.partnerId)) continue;
                add.push_back(s.id);
                add.push_back(q->id);
                add.push_back(s.partnerId);
                for (const auto& cs : s.cornerSides) {
                    if (cs.first && cs.second && (has(cs.first) || has(cs.second))) {
                        add.push_back(cs.first);
                        add.push_back(cs.second);
                    }
                }
            }
        }
        if (add.empty()) break;
        const size_t before = on.size();
        on.insert(on.end(), add.begin(), add.end());
        std::sort(on.begin(), on.end());
        on.erase(std::unique(on.begin(), on.end()), on.end());
        planes.insert(planes.end(), add.begin(), add.end());
        std::sort(planes.begin(), planes.end());
        planes.erase(std::unique(planes.begin(), planes.end()), planes.end());
        if (on.size() == before) break;
    }
    // A face needs two planes, an edge one, the inside three; inside the tet
    // the three must also be independent. Prisms: a mitre and the two offset
    // planes it bisects meet in one line, so a point on that line is named
    // by the three and nothing else when its other plane is not active
    // (outside that prism): two points of the line would share the name.
    // The planes that made it complete the name (inside points are named
    // only in this tet, so the union is the same whichever pair made it).
    if (int(planes.size()) < int(key.dim) || (key.dim == 3 && independentPlanes(planes).size() < 3)) {
        planes.insert(planes.end(), defining.begin(), defining.end());
        std::sort(planes.begin(), planes.end());
        planes.erase(std::unique(planes.begin(), planes.end()), planes.end());
    }
    if (planes.size() > key.planes.size() && key.dim == 3) {
        // A point inside the tet on more planes than a name holds (a blade
        // pivoting exactly about it: every stick, so every mitre and quad
        // plane, passes through it). No other tet or cell names it and its
        // position is pos0, so any of its planes that fix the point name it
        // uniquely: three with independent normals (the lowest ids that are),
        // then the lowest others. The same plane set always gives the same
        // name; the dropped planes still hold it (sign() finds it on them).
        PlaneList chosen = independentPlanes(planes);
        if (chosen.size() == 3) {
            for (uint64_t id : planes)
                if (chosen.size() < key.planes.size() && std::find(chosen.begin(), chosen.end(), id) == chosen.end())
                    chosen.push_back(id);
            std::sort(chosen.begin(), chosen.end());
            planes = chosen;
        }
    }
    if (planes.size() > key.planes.size()) {
        throw std::runtime_error("remesh: a point lies on more than 8 blade planes in cell " + cellText(mCell));
    }
    key.planeCount = uint8_t(planes.size());
    for (size_t i = 0; i < planes.size(); ++i) key.planes[i] = planes[i];
    const uint64_t hash = CutVertexIdHash()(key);
    if (const int found = findVertex(key, hash); found >= 0) return found;
    // Inside the tet (no other tet or cell ever names it), one point made by
    // different planes (two pieces of one region split by the planes of two
    // joined quads whose rims are coplanar) is one vertex: its name is the
    // union of the planes, so the pieces share it and merge.
    if (const int i = key.dim == 3 ? mergeCandidate(key.feature, pos0) : -1; i >= 0) {
        Vert& o = mVerts[size_t(i)];
        std::vector<uint64_t> all(o.key.planes.begin(), o.key.planes.begin() + o.key.planeCount);
        all.insert(all.end(), planes.begin(), planes.end());
        std::sort(all.begin(), all.end());
        all.erase(std::unique(all.begin(), all.end()), all.end());
        if (all.size() <= o.key.planes.size()) {
            o.key.planeCount = uint8_t(all.size());
            for (size_t k = 0; k < all.size(); ++k) o.key.planes[k] = all[k];
            mVertHash[size_t(i)] = CutVertexIdHash()(o.key);
            if (mHashIndexed) rebuildHashIndex();
            forgetSigns(size_t(i));
            o.member = 2;
            return i;
        }
    }
    Vert v;
    v.key = key;
    v.support = support;
    v.pos = canonicalPosition(key, support, pos0);
    pushVertex(std::move(v), hash);
    return int(mVerts.size() - 1);
}

int RemeshKernel::makeSteiner(uint8_t support, PlaneList planes, const dvec3& pos)
{
    CutVertexId key = featureKey(support);
    std::sort(planes.begin(), planes.end());
    key.planeCount = uint8_t(planes.size());
    for (size_t i = 0; i < planes.size(); ++i) key.planes[i] = planes[i];
    const uint64_t hash = CutVertexIdHash()(key);
    if (const int found = findVertex(key, hash); found >= 0) return found;
    Vert v;
    v.key = key;
    v.support = support;
    v.pos = pos;
    v.steiner = true;
    pushVertex(std::move(v), hash);
    return int(mVerts.size() - 1);
}

int RemeshKernel::signSlow(int vi, uint64_t id, size_t pidx)
{
    int8_t* slot = nullptr; // in mSignTab
    if (pidx != SIZE_MAX) {
        slot = &signSlot(size_t(vi), pidx);
        if (*slot != 2) return *slot;
    }
    Vert& v = mVerts[size_t(vi)];
    for (const auto& s : v.signs)
        if (s.first == id) return s.second;
    int r;
    const bool inKey = std::binary_search(v.key.planes.begin(), v.key.planes.begin() + v.key.planeCount, id);
    if (inKey) {
        r = 0;
    } else if ((id == kIsoA || id == kIsoB) && v.key.planeCount > 0 && v.key.planes[0] == kIso &&
               (v.key.dim == 1 || v.key.dim == 2)) {
        const int tri = int(id - kIsoA);
        bool on = false;
        if (v.key.dim == 1) {
            for (int c : mTriVerts[tri]) on = on || c == vi;
            // MT corner of this triangle with extra planes in its key: compare positions.
            if (!on)
                for (int c : mTriVerts[tri]) on = on || mVerts[size_t(c)].key.feature == v.key.feature;
        } else {
            int f = 0;
            while (v.support >> f & 1) ++f;
            on = mFaceTri[f] == tri;
        }
        if (on) {
            r = 0;
        } else {
            const double h = planeById(id)->h(v.pos);
            r = std::abs(h) <= epsAt(v.pos) ? 0 : (h > 0 ? 1 : -1);
        }
    } else {
        const Plane* p = planeById(id);
        assert(p);
        const double h = p->h(v.pos);
        r = std::abs(h) <= epsAt(v.pos) ? 0 : (h > 0 ? 1 : -1);
    }
    if (slot) *slot = int8_t(r);
    else v.signs.push_back({id, int8_t(r)});
    return r;
}

int RemeshKernel::member(int vi)
{
    Vert& v = mVerts[size_t(vi)];
    if (v.member != 2) return v.member;
    int r;
    const bool onIso = v.key.planeCount > 0 && v.key.planes[0] == kIso;
    if (v.key.dim == 0) {
        int i = 0;
        while (!(v.support >> i & 1)) ++i;
        r = mT.inside[i] ? 1 : -1;
    } else if (v.key.dim < 3) {
        if (onIso) {
            r = 0;
        } else {
            const double d = v.key.dim == 1 ? edgeIsoDistance(v.support, v.pos) : faceIsoDistance(v.support, v.pos);
            r = d > 0 ? 1 : -1;
        }
    } else if (mTriCount == 0) {
        r = mT.inside[0] ? 1 : -1;
    } else {
        const int a = sign(vi, kIsoA);
        if (mTriCount == 1) {
            r = a;
        } else {
            const int b = sign(vi, kIsoB);
            r = mFoldConvex ? std::min(a, b) : std::max(a, b);
        }
    }
    v.member = int8_t(r);
    return r;
}

void RemeshKernel::splitPoly(Poly&& in, uint64_t polyPlane, uint64_t p, std::vector<Poly>& out)
{
    const size_t n = in.v.size();
    SmallVector<int, 8> sv(n);
    bool pos = false, neg = false;
    for (size_t i = 0; i < n; ++i) {
        sv[i] = sign(in.v[i], p);
        pos |= sv[i] > 0;
        neg |= sv[i] < 0;
    }
    if (!(pos && neg)) {
        out.push_back(std::move(in));
        return;
    }
    const Plane* pl = planeById(p);
    // Cut points on crossing edges.
    SmallVector<int, 8> cut(n, -1);
    for (size_t i = 0; i < n; ++i) {
        const size_t j = (i + 1) % n;
        if (sv[i] * sv[j] >= 0) continue;
        const Vert& a = mVerts[size_t(in.v[i])];
        const Vert& b = mVerts[size_t(in.v[j])];
        const double ha = pl->h(a.pos), hb = pl->h(b.pos);
        double t = (ha - hb) != 0 ? ha / (ha - hb) : 0.5;
        if (!(t > 0.0 && t < 1.0)) t = 0.5;
        const dvec3 x = a.pos + t * (b.pos - a.pos);
        PlaneList def{p};
        if (polyPlane != 0) def.push_back(polyPlane);
        if (!(in.lab[i] & kBoundaryLabel)) def.push_back(in.lab[i]);
        cut[i] = makeVertex(uint8_t(a.support | b.support), def, x);
    }
    for (int keep : {1, -1}) {
        Poly o;
        for (size_t i = 0; i < n; ++i) {
            const size_t j = (i + 1) % n;
            const int sa = keep * sv[i], sb = keep * sv[j];
            if (sa >= 0) {
                o.v.push_back(in.v[i]);
                o.lab.push_back(sa == 0 && sb < 0 ? p : in.lab[i]);
            }
            if (cut[i] >= 0) {
                o.v.push_back(cut[i]);
                o.lab.push_back(sa > 0 ? p : in.lab[i]);
            }
        }
        // Keep only pieces with a vertex strictly on the kept side.
        bool strict = false;
        for (size_t i = 0; i < n; ++i) strict |= keep * sv[i] > 0;
        if (strict && o.v.size() >= 3) out.push_back(std::move(o));
    }
}

void RemeshKernel::pushSimple(Poly o, std::vector<Poly>& out)
{
    // Conformity can put a vertex on an edge of a piece that already has it
    // (near-coincident lines whose points are one vertex by name: the offset
    // planes of two mitred quads on their mitre): the piece then runs out
    // along a line and back through that vertex, a loop plus a spike of zero
    // area, and its classification by its first off-plane vertex could be
    // the spike's. Split it at the repeat; loops of fewer than 3 go.
    const size_t n = o.v.size();
    for (size_t i = 0; i < n; ++i)
        for (size_t j = i + 1; j < n; ++j) {
            if (o.v[i] != o.v[j]) continue;
            Poly a, b;
            for (size_t k = i; k < j; ++k) {
                a.v.push_back(o.v[k]);
                a.lab.push_back(o.lab[k]);
            }
            for (size_t k = j; k < n + i; ++k) {
                b.v.push_back(o.v[k % n]);
                b.lab.push_back(o.lab[k % n]);
            }
            if (a.v.size() >= 3) pushSimple(std::move(a), out);
            if (b.v.size() >= 3) pushSimple(std::move(b), out);
            return;
        }
    out.push_back(std::move(o));
}

void RemeshKernel::remesh(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out)
{
    out.clear();
    mPrism = prism;
    mCell = cell;
    mCellQuads = &quads;
    std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash> cellIndex;
    const int parity = cellParity(cell.x(), cell.y(), cell.z());
    const auto& tets = cellTets(parity);
    for (int t = 0; t < kTetsPerCell; ++t) {
        mTet = t;
        for (int i = 0; i < 4; ++i) {
            const int c = tets[size_t(t)][size_t(i)];
            const Coord g = cell + Coord(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            mT.p[i] = dvec3(g.x(), g.y(), g.z());
            mT.id[i] = gridVertexId(g.x(), g.y(), g.z());
            // As the isosurface: outside the scan box, the background and outside.
            const bool inBox = g.x() >= 0 && g.y() >= 0 && g.z() >= 0 && g.x() < mDims.x() && g.y() < mDims.y() &&
                               g.z() < mDims.z();
            mT.value[i] = inBox ? value(g) : mBackground;
            mT.inside[i] = inBox && mT.value[i] >= mIso;
        }
        remeshTet(out, cellIndex);
    }
    if (mPrism) splitPinches(cell, out);
}

namespace {

void splitPinches(const openvdb::Coord& cell, CutCellGeometry& out)
{
    const uint32_t nv = uint32_t(out.vertexIds.size());
    const size_t nt = out.indices.size() / 3;
    // Triangles around each tet-inside vertex (only its tet's triangles can use it).
    std::vector<std::vector<uint32_t>> around;
    std::vector<int32_t> slot(nv, -1);
    for (size_t t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = out.indices[3 * t + size_t(k)];
            if (out.vertexIds[v].dim != 3) continue;
            if (slot[v] < 0) {
                slot[v] = int32_t(around.size());
                around.emplace_back();
            }
            around[size_t(slot[v])].push_back(uint32_t(t));
        }
    for (uint32_t v = 0; v < nv; ++v) {
        if (slot[v] < 0) continue;
        const std::vector<uint32_t>& tris = around[size_t(slot[v])];
        if (tris.size() < 6) continue; // two fans need at least 3 triangles each
        // Link edges b -> c of the triangles (v, b, c); fans = their components.
        std::vector<std::pair<uint32_t, uint32_t>> link(tris.size());
        for (size_t i = 0; i < tris.size(); ++i) {
            const uint32_t* tri = &out.indices[3 * tris[i]];
            const int k = tri[0] == v ? 0 : tri[1] == v ? 1 : 2;
            link[i] = {tri[(k + 1) % 3], tri[(k + 2) % 3]};
        }
        std::vector<int> fan(tris.size(), -1);
        int fans = 0;
        for (size_t s = 0; s < tris.size(); ++s) {
            if (fan[s] >= 0) continue;
            std::vector<size_t> stack{s};
            fan[s] = fans;
            while (!stack.empty()) {
                const size_t a = stack.back();
                stack.pop_back();
                for (size_t b = 0; b < tris.size(); ++b)
                    if (fan[b] < 0 && (link[b].first == link[a].second || link[b].second == link[a].first ||
                                       link[b].first == link[a].first || link[b].second == link[a].second)) {
                        fan[b] = fans;
                        stack.push_back(b);
                    }
            }
            ++fans;
        }
        if (fans < 2) continue;
        // Each fan must be one closed cycle (a disc); otherwise leave it to the
        // local check, which refuses the cell.
        bool discs = true;
        for (int f = 0; f < fans && discs; ++f) {
            std::map<uint32_t, int> out1, in1;
            for (size_t i = 0; i < tris.size(); ++i)
                if (fan[i] == f) {
                    ++out1[link[i].first];
                    ++in1[link[i].second];
                }
            for (const auto& [u, c] : out1) discs = discs && c == 1 && in1[u] == 1;
            discs = discs && out1.size() == in1.size();
        }
        if (!discs) continue;
        // Fan 0 (the one with the first triangle) keeps the vertex; each other
        // fan gets a copy at the same position, told apart by a pinch tag.
        for (int f = 1; f < fans; ++f) {
            CutVertexId id = out.vertexIds[v];
            if (id.tagCount >= id.tags.size())
                throw std::runtime_error("remesh: a pinch point whose vertex has no free tag in cell " + cellText(cell));
            id.tags[id.tagCount++] = kPinchTag | uint64_t(f);
            const uint32_t copy = uint32_t(out.vertexIds.size());
            out.vertexIds.push_back(id);
            out.indexPositions.push_back(out.indexPositions[v]);
            for (size_t i = 0; i < tris.size(); ++i)
                if (fan[i] == f)
                    for (int k = 0; k < 3; ++k)
                        if (out.indices[3 * tris[i] + size_t(k)] == v) out.indices[3 * tris[i] + size_t(k)] = copy;
        }
    }
}

} // namespace

/// Even permutation of (0,1,2,3) starting with the given 1 or 2 entries (as the isosurface tables).
static std::array<int, 4> evenPerm(std::initializer_list<int> first)
{
    std::array<int, 4> p{};
    int n = 0;
    for (int f : first) p[size_t(n++)] = f;
    for (int v = 0; v < 4; ++v)
        if (std::find(p.begin(), p.begin() + n, v) == p.begin() + n) p[size_t(n++)] = v;
    int inv = 0;
    for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) inv += p[size_t(a)] > p[size_t(b)];
    if (inv & 1) std::swap(p[2], p[3]);
    return p;
}

void RemeshKernel::remeshTet(CutCellGeometry& out, std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash>& cellIndex)
{
    // No solid in the tet (all four values below the isovalue): P is empty,
    // so there is neither an iso piece nor a cap (caps are kept inside P;
    // prism faces inside the solid). Most cells of a cut through a head are
    // air; they cost nothing now.
    if (!mT.inside[0] && !mT.inside[1] && !mT.inside[2] && !mT.inside[3]) return;
    mVerts.clear();
    mVertHash.clear();
    if (mHashIndexed) {
        mHashChain.clear();
        mNextSameHash.clear();
        mNear.clear();
        mHashIndexed = false;
    }
    mSignTab.clear();
    mSignStride = 0;
    mSignCap = 0;
    mQuads.clear();
    mPlanes.clear();
    mTriCount = 0;
    std::fill(std::begin(mFaceTri), std::end(mFaceTri), -1);

    // Quads whose region can reach the tet.
    for (const QuadGeom& q : *mCellQuads) {
        auto crosses = [&](const Plane& p) {
            bool pos = false, neg = false;
            for (int i = 0; i < 4; ++i) {
                const double h = p.h(mT.p[i]), e = epsAt(mT.p[i]);
                pos |= h >= -e;
                neg |= h <= e;
            }
            return pos && neg;
        };
        if (!mPrism && !crosses(q.pi)) continue;
        bool reach = true;
        for (const auto& s : q.sides) {
            bool any = false;
            for (int i = 0; i < 4; ++i) any |= s.orient * s.plane.h(mT.p[i]) >= -epsAt(mT.p[i]);
            reach = reach && any;
        }
        if (!reach) continue;
        mQuads.push_back(&q);
        if (!mPrism) mPlanes.push_back({q.id, q.pi});
        for (const auto& s : q.sides) mPlanes.push_back({s.id, s.plane});
    }

    // Marching-tetrahedra triangles of the tet (as the isosurface tables).
    int ni = 0, ins[4], outs[4], no = 0;
    for (int i = 0; i < 4; ++i) {
        if (mT.inside[i]) ins[ni++] = i;
        else outs[no++] = i;
    }
    if (ni == 0) return; // nothing solid here
    SmallVector<SmallVector<std::array<int, 2>, 4>, 2> triEdges;
    if (ni == 1 || ni == 3) {
        const int lone = ni == 1 ? ins[0] : outs[0];
        const auto p = evenPerm({lone});
        const int a = p[0], b = p[1], c = p[2], d = p[3];
        if (ni == 1) triEdges.push_back({{a, b}, {a, c}, {a, d}});
        else triEdges.push_back({{a, b}, {a, d}, {a, c}});
    } else if (ni == 2) {
        const auto p = evenPerm({ins[0], ins[1]});
        const int a = p[0], b = p[1], c = p[2], d = p[3];
        // The marching-tetrahedra quad; when its (clamped) corners are not
        // coplanar it is the two triangles of the isosurface, a fold.
        const dvec3 pac = mtPoint(a, c), pad = mtPoint(a, d), pbd = mtPoint(b, d), pbc = mtPoint(b, c);
        const dvec3 nrm = glm::cross(pad - pac, pbd - pac);
        const double dev = glm::dot(nrm, pbc - pac) / glm::length(nrm);
        if (std::abs(dev) <= 1e-7) {
            triEdges.push_back({{a, c}, {a, d}, {b, d}, {b, c}});
        } else {
            triEdges.push_back({{a, c}, {a, d}, {b, d}});
            triEdges.push_back({{a, c}, {b, d}, {b, c}});
        }
    }
    mTriCount = int(triEdges.size());
    // Iso planes first (so ISO_A/B sort first in mPlanes too).
    SmallVector<dvec3, 4> triPts[2];
    for (int k = 0; k < mTriCount; ++k) {
        for (const auto& e : triEdges[size_t(k)]) triPts[k].push_back(mtPoint(e[0], e[1]));
        dvec3 nrm(0.0);
        const size_t n = triPts[k].size();
        for (size_t c = 0; c < n; ++c) nrm += glm::cross(triPts[k][c], triPts[k][(c + 1) % n]); // Newell
        const double len = glm::length(nrm);
        mTriPlane[k].n = len > 0 ? -nrm / len : dvec3(0.0);
        dvec3 centre(0.0);
        for (const dvec3& q : triPts[k]) centre += q / double(n);
        mTriPlane[k].d = glm::dot(mTriPlane[k].n, centre);
        mPlanes.push_back({kIsoA + uint64_t(k), mTriPlane[k]});
    }
    std::sort(mPlanes.begin(), mPlanes.end(),
              [](const std::pair<uint64_t, Plane>& a, const std::pair<uint64_t, Plane>& b) { return a.first < b.first; });
    mPlanes.erase(std::unique(mPlanes.begin(), mPlanes.end(),
                              [](const std::pair<uint64_t, Plane>& a, const std::pair<uint64_t, Plane>& b) {
                                  return a.first == b.first;
                              }),
                  mPlanes.end());
    mSignStride = mPlanes.size();
    buildPlaneSlots();
    if (mTriCount == 2) mFoldConvex = mTriPlane[0].h(triPts[1][2]) >= 0;

    struct Surface
    {
        uint64_t plane;      // supporting plane id (ISO_A/B or a quad plane)
        const QuadGeom* quad; // cap: its quad
        /// Kerf > 0: further prisms with this very face plane (a rim shared
        /// along the stroke, facing the same way): one surface, whose pieces
        /// are kept where any of these prisms' rule keeps them, so the faces
        /// merge into one region (no corner where one prism's face ends
        /// inside the other's, which the neighbouring cell need not see).
        SmallVector<const QuadGeom*, 2> also;
        int sides;           // cap: bit 0 = + side output, bit 1 = - side output
        dvec3 normal;        // reference normal (pieces are CCW around it)
        Poly poly;
    };
    SmallVector<Surface, 8> surfaces;
    for (int k = 0; k < mTriCount; ++k) {
        Surface s;
        s.plane = kIsoA + uint64_t(k);
        s.quad = nullptr;
        s.sides = 1;
        s.normal = -mTriPlane[k].n;
        const size_t n = triEdges[size_t(k)].size();
        mTriVerts[k].clear();
        mTriEdgeMasks[k].clear();
        for (const auto& e : triEdges[size_t(k)]) mTriEdgeMasks[k].push_back(uint8_t(1 << e[0] | 1 << e[1]));
        for (size_t c = 0; c < n; ++c) {
            const auto& e = triEdges[size_t(k)][c];
            s.poly.v.push_back(makeVertex(uint8_t(1 << e[0] | 1 << e[1]), {kIsoA + uint64_t(k)}, triPts[k][c]));
            mTriVerts[k].push_back(s.poly.v.back());
        }
        for (size_t c = 0; c < n; ++c) {
            const auto& e0 = triEdges[size_t(k)][c];
            const auto& e1 = triEdges[size_t(k)][(c + 1) % n];
            const uint8_t m = uint8_t(1 << e0[0] | 1 << e0[1] | 1 << e1[0] | 1 << e1[1]);
            if (m == 15) {
                s.poly.lab.push_back(kIsoA + uint64_t(1 - k));
            } else {
                s.poly.lab.push_back(kBoundaryLabel | m);
                int f = 0;
                while (m >> f & 1) ++f;
                mFaceTri[f] = k;
            }
        }
        surfaces.push_back(std::move(s));
    }
    // Caps: the quad's plane through the tet; with kerf, every face plane of
    // the prism (one-sided, its surface normal pointing into the prism).
    struct FacePlane
    {
        const QuadGeom* q;
        uint64_t id;
        Plane plane;
        dvec3 normal; // surface normal (zero kerf: reference normal of the two-sided cap)
    };
    SmallVector<FacePlane, 8> facePlanes;
    for (const QuadGeom* q : mQuads) {
        if (!mPrism) {
            facePlanes.push_back({q, q->id, q->pi, q->pi.n});
            continue;
        }
        for (const auto& sd : q->sides) facePlanes.push_back({q, sd.id, sd.plane, sd.orient * sd.plane.n});
    }
    for (const FacePlane& fp : facePlanes) {
        const QuadGeom* q = fp.q;
        if (mPrism) {
            auto same = std::find_if(surfaces.begin(), surfaces.end(), [&](const Surface& o) {
                return o.quad && o.plane == fp.id && glm::dot(o.normal, fp.normal) > 0;
            });
            if (same != surfaces.end()) {
                same->also.push_back(q);
                continue;
            }
        }
        double h[4];
        int on = 0;
        for (int i = 0; i < 4; ++i) {
            h[i] = fp.plane.h(mT.p[i]);
            if (std::abs(h[i]) <= epsAt(mT.p[i])) {
                h[i] = 0;
                ++on;
            }
        }
        SmallVector<std::pair<int, dvec3>, 8> pts; // vertex, position
        for (int i = 0; i < 4; ++i)
            if (h[i] == 0) pts.push_back({makeVertex(uint8_t(1 << i), {fp.id}, mT.p[i]), mT.p[i]});
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j) {
                if (!(h[i] * h[j] < 0)) continue;
                int a = i, b = j;
                if (mT.id[b] < mT.id[a]) std::swap(a, b);
                const double t = h[a] / (h[a] - h[b]);
                const dvec3 x = mT.p[a] + t * (mT.p[b] - mT.p[a]);
                pts.push_back({makeVertex(uint8_t(1 << i | 1 << j), {fp.id}, x), x});
            }
        if (pts.size() < 3) continue;
        Surface s;
        s.plane = fp.id;
        s.quad = q;
        s.normal = fp.normal;
        s.sides = 3;
        if (on == 3) { // the plane is a tet face: only the cap facing away from this tet
            int f = 0;
            while (h[f] == 0) ++f;
            s.sides = h[f] > 0 ? 1 : 2;
            if (mPrism && glm::dot(fp.normal, fp.plane.n) * h[f] > 0) continue; // faces into this tet
        }
        if (mPrism) s.sides = 1;
        dvec3 c(0.0);
        for (const auto& p : pts) c += p.second;
        c /= double(pts.size());
        dvec3 e1 = glm::normalize(pts[0].second - c);
        const dvec3 e2 = glm::cross(s.normal, e1);
        {
            // By angle about the centre (each angle computed once).
            SmallVector<std::pair<double, std::pair<int, dvec3>>, 8> byAngle;
            for (const auto& p : pts)
                byAngle.push_back({std::atan2(glm::dot(p.second - c, e2), glm::dot(p.second - c, e1)), p});
            std::sort(byAngle.begin(), byAngle.end(),
                      [](const auto& a, const auto& b) { return a.first < b.first; });
            for (size_t i = 0; i < pts.size(); ++i) pts[i] = byAngle[i].second;
        }
        for (size_t i = 0; i < pts.size(); ++i) {
            s.poly.v.push_back(pts[i].first);
            const uint8_t m = uint8_t(mVerts[size_t(pts[i].first)].support |
                                      mVerts[size_t(pts[(i + 1) % pts.size()].first)].support);
            s.poly.lab.push_back(kBoundaryLabel | m);
        }
        surfaces.push_back(std::move(s));
    }

    // Split order: iso planes, junction planes, then the rest by id.
    struct SplitPlane
    {
        uint64_t id;
        const QuadGeom* owner; // restricts a quad's plane / rim side to its junction zone
    };
    SmallVector<SplitPlane, 16> splitOrder;
    for (const auto& pl : mPlanes)
        if (pl.first <= kIsoB) splitOrder.push_back({pl.first, nullptr});
    for (const auto& pl : mPlanes)
        if (pl.first > kIsoB && (pl.first & 15) == kJunctionKind) splitOrder.push_back({pl.first, nullptr});
    for (const auto& pl : mPlanes) {
        if (pl.first <= kIsoB || (pl.first & 15) == kJunctionKind) continue;
        const QuadGeom* owner = nullptr;
        for (const QuadGeom* q : mQuads)
            if ((q->id >> 4) == (pl.first >> 4)) owner = q;
        // Prisms: a rim plane shared along the stroke by several quads here
        // splits everywhere (each of them needs it).
        if (mPrism && owner) {
            int users = 0;
            for (const QuadGeom* q : mQuads)
                for (const auto& sd : q->sides) users += sd.id == pl.first;
            if (users > 1) owner = nullptr;
        }
        splitOrder.push_back({pl.first, owner});
    }

    // Arrangements, classification, tagged loops.
    std::vector<Node>& nodes = mNodes;
    nodes.clear();
    // The nodes of each vertex, chained in creation order (nodeOf returns
    // the first with these tags, as a scan of `nodes` would).
    std::vector<int>& nodeHead = mNodeHead;
    std::vector<int>& nodeNext = mNodeNext;
    nodeHead.clear();
    nodeNext.clear();
    auto nodeOf = [&](int vert, Tags& tags) {
        std::sort(tags.begin(), tags.end());
        if (size_t(vert) >= nodeHead.size()) nodeHead.resize(mVerts.size() + 16, -1);
        int last = -1;
        for (int i = nodeHead[size_t(vert)]; i >= 0; i = nodeNext[size_t(i)]) {
            if (nodes[size_t(i)].tags == tags) return i;
            last = i;
        }
        nodes.emplace_back();
        nodes.back().vert = vert;
        nodes.back().tags.assign(tags.begin(), tags.end());
        nodeNext.push_back(-1);
        const int id = int(nodes.size() - 1);
        (last < 0 ? nodeHead[size_t(vert)] : nodeNext[size_t(last)]) = id;
        return id;
    };
    struct Loop
    {
        SmallVector<int, 16> nodes;
        SmallVector<uint64_t, 16> labels; // labels[i]: edge nodes[i] -> nodes[i+1]
    };
    struct Region
    {
        dvec3 normal;
        SmallVector<Loop, 1> loops;
        const QuadGeom* cap = nullptr; // cap regions: the quad, and the side
        int side = 0;
    };
    SmallVector<Region, 8> regions;

    for (Surface& s : surfaces) {
        std::vector<Poly>& pieces = mPieces;
        std::vector<Poly>& next = mNextPieces;
        pieces.clear();
        pieces.push_back(s.poly);
        auto pieceSign = [&](const Poly& p, uint64_t id) {
            for (int v : p.v) {
                const int sg = sign(v, id);
                if (sg != 0) return sg;
            }
            return 0;
        };
        for (const SplitPlane& sp : splitOrder) {
            if (sp.id == s.plane) continue;
            if (!s.quad && (sp.id == kIsoA || sp.id == kIsoB)) continue;
            next.clear();
            for (Poly& p : pieces) {
                // A quad's plane and rim sides only split inside its junction zone,
                // so near-coincident planes of consecutive quads never meet there.
                bool outside = false;
                if (sp.owner)
                    for (const auto& sd : sp.owner->sides)
                        if (sd.partner >= 0 && sd.orient * pieceSign(p, sd.id) < 0) outside = true;
                if (outside) next.push_back(std::move(p));
                else splitPoly(std::move(p), s.plane, sp.id, next);
            }
            pieces.swap(next);
        }
        // Conformity: restricted splits end on junction lines; put their end
        // points on the neighbouring pieces' edges too (no T-junction inside).
        {
            SmallVector<int, 32> all;
            for (const Poly& p : pieces) all.insert(all.end(), p.v.begin(), p.v.end());
            std::sort(all.begin(), all.end());
            all.erase(std::unique(all.begin(), all.end()), all.end());
            // The vertices of `all` on each edge label's line (ascending),
            // found once per label rather than once per edge: a cell where
            // many quads pivot has thousands of edges and vertices here.
            // onLabel: (label, begin, end) of its vertices in mOnLine.
            SmallVector<std::array<uint64_t, 3>, 8> onLabel;
            std::vector<int>& onLine = mOnLine;
            onLine.clear();
            auto onLineOf = [&](uint64_t L) -> std::pair<const int*, const int*> {
                for (const auto& e : onLabel)
                    if (e[0] == L) return {onLine.data() + e[1], onLine.data() + e[2]};
                const size_t begin = onLine.size();
                for (int x : all) {
                    const Vert& vx = mVerts[size_t(x)];
                    const bool on = (L & kBoundaryLabel) ? (vx.support & ~uint8_t(L & 15)) == 0 : sign(x, L) == 0;
                    if (on) onLine.push_back(x);
                }
                onLabel.push_back({L, begin, onLine.size()});
                return {onLine.data() + begin, onLine.data() + onLine.size()};
            };
            for (Poly& p : pieces) {
                Poly q;
                const size_t n = p.v.size();
                for (size_t k = 0; k < n; ++k) {
                    const int u = p.v[k], w = p.v[(k + 1) % n];
                    const uint64_t L = p.lab[k];
                    q.v.push_back(u);
                    q.lab.push_back(L);
                    const dvec3 a = mVerts[size_t(u)].pos, d = mVerts[size_t(w)].pos - a;
                    const double dd = glm::dot(d, d);
                    SmallVector<std::pair<double, int>, 4> on;
                    const auto [xsBegin, xsEnd] = onLineOf(L);
                    for (const int* it = xsBegin; it != xsEnd; ++it) {
                        const int x = *it;
                        if (x == u || x == w) continue;
                        const Vert& vx = mVerts[size_t(x)];
                        const double t = glm::dot(vx.pos - a, d) / dd;
                        if (!(t > 1e-12 && t < 1 - 1e-12)) continue;
                        if (glm::length(vx.pos - (a + t * d)) > 1e-9 * (1 + std::sqrt(dd))) continue;
                        on.push_back({t, x});
                    }
                    std::sort(on.begin(), on.end());
                    for (const auto& o : on) {
                        q.v.push_back(o.second);
                        q.lab.push_back(L);
                    }
                }
                p = std::move(q);
            }
            // A piece folded onto itself (it runs out along a line and back
            // through the same vertex): its loop and the spike, apart.
            next.clear();
            for (Poly& p : pieces) pushSimple(std::move(p), next);
            pieces.swap(next);
        }
        // Classification.
        SmallVector<char, 32> kept(pieces.size(), 1);
        if (mPrism) {
            // Kerf > 0 (DESIGN's sketch): iso pieces outside every closed prism;
            // prism face pieces inside closed P, on their own closed face and
            // outside every other closed prism, except that of two coincident
            // faces facing the same way the lower quad's is kept.
            auto insidePrism = [&](const Poly& p, const QuadGeom& q) {
                for (const auto& sd : q.sides)
                    if (sd.orient * pieceSign(p, sd.id) < 0) return false;
                return true;
            };
            for (size_t i = 0; i < pieces.size(); ++i) {
                const Poly& p = pieces[i];
                bool ok = true;
                if (!s.quad) {
                    for (const QuadGeom* q : mQuads) ok = ok && !insidePrism(p, *q);
                } else {
                    for (int v : p.v) ok = ok && member(v) >= 0;
                    auto keptBy = [&](const QuadGeom* own) {
                        bool k = insidePrism(p, *own);
                        for (const QuadGeom* q : mQuads) {
                            if (!k) break;
                            if (q == own || !insidePrism(p, *q)) continue;
                            bool sameFace = false;
                            for (const auto& sd : q->sides)
                                sameFace = sameFace || (pieceSign(p, sd.id) == 0 &&
                                                        glm::dot(sd.orient * sd.plane.n, s.normal) > 0);
                            k = sameFace && q->id > own->id;
                        }
                        return k;
                    };
                    bool any = ok && keptBy(s.quad);
                    for (const QuadGeom* own : s.also) any = any || (ok && keptBy(own));
                    ok = any;
                }
                kept[i] = ok;
            }
        } else if (s.quad) {
            for (size_t i = 0; i < pieces.size(); ++i) {
                bool ok = true;
                for (int v : pieces[i].v) ok = ok && member(v) >= 0;
                for (const auto& sd : s.quad->sides) ok = ok && sd.orient * pieceSign(pieces[i], sd.id) >= 0;
                kept[i] = ok;
            }
        }
        // Steiner midpoints on slit chords between rim points (see needsMidpoint).
        for (size_t i = 0; i < pieces.size(); ++i) {
            if (!kept[i]) continue;
            Poly& p = pieces[i];
            for (size_t k = 0; k < p.v.size(); ++k) {
                const int u = p.v[k], w = p.v[(k + 1) % p.v.size()];
                for (const QuadGeom* r : mQuads) {
                    if (!needsMidpoint(u, w, *r)) continue;
                    const Vert &vu = mVerts[size_t(u)], &vw = mVerts[size_t(w)];
                    uint64_t hu = CutVertexIdHash()(vu.key) >> 2 | uint64_t(1) << 62;
                    uint64_t hw = CutVertexIdHash()(vw.key) >> 2 | uint64_t(1) << 62;
                    PlaneList planes{kMid, r->id, std::min(hu, hw), std::max(hu, hw)};
                    const uint8_t sup = uint8_t(vu.support | vw.support);
                    if (bits(sup) < 4) {
                        const bool isoU = vu.key.planeCount && vu.key.planes[0] == kIso;
                        const bool isoW = vw.key.planeCount && vw.key.planes[0] == kIso;
                        if (isoU && isoW) planes.push_back(kIso);
                    }
                    const int m = makeSteiner(sup, planes, 0.5 * (vu.pos + vw.pos));
                    p.v.insert(p.v.begin() + long(k) + 1, m);
                    p.lab.insert(p.lab.begin() + long(k) + 1, p.lab[k]);
                    ++k;
                    break;
                }
            }
        }
        for (int side : {1, -1}) {
            if (s.quad && !mPrism ? !(s.sides & (side > 0 ? 1 : 2)) : side < 0) continue;
            // Slit edges: on another quad's plane inside that quad.
            auto isSlit = [&](int a, int b) {
                if (mPrism) return false;
                for (const QuadGeom* r : mQuads) {
                    if (r == s.quad) continue;
                    if (sign(a, r->id) == 0 && sign(b, r->id) == 0 && inExtentClosed(a, *r) && inExtentClosed(b, *r))
                        return true;
                }
                return false;
            };
            // Union-find over kept pieces across non-slit shared edges: each
            // later use of an edge joins its piece to the edge's first piece.
            std::vector<int>& parent = mParent;
            parent.resize(pieces.size());
            for (size_t i = 0; i < parent.size(); ++i) parent[i] = int(i);
            auto find = [&](int x) {
                int r = x;
                while (parent[size_t(r)] != r) r = parent[size_t(r)];
                while (parent[size_t(x)] != r) x = std::exchange(parent[size_t(x)], r);
                return r;
            };
            auto& uses = mEdgeUses; // (lower vertex, higher vertex, sequence, piece)
            uses.clear();
            for (size_t i = 0; i < pieces.size(); ++i) {
                if (!kept[i]) continue;
                const Poly& p = pieces[i];
                for (size_t k = 0; k < p.v.size(); ++k) {
                    int a = p.v[k], b = p.v[(k + 1) % p.v.size()];
                    if (a > b) std::swap(a, b);
                    uses.push_back({a, b, int(uses.size()), int(i)});
                }
            }
            auto& order = mEdgeOrder; // first use of the same edge, per use in sequence
            order.assign(uses.size(), -1);
            {
                auto& sorted = mEdgeSorted;
                sorted.assign(uses.begin(), uses.end());
                std::sort(sorted.begin(), sorted.end());
                for (size_t k = 1; k < sorted.size(); ++k) {
                    const auto& f = sorted[k - 1];
                    const auto& g = sorted[k];
                    if (f[0] == g[0] && f[1] == g[1]) order[size_t(g[2])] = order[size_t(f[2])] >= 0 ? order[size_t(f[2])] : f[3];
                }
            }
            for (const auto& u : uses)
                if (order[size_t(u[2])] >= 0 && !isSlit(u[0], u[1])) parent[size_t(find(u[3]))] = find(order[size_t(u[2])]);
            // Directed edges per region, with tagged nodes.
            auto stripSide = [&](const Poly& piece, const QuadGeom* r, int vert) -> int {
                if (r == s.quad) return side;
                for (const auto& sd : r->sides) {
                    if (sd.partnerId == 0 || sign(vert, sd.id) != 0) continue;
                    const QuadGeom* o = quadById(sd.partnerId);
                    if (!o) continue;
                    if (sd.orient * pieceSign(piece, sd.id) < 0) { // the piece is on the partner's half
                        if (o == s.quad) return side;
                        const int sg = pieceSign(piece, o->id);
                        if (sg == 0) throw std::runtime_error("remesh: coplanar overlapping quads in cell " + cellText(mCell));
                        return sg;
                    }
                }
                const int sg = pieceSign(piece, r->id);
                if (sg == 0) throw std::runtime_error("remesh: coplanar overlapping quads in cell " + cellText(mCell));
                return sg;
            };
            // Per root piece (ascending): (from node, to node, label).
            auto& regionEdges = mRegionEdges;
            if (regionEdges.size() < pieces.size()) regionEdges.resize(pieces.size());
            for (size_t i = 0; i < pieces.size(); ++i) regionEdges[i].clear();
            for (size_t i = 0; i < pieces.size(); ++i) {
                if (!kept[i]) continue;
                const Poly& p = pieces[i];
                const size_t n = p.v.size();
                SmallVector<int, 16> pn(n);
                for (size_t k = 0; k < n; ++k) {
                    Tags tags;
                    for (const QuadGeom* r : mQuads) {
                        if (mPrism) break;
                        if (sign(p.v[k], r->id) != 0 || !inSlitOpen(p.v[k], *r) || onStripRim(p.v[k], *r)) continue;
                        const int sg = stripSide(p, r, p.v[k]);
                        tags.push_back(r->id << 1 | (sg < 0 ? 1u : 0u));
                    }
                    pn[k] = nodeOf(p.v[k], tags);
                }
                auto& list = regionEdges[size_t(find(int(i)))];
                const bool reverse = s.quad && !mPrism && side > 0;
                for (size_t k = 0; k < n; ++k) {
                    const int a = pn[k], b = pn[(k + 1) % n];
                    if (reverse) list.push_back({b, a, int64_t(p.lab[k])});
                    else list.push_back({a, b, int64_t(p.lab[k])});
                }
            }
            const dvec3 outNormal = s.quad && !mPrism && side > 0 ? -s.normal : s.normal;
            for (size_t root = 0; root < pieces.size(); ++root) {
                const auto& edges = regionEdges[root];
                if (edges.empty()) continue;
                // Boundary edges: those whose reverse is not in the region.
                auto& keys = mBoundaryKeys;
                keys.clear();
                for (const auto& e : edges) keys.push_back({int(e[0]), int(e[1])});
                std::sort(keys.begin(), keys.end());
                SmallVector<std::array<int64_t, 3>, 16> bnd;
                for (const auto& e : edges)
                    if (!std::binary_search(keys.begin(), keys.end(), std::pair<int, int>(int(e[1]), int(e[0]))))
                        bnd.push_back(e);
                if (bnd.empty()) continue;
                dvec3 e1 = std::abs(outNormal.x) < 0.9 ? dvec3(1, 0, 0) : dvec3(0, 1, 0);
                e1 = glm::normalize(e1 - outNormal * glm::dot(outNormal, e1));
                const dvec3 e2 = glm::cross(outNormal, e1);
                auto p2 = [&](int node) {
                    const dvec3& x = mVerts[size_t(nodes[size_t(node)].vert)].pos;
                    return Vec2{glm::dot(x, e1), glm::dot(x, e2)};
                };
                SmallVector<char, 16> used(bnd.size(), 0);
                Region region;
                region.normal = outNormal;
                region.cap = s.quad;
                region.side = side;
                for (size_t start = 0; start < bnd.size(); ++start) {
                    if (used[start]) continue;
                    Loop loop;
                    size_t cur = start;
                    for (size_t guard = 0; guard <= bnd.size(); ++guard) {
                        used[cur] = 1;
                        loop.nodes.push_back(int(bnd[cur][0]));
                        loop.labels.push_back(uint64_t(bnd[cur][2]));
                        const int at = int(bnd[cur][1]);
                        if (at == loop.nodes.front()) break;
                        // Next: unused edge from `at`, the most clockwise from the way back.
                        size_t best = bnd.size();
                        double bestAngle = 1e9;
                        const Vec2 pa = p2(at), pb = p2(int(bnd[cur][0]));
                        const double back = std::atan2(pb.y - pa.y, pb.x - pa.x);
                        for (size_t k = 0; k < bnd.size(); ++k) {
                            if (used[k] || bnd[k][0] != at) continue;
                            const Vec2 pc = p2(int(bnd[k][1]));
                            double ang = back - std::atan2(pc.y - pa.y, pc.x - pa.x);
                            while (ang <= 0) ang += 2 * M_PI;
                            while (ang > 2 * M_PI) ang -= 2 * M_PI;
                            if (ang < bestAngle) {
                                bestAngle = ang;
                                best = k;
                            }
                        }
                        if (best == bnd.size()) {
                            throw std::runtime_error("remesh: open boundary loop in cell " + cellText(mCell));
                        }
                        cur = best;
                    }
                    region.loops.push_back(std::move(loop));
                }
                regions.push_back(std::move(region));
            }
        }
    }

    // Corners: a node is kept when it is a corner of some loop of the tet.
    // A point of a quad's rim on the tet's boundary (zero kerf) is always
    // kept: where the rim lies in a tet face (a blade edge exactly on a grid
    // plane), the tet on the quad's side ends its slit there while the tet on
    // the other side sees a straight boundary through it; both must keep it.
    auto onOwnRim = [&](const CutVertexId& k) {
        if (mPrism || k.dim == 3) return false;
        for (int i = 0; i < k.planeCount; ++i) {
            const uint64_t p = k.planes[size_t(i)];
            const uint64_t kind = p & 15;
            if (p < (uint64_t(1) << 36) || kind < 1 || kind > 4) continue;
            if (std::binary_search(k.planes.begin(), k.planes.begin() + k.planeCount, p & ~uint64_t(15))) return true;
        }
        return false;
    };
    SmallVector<char, 64> corner(nodes.size(), 0);
    for (const Region& r : regions) {
        for (const Loop& l : r.loops) {
            const size_t n = l.nodes.size();
            for (size_t i = 0; i < n; ++i) {
                const uint64_t in = l.labels[(i + n - 1) % n], outL = l.labels[i];
                bool c = in != outL;
                if (!c) {
                    const dvec3& a = mVerts[size_t(nodes[size_t(l.nodes[(i + n - 1) % n])].vert)].pos;
                    const dvec3& b = mVerts[size_t(nodes[size_t(l.nodes[i])].vert)].pos;
                    const dvec3& d = mVerts[size_t(nodes[size_t(l.nodes[(i + 1) % n])].vert)].pos;
                    c = glm::dot(b - a, d - b) < 0;
                }
                const Vert& vx = mVerts[size_t(nodes[size_t(l.nodes[i])].vert)];
                if (c || vx.steiner || onOwnRim(vx.key)) corner[size_t(l.nodes[i])] = 1;
            }
        }
    }

    // Triangulate each region.
    for (const Region& r : regions) {
        const dvec3& nrm = r.normal;
        dvec3 e1 = std::abs(nrm.x) < 0.9 ? dvec3(1, 0, 0) : dvec3(0, 1, 0);
        e1 = glm::normalize(e1 - nrm * glm::dot(nrm, e1));
        const dvec3 e2 = glm::cross(nrm, e1);
        std::vector<Vec2>& pts = mTriangulatePts;
        std::vector<int>& ptNode = mTriangulateNodes;
        pts.clear();
        ptNode.clear();
        std::vector<std::vector<int>> outers, holes;
        for (const Loop& l : r.loops) {
            std::vector<int> loop;
            for (int nd : l.nodes) {
                if (!corner[size_t(nd)]) continue;
                const dvec3& x = mVerts[size_t(nodes[size_t(nd)].vert)].pos;
                pts.push_back({glm::dot(x, e1), glm::dot(x, e2)});
                ptNode.push_back(nd);
                loop.push_back(int(pts.size() - 1));
            }
            if (loop.size() < 3) {
                if (loop.empty()) continue;
                throw std::runtime_error("remesh: degenerate boundary loop in cell " + cellText(mCell));
            }
            // A loop of (nearly) zero area is a slit inside the region (a blade
            // corner through the surface): a hole, whatever its rounding says.
            double perim = 0.0;
            for (size_t i = 0; i < loop.size(); ++i) {
                const Vec2 &a = pts[size_t(loop[i])], &b = pts[size_t(loop[(i + 1) % loop.size()])];
                perim += std::hypot(a.x - b.x, a.y - b.y);
            }
            const double area = signedArea(loop, pts);
            (area > 1e-9 * perim * perim ? outers : holes).push_back(loop);
        }
        if (outers.empty()) {
            if (holes.empty()) continue;
            throw std::runtime_error("remesh: region without outer loop in cell " + cellText(mCell));
        }
        std::vector<std::vector<std::vector<int>>> holesOf(outers.size());
        for (auto& h : holes) {
            size_t best = 0;
            if (outers.size() > 1) {
                Vec2 c{0, 0};
                for (int i : h) {
                    c.x += pts[size_t(i)].x / double(h.size());
                    c.y += pts[size_t(i)].y / double(h.size());
                }
                for (size_t o = 0; o < outers.size(); ++o) {
                    bool in = false;
                    const auto& L = outers[o];
                    for (size_t i = 0, j = L.size() - 1; i < L.size(); j = i++) {
                        const Vec2 &a = pts[size_t(L[i])], &b = pts[size_t(L[j])];
                        if ((a.y > c.y) != (b.y > c.y) && c.x < (b.x - a.x) * (c.y - a.y) / (b.y - a.y) + a.x) in = !in;
                    }
                    if (in) best = o;
                }
            }
            holesOf[best].push_back(h);
        }
        for (size_t o = 0; o < outers.size(); ++o) {
            std::vector<int> poly = outers[o];
            if (!holesOf[o].empty() && !bridgeHoles(poly, holesOf[o], pts))
                throw std::runtime_error("remesh: cannot bridge a hole in cell " + cellText(mCell));
            std::vector<int> tris;
            bool convex = r.cap && !mPrism && outers.size() == 1 && holesOf[o].empty();
            for (size_t i = 0; i < poly.size() && convex; ++i) {
                const Vec2 &a = pts[size_t(poly[(i + poly.size() - 1) % poly.size()])], &b = pts[size_t(poly[i])],
                           &c = pts[size_t(poly[(i + 1) % poly.size()])];
                // Straight within rounding counts as convex: the corners of a slit
                // chord's Steiner midpoint are collinear only up to rounding.
                convex = cross2(a, b, c) >= -1e-9 * std::hypot(b.x - a.x, b.y - a.y) * std::hypot(c.x - b.x, c.y - b.y);
            }
            // A triangle inside its own slit (every corner tagged with this
            // cap's side, so the other side's triangle shares no vertex)
            // needs no centre: a centre would add three triangles, and in a
            // region a few float ulps wide one of them has zero area once
            // rounded to float mm (seed 1021).
            const bool ownSlit = convex && poly.size() == 3 && std::all_of(poly.begin(), poly.end(), [&](int i) {
                const auto& tags = nodes[size_t(ptNode[size_t(i)])].tags;
                return std::binary_search(tags.begin(), tags.end(), r.cap->id << 1 | (r.side < 0 ? 1u : 0u));
            });
            if (ownSlit) {
                tris.insert(tris.end(), poly.begin(), poly.end());
            } else if (convex) {
                // A cap region: fan from a tagged centre, so no chord joins two rim
                // points (the two sides of the slit would share it).
                dvec3 centre(0.0);
                for (int i : poly) centre += mVerts[size_t(nodes[size_t(ptNode[size_t(i)])].vert)].pos / double(poly.size());
                const int cv = makeSteiner(15, {kCentroid, r.cap->id, uint64_t(&r - regions.data()) + 8}, centre);
                Tags tags{r.cap->id << 1 | (r.side < 0 ? 1u : 0u)};
                const int cn = nodeOf(cv, tags);
                pts.push_back({glm::dot(centre, e1), glm::dot(centre, e2)});
                ptNode.push_back(cn);
                const int ci = int(pts.size() - 1);
                for (size_t i = 0; i < poly.size(); ++i) {
                    tris.push_back(ci);
                    tris.push_back(poly[i]);
                    tris.push_back(poly[(i + 1) % poly.size()]);
                }
            } else if (!(mPrism && bestTriangulation(poly, pts, tris)) && !earClip(poly, pts, tris)) {
                throw std::runtime_error("remesh: triangulation failed in cell " + cellText(mCell));
            }
            for (int i : tris) {
                const Node& nd = nodes[size_t(ptNode[size_t(i)])];
                CutVertexId id = mVerts[size_t(nd.vert)].key;
                id.tagCount = uint8_t(std::min<size_t>(nd.tags.size(), id.tags.size()));
                if (nd.tags.size() > id.tags.size())
                    throw std::runtime_error("remesh: a point lies in more than 4 slits in cell " + cellText(mCell));
                for (size_t k = 0; k < nd.tags.size(); ++k) id.tags[k] = nd.tags[k];
                auto it = cellIndex.find(id);
                if (it == cellIndex.end()) {
                    it = cellIndex.emplace(id, uint32_t(out.vertexIds.size())).first;
                    out.vertexIds.push_back(id);
                    out.indexPositions.push_back(mVerts[size_t(nd.vert)].pos);
                }
                out.indices.push_back(it->second);
            }
        }
    }
}

// ============================================================ front end ====

namespace {

} // namespace

/// One re-meshing kernel per thread for CutRemesher::update().
struct KernelPool : tbb::enumerable_thread_specific<RemeshKernel>
{
    KernelPool(const vdb::Volume& volume, float iso) : tbb::enumerable_thread_specific<RemeshKernel>(std::cref(volume), iso) {}
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
    RemeshKernel kernel(volume, isovalue);
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
    const openvdb::Vec3d origin = volume.origin(), spacing = volume.spacing();
    return glm::vec3(float(origin[0] + spacing[0] * p.x), float(origin[1] + spacing[1] * p.y),
                     float(origin[2] + spacing[2] * p.z));
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

void CutRemesher::checkLocally(const std::vector<Coord>& changed) const
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
    struct Tri
    {
        uint32_t v[3];
        Coord cell;
    };
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
                tris.push_back({{local[g.indices[k]], local[g.indices[k + 1]], local[g.indices[k + 2]]}, c});
        } else {
            for (size_t k = cornerStart[i]; k + 2 < cornerStart[i + 1]; k += 3)
                tris.push_back({{edgeNameOf(corners[k]), edgeNameOf(corners[k + 1]), edgeNameOf(corners[k + 2])}, c});
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
        if (!isChanged(tr.cell) || !mCells.count(tr.cell)) continue;
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
}

size_t CutRemesher::update(const CutMask& mask, Interrupter* interrupter)
{
    const Coord last = mVolume->dims - Coord(2);
    auto inBox = [&](const Coord& c) {
        return c.x() >= 0 && c.y() >= 0 && c.z() >= 0 && c.x() <= last.x() && c.y() <= last.y() && c.z() <= last.z();
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
            RemeshKernel& kernel = mKernels->local();
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
        checkLocally(changedCells);
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
