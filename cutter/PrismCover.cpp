// The prisms of a cell that the others cover (PrismCover.h).
//
// A prism's part of the cell, C = P ∩ box, is a convex polytope, held as
// its faces (convex polygons). C minus the union of the others is found by
// subtracting them one at a time: X minus a convex prism Q (shrunk by the
// margin) is the union of X ∩ {outside Q's face 1}, X ∩ {inside face 1,
// outside face 2}, ..., each convex; pieces with no volume go. C is covered
// when nothing is left. Plain doubles: the margin (1e-6 voxel) dwarfs their
// rounding (1e-13 here), and every doubt (a sliver left, the budget spent)
// keeps the prism. No GL.
#include "cutter/PrismCover.h"

#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <tuple>

namespace mtcut::cutter::remesh_detail {

namespace {

using Polygon = std::vector<dvec3>;

/// A convex polytope as its faces; empty when it has no volume.
struct Polytope
{
    std::vector<Polygon> faces;
    bool empty() const { return faces.size() < 4; }
};

/// Pieces one prism's test may hold at once before it gives up (covered:
/// no). A saw's cell needs a handful.
constexpr size_t kPieceBudget = 64;

/// How far the prism tested is grown where it meets a cell's solid (a cell
/// with air), so that a prism that only touches the solid is tested there
/// too. Half the margin: grown by the whole margin, its face on a plane it
/// shares with another prism (a junction's mitre, facing the other way)
/// lies exactly on that prism's shrunk face. `clip` once lost such a piece
/// (each face computed a crossing its own way; `crossing` now makes them
/// one point) and the whole margin passes APrismBeyondItsPartnersMitreStays
/// since, but half keeps that face off the plane by a margin of its own.
constexpr double kGrow = 0.5 * kCoverMargin;

/// Points closer than this (index space) are one (a clip's cap corners).
constexpr double kSamePoint = 1e-11;

Polytope cellBox(const Coord& c)
{
    const dvec3 lo(c.x(), c.y(), c.z()), hi = lo + dvec3(1.0);
    auto at = [&](int k) { return dvec3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z); };
    Polytope box;
    // Corner k: bit 0 x, bit 1 y, bit 2 z; each face a loop of four corners.
    const int faces[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
    for (const auto& f : faces) box.faces.push_back({at(f[0]), at(f[1]), at(f[2]), at(f[3])});
    return box;
}

/// Where the plane crosses edge ab (g(a) = ga and g(b) = gb of opposite
/// signs), computed from the ends in one order whichever way the edge is
/// walked: the two faces that share the edge get the same point, bit for
/// bit, so every later clip puts it on the same side in both, and the
/// faces of a piece stay one closed surface. (Walked each its own way, the
/// two copies could differ in the last bits and a later plane through the
/// point could keep it in one face and drop it from the other, losing a
/// face: a piece with a face on the clipping plane came out empty.)
dvec3 crossing(const dvec3& a, double ga, const dvec3& b, double gb)
{
    if (std::tie(b.x, b.y, b.z) < std::tie(a.x, a.y, a.z)) return b + (gb / (gb - ga)) * (a - b);
    return a + (ga / (ga - gb)) * (b - a);
}

/// The part of `p` where g(x) = n . x - d >= 0: each face clipped
/// (Sutherland-Hodgman), and the cap on g = 0 from the crossings, ordered
/// round their centre.
Polytope clip(const Polytope& p, const dvec3& n, double d)
{
    Polytope out;
    Polygon cap;
    auto g = [&](const dvec3& x) { return glm::dot(n, x) - d; };
    for (const Polygon& f : p.faces) {
        Polygon kept;
        const size_t m = f.size();
        for (size_t i = 0; i < m; ++i) {
            const dvec3 &a = f[i], &b = f[(i + 1) % m];
            const double ga = g(a), gb = g(b);
            if (ga >= 0) kept.push_back(a);
            if (ga == 0) cap.push_back(a);
            if ((ga > 0 && gb < 0) || (ga < 0 && gb > 0)) {
                const dvec3 x = crossing(a, ga, b, gb);
                kept.push_back(x);
                cap.push_back(x);
            }
        }
        if (kept.size() >= 3) out.faces.push_back(std::move(kept));
    }
    if (out.faces.empty()) return out;
    // The cap: its corners once each, ordered by angle in the plane.
    Polygon unique;
    for (const dvec3& x : cap)
        if (std::none_of(unique.begin(), unique.end(), [&](const dvec3& y) { return glm::length(x - y) < kSamePoint; }))
            unique.push_back(x);
    if (unique.size() >= 3) {
        dvec3 centre(0.0);
        for (const dvec3& x : unique) centre += x;
        centre /= double(unique.size());
        dvec3 u(0.0);
        for (const dvec3& x : unique)
            if (glm::length(x - centre) > glm::length(u)) u = x - centre;
        u = glm::normalize(u);
        const dvec3 v = glm::cross(n, u);
        std::sort(unique.begin(), unique.end(), [&](const dvec3& a, const dvec3& b) {
            return std::atan2(glm::dot(a - centre, v), glm::dot(a - centre, u)) <
                   std::atan2(glm::dot(b - centre, v), glm::dot(b - centre, u));
        });
        out.faces.push_back(std::move(unique));
    }
    if (out.empty()) out.faces.clear();
    return out;
}

/// g_f(x) = orient * h_f(x) - margin for face f of q: q shrunk by the
/// margin is where every g_f > 0.
double inside(const QuadGeom::Side& s, const dvec3& x) { return s.orient * s.plane.h(x) - kCoverMargin; }

/// Appends X minus the prism q shrunk by the margin to `out`, as convex
/// pieces. False when the budget ran out.
bool subtract(const Polytope& x, const QuadGeom& q, std::vector<Polytope>& out)
{
    // Quick: X wholly inside (nothing left), or wholly outside one face (X as it is).
    bool allInside = true;
    for (const QuadGeom::Side& s : q.sides) {
        bool anyIn = false, anyOut = false;
        for (const Polygon& f : x.faces)
            for (const dvec3& v : f) (inside(s, v) > 0 ? anyIn : anyOut) = true;
        if (!anyIn) {
            out.push_back(x);
            return out.size() <= kPieceBudget;
        }
        allInside = allInside && !anyOut;
    }
    if (allInside) return true;
    Polytope rest = x;
    for (const QuadGeom::Side& s : q.sides) {
        // outside this face: orient * h - margin <= 0
        const dvec3 n = s.orient * s.plane.n;
        const double d = s.orient * s.plane.d + kCoverMargin; // inside(s, x) = n . x - d
        Polytope piece = clip(rest, -n, -d);
        if (!piece.empty()) out.push_back(std::move(piece));
        if (out.size() > kPieceBudget) return false;
        rest = clip(rest, n, d);
        if (rest.empty()) break;
    }
    return true;
}

/// A convex region of the cell to test in, with its bounding planes (inside: h >= 0).
struct Region
{
    Polytope poly;
    std::vector<Plane> planes;
    bool holds(const dvec3& x) const
    {
        return std::all_of(planes.begin(), planes.end(), [&](const Plane& p) { return p.h(x) >= 0.0; });
    }
};

Polytope tetPolytope(const std::array<dvec3, 4>& v)
{
    // A face opposite each corner (clip reads no winding).
    Polytope t;
    t.faces.push_back({v[1], v[2], v[3]});
    t.faces.push_back({v[0], v[3], v[2]});
    t.faces.push_back({v[0], v[1], v[3]});
    t.faces.push_back({v[0], v[2], v[1]});
    return t;
}

std::atomic<bool> gDropCovered{true};

} // namespace

std::vector<std::vector<dvec3>> clipCellForTesting(const Coord& cell, const std::vector<Plane>& planes)
{
    Polytope p = cellBox(cell);
    for (const Plane& plane : planes) {
        p = clip(p, plane.n, plane.d);
        if (p.empty()) break;
    }
    return p.faces;
}

void dropCoveredPrismsForTesting(bool drop) { gDropCovered.store(drop); }

bool dropCoveredPrisms() { return gDropCovered.load(std::memory_order_relaxed); }

CellSolid cellSolid(const Coord& cell, const std::array<float, 8>& values, uint8_t inside, float iso)
{
    CellSolid s;
    const auto& tets = cellTets(cellParity(cell.x(), cell.y(), cell.z()));
    for (int t = 0; t < kTetsPerCell; ++t) {
        int in = 0;
        std::array<uint64_t, 4> id{};
        for (int i = 0; i < 4; ++i) {
            const int c = tets[size_t(t)][size_t(i)];
            const Coord g = cell + Coord(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            s.corners[size_t(t)][size_t(i)] = dvec3(g.x(), g.y(), g.z());
            id[size_t(i)] = gridVertexId(g.x(), g.y(), g.z());
            in += inside >> c & 1;
        }
        s.holds[size_t(t)] = in > 0;
        if (in == 0 || in == 4) continue;
        // The MT points, as the kernel makes them (RemeshKernel::mtPoint).
        std::array<dvec3, 4> pts; // 3 or 4
        std::array<dvec3, 3> inCorners;
        size_t np = 0, nIn = 0;
        dvec3 inSum(0.0), outSum(0.0);
        for (int a = 0; a < 4; ++a) {
            const int ca = tets[size_t(t)][size_t(a)];
            const bool ia = inside >> ca & 1;
            (ia ? inSum : outSum) += s.corners[size_t(t)][size_t(a)];
            if (ia) inCorners[nIn++] = s.corners[size_t(t)][size_t(a)];
            for (int b = a + 1; b < 4; ++b) {
                const int cb = tets[size_t(t)][size_t(b)];
                if (ia == bool(inside >> cb & 1)) continue;
                int lo = a, hi = b, clo = ca, chi = cb;
                if (id[size_t(hi)] < id[size_t(lo)]) std::swap(lo, hi), std::swap(clo, chi);
                const double u = edgeCrossing(values[size_t(clo)], values[size_t(chi)], iso);
                pts[np++] = s.corners[size_t(t)][size_t(lo)] +
                            u * (s.corners[size_t(t)][size_t(hi)] - s.corners[size_t(t)][size_t(lo)]);
            }
        }
        // The pieces' normal (a quad's from its diagonals), toward the
        // inside; any direction would hold the hull, this one nearly hugs it.
        dvec3 n = np == 3 ? glm::cross(pts[1] - pts[0], pts[2] - pts[0])
                          : glm::cross(pts[3] - pts[0], pts[2] - pts[1]);
        const double len = glm::length(n);
        if (!(len > 0)) continue; // no plane: test the whole tet
        n /= len;
        if (glm::dot(n, inSum / double(in) - outSum / double(4 - in)) < 0) n = -n;
        double d = 1e300;
        for (size_t k = 0; k < np; ++k) d = std::min(d, glm::dot(n, pts[k]));
        for (size_t k = 0; k < nIn; ++k) d = std::min(d, glm::dot(n, inCorners[k]));
        s.hull[size_t(t)] = Plane{n, d - kCoverMargin};
    }
    return s;
}

std::vector<char> coveredPrisms(const Coord& cell, const std::vector<QuadGeom>& quads, const CellSolid* solid)
{
    std::vector<char> covered(quads.size(), 0);
    if (quads.size() < kCoverMinPrisms) return covered;
    const Polytope box = cellBox(cell);
    std::vector<Region> regions;
    if (solid) {
        for (int t = 0; t < kTetsPerCell; ++t) {
            if (!solid->holds[size_t(t)]) continue;
            const auto& v = solid->corners[size_t(t)];
            Region r;
            r.poly = tetPolytope(v);
            for (int k = 0; k < 4; ++k) {
                // Face opposite corner k, inward.
                const dvec3 &a = v[size_t((k + 1) % 4)], &b = v[size_t((k + 2) % 4)], &c = v[size_t((k + 3) % 4)];
                dvec3 n = glm::cross(b - a, c - a);
                if (glm::dot(n, v[size_t(k)] - a) < 0) n = -n;
                r.planes.push_back(Plane{n, glm::dot(n, a)});
            }
            const Plane& h = solid->hull[size_t(t)];
            if (h.n != dvec3(0.0)) {
                r.poly = clip(r.poly, h.n, h.d);
                r.planes.push_back(h);
            }
            if (!r.poly.empty()) regions.push_back(std::move(r));
        }
    }
    auto within = [](const QuadGeom& q, const dvec3& x, double margin) {
        for (const QuadGeom::Side& s : q.sides)
            if (!(s.orient * s.plane.h(x) > margin)) return false;
        return true;
    };
    const dvec3 lo(cell.x(), cell.y(), cell.z());
    for (size_t i = 0; i < quads.size(); ++i) {
        // A witness first (most prisms of an ordinary stroke have one): the
        // cell's centre or a corner, moved onto the prism's mid-plane, in
        // the prism and the cell but in none of the others kept.
        bool witness = false;
        for (int k = 0; k < 9 && !witness; ++k) {
            const dvec3 p = k == 8 ? lo + dvec3(0.5) : lo + dvec3(k & 1, (k >> 1) & 1, (k >> 2) & 1);
            const dvec3 x = p - quads[i].pi.h(p) * quads[i].pi.n;
            if (glm::any(glm::lessThan(x, lo)) || glm::any(glm::greaterThan(x, lo + dvec3(1.0))) || !within(quads[i], x, 0.0))
                continue;
            if (solid && std::none_of(regions.begin(), regions.end(), [&](const Region& r) { return r.holds(x); }))
                continue;
            witness = true;
            for (size_t j = 0; j < quads.size() && witness; ++j)
                witness = j == i || covered[j] || !within(quads[j], x, kCoverMargin);
        }
        if (witness) continue;
        Polytope own = box;
        for (const QuadGeom::Side& s : quads[i].sides) {
            own = clip(own, s.orient * s.plane.n, s.orient * s.plane.d);
            if (own.empty()) break;
        }
        if (own.empty()) continue; // no volume in the cell: its planes may still hold the surface on a face
        // Whether the others leave nothing of `part` (the budget counts each
        // part's pieces on their own).
        std::vector<Polytope> pieces, next;
        auto coveredPart = [&](Polytope part) {
            pieces.assign(1, std::move(part));
            for (size_t j = 0; j < quads.size() && !pieces.empty(); ++j) {
                if (j == i || covered[j]) continue;
                next.clear();
                for (const Polytope& p : pieces)
                    if (!subtract(p, quads[j], next)) return false;
                pieces.swap(next);
            }
            return pieces.empty();
        };
        if (!solid) {
            covered[i] = coveredPart(std::move(own));
            continue;
        }
        bool all = true;
        for (size_t r = 0; r < regions.size() && all; ++r) {
            // The prism grown by kGrow, in the region.
            Polytope part = regions[r].poly;
            for (const QuadGeom::Side& s : quads[i].sides) {
                part = clip(part, s.orient * s.plane.n, s.orient * s.plane.d - kGrow);
                if (part.empty()) break;
            }
            all = part.empty() || coveredPart(std::move(part));
        }
        covered[i] = all;
    }
    return covered;
}

} // namespace mtcut::cutter::remesh_detail
