// Property tests of the cut, the cut issue's list (DESIGN invariants 5-10),
// each for kerf w = 0 and w = 0.5 mm:
//  - a sphere and a box cut through by a plane (axis-aligned off the grid, and
//    oblique): exactly 2 fragments; their volumes add up to the original minus
//    the kerf slab within invariant 10's bound (one tet per cut cell);
//  - cuts that stop inside (a notch, a blade whose tip stays inside, both):
//    1 closed, manifold fragment;
//  - seeded random strokes and hand-made ones (straight, curved, self-crossing,
//    two strokes crossing, blades in grid planes and through grid vertices)
//    on the real heads: zero checkMesh defects on every fused mesh; the
//    re-mesher's refusals (a thrown "remesh: ... cell (i, j, k)", mesh kept)
//    counted and bounded; a saw worked back and forth (sawing strokes with
//    tremor, live): no stroke stops, clean, undo exact;
//  - outside the re-meshed cells the triangles are the uncut ones exactly (the
//    same indices per cell, the same vertex positions); undo of each stroke
//    (and back to a stick inside a stroke) gives the earlier mesh exactly;
//  - cap vertices lie within one voxel diagonal of the blade's swept surface;
//  - an independent self-intersection check with CGAL (tests/SelfIntersect.h):
//    none for w > 0; for w = 0 the two sides touch (invariant 7) only on the
//    swept surface.
// kerf > 0 is not implemented yet: the re-mesher throws InputError("... kerf
// > 0 is not implemented yet ..."); those cases skip with that message and run
// by themselves once it lands. Any other exception fails.
// test_remesh.cpp already checks the zero-kerf sphere's volumes against the
// uncut one and its analytic small cap, its 100 random head strokes undone
// together at the end, and the local check's refusals; that is not repeated.
#include "cutter/CutMask.h"
#include "cutter/Fusion.h"
#include "cutter/Isosurface.h"
#include "cutter/LiveStroke.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"
#include "tests/SelfIntersect.h"
#include "tests/TestStrokes.h"
#include "tests/TestUtil.h"
#include "tests/TestVolumes.h"
#include "vdb/Error.h"
#include "vdb/VolumeIO.h"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <tbb/global_control.h>

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/intersections.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

using namespace mtcut;
using namespace mtcut::cutter;
using glm::dvec3;
using openvdb::Coord;
using openvdb::Vec3d;
using mtcut::test::fieldVolume;
using mtcut::test::straightStroke;
using mtcut::test::selfIntersections;

namespace {

constexpr const char* kKerfTodo = "kerf > 0 is not implemented yet";

// ------------------------------------------------------------------ update --

enum class Outcome { Ok, KerfTodo, Refused };

struct UpdateResult
{
    Outcome outcome = Outcome::Ok;
    std::string message;
    size_t cells = 0;
    size_t kept = 0; ///< remesher.lastKeptCells() after a done update
};

/// remesher.update(mask), telling apart: done; kerf > 0 not implemented yet
/// (InputError naming it, only for a mask with kerf > 0); a refused cell
/// (std::runtime_error "remesh: ... cell (i, j, k)"). Anything else is
/// rethrown, so it fails the test.
UpdateResult tryUpdate(CutRemesher& remesher, const CutMask& mask)
{
    UpdateResult r;
    try {
        r.cells = remesher.update(mask);
        r.kept = remesher.lastKeptCells();
    } catch (const InputError& e) {
        r.message = e.what();
        if (mask.kerf() > 0 && r.message.find(kKerfTodo) != std::string::npos) {
            r.outcome = Outcome::KerfTodo;
            return r;
        }
        throw;
    } catch (const std::runtime_error& e) {
        r.message = e.what();
        if (r.message.rfind("remesh: ", 0) == 0 && r.message.find(" cell (") != std::string::npos) {
            r.outcome = Outcome::Refused;
            return r;
        }
        throw;
    }
    return r;
}

/// In a TEST body: update, skip while kerf > 0 is not implemented, fail on a refusal.
#define UPDATE_OR_SKIP(remesher, mask)                                                                     \
    do {                                                                                                   \
        const UpdateResult r_ = tryUpdate(remesher, mask);                                                 \
        if (r_.outcome == Outcome::KerfTodo) {                                                             \
            GTEST_SKIP() << r_.message;                                                                    \
        }                                                                                                  \
        ASSERT_EQ(r_.outcome, Outcome::Ok) << r_.message;                                                  \
    } while (0)

bool sameMesh(const Mesh& a, const Mesh& b)
{
    return a.positions == b.positions && a.normals == b.normals && a.indices == b.indices &&
           a.triangleVoxels == b.triangleVoxels;
}

/// The same triangles per cell as position triples, each up to the corner it
/// starts at (orientation kept) and up to the numbering of the vertices.
bool sameTriangles(const Mesh& a, const Mesh& b)
{
    if (a.triangleCount() != b.triangleCount()) return false;
    using Key = std::array<float, 12>;
    auto canon = [](const Mesh& m) {
        std::vector<Key> t(m.triangleCount());
        for (size_t i = 0; i < t.size(); ++i) {
            std::array<std::array<float, 3>, 3> p;
            for (int j = 0; j < 3; ++j) {
                const glm::vec3& v = m.positions[m.indices[3 * i + size_t(j)]];
                p[size_t(j)] = {v.x, v.y, v.z};
            }
            std::rotate(p.begin(), std::min_element(p.begin(), p.end()), p.end());
            const glm::ivec3 c = m.triangleVoxels[i];
            t[i] = {float(c.x), float(c.y), float(c.z), p[0][0], p[0][1], p[0][2], p[1][0], p[1][1], p[1][2],
                    p[2][0], p[2][1], p[2][2]};
        }
        std::sort(t.begin(), t.end());
        return t;
    };
    return canon(a) == canon(b);
}

std::string kerfName(double w) { return w > 0 ? "w=" + std::to_string(w).substr(0, 3) + "mm" : "w=0"; }

// ------------------------------------------------------------------ strokes --

Pose pose(double t, dvec3 base, dvec3 dir, double len)
{
    Pose p;
    p.time = t;
    p.base = base;
    p.direction = dir;
    p.length = len;
    return p;
}


/// Adds a stroke as one mask stroke; returns its quad count.
size_t addStroke(CutMask& mask, const std::vector<Pose>& poses)
{
    const std::vector<Quad> quads = filterStroke(poses, mask.frame());
    mask.beginStroke();
    for (const Quad& q : quads) mask.addQuad(q);
    return quads.size();
}

// ----------------------------------------------------------------- geometry --

/// Largest tet of the 5-tet split, world mm^3 (the central tet: a third of the cell).
double largestTetVolume(const IndexFrame& f)
{
    double best = 0.0;
    for (int parity = 0; parity < 2; ++parity)
        for (const auto& t : cellTets(parity)) {
            dvec3 v[4];
            for (int i = 0; i < 4; ++i)
                v[i] = dvec3(t[size_t(i)] & 1, (t[size_t(i)] >> 1) & 1, (t[size_t(i)] >> 2) & 1) * f.spacing;
            best = std::max(best, std::abs(glm::dot(v[1] - v[0], glm::cross(v[2] - v[0], v[3] - v[0]))) / 6.0);
        }
    return best;
}

double segmentDistance(const dvec3& p, const dvec3& a, const dvec3& b)
{
    const dvec3 ab = b - a;
    const double l2 = glm::dot(ab, ab);
    const double t = l2 > 0 ? std::clamp(glm::dot(p - a, ab) / l2, 0.0, 1.0) : 0.0;
    return glm::length(p - (a + t * ab));
}

/// Distance from p to the convex hull of a quad's corners moved by `shift`
/// (world mm). In-plane inside test: p's projection lies in one of the corner
/// triangles (the hull of 4 coplanar points is the union of its 4 corner
/// triangles); else the nearest corner-to-corner segment.
double quadDistance(const dvec3& p, const Quad& q, const dvec3& shift)
{
    const uint32_t n = q.cornerCount;
    dvec3 c[4];
    for (uint32_t i = 0; i < n; ++i) c[i] = q.corners[i] + shift;
    double seg = 1e300;
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t j = i + 1; j < n; ++j) seg = std::min(seg, segmentDistance(p, c[i], c[j]));
    if (q.degenerate || glm::length(q.normal) < 0.5) return seg;
    const dvec3 nrm = q.normal;
    const double h = glm::dot(nrm, p - c[0]);
    const dvec3 pp = p - h * nrm;
    for (uint32_t a = 0; a < n; ++a)
        for (uint32_t b = a + 1; b < n; ++b)
            for (uint32_t d = b + 1; d < n; ++d) {
                const double s0 = glm::dot(nrm, glm::cross(c[b] - c[a], c[d] - c[a]));
                if (std::abs(s0) < 1e-12) continue;
                const double s1 = glm::dot(nrm, glm::cross(c[b] - c[a], pp - c[a]));
                const double s2 = glm::dot(nrm, glm::cross(c[d] - c[b], pp - c[b]));
                const double s3 = glm::dot(nrm, glm::cross(c[a] - c[d], pp - c[d]));
                if (s1 * s0 >= 0 && s2 * s0 >= 0 && s3 * s0 >= 0) return std::abs(h);
            }
    return seg;
}

/// Distance from p to the blade's swept surface made of `quads`: with kerf w
/// the quads moved by -w/2 and +w/2 along their normal (the slab's faces).
double bladeDistance(const dvec3& p, const std::vector<const Quad*>& quads, double kerf)
{
    double best = 1e300;
    for (const Quad* q : quads) {
        if (kerf > 0) {
            best = std::min(best, quadDistance(p, *q, 0.5 * kerf * q->normal));
            best = std::min(best, quadDistance(p, *q, -0.5 * kerf * q->normal));
        } else {
            best = std::min(best, quadDistance(p, *q, dvec3(0.0)));
        }
    }
    return best;
}

/// The quads that touch `cell`; for a re-meshed cell outside the mask (just
/// outside the scan box), those of its cut neighbours.
std::vector<const Quad*> quadsNear(const CutMask& mask, const Coord& cell)
{
    std::vector<const Quad*> out;
    std::set<std::pair<uint32_t, uint32_t>> seen;
    auto take = [&](const Coord& c) {
        if (const std::vector<QuadRef>* refs = mask.quadsAt(c))
            for (const QuadRef& r : *refs)
                if (seen.insert({r.stroke, r.quad}).second) out.push_back(&mask.quad(r));
    };
    take(cell);
    if (out.empty())
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) take(cell + Coord(dx, dy, dz));
    return out;
}

/// A vertex made by the iso surface alone (planes 1 = the iso surface, 2 and
/// 3 its triangles in a tet; no blade plane, no slit side tag).
bool isoOnly(const CutVertexId& id)
{
    if (id.tagCount > 0) return false;
    for (uint8_t i = 0; i < id.planeCount; ++i)
        if (id.planes[i] > 3) return false;
    return true;
}

struct CapStats
{
    size_t vertices = 0;     ///< new vertices on a blade plane
    size_t onSurface = 0;    ///< of them, within 1e-4 mm of the swept surface
    double maxMm = 0.0;      ///< largest distance to the swept surface
    double diagonalMm = 0.0; ///< the bound: one voxel diagonal
    void merge(const CapStats& o)
    {
        vertices += o.vertices;
        onSurface += o.onSurface;
        maxMm = std::max(maxMm, o.maxMm);
        diagonalMm = std::max(diagonalMm, o.diagonalMm);
    }
};

/// Invariant 10's first half: every new vertex of the re-meshed cells that lies
/// on a blade plane is within one tet (bounded by one voxel diagonal) of the
/// swept surface (world mm; for w > 0 its slab's faces).
CapStats capDistances(const CutRemesher& remesher, const CutMask& mask)
{
    CapStats st;
    const IndexFrame& f = mask.frame();
    st.diagonalMm = glm::length(f.spacing);
    for (const auto& [cell, geom] : remesher.cells()) {
        const std::vector<const Quad*> quads = quadsNear(mask, cell);
        for (size_t v = 0; v < geom.vertexIds.size(); ++v) {
            if (isoOnly(geom.vertexIds[v])) continue;
            const dvec3 world = f.toWorld(geom.indexPositions[v]);
            const double d = bladeDistance(world, quads, mask.kerf());
            ++st.vertices;
            if (d <= 1e-4) ++st.onSurface;
            st.maxMm = std::max(st.maxMm, d);
        }
    }
    return st;
}

// ------------------------------------------------------ untouched outside --

using CellTri = std::array<int64_t, 6>; // cell x, y, z, then the indices rotated to start at the smallest

/// Triangles of cells not re-meshed, by cell, with their vertex indices
/// (rotated, orientation kept), sorted.
std::vector<CellTri> outsideTriangles(const Mesh& m, const std::map<Coord, CutCellGeometry>& cells)
{
    std::vector<CellTri> out;
    out.reserve(m.triangleCount());
    for (size_t t = 0; t < m.triangleCount(); ++t) {
        const glm::ivec3 c = m.triangleVoxels[t];
        if (cells.count(Coord(c.x, c.y, c.z))) continue;
        std::array<uint32_t, 3> i{m.indices[3 * t], m.indices[3 * t + 1], m.indices[3 * t + 2]};
        const int r = int(std::min_element(i.begin(), i.end()) - i.begin());
        std::rotate(i.begin(), i.begin() + r, i.end());
        out.push_back({c.x, c.y, c.z, i[0], i[1], i[2]});
    }
    std::sort(out.begin(), out.end());
    return out;
}

/// Invariant 9: outside the re-meshed cells the fused mesh has exactly the
/// uncut triangles (the same vertex indices, as a set per cell) and every uncut
/// vertex keeps its position.
bool untouchedOutside(const Mesh& uncut, const Mesh& fused, const CutRemesher& remesher, std::string& why)
{
    if (fused.positions.size() < uncut.positions.size() ||
        !std::equal(uncut.positions.begin(), uncut.positions.end(), fused.positions.begin())) {
        why = "an uncut vertex moved or is missing";
        return false;
    }
    const std::vector<CellTri> a = outsideTriangles(uncut, remesher.cells());
    const std::vector<CellTri> b = outsideTriangles(fused, remesher.cells());
    if (a != b) {
        std::vector<CellTri> diff;
        std::set_symmetric_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(diff));
        why = std::to_string(diff.size()) + " triangles differ outside the cut cells, first in cell (" +
              std::to_string(diff[0][0]) + ", " + std::to_string(diff[0][1]) + ", " + std::to_string(diff[0][2]) + ")";
        return false;
    }
    return true;
}

// ------------------------------------------------------ self-intersections --

struct TouchStats
{
    size_t pairs = 0;     ///< intersecting triangle pairs CGAL found, less the pinch contacts
    /// Pairs that meet in one point only, a corner of each where two vertices
    /// of the mesh have one position: the copies a kerf > 0 cut gives a vertex
    /// where the removed region's boundary pinches (Remesh.h). A surface
    /// touching itself there is the exact shape, not a defect.
    size_t pinchContacts = 0;
    size_t offBlade = 0;  ///< of them, meeting somewhere off the swept surface
    size_t cutPairs = 0;  ///< pairs with at least one triangle in a re-meshed cell
    size_t coplanar = 0;  ///< of them, one triangle in a quad's plane (a cap piece)
    double findSeconds = 0.0, classifySeconds = 0.0;
    void merge(const TouchStats& o)
    {
        findSeconds += o.findSeconds;
        classifySeconds += o.classifySeconds;
        pairs += o.pairs;
        pinchContacts += o.pinchContacts;
        offBlade += o.offBlade;
        cutPairs += o.cutPairs;
        coplanar += o.coplanar;
    }
};

/// The exact intersection of triangles a and b (CGAL, exact constructions),
/// as the corners of its point/segment/polygon; empty when they miss.
std::vector<dvec3> intersectionCorners(const Mesh& m, uint32_t a, uint32_t b)
{
    using EK = CGAL::Exact_predicates_exact_constructions_kernel;
    auto tri = [&](uint32_t t) {
        EK::Point_3 p[3];
        for (int j = 0; j < 3; ++j) {
            const glm::vec3& v = m.positions[m.indices[3 * t + uint32_t(j)]];
            p[j] = EK::Point_3(double(v.x), double(v.y), double(v.z));
        }
        return EK::Triangle_3(p[0], p[1], p[2]);
    };
    std::vector<dvec3> out;
    const auto res = CGAL::intersection(tri(a), tri(b));
    if (!res) return out;
    auto put = [&](const EK::Point_3& p) {
        out.emplace_back(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
    };
    if (const EK::Point_3* p = boost::get<EK::Point_3>(&*res)) put(*p);
    else if (const EK::Segment_3* s = boost::get<EK::Segment_3>(&*res)) {
        put(s->source());
        put(s->target());
    } else if (const EK::Triangle_3* t = boost::get<EK::Triangle_3>(&*res)) {
        for (int i = 0; i < 3; ++i) put(t->vertex(i));
    } else if (const auto* poly = boost::get<std::vector<EK::Point_3>>(&*res)) {
        for (const EK::Point_3& q : *poly) put(q);
    }
    return out;
}

/// Self-intersections of `fused` near the cut (the triangles of the re-meshed
/// cells and of their 26 neighbours: two triangles can meet only when their
/// closed cells do), counting the pairs that involve a re-meshed cell. A pair
/// is off the blade when a corner of its exact intersection lies farther than
/// `tolMm` from the swept surface (the slit itself, w = 0).
TouchStats touchesNearCut(const Mesh& fused, const CutRemesher& remesher, const CutMask& mask, double tolMm)
{
    std::set<Coord> near;
    for (const auto& c : remesher.cells())
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) near.insert(c.first + Coord(dx, dy, dz));
    std::vector<uint32_t> only;
    for (size_t t = 0; t < fused.triangleCount(); ++t) {
        const glm::ivec3 c = fused.triangleVoxels[t];
        if (near.count(Coord(c.x, c.y, c.z))) only.push_back(uint32_t(t));
    }
    const auto t0 = std::chrono::steady_clock::now();
    const mtcut::test::SelfIntersectResult si = selfIntersections(fused, &only);
    const auto t1 = std::chrono::steady_clock::now();
    TouchStats st;
    st.findSeconds = std::chrono::duration<double>(t1 - t0).count();
    st.pairs = si.count();
    // A pair in which one triangle lies in a quad's plane (a cap piece of the
    // slit, w = 0) meets inside that triangle, so on the swept surface (the cap
    // vertices' distance to it is checked by capDistances): no exact
    // construction needed. Other pairs: the exact intersection's corners.
    std::unordered_map<uint32_t, const Quad*> capPlane;
    auto inPlane = [&](uint32_t t, const Quad& q) {
        if (q.degenerate) return false;
        for (int j = 0; j < 3; ++j) {
            const dvec3 p(fused.positions[fused.indices[3 * t + uint32_t(j)]]);
            if (std::abs(glm::dot(q.normal, p) - q.offset) > tolMm) return false;
        }
        return true;
    };
    auto planeOf = [&](uint32_t t, const std::vector<const Quad*>& quads) {
        const auto it = capPlane.find(t);
        if (it != capPlane.end()) return it->second;
        const Quad* found = nullptr;
        for (const Quad* q : quads)
            if (inPlane(t, *q)) {
                found = q;
                break;
            }
        capPlane.emplace(t, found);
        return found;
    };
    for (const auto& [a, b] : si.pairs) {
        const glm::ivec3 ca = fused.triangleVoxels[a], cb = fused.triangleVoxels[b];
        const Coord ka(ca.x, ca.y, ca.z), kb(cb.x, cb.y, cb.z);
        if (!remesher.cells().count(ka) && !remesher.cells().count(kb)) continue;
        if (mask.kerf() > 0) {
            // A pinch contact: the exact intersection is one point, which is a
            // corner of a and a different vertex of b at the same position.
            const std::vector<dvec3> at = intersectionCorners(fused, a, b);
            bool pinch = false;
            if (at.size() == 1)
                for (int i = 0; i < 3; ++i)
                    for (int j = 0; j < 3; ++j) {
                        const uint32_t va = fused.indices[3 * a + uint32_t(i)], vb = fused.indices[3 * b + uint32_t(j)];
                        pinch = pinch || (va != vb && fused.positions[va] == fused.positions[vb] &&
                                          dvec3(fused.positions[va]) == at[0]);
                    }
            if (pinch) {
                ++st.pinchContacts;
                --st.pairs;
                continue;
            }
        }
        ++st.cutPairs;
        std::vector<const Quad*> quads = quadsNear(mask, ka);
        const std::vector<const Quad*> qb = quadsNear(mask, kb);
        quads.insert(quads.end(), qb.begin(), qb.end());
        if (planeOf(a, quads) || planeOf(b, quads)) {
            ++st.coplanar;
            continue;
        }
        for (const dvec3& p : intersectionCorners(fused, a, b))
            if (bladeDistance(p, quads, 0.0) > tolMm) {
                ++st.offBlade;
                if (st.offBlade <= 3)
                    std::printf("  off-blade intersection: triangles %u (cell %d,%d,%d) and %u (cell %d,%d,%d)\n", a,
                                ca.x, ca.y, ca.z, b, cb.x, cb.y, cb.z);
                break;
            }
    }
    st.classifySeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    return st;
}

// ------------------------------------------------------------------ solids --

/// An analytic solid on the 40^3, 1 mm grid of test_remesh (voxel centres at
/// -19.5 .. 19.5 mm), isovalue 0.
struct Solid
{
    std::string name;
    std::function<double(const Vec3d&)> field; ///< >= 0 inside
    double volume = 0.0;                        ///< exact, mm^3
    /// Exact volume of the solid between the planes n.x = lo and n.x = hi
    /// (n unit, horizontal for the box).
    std::function<double(const dvec3&, double, double)> between;
};

Solid sphereSolid()
{
    const double R = 15.0;
    Solid s;
    s.name = "sphere";
    s.field = [R](const Vec3d& p) { return R - p.length(); };
    s.volume = 4.0 / 3.0 * M_PI * R * R * R;
    s.between = [R](const dvec3&, double lo, double hi) {
        lo = std::clamp(lo, -R, R);
        hi = std::clamp(hi, -R, R);
        auto F = [R](double z) { return R * R * z - z * z * z / 3.0; };
        return hi > lo ? M_PI * (F(hi) - F(lo)) : 0.0;
    };
    return s;
}

Solid boxSolid()
{
    const dvec3 c(0.21, -0.33, 0.45), h(11.3, 8.65, 9.9);
    Solid s;
    s.name = "box";
    s.field = [c, h](const Vec3d& p) {
        return std::min({h.x - std::abs(p.x() - c.x), h.y - std::abs(p.y() - c.y), h.z - std::abs(p.z() - c.z)});
    };
    s.volume = 8.0 * h.x * h.y * h.z;
    // Section of the box by the vertical plane n.x = s: 2 h.z times the length of
    // the line's chord through the rectangle; integrated by the midpoint rule
    // (the chord length is piecewise linear in s: error ~1e-6 of the volume).
    s.between = [c, h](const dvec3& n, double lo, double hi) {
        EXPECT_EQ(n.z, 0.0);
        const double ext = std::abs(n.x) * h.x + std::abs(n.y) * h.y, mid = n.x * c.x + n.y * c.y;
        lo = std::max(lo, mid - ext);
        hi = std::min(hi, mid + ext);
        if (hi <= lo) return 0.0;
        auto chord = [&](double off) {
            const dvec3 p0 = dvec3(n.x, n.y, 0) * off, d(-n.y, n.x, 0);
            double u0 = -1e300, u1 = 1e300;
            for (int a = 0; a < 2; ++a) {
                const double lo_a = c[a] - h[a] - p0[a], hi_a = c[a] + h[a] - p0[a];
                if (std::abs(d[a]) < 1e-15) {
                    if (lo_a > 0 || hi_a < 0) return 0.0;
                    continue;
                }
                const double t0 = lo_a / d[a], t1 = hi_a / d[a];
                u0 = std::max(u0, std::min(t0, t1));
                u1 = std::min(u1, std::max(t0, t1));
            }
            return std::max(0.0, u1 - u0);
        };
        const int steps = 20000;
        double sum = 0.0;
        for (int i = 0; i < steps; ++i) sum += chord(lo + (hi - lo) * (i + 0.5) / steps);
        return sum * (hi - lo) / steps * 2.0 * h.z;
    };
    return s;
}

vdb::Volume volumeOf(const Solid& s) { return fieldVolume(Coord(40), Vec3d(1.0), Vec3d(-19.5), s.field); }

/// A vertical cutting plane n.x = c: its name, the stroke along it (the base
/// at z = 22 mm moving along the plane from u0 to u1, the blade pointing down,
/// length len: 45 mm cuts through the whole grid).
struct CutPlane
{
    std::string name;
    dvec3 n;
    double c;
    std::vector<Pose> stroke(double u0, double u1, double len) const
    {
        const dvec3 m(-n.y, n.x, 0.0);
        const dvec3 o = c * n + dvec3(0, 0, 22);
        return straightStroke(o + u0 * m, o + u1 * m, dvec3(0, 0, -1), len, int(std::ceil(4 * (u1 - u0))));
    }
};

std::vector<std::pair<Solid, CutPlane>> throughCuts()
{
    const double a = 23.0 * M_PI / 180.0;
    return {
        {sphereSolid(), {"y = 0.37", dvec3(0, 1, 0), 0.37}},
        {sphereSolid(), {"oblique 23 deg", dvec3(std::cos(a), std::sin(a), 0), -3.1}},
        {boxSolid(), {"x = 1.37", dvec3(1, 0, 0), 1.37}},
        {boxSolid(), {"oblique 23 deg", dvec3(std::cos(a), std::sin(a), 0), 0.8}},
    };
}

class CutProps : public ::testing::TestWithParam<double>
{
};

} // namespace

// ----------------------------------------------------------- the checker ---

// The CGAL checker itself: a clean closed surface has no self-intersection;
// two interpenetrating boxes do; triangles that share only a vertex, or an
// edge with a fold that does not lie back onto the other, do not; a fold
// flat onto its neighbour across the shared edge does.
TEST(SelfIntersect, CheckerSeesWhatItShould)
{
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh sphere = extractIsosurface(vol, 0.0f);
    ASSERT_TRUE(checkMesh(sphere).ok());
    EXPECT_EQ(selfIntersections(sphere).count(), 0u);

    auto box = [](Mesh& m, dvec3 lo, dvec3 hi) {
        const uint32_t base = uint32_t(m.positions.size());
        for (int c = 0; c < 8; ++c)
            m.positions.emplace_back(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
        const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
        for (const auto& q : quads) {
            for (uint32_t i : {q[0], q[1], q[2], q[0], q[2], q[3]}) m.indices.push_back(base + i);
            m.triangleVoxels.emplace_back(0);
            m.triangleVoxels.emplace_back(0);
        }
    };
    Mesh one;
    box(one, dvec3(0), dvec3(1));
    ASSERT_TRUE(checkMesh(one).ok()) << checkMesh(one).report();
    EXPECT_EQ(selfIntersections(one).count(), 0u);
    Mesh two = one;
    box(two, dvec3(0.5, 0.25, 0.3), dvec3(1.5, 1.25, 1.3));
    EXPECT_GT(selfIntersections(two).count(), 0u);
    Mesh apart = one;
    box(apart, dvec3(2, 0, 0), dvec3(3, 1, 1));
    EXPECT_EQ(selfIntersections(apart).count(), 0u);

    // A fan of 4 triangles around vertex 0 (a manifold patch): the first and
    // the third share vertex 0 only and meet nowhere else.
    auto fan = [](std::array<glm::vec3, 4> ring) {
        Mesh m;
        m.positions = {{0, 0, 0}, ring[0], ring[1], ring[2], ring[3]};
        m.indices = {0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1};
        m.triangleVoxels.assign(4, glm::ivec3(0));
        return m;
    };
    EXPECT_EQ(selfIntersections(fan({glm::vec3(1, 0, 0), {0, 1, 0.5f}, {-1, 0, 0}, {0, -1, 0.5f}})).count(), 0u);
    // The same fan with the third triangle crossing the first beyond vertex 0.
    EXPECT_GT(selfIntersections(fan({glm::vec3(1, 0, 0), {0, 1, 0}, {0.5f, 0.2f, -1}, {0.2f, 0.5f, 1}})).count(), 0u);
    // Sharing an edge (a hinge at 90 degrees): none.
    Mesh e;
    e.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    e.indices = {0, 1, 2, 1, 0, 3};
    EXPECT_EQ(selfIntersections(e).count(), 0u);
    // Sharing an edge, the second folded flat back onto the first: overlap beyond the edge.
    Mesh f;
    f.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3f, 0.5f, 0}};
    f.indices = {0, 1, 2, 1, 0, 3};
    EXPECT_GT(selfIntersections(f).count(), 0u);
    // Touching at one point without sharing a vertex: an intersection.
    Mesh t;
    t.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {-1, 0, 0.5f}, {0, -1, 0.25f}};
    t.indices = {0, 1, 2, 3, 4, 5};
    EXPECT_GT(selfIntersections(t).count(), 0u);

    // A local check (pairs within `only`) converts only the part of the mesh
    // around `only`, and answers as the whole mesh does for those pairs: two
    // triangles that share just a vertex still share it there.
    auto within = [](const Mesh& m, const std::vector<uint32_t>& only) {
        std::vector<std::pair<uint32_t, uint32_t>> want;
        for (const auto& p : selfIntersections(m).pairs)
            if (std::count(only.begin(), only.end(), p.first) && std::count(only.begin(), only.end(), p.second))
                want.push_back(p);
        return want;
    };
    const Mesh apartFan = fan({glm::vec3(1, 0, 0), {0, 1, 0.5f}, {-1, 0, 0}, {0, -1, 0.5f}});
    const Mesh crossingFan = fan({glm::vec3(1, 0, 0), {0, 1, 0}, {0.5f, 0.2f, -1}, {0.2f, 0.5f, 1}});
    const std::vector<uint32_t> firstAndThird{2, 0};
    EXPECT_EQ(selfIntersections(apartFan, &firstAndThird).count(), 0u);
    EXPECT_EQ(selfIntersections(crossingFan, &firstAndThird).pairs, within(crossingFan, firstAndThird));
    EXPECT_EQ(selfIntersections(crossingFan, &firstAndThird).count(), 1u);
    std::vector<uint32_t> someOfTwo; // the first box's triangles and half the second's
    for (uint32_t tri = 0; tri < 24; ++tri)
        if (tri < 12 || tri % 2) someOfTwo.push_back(tri);
    const auto local = selfIntersections(two, &someOfTwo);
    EXPECT_GT(local.count(), 0u);
    EXPECT_EQ(local.pairs, within(two, someOfTwo));
    EXPECT_THROW(selfIntersections(f, &firstAndThird), std::invalid_argument) << "f has 2 triangles";
}

// The uncut 4 mm head's isosurface has no self-intersection (exactly, with
// the float positions as they are), so any the cut tests find come from the cut.
TEST(SelfIntersect, UncutHeadHasNone)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    const auto t0 = std::chrono::steady_clock::now();
    const auto si = selfIntersections(uncut);
    std::printf("uncut 4 mm head: %zu triangles, %zu self-intersecting pairs (%.2f s)\n", uncut.triangleCount(),
                si.count(), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    EXPECT_EQ(si.count(), 0u);
}

namespace {

struct StateStats
{
    CapStats caps;
    TouchStats touches;
    size_t cgalChecks = 0;
    size_t kerfIntersecting = 0; ///< w > 0 states with self-intersections (counted and printed, then asserted zero: see the head tests)
};

/// The checks every cut state gets besides checkMesh: untouched outside the
/// re-meshed cells (invariant 9), cap vertices near the swept surface
/// (invariant 10), and when `cgal`, self-intersections near the cut: none for
/// w > 0 (invariant 7), only on the swept surface for w = 0.
void checkState(const Mesh& uncut, const Mesh& fused, const CutRemesher& remesher, const CutMask& mask, bool cgal,
                StateStats& st, const std::string& what, bool countKerfIntersections = false)
{
    std::string why;
    EXPECT_TRUE(untouchedOutside(uncut, fused, remesher, why)) << what << ": " << why;
    const CapStats caps = capDistances(remesher, mask);
    EXPECT_LE(caps.maxMm, caps.diagonalMm) << what << ": a cap vertex " << caps.maxMm
                                           << " mm from the swept surface (one voxel diagonal: " << caps.diagonalMm
                                           << " mm)";
    st.caps.merge(caps);
    if (!cgal) return;
    const TouchStats t = touchesNearCut(fused, remesher, mask, 1e-3);
    if (mask.kerf() > 0 && countKerfIntersections) {
        if (t.pairs > 0) {
            ++st.kerfIntersecting;
            std::printf("known defect: %s: %zu self-intersecting triangle pairs near the cut\n", what.c_str(), t.pairs);
        }
    } else if (mask.kerf() > 0) {
        EXPECT_EQ(t.pairs, 0u) << what << ": self-intersecting triangle pairs near the cut";
    } else {
        EXPECT_EQ(t.offBlade, 0u) << what << ": triangle pairs meeting off the swept surface";
    }
    st.touches.merge(t);
    ++st.cgalChecks;
}

void printState(const char* what, const StateStats& st)
{
    std::printf("%s: cap vertices %zu (%zu on the swept surface within 1e-4 mm), largest distance %.4g mm = %.4f of "
                "the bound %.4g mm (one voxel diagonal); CGAL checks %zu: %zu touching pairs at the cut (%zu "
                "with a cap piece), %zu off the swept surface, %zu pinch contacts (%.1f s finding, %.1f s classifying)\n",
                what, st.caps.vertices, st.caps.onSurface, st.caps.maxMm, st.caps.maxMm / st.caps.diagonalMm,
                st.caps.diagonalMm, st.cgalChecks, st.touches.cutPairs, st.touches.coplanar, st.touches.offBlade,
                st.touches.pinchContacts,
                st.touches.findSeconds, st.touches.classifySeconds);
}

} // namespace

// ----------------------------------------------------- analytic solids ---

// A sphere and a box cut through by a plane (axis-aligned but off the grid,
// and oblique): exactly 2 fragments, zero defects; invariant 10: the
// fragments' total volume is the uncut volume minus the kerf slab within one
// tet per cut cell, and each fragment is its analytic side within that bound
// plus the isosurface's own error; outside the cut cells nothing changes;
// caps within one voxel diagonal of the blade; for w > 0 no self-intersection
// anywhere (whole mesh), for w = 0 the two sides touch only on the blade.
TEST_P(CutProps, SphereAndBoxCutThroughGiveTwoFragmentsWithinTheVolumeBound)
{
    const double w = GetParam();
    StateStats st;
    for (const auto& [solid, plane] : throughCuts()) {
        const std::string what = solid.name + " cut by " + plane.name + ", " + kerfName(w);
        SCOPED_TRACE(what);
        const vdb::Volume vol = volumeOf(solid);
        const Mesh uncut = extractIsosurface(vol, 0.0f);
        ASSERT_TRUE(checkMesh(uncut).ok());
        const double v0 = meshVolume(uncut);
        CutMask mask(frameOf(vol), w);
        addStroke(mask, plane.stroke(-28, 28, 45));
        CutRemesher remesher(vol, 0.0f, uncut);
        UPDATE_OR_SKIP(remesher, mask);
        const Mesh fused = remesher.fusedMesh();
        const MeshCheck check = checkMesh(fused);
        EXPECT_TRUE(check.ok()) << check.report();
        const std::vector<Fragment> frags = fragmentsOf(fused);
        ASSERT_EQ(frags.size(), 2u);

        const double bound = double(mask.cutCellCount()) * largestTetVolume(mask.frame());
        const double slab = w > 0 ? solid.between(plane.n, plane.c - 0.5 * w, plane.c + 0.5 * w) : 0.0;
        const double sum = frags[0].volume + frags[1].volume;
        const double errUncut = sum - (v0 - slab);
        const double isoErr = v0 - solid.volume;
        const double errExact = sum - (solid.volume - slab);
        EXPECT_LE(std::abs(errUncut), bound);
        EXPECT_LE(std::abs(errExact), bound + std::abs(isoErr));
        double sideErr = 0.0;
        for (const Fragment& f : frags) {
            dvec3 mean(0.0);
            for (const glm::vec3& p : f.mesh.positions) mean += dvec3(p);
            mean /= double(f.mesh.positions.size());
            const bool plus = glm::dot(plane.n, mean) > plane.c;
            const double side = plus ? solid.between(plane.n, plane.c + 0.5 * w, 1e9)
                                     : solid.between(plane.n, -1e9, plane.c - 0.5 * w);
            EXPECT_LE(std::abs(f.volume - side), bound + std::abs(isoErr)) << (plus ? "+" : "-") << " side";
            sideErr = std::max(sideErr, std::abs(f.volume - side));
        }
        std::printf("%s: %zu cut cells, bound %.1f mm^3 (x %.4g mm^3 per tet); fragments %.2f + %.2f mm^3; vs uncut "
                    "minus slab %.1f: error %.3g mm^3 = %.2g of the bound; vs exact solid: %.3g (isosurface error "
                    "%.3g); worst side vs analytic %.3g\n",
                    what.c_str(), mask.cutCellCount(), bound, largestTetVolume(mask.frame()), frags[0].volume,
                    frags[1].volume, slab, errUncut, errUncut / bound, errExact, isoErr, sideErr);

        checkState(uncut, fused, remesher, mask, true, st, what);
        if (w > 0) {
            EXPECT_EQ(selfIntersections(fused).count(), 0u);
        }
    }
    printState(("through cuts, " + kerfName(w)).c_str(), st);
}

// Cuts that stop inside (a notch half way across, a blade whose tip stays
// inside, both): 1 fragment, closed and manifold (zero defects); the volume
// is kept (w = 0) or loses at most the full slab (w > 0), within invariant
// 10's bound; same outside, cap and self-intersection checks as above.
TEST_P(CutProps, CutsThatStopInsideLeaveOneClosedManifoldFragment)
{
    const double w = GetParam();
    StateStats st;
    struct Stop
    {
        const char* name;
        double u1, len;
    };
    const Stop stops[] = {{"notch half way", 0.3, 45}, {"tip inside", 28, 30}, {"notch with the tip inside", 0.3, 30}};
    for (const auto& [solid, plane] : throughCuts()) {
        const vdb::Volume vol = volumeOf(solid);
        const Mesh uncut = extractIsosurface(vol, 0.0f);
        const double v0 = meshVolume(uncut);
        for (const Stop& s : stops) {
            const std::string what = solid.name + ", " + plane.name + ", " + s.name + ", " + kerfName(w);
            SCOPED_TRACE(what);
            CutMask mask(frameOf(vol), w);
            addStroke(mask, plane.stroke(-28, s.u1, s.len));
            CutRemesher remesher(vol, 0.0f, uncut);
            UPDATE_OR_SKIP(remesher, mask);
            const Mesh fused = remesher.fusedMesh();
            const MeshCheck check = checkMesh(fused);
            EXPECT_TRUE(check.ok()) << check.report();
            EXPECT_EQ(check.boundaryEdges + check.nonManifoldEdges + check.nonManifoldVertices, 0u);
            EXPECT_EQ(fragmentsOf(fused).size(), 1u);
            EXPECT_EQ(check.shells, 1u);
            const double bound = double(mask.cutCellCount()) * largestTetVolume(mask.frame());
            const double lost = v0 - meshVolume(fused);
            if (w > 0) {
                const double slab = solid.between(plane.n, plane.c - 0.5 * w, plane.c + 0.5 * w);
                EXPECT_GE(lost, -bound);
                EXPECT_LE(lost, slab + bound);
            } else {
                EXPECT_LE(std::abs(lost), bound);
            }
            std::printf("%s: %zu cut cells, volume lost %.3g mm^3 (bound %.1f)\n", what.c_str(), mask.cutCellCount(),
                        lost, bound);
            // CGAL for w = 0 (slow: coincident caps) on the oblique planes only.
            checkState(uncut, fused, remesher, mask, w > 0 || plane.name.rfind("oblique", 0) == 0, st, what);
            if (w > 0) {
            EXPECT_EQ(selfIntersections(fused).count(), 0u);
        }
        }
    }
    printState(("stopping cuts, " + kerfName(w)).c_str(), st);
}

// Two strokes crossing, cutting the sphere through along y = 0.37 and then
// x = 3.21: 4 fragments, zero defects; the volume lost is the two slabs minus
// their common column (w^2 times the sphere's chord there), within invariant
// 10's bound; the usual outside, cap and self-intersection checks.
TEST_P(CutProps, TwoCrossingCutsThroughTheSphereGiveFourFragments)
{
    const double w = GetParam();
    const Solid solid = sphereSolid();
    const vdb::Volume vol = volumeOf(solid);
    const Mesh uncut = extractIsosurface(vol, 0.0f);
    const double v0 = meshVolume(uncut);
    const CutPlane a{"y = 0.37", dvec3(0, 1, 0), 0.37}, b{"x = 3.21", dvec3(1, 0, 0), 3.21};
    CutMask mask(frameOf(vol), w);
    addStroke(mask, a.stroke(-28, 28, 45));
    addStroke(mask, b.stroke(-28, 28, 45));
    CutRemesher remesher(vol, 0.0f, uncut);
    UPDATE_OR_SKIP(remesher, mask);
    const Mesh fused = remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    EXPECT_EQ(fragmentsOf(fused).size(), 4u);
    const double bound = double(mask.cutCellCount()) * largestTetVolume(mask.frame());
    const double column = w * w * 2.0 * std::sqrt(15.0 * 15.0 - a.c * a.c - b.c * b.c);
    const double slabs = w > 0 ? solid.between(a.n, a.c - 0.5 * w, a.c + 0.5 * w) +
                                     solid.between(b.n, b.c - 0.5 * w, b.c + 0.5 * w) - column
                               : 0.0;
    const double err = meshVolume(fused) - (v0 - slabs);
    EXPECT_LE(std::abs(err), bound);
    std::printf("two crossing cuts, %s: %zu cut cells, volume error %.3g mm^3 = %.2g of the bound %.1f\n",
                kerfName(w).c_str(), mask.cutCellCount(), err, err / bound, bound);
    StateStats st;
    checkState(uncut, fused, remesher, mask, true, st, "two crossing cuts, " + kerfName(w));
    printState(("two crossing cuts, " + kerfName(w)).c_str(), st);
}

// ------------------------------------------------------------ real heads ---

namespace {

struct HeadStats
{
    size_t strokes = 0, refused = 0, cells = 0, defects = 0, undoChecks = 0;
    size_t kept = 0; ///< cells kept (not re-meshed) by updates, each checked against a re-mesh
    size_t historyDiffs = 0; ///< redo in one update gave rotated triangles (known defect)
    StateStats state;
    std::vector<std::string> refusals;
};

/// One head being cut stroke after stroke.
struct HeadRun
{
    HeadRun(const vdb::Volume& vol, const Mesh& uncutMesh, float iso, double kerf)
        : uncut(uncutMesh), mask(frameOf(vol), kerf), remesher(vol, iso, uncutMesh), current(uncutMesh)
    {
        remesher.setVerifyKeptCellsForTesting(true);
    }
    const Mesh& uncut;
    CutMask mask;
    CutRemesher remesher;
    Mesh current; ///< the last good fused mesh
};

/// Adds one stroke to `run` and checks: zero checkMesh defects, the state
/// checks (checkState), undo of the stroke gives the earlier mesh exactly and
/// redo the new one; with `partial`, the stroke is first updated at half its
/// quads, and undo back to that stick gives that mesh exactly. A refusal
/// ("remesh: ... cell") must leave the remesher's mesh as it was; it is
/// counted and the stroke undone. Returns KerfTodo to skip.
Outcome cutStroke(HeadRun& run, const std::vector<Pose>& poses, const std::string& what, bool cgal, bool partial,
                  HeadStats& st)
{
    const std::vector<Quad> quads = filterStroke(poses, run.mask.frame());
    if (quads.empty()) return Outcome::Ok;
    const size_t half = partial && quads.size() >= 4 ? quads.size() / 2 : 0;
    run.mask.beginStroke();
    Mesh mid;
    bool midDone = false;
    auto refused = [&](const UpdateResult& u) {
        ++st.refused;
        st.refusals.push_back(what + ": " + u.message);
        std::printf("refused: %s: %s\n", what.c_str(), u.message.c_str());
        EXPECT_TRUE(sameMesh(run.remesher.fusedMesh(), midDone ? mid : run.current))
            << what << ": a refusal changed the mesh";
        EXPECT_TRUE(run.mask.undoStroke());
        const UpdateResult back = tryUpdate(run.remesher, run.mask);
        EXPECT_EQ(back.outcome, Outcome::Ok) << back.message;
        if (!midDone) {
            EXPECT_EQ(back.cells, 0u) << what << ": after a refusal and undo there should be nothing to do";
        }
        EXPECT_TRUE(sameMesh(run.remesher.fusedMesh(), run.current)) << what << ": undo after a refusal";
    };
    ++st.strokes;
    for (size_t q = 0; q < quads.size(); ++q) {
        run.mask.addQuad(quads[q]);
        if (q + 1 != half) continue;
        const UpdateResult u = tryUpdate(run.remesher, run.mask);
        if (u.outcome == Outcome::KerfTodo) return u.outcome;
        if (u.outcome == Outcome::Refused) {
            refused(u);
            return Outcome::Ok;
        }
        st.kept += u.kept;
        mid = run.remesher.fusedMesh();
        midDone = true;
    }
    const UpdateResult u = tryUpdate(run.remesher, run.mask);
    if (u.outcome == Outcome::KerfTodo) return u.outcome;
    if (u.outcome == Outcome::Refused) {
        refused(u);
        return Outcome::Ok;
    }
    st.cells += u.cells;
    st.kept += u.kept;
    Mesh fused = run.remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    st.defects += check.defects();
    EXPECT_TRUE(check.ok()) << what << "\n" << check.report();
    checkState(run.uncut, fused, run.remesher, run.mask, cgal && check.ok(), st.state, what, true);

    auto expectBack = [&](const Mesh& want, const char* step) {
        const UpdateResult r = tryUpdate(run.remesher, run.mask);
        st.kept += r.kept;
        EXPECT_EQ(r.outcome, Outcome::Ok) << what << ", " << step << ": " << r.message;
        EXPECT_TRUE(sameMesh(run.remesher.fusedMesh(), want)) << what << ", " << step << ": not the earlier mesh";
        ++st.undoChecks;
    };
    if (half) {
        run.mask.undoToQuad(uint32_t(half));
        expectBack(mid, "undo to the middle stick");
        EXPECT_TRUE(run.mask.redoStroke());
        expectBack(fused, "redo after undo to the middle stick");
    }
    EXPECT_TRUE(run.mask.undoStroke());
    expectBack(run.current, "undo of the stroke");
    EXPECT_TRUE(run.mask.redoStroke());
    if (!half) {
        expectBack(fused, "redo of the stroke");
    } else {
        // The stroke was meshed in two updates; redo meshes it in one: the same
        // arrays (LiveUpdatesGiveTheBatchMeshExactly); counted if not.
        const UpdateResult r = tryUpdate(run.remesher, run.mask);
        EXPECT_EQ(r.outcome, Outcome::Ok) << what << ", redo: " << r.message;
        Mesh redone = run.remesher.fusedMesh();
        if (!sameMesh(redone, fused)) {
            ++st.historyDiffs;
            EXPECT_TRUE(sameTriangles(redone, fused)) << what << ": redo in one update is not the same triangles";
            ADD_FAILURE() << what << ": redo in one update is not the same mesh (arrays)";
        }
        fused = std::move(redone);
    }
    run.current = std::move(fused);
    return Outcome::Ok;
}

/// Hand-made strokes on a head, relative to its box: name and strokes (cut
/// one after another on one mask).
std::vector<std::pair<std::string, std::vector<std::vector<Pose>>>> handStrokes(const IndexFrame& f)
{
    const dvec3 lo = f.toWorld(dvec3(0.0)), hi = f.toWorld(dvec3(f.dims - 1));
    // The free-hand shapes are placed off the grid (C is no grid vertex and no
    // base line lies in a grid plane); the grid-aligned ones below are exact.
    const dvec3 C = 0.5 * (lo + hi) + dvec3(0.37, -0.21, 0.43), E = hi - lo;
    const double step = 0.5; // mm per pose
    std::vector<std::pair<std::string, std::vector<std::vector<Pose>>>> out;
    auto curve = [&](const std::function<dvec3(double)>& base, const std::function<dvec3(double)>& dir, double len,
                     double t0, double t1) {
        // About `step` mm of base motion per pose.
        double arc = 0.0;
        const int probe = 1000;
        for (int i = 0; i < probe; ++i)
            arc += glm::length(base(t0 + (t1 - t0) * (i + 1) / probe) - base(t0 + (t1 - t0) * i / probe));
        const int n = std::max(2, int(arc / step));
        std::vector<Pose> poses;
        for (int i = 0; i <= n; ++i) {
            const double t = t0 + (t1 - t0) * i / n;
            poses.push_back(pose(0.001 * i, base(t), glm::normalize(dir(t)), len));
        }
        return poses;
    };
    auto line = [&](dvec3 a, dvec3 b, dvec3 dir, double len) {
        return curve([=](double t) { return a + t * (b - a); }, [=](double) { return dir; }, len, 0.0, 1.0);
    };
    out.push_back({"straight", {line(C + E * dvec3(-0.45, 0.05, 0.45), C + E * dvec3(0.45, 0.05, 0.45),
                                     dvec3(0.15, 0.1, -1), 0.55 * E.z)}});
    const double r = 0.3 * std::min(E.x, E.y);
    out.push_back({"curved", {curve([=](double a) { return C + dvec3(r * std::cos(a), r * std::sin(a), 0.15 * E.z); },
                                    [=](double a) { return dvec3(-0.3 * std::cos(a), -0.3 * std::sin(a), -1); },
                                    0.3 * E.z, -0.2 * M_PI, 1.2 * M_PI)}});
    // Sawing back over the curve to its start and on past it (rule 2b's
    // restart: no chord from the far end across the bone).
    {
        const auto arcBase = [=](double a) { return C + dvec3(r * std::cos(a), r * std::sin(a), 0.15 * E.z); };
        const auto arcDir = [=](double a) { return dvec3(-0.3 * std::cos(a), -0.3 * std::sin(a), -1); };
        std::vector<Pose> poses = curve(arcBase, arcDir, 0.3 * E.z, -0.2 * M_PI, 0.6 * M_PI);
        for (const auto& [a0, a1] : {std::pair<double, double>{0.6 * M_PI, -0.2 * M_PI}, {-0.2 * M_PI, -0.45 * M_PI}}) {
            const std::vector<Pose> more = curve(arcBase, arcDir, 0.3 * E.z, a0, a1);
            for (size_t i = 1; i < more.size(); ++i) {
                poses.push_back(more[i]);
                poses.back().time = 0.001 * double(poses.size());
            }
        }
        out.push_back({"curved, back over it and out past its start", {poses}});
    }
    out.push_back({"self-crossing figure eight",
                   {curve([=](double t) {
                              return C + dvec3(0.3 * E.x * std::sin(t), 0.25 * E.y * std::sin(t) * std::cos(t), 0.1 * E.z);
                          },
                          [](double) { return dvec3(0.1, 0.2, -1); }, 0.25 * E.z, 0.15, 2 * M_PI - 0.15)}});
    // The same figure eight run on until it retraces its start (t 0.15 .. 2 pi + 0.3).
    out.push_back({"figure eight retracing its start",
                   {curve([=](double t) {
                              return C + dvec3(0.3 * E.x * std::sin(t), 0.25 * E.y * std::sin(t) * std::cos(t), 0.1 * E.z);
                          },
                          [](double) { return dvec3(0.1, 0.2, -1); }, 0.25 * E.z, 0.15, 2 * M_PI + 0.3)}});
    const double a = 0.06 * E.x, b = 0.16 * E.x;
    out.push_back({"self-crossing loop",
                   {curve([=](double t) {
                              return C + dvec3(a * (t - M_PI) - b * std::sin(t), b * std::cos(t), 0.2 * E.z);
                          },
                          [](double) { return dvec3(0.3, -0.2, -1); }, 0.25 * E.z, 0.0, 2 * M_PI)}});
    out.push_back({"two strokes crossing",
                   {line(C + E * dvec3(-0.45, -0.1, 0.35), C + E * dvec3(0.45, -0.1, 0.35), dvec3(0, 0, -1), 0.4 * E.z),
                    line(C + E * dvec3(0.05, -0.45, 0.35), C + E * dvec3(0.05, 0.45, 0.35), dvec3(0.1, 0, -1),
                         0.4 * E.z)}});
    // Blades lying exactly in grid planes (x = i, y = j, z = k in world mm).
    const glm::ivec3 mid = f.dims / 2;
    const dvec3 g = f.toWorld(dvec3(mid));
    out.push_back({"blade in the grid plane z = k",
                   {line(dvec3(lo.x + 0.05 * E.x, lo.y - 5, g.z), dvec3(hi.x - 0.05 * E.x, lo.y - 5, g.z),
                         dvec3(0, 1, 0), 0.5 * E.y)}});
    out.push_back({"blade in the grid plane x = i",
                   {line(dvec3(g.x, lo.y - 5, hi.z + 5), dvec3(g.x, hi.y + 5, hi.z + 5), dvec3(0, 0, -1), 0.6 * E.z)}});
    out.push_back({"blade in the grid plane y = j",
                   {line(dvec3(lo.x - 5, g.y, hi.z + 5), dvec3(hi.x + 5, g.y, hi.z + 5), dvec3(0, 0, -1), 0.6 * E.z)}});
    // Through grid vertices exactly: bases on grid vertices, one pose per vertex.
    {
        const int i0 = int(0.15 * f.dims.x), i1 = int(0.85 * f.dims.x);
        const int j0 = int(0.3 * f.dims.y), k0 = int(0.3 * f.dims.z);
        std::vector<Pose> diag, vert;
        const dvec3 d111 = glm::normalize(f.spacing); // index direction (1,1,1)
        for (int i = i0; i <= i1; ++i)
            diag.push_back(pose(0.001 * (i - i0), f.toWorld(dvec3(i, j0, k0)), d111, 25.0 * glm::length(f.spacing)));
        const int stairs = int(0.4 * std::min(f.dims.x, f.dims.y));
        for (int n = 0; n <= 2 * stairs; ++n)
            vert.push_back(pose(0.001 * n, f.toWorld(dvec3(i0 + (n + 1) / 2, j0 + n / 2, k0)), dvec3(0, 0, 1), 0.5 * E.z));
        // vert: the base walks grid vertices along x and y in turn (a staircase of
        // quads in grid planes x = i and y = j, turning 90 degrees at every stick).
        out.push_back({"blade through grid vertices along (1,1,1)", {diag}});
        out.push_back({"staircase of grid vertices, blade along z", {vert}});
    }
    return out;
}

/// Random strokes of makeRandomStrokes with parameters varied by seed (as
/// bench_strokes makes them; `turn` as its --turn).
std::vector<std::vector<Pose>> randomStrokes(const IndexFrame& f, uint32_t seed, int count, double turn = 0.05)
{
    return makeRandomStrokes(f, seed, count, 150 + 50 * int(seed % 5), 0.4 + 0.2 * (seed % 4),
                             20.0 + 10.0 * (seed % 4), turn);
}

void printHead(const std::string& what, const HeadStats& st, double seconds)
{
    std::printf("%s: %zu strokes, %zu refused, %zu cells re-meshed, %zu kept, %zu defects, %zu exact undo/redo checks (%zu redo "
                "meshes with rotated triangles), %.1f s\n",
                what.c_str(), st.strokes, st.refused, st.cells, st.kept, st.defects, st.undoChecks, st.historyDiffs, seconds);
    printState(what.c_str(), st.state);
}

/// Kerf > 0 on the heads: no self-intersection once written (the issue's
/// goal, met 2026-11-23). In double positions the cells never intersected
/// themselves; rounding to float world mm folded sub-micron features over
/// (seed 1015's last stroke: an inner mitre vertex 1.5e-5 voxel off a cell
/// face rounded onto it, 4 pairs; the self-crossing figure eight on the 4 mm
/// head: two face vertices of nearly equal planes 5e-6 mm apart rounded
/// apart, 3 pairs). The kernel's repairFloatFolds now collapses such
/// float-short edges. Each stroke with pairs is still printed ("known
/// defect") before the count is asserted, so a failure says where. No
/// refusal (the last one, an open edge at a mitre in seed 1017, is
/// PointsOnAMitreLineAreNamedApart; the pivot pinches that were refused are
/// split into fans). No refusal at w = 0 either: the last, the figure eight
/// retracing its start, no longer folds its strip since the path filter
/// drops poses that retrace any quad of the stroke (the same retrace as two
/// strokes is still refused: RetracedStrokeStartIsNeverSilentlyNonManifold).

} // namespace

// Seeded random strokes on the 4 mm head (curved, turning, sometimes self-
// crossing; each seed's strokes accumulate on one mask, so they cross each
// other): every fused mesh clean, untouched outside, exact undo/redo of each
// stroke and back to its middle stick, caps near the blade; refusals rare.
TEST_P(CutProps, RandomStrokesOnThe4mmHead)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    const double w = GetParam();
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    const IndexFrame frame = frameOf(vol);
    HeadStats st;
    const auto t0 = std::chrono::steady_clock::now();
    for (uint32_t seed = 1001; seed <= 1026; ++seed) {
        HeadRun run(vol, uncut, 400.0f, w);
        const auto strokes = randomStrokes(frame, seed, 4);
        for (size_t s = 0; s < strokes.size(); ++s) {
            const std::string what = "seed " + std::to_string(seed) + " stroke " + std::to_string(s) + ", " + kerfName(w);
            // CGAL after the last stroke of a seed (the strokes accumulate, so
            // its mesh holds every earlier stroke's cut too): every seed for
            // w > 0, every third for w = 0 (its coincident caps make it slow).
            const bool cgal = s + 1 == strokes.size() && (w > 0 || seed % 3 == 0);
            if (cutStroke(run, strokes[s], what, cgal, s % 2 == 0, st) == Outcome::KerfTodo) {
                GTEST_SKIP() << kKerfTodo;
            }
        }
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    printHead("4 mm head, random strokes, " + kerfName(w), st, seconds);
    EXPECT_EQ(st.defects, 0u);
    // None refused (the last ones: seed 1021 at w = 0, seed 1017 at w = 0.5,
    // see CutPropsDefects).
    EXPECT_EQ(st.refused, 0u) << st.refusals.front();
    EXPECT_EQ(st.state.kerfIntersecting, 0u);
    // Updates kept cells (each verified against a re-mesh by the remesher).
    EXPECT_GT(st.kept, 0u);
}

// A saw worked back and forth on the 4 mm head (cutter::makeSawingStrokes,
// `bench_strokes --saw both`): four strokes a seed, each 400 poses swinging
// the blade across itself while pushing it deeper or sliding it along its
// own line while it advances, with a hand's tremor, each pass mostly over
// the cut already made. Cut live (updated after every quad): no stroke
// stops, and every seed's cut is the same as from scratch, clean (checkMesh,
// untouched outside the cut cells, caps on the swept surface, CGAL near the
// cut: none crossing with a kerf), and undoing its strokes one by one gives
// back the mesh before each exactly. The eight seeds are ones the re-mesher
// takes today at both widths (benchmarks/RESULTS.md, "A saw worked back and
// forth", has the sweep and the strokes it stops); they guard what works.
// The same with the path filter's retrace tolerance at a voxel (`--retrace
// 1`, "The retrace tolerance"): a third of the quads or fewer, the same checks;
// and five seeds whose passes fold back onto the last nearly in its plane.
TEST_P(CutProps, SawingBackAndForthOnThe4mmHead)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    const double w = GetParam();
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    StateStats st;
    size_t updates = 0, quads = 0, stepped = 0, quadsWide = 0;
    std::vector<std::pair<double, uint32_t>> runs; // (retrace tolerance, seed)
    for (const double retrace : {PathFilterOptions{}.retraceTolerance, 1.0})
        for (uint32_t seed : {102u, 104u, 105u, 106u, 108u, 111u, 115u, 117u}) runs.emplace_back(retrace, seed);
    // Passes that fold back within 1e-3 rad, whose prisms borrow the
    // last one's faces (Remesh.AQuadFoldingBackOntoTheLastBorrowsItsFaces):
    // at kerf 0.5 they stopped on "triangulation failed" before; in 185 and
    // 223 the pass after the fold goes on nearly straight from it.
    const size_t sawingRuns = runs.size(); // the ratio of quads below is theirs
    runs.insert(runs.end(), {{1.0, 103u}, {0.5, 103u}, {0.5, 108u}, {1.0, 185u}, {1.0, 223u}});
    for (size_t run = 0; run < runs.size(); ++run) {
        const auto [retrace, seed] = runs[run];
        const std::string what =
            "sawing seed " + std::to_string(seed) + ", " + kerfName(w) + ", retrace " + std::to_string(retrace);
        SCOPED_TRACE(what);
        PathFilterOptions filterOptions;
        filterOptions.retraceTolerance = retrace;
        CutMask mask(frameOf(vol), w);
        CutRemesher remesher(vol, 400.0f, uncut);
        std::vector<Mesh> before{remesher.fusedMesh()};
        for (const std::vector<Pose>& poses : makeSawingStrokes(uncut.positions, seed, 4, SawMotion::Both)) {
            LiveStroke live(mask, remesher);
            const std::vector<Quad> stroke = filterStroke(poses, mask.frame(), filterOptions);
            for (size_t q = 0; q < stroke.size() && live.add(stroke[q]); ++q) {
                const LiveStroke::Result r = q + 1 < stroke.size() ? live.update() : live.finish();
                ++updates;
                ASSERT_NE(r.outcome, LiveStroke::Outcome::Stopped) << r.refusal;
            }
            ASSERT_FALSE(live.stopped());
            EXPECT_EQ(live.acceptedQuads(), stroke.size());
            if (run < sawingRuns) (retrace == 1.0 ? quadsWide : quads) += stroke.size();
            stepped += live.steppedRound();
            before.push_back(remesher.fusedMesh());
        }
        const Mesh fused = remesher.fusedMesh();
        const MeshCheck check = checkMesh(fused);
        EXPECT_TRUE(check.ok()) << check.report();
        checkState(uncut, fused, remesher, mask, true, st, what);
        CutRemesher scratch(vol, 400.0f, uncut);
        scratch.update(mask);
        EXPECT_TRUE(sameMesh(scratch.fusedMesh(), fused)) << "the live cut differs from a from-scratch cut";
        for (size_t k = before.size() - 1; k-- > 0;) {
            ASSERT_TRUE(mask.undoStroke());
            remesher.update(mask);
            EXPECT_TRUE(sameMesh(remesher.fusedMesh(), before[k])) << "undo of stroke " << k;
        }
    }
    std::printf("4 mm head, sawing, %s: %zu quads (%zu with retrace 1), %zu live updates, %zu stepped round\n",
                kerfName(w).c_str(), quads, quadsWide, updates, stepped);
    printState(("4 mm head, sawing, " + kerfName(w)).c_str(), st);
    EXPECT_GT(quads, 400u); // 671 before slides were held back (path filter rule 2c), 475 since
    EXPECT_LT(3 * quadsWide, quads);
}

// A saw swung across its blade on the 2 mm head at kerf 0, its strokes cut
// whole one after another: each cut is clean. Seed 78105 (two strokes): in
// cell (111, 56, 66) a tetrahedron of solid between three slits' sides had a
// face of no area once written, and the float repair's collapse of one of
// its edges (2e-3 mm) crushed it into two triangles lying on each other, a
// flat shell inside the solid (checkMesh: wrong way for its nesting).
// Seed 78119 (four strokes): a tetrahedron of solid 1e-7 mm thick between
// three slits' sides and the isosurface, a fragment of its own, judged
// inside the fragment whose sheets it lay on; a shell of the cell's own
// thinner than a float step now goes as a whole.
TEST(CutPropsDefects, ASawAcrossTheBladeAtKerf0IsCleanStrokeByStroke)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    for (const auto& [seed, strokes] : {std::pair{78105u, 2}, std::pair{78119u, 4}}) {
        CutMask mask(frameOf(vol), 0.0);
        CutRemesher remesher(vol, 400.0f, uncut);
        int stroke = 0;
        for (const std::vector<Pose>& poses : makeSawingStrokes(uncut.positions, seed, strokes, SawMotion::Across)) {
            SCOPED_TRACE("seed " + std::to_string(seed) + " stroke " + std::to_string(stroke++));
            mask.beginStroke();
            for (const Quad& q : filterStroke(poses, mask.frame())) mask.addQuad(q);
            ASSERT_NO_THROW(remesher.update(mask));
            const MeshCheck check = checkMesh(remesher.fusedMesh());
            EXPECT_TRUE(check.ok()) << check.report();
        }
    }
}

// A slit chord split by the lines of many quads is walked whole: the 2 mm
// head at kerf 0, a saw swung across its blade, seed 78115, stroke 0 whole,
// then stroke 1 to its quad 85. In face z = 121 between cells (98, 68, 120)
// and (98, 68, 121) quad 8's chord runs between its two rim lines; in
// (..., 120), where 32 quads cross, the lines of 17 other quads' planes and
// sides split it into 18 pieces, in (..., 121) it is whole. splitChord's
// walk from the piece that holds the midpoint gave up after 16 hops, so only
// (..., 121) took the midpoint: an edge used once, the stroke stopped at
// quad 85 of 126. A walk now goes on for as many hops as the tet has
// vertices (each hop moves on along the line).
TEST(CutPropsDefects, AChordSplitByTheLinesOfManyQuadsIsWalkedWhole)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    CutMask mask(frameOf(vol), 0.0);
    CutRemesher remesher(vol, 400.0f, uncut);
    const auto strokes = makeSawingStrokes(uncut.positions, 78115, 2, SawMotion::Across);
    for (size_t s = 0; s < 2; ++s) {
        const std::vector<Quad> quads = filterStroke(strokes[s], mask.frame());
        if (s == 1) {
            ASSERT_EQ(quads.size(), 126u);
        }
        mask.beginStroke();
        for (size_t q = 0; q < quads.size() && (s == 0 || q <= 85); ++q) mask.addQuad(quads[q]);
        if (s == 0) remesher.update(mask);
    }
    ASSERT_NO_THROW(remesher.update(mask));
    const Mesh fused = remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    CutRemesher scratch(vol, 400.0f, uncut);
    scratch.update(mask);
    EXPECT_TRUE(sameMesh(scratch.fusedMesh(), fused)) << "the cut differs from a cut from scratch";
}

// A reflex cap region at kerf 0 whose ear clipping joins two rim points of
// its quad by a diagonal: the other side's region has the same corners and
// its ears the same diagonal, an edge used by both sides of the slit (twice
// each way). The tooth at 400, kerf 0, a saw swung across, seed 79002: quad
// 20 of stroke 1 in cell (20, 9, 130), tet 0, a region of eight corners
// bounded by quads 26 and 27, which no centre sees whole; the stroke stepped
// round there. Each such diagonal now gets a midpoint of the side's own. Cut
// with those three quads alone, and as the sweep cut it: stroke 0 whole,
// then stroke 1 to its quad 34.
TEST(CutPropsDefects, ARimToRimDiagonalOfACapIsSplitOnEachSide)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    const auto strokes = makeSawingStrokes(uncut.positions, 79002, 2, SawMotion::Across);
    auto expectClean = [&](const CutMask& mask, const char* what) -> Mesh {
        SCOPED_TRACE(what);
        CutRemesher remesher(vol, 400.0f, uncut);
        try {
            remesher.update(mask);
        } catch (const std::exception& e) {
            ADD_FAILURE() << "refused: " << e.what();
            return Mesh();
        }
        const MeshCheck check = checkMesh(remesher.fusedMesh());
        EXPECT_TRUE(check.ok()) << check.report();
        return remesher.fusedMesh();
    };
    {
        CutMask mask(frameOf(vol), 0.0);
        ASSERT_TRUE(test::addRimDiagonalQuads(mask, strokes));
        expectClean(mask, "quad 20, then quads 26 and 27");
    }
    CutMask mask(frameOf(vol), 0.0);
    CutRemesher live(vol, 400.0f, uncut);
    for (size_t s = 0; s < 2; ++s) {
        const std::vector<Quad> quads = filterStroke(strokes[s], mask.frame());
        mask.beginStroke();
        for (size_t q = 0; q < quads.size() && (s == 0 || q <= 34); ++q) mask.addQuad(quads[q]);
        if (s == 0) live.update(mask);
    }
    ASSERT_NO_THROW(live.update(mask));
    EXPECT_TRUE(sameMesh(live.fusedMesh(), expectClean(mask, "stroke 0, stroke 1 to quad 34")))
        << "the cut differs from a cut from scratch";
}

// Hand-made strokes on the 4 mm and 2 mm heads (straight, curved, a figure
// eight and a loop that cross themselves, two strokes crossing, blades in the
// grid planes x = i, y = j, z = k and through grid vertices), each on a fresh
// mask, with CGAL after every stroke; then a few random strokes on the 2 mm head.
TEST_P(CutProps, HandMadeStrokesOnTheHeads)
{
    const double w = GetParam();
    size_t found = 0;
    for (const char* name : {"vhm_head_4mm.nhdr", "vhm_head_2mm.nhdr"}) {
        const std::string path = mtcut::test::dataPath(name);
        if (path.empty()) continue;
        ++found;
        const vdb::Volume vol = vdb::readVolume(path);
        const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
        const IndexFrame frame = frameOf(vol);
        HeadStats st;
        const auto t0 = std::chrono::steady_clock::now();
        const bool fine = std::string(name) == "vhm_head_2mm.nhdr";
        // On the 2 mm head (4x the cells per stroke) a subset, CGAL for w > 0 only.
        const std::set<std::string> fineShapes = {"self-crossing figure eight", "blade in the grid plane z = k"};
        // CGAL for w = 0 (slow: the coincident caps touch everywhere) on the crossing shapes only.
        const std::set<std::string> crossing = {"self-crossing figure eight", "self-crossing loop",
                                                "two strokes crossing"};
        for (const auto& [shape, strokes] : handStrokes(frame)) {
            if (fine && !fineShapes.count(shape)) continue;
            HeadRun run(vol, uncut, 400.0f, w);
            for (size_t s = 0; s < strokes.size(); ++s) {
                const std::string what = std::string(name) + ", " + shape + " (stroke " + std::to_string(s) + "), " +
                                         kerfName(w);
                const bool cgal = w > 0 || (!fine && crossing.count(shape));
                if (cutStroke(run, strokes[s], what, cgal, true, st) == Outcome::KerfTodo) {
                    GTEST_SKIP() << kKerfTodo;
                }
            }
        }
        if (fine)
            for (uint32_t seed = 2001; seed <= 2001; ++seed) {
                HeadRun run(vol, uncut, 400.0f, w);
                const auto strokes = randomStrokes(frame, seed, 2);
                for (size_t s = 0; s < strokes.size(); ++s) {
                    const std::string what = std::string(name) + ", seed " + std::to_string(seed) + " stroke " +
                                             std::to_string(s) + ", " + kerfName(w);
                    if (cutStroke(run, strokes[s], what, w > 0 && s + 1 == strokes.size(), false, st) ==
                        Outcome::KerfTodo) {
                        GTEST_SKIP() << kKerfTodo;
                    }
                }
            }
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        printHead(std::string(name) + ", hand-made strokes, " + kerfName(w), st, seconds);
        EXPECT_EQ(st.defects, 0u);
        EXPECT_EQ(st.refused, 0u) << (st.refusals.empty() ? std::string() : st.refusals.front());
        EXPECT_EQ(st.state.kerfIntersecting, 0u);
        // The exact shapes (blades in grid planes, through grid vertices, the
        // staircase whose prisms' bottoms lie in one grid plane across 90
        // degree turns) are never refused, with or without kerf.
        for (const std::string& r : st.refusals)
            EXPECT_EQ(r.find("grid"), std::string::npos) << "an exact grid-aligned stroke was refused: " << r;
    }
    if (!found) GTEST_SKIP() << "shared data 'vhm_head_4mm.nhdr' / 'vhm_head_2mm.nhdr' not found (set MTCUT_DATA)";
}

namespace {

/// A stroke along the plane y = 0.37 through the sphere that bends as it
/// goes (base += (0, 6 u^2, 0), blade normalize(0.3 u, 0.1, -1), u = 0..1
/// along the stroke), so consecutive quads meet at mitre junctions.
std::vector<Pose> bentStroke()
{
    std::vector<Pose> poses = CutPlane{"y = 0.37", dvec3(0, 1, 0), 0.37}.stroke(-28, 28, 45);
    for (size_t i = 0; i < poses.size(); ++i) {
        const double u = double(i) / double(poses.size());
        poses[i].base += dvec3(0, 6 * u * u, 0);
        poses[i].direction = glm::normalize(dvec3(0.3 * u, 0.1, -1));
    }
    return poses;
}

/// The fused meshes of cutting `poses` updating after every quad (live) and once (batch).
std::pair<Mesh, Mesh> liveAndBatch(const vdb::Volume& vol, const Mesh& uncut, float iso, const std::vector<Pose>& poses,
                                   double kerf, bool& skip)
{
    CutMask mask(frameOf(vol), kerf);
    CutRemesher live(vol, iso, uncut);
    live.setVerifyKeptCellsForTesting(true);
    mask.beginStroke();
    skip = false;
    for (const Quad& q : filterStroke(poses, mask.frame())) {
        mask.addQuad(q);
        const UpdateResult u = tryUpdate(live, mask);
        skip = u.outcome == Outcome::KerfTodo;
        if (skip) return {};
        EXPECT_EQ(u.outcome, Outcome::Ok) << u.message;
    }
    CutRemesher batch(vol, iso, uncut);
    const UpdateResult u = tryUpdate(batch, mask);
    EXPECT_EQ(u.outcome, Outcome::Ok) << u.message;
    return {live.fusedMesh(), batch.fusedMesh()};
}

} // namespace

// Live cutting updates after every quad; a batch cut updates once. Both give
// the same triangles, with zero defects (the test below asks for the same
// arrays).
TEST_P(CutProps, LiveUpdatesGiveTheBatchTriangles)
{
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh uncut = extractIsosurface(vol, 0.0f);
    bool skip = false;
    const auto [live, batch] = liveAndBatch(vol, uncut, 0.0f, bentStroke(), GetParam(), skip);
    if (skip) {
        GTEST_SKIP() << kKerfTodo;
    }
    EXPECT_TRUE(checkMesh(live).ok()) << checkMesh(live).report();
    EXPECT_TRUE(checkMesh(batch).ok()) << checkMesh(batch).report();
    EXPECT_TRUE(sameTriangles(live, batch));
}

// The same, exactly (same arrays): the fused mesh is a function of the mask
// alone, so redo after a stroke was meshed in parts gives the first mesh
// back. This failed until CutRemesher's cell records compared the corners of
// each quad's stroke neighbours too (a cell touching quad k but not k+1 must
// be re-meshed when k+1 arrives: quad k's side there turns into the k/k+1
// mitre). Reproducer: the sphere (R 15 mm, 40^3 grid of 1 mm), bentStroke(),
// cell (12, 25, 7).
TEST(CutProps, LiveUpdatesGiveTheBatchMeshExactly)
{
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh uncut = extractIsosurface(vol, 0.0f);
    bool skip = false;
    const auto [live, batch] = liveAndBatch(vol, uncut, 0.0f, bentStroke(), 0.0, skip);
    EXPECT_TRUE(sameMesh(live, batch));
}

// A quad's stroke neighbour arriving changes the quad's far side (rim ->
// junction). update() keeps the quad's cells that this side does not reach
// instead of re-meshing them (the kernel's input there is unchanged); with
// verification on, the remesher re-meshes each kept cell anyway and throws
// when the geometry differs. Updating after every quad of a bent stroke, at
// kerf 0 and 0.5: cells are kept at most steps, every kept cell is verified,
// and the result is the batch mesh exactly.
TEST(CutProps, CellsKeptWhenANeighbourQuadArrivesAreThoseARemeshMakes)
{
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh uncut = extractIsosurface(vol, 0.0f);
    for (double kerf : {0.0, 0.5}) {
        CutMask mask(frameOf(vol), kerf);
        CutRemesher live(vol, 0.0f, uncut);
        live.setVerifyKeptCellsForTesting(true);
        mask.beginStroke();
        size_t steps = 0, stepsKeeping = 0, kept = 0, remeshed = 0;
        for (const Quad& q : filterStroke(bentStroke(), mask.frame())) {
            mask.addQuad(q);
            remeshed += live.update(mask); // throws std::logic_error on a kept cell a re-mesh changes
            kept += live.lastKeptCells();
            stepsKeeping += live.lastKeptCells() > 0;
            ++steps;
        }
        std::printf("kerf %g: %zu steps, %zu keep cells; %zu cells kept, %zu re-meshed\n", kerf, steps, stepsKeeping,
                    kept, remeshed);
        EXPECT_GT(stepsKeeping, steps / 2) << "kerf " << kerf;
        CutRemesher batch(vol, 0.0f, uncut);
        batch.update(mask);
        EXPECT_EQ(batch.lastKeptCells(), 0u);
        EXPECT_TRUE(sameMesh(live.fusedMesh(), batch.fusedMesh())) << "kerf " << kerf;
    }
}

// The mask lists a quad in every cell its cut region touches, and at
// kerf > 0 that region is grown round the mitres, so a new quad is listed in
// cells behind it that its prism reaches in none of their tets. The kernel's
// input there is the same (kernelInputDigest leaves such a quad out), and
// update() keeps those cells although their lists changed. Updating after
// every quad of a bent stroke at kerf 0.5 and then undoing one quad at a
// time, with every kept cell re-meshed anyway and compared (verification
// on): such cells are kept on the way out and back, and every step's mesh is
// the one the way out had, the last the batch mesh. A refused update that
// kept some leaves the mesh as it was, and done again keeps them again.
TEST(CutProps, CellsAQuadListsButReachesInNoTetAreKept)
{
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh uncut = extractIsosurface(vol, 0.0f);
    CutMask mask(frameOf(vol), 0.5);
    CutRemesher live(vol, 0.0f, uncut);
    live.setVerifyKeptCellsForTesting(true);
    const std::vector<Quad> quads = filterStroke(bentStroke(), mask.frame());
    ASSERT_GT(quads.size(), 20u);
    // Cells of geometry whose mask list changed in a step yet were not re-made.
    auto listedKept = [&](const std::map<Coord, std::vector<QuadRef>>& before) {
        const std::vector<Coord>& changed = live.lastChangedCells();
        size_t n = 0;
        for (const auto& [c, list] : before) {
            const std::vector<QuadRef>* now = mask.quadsAt(c);
            if (now && *now != list && !std::binary_search(changed.begin(), changed.end(), c)) ++n;
        }
        return n;
    };
    auto lists = [&] {
        std::map<Coord, std::vector<QuadRef>> out;
        for (const auto& [c, g] : live.cells())
            if (const std::vector<QuadRef>* l = mask.quadsAt(c)) out[c] = *l;
        return out;
    };
    mask.beginStroke();
    std::vector<Mesh> meshes{live.fusedMesh()};
    size_t outKept = 0, backKept = 0, best = 0, bestStep = 0;
    for (size_t k = 0; k < quads.size(); ++k) {
        const auto before = lists();
        mask.addQuad(quads[k]);
        live.update(mask); // throws std::logic_error on a kept cell a re-mesh changes
        const size_t n = listedKept(before);
        outKept += n;
        if (n > best) {
            best = n;
            bestStep = k;
        }
        meshes.push_back(live.fusedMesh());
    }
    CutRemesher batch(vol, 0.0f, uncut);
    batch.update(mask);
    EXPECT_TRUE(sameMesh(live.fusedMesh(), batch.fusedMesh()));
    for (size_t k = quads.size(); k-- > 0;) {
        const auto before = lists();
        mask.undoToQuad(uint32_t(k));
        live.update(mask);
        backKept += listedKept(before);
        EXPECT_TRUE(sameMesh(live.fusedMesh(), meshes[k])) << "undone to quad " << k;
    }
    std::printf("%zu quads: cells kept with a changed list %zu adding, %zu undoing; at most %zu a step (quad %zu)\n",
                quads.size(), outKept, backKept, best, bestStep);
    EXPECT_GT(outKept, 0u);
    EXPECT_GT(backKept, 0u);

    // A refused update that kept such cells leaves the remesher as it was,
    // and the same update done again keeps them again.
    for (size_t k = 0; k < bestStep; ++k) mask.addQuad(quads[k]);
    live.update(mask);
    const Mesh good = live.fusedMesh();
    const auto before = lists();
    mask.addQuad(quads[bestStep]);
    bool broken = false;
    live.setCellHookForTesting([&](const Coord&, CutCellGeometry& g) {
        if (broken || g.indices.size() < 6) return;
        broken = true;
        g.indices.resize(g.indices.size() - 3);
        g.cap.pop_back();
    });
    EXPECT_THROW(live.update(mask), std::runtime_error);
    ASSERT_TRUE(broken);
    EXPECT_TRUE(sameMesh(live.fusedMesh(), good));
    live.setCellHookForTesting(nullptr);
    live.update(mask);
    EXPECT_EQ(listedKept(before), best);
    EXPECT_TRUE(sameMesh(live.fusedMesh(), meshes[bestStep + 1]));
}

// update() runs the kernel over the cells in parallel: one thread and four
// give the same cells (ids, positions, triangles) and the same fused mesh,
// on the 4 mm head with the four random strokes of seed 1002 at kerf 0 and 0.5.
TEST(CutProps, ParallelUpdateGivesTheSerialResultExactly)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    for (double kerf : {0.0, 0.5}) {
        CutMask mask(frameOf(vol), kerf);
        for (const auto& poses : randomStrokes(frameOf(vol), 1002, 4)) {
            mask.beginStroke();
            for (const Quad& q : filterStroke(poses, mask.frame())) mask.addQuad(q);
        }
        auto run = [&](size_t threads, std::map<openvdb::Coord, CutCellGeometry>& cells, Mesh& fused) {
            tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
            CutRemesher remesher(vol, 400.0f, uncut);
            try {
                remesher.update(mask);
            } catch (const std::runtime_error& e) {
                return std::string(e.what());
            }
            cells = remesher.cells();
            fused = remesher.fusedMesh();
            return std::string();
        };
        std::map<openvdb::Coord, CutCellGeometry> serialCells, parallelCells;
        Mesh serial, parallel;
        const std::string serialError = run(1, serialCells, serial), parallelError = run(4, parallelCells, parallel);
        EXPECT_EQ(serialError, parallelError) << "kerf " << kerf << ": a refusal names the same cell";
        ASSERT_TRUE(serialError.empty()) << serialError;
        size_t surface = 0;
        for (const auto& [c, g] : serialCells) surface += !g.indices.empty();
        std::printf("kerf %g: %zu cut cells, %zu with geometry\n", kerf, serialCells.size(), surface);
        ASSERT_GT(surface, 100u);
        ASSERT_EQ(serialCells.size(), parallelCells.size());
        for (auto a = serialCells.begin(), b = parallelCells.begin(); a != serialCells.end(); ++a, ++b) {
            ASSERT_EQ(a->first, b->first);
            EXPECT_TRUE(a->second.vertexIds == b->second.vertexIds && a->second.indexPositions == b->second.indexPositions &&
                        a->second.indices == b->second.indices)
                << "kerf " << kerf << ", cell " << a->first;
        }
        EXPECT_TRUE(sameMesh(serial, parallel)) << "kerf " << kerf;
    }
}

// The verification can fail: a kept cell whose stored geometry is not what
// the kernel makes (here nudged by the test hook when it was first meshed)
// is reported, and the update leaves the remesher as it was.
TEST(CutProps, VerifyingKeptCellsCatchesAStoredCellThatDiffers)
{
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh uncut = extractIsosurface(vol, 0.0f);
    CutMask mask(frameOf(vol), 0.0);
    CutRemesher live(vol, 0.0f, uncut);
    live.setVerifyKeptCellsForTesting(true);
    live.setCellHookForTesting([](const openvdb::Coord&, CutCellGeometry& g) {
        for (glm::dvec3& p : g.indexPositions) p.x += 1e-12; // no float or topology change: only the verifier sees it
    });
    mask.beginStroke();
    bool caught = false;
    for (const Quad& q : filterStroke(bentStroke(), mask.frame())) {
        mask.addQuad(q);
        const Mesh before = live.fusedMesh();
        try {
            live.update(mask);
        } catch (const std::logic_error& e) {
            EXPECT_NE(std::string(e.what()).find("kept geometry differs"), std::string::npos) << e.what();
            EXPECT_TRUE(sameMesh(live.fusedMesh(), before));
            caught = true;
            break;
        }
    }
    EXPECT_TRUE(caught);
}

// A stroke whose end retraces its start (the blade comes back over the same
// cut, nearly in the same plane) must be refused or come out clean; never a
// silently non-manifold mesh. This failed (w = 0) until the local check
// judged float positions (see the seed 1021 test below): update() returned
// normally and the fused mesh had 1 non-manifold edge (in 4 triangles, all in
// cell (54, 48, 36)); it is refused now ("an edge used 2 time(s) one way and 2
// the other"). Reproducer, 4 mm head at 400 HU: the "figure eight retracing
// its start" stroke of handStrokes() (197 quads with the path filter's
// retrace rule off; with it on, as a user gets it, the returning poses are
// dropped and the stroke is clean); minimal: its quads 4..5 and 193..194 as
// two strokes of 2 quads each (also quads 2..7 and 191..196). Two strokes
// are not filtered against each other: this is still refused.
TEST(CutPropsDefects, RetracedStrokeStartIsNeverSilentlyNonManifold)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    const IndexFrame frame = frameOf(vol);
    std::vector<Pose> poses;
    for (const auto& [shape, strokes] : handStrokes(frame))
        if (shape == "figure eight retracing its start") poses = strokes[0];
    PathFilterOptions noRetrace;
    noRetrace.retraceTolerance = -1.0;
    const std::vector<Quad> quads = filterStroke(poses, frame, noRetrace);
    ASSERT_EQ(quads.size(), 197u);
    CutMask mask(frame, 0.0);
    for (const auto& [lo, hi] : {std::pair<size_t, size_t>{4, 5}, {193, 194}}) {
        mask.beginStroke();
        for (size_t q = lo; q <= hi; ++q) mask.addQuad(quads[q]);
    }
    CutRemesher remesher(vol, 400.0f, uncut);
    const UpdateResult u = tryUpdate(remesher, mask);
    if (u.outcome == Outcome::Refused) { std::printf("refused: %s\n", u.message.c_str()); return; } // refused: not silent
    const MeshCheck check = checkMesh(remesher.fusedMesh());
    EXPECT_TRUE(check.ok()) << check.report();
}

/// Strokes 0 .. strokes-1 of randomStrokes(frame, seed, 4) cut on a fresh
/// mask of the 4 mm head at 400 HU with kerf `kerf`, one update after each;
/// `result` is the last update's outcome (the first refusal's, if any).
struct HeadStrokeCut
{
    HeadStrokeCut(const std::string& path, uint32_t seed, double kerf, size_t strokes = 1)
        : vol(vdb::readVolume(path)), uncut(extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false})),
          mask(frameOf(vol), kerf), remesher(vol, 400.0f, uncut)
    {
        const auto all = randomStrokes(mask.frame(), seed, 4);
        for (size_t s = 0; s < strokes && s < all.size() && result.outcome == Outcome::Ok; ++s) {
            addStroke(mask, all[s]);
            result = tryUpdate(remesher, mask);
        }
    }
    /// The strokes before upTo.stroke whole and its quads up to upTo.quad,
    /// cut from scratch (a state a live stroke updated after every quad is
    /// in), at isovalue iso, the strokes turning by `turn` (randomStrokes).
    struct UpToQuad
    {
        size_t stroke, quad;
    };
    HeadStrokeCut(const std::string& path, uint32_t seed, double kerf, UpToQuad upTo, float iso = 400.0f,
                  double turn = 0.05)
        : vol(vdb::readVolume(path)), uncut(extractIsosurface(vol, iso, IsosurfaceOptions{nullptr, false})),
          mask(frameOf(vol), kerf), remesher(vol, iso, uncut)
    {
        const auto all = randomStrokes(mask.frame(), seed, int(upTo.stroke) + 1, turn);
        for (size_t s = 0; s <= upTo.stroke; ++s) {
            const std::vector<Quad> quads = filterStroke(all[s], mask.frame());
            mask.beginStroke();
            for (size_t q = 0; q < quads.size() && (s < upTo.stroke || q <= upTo.quad); ++q) mask.addQuad(quads[q]);
        }
        result = tryUpdate(remesher, mask);
    }
    vdb::Volume vol;
    Mesh uncut;
    CutMask mask;
    CutRemesher remesher;
    UpdateResult result;
};

/// The first `strokes` random strokes of `seed` on `path` at 400 with kerf
/// w: accepted, a clean fused mesh, and no intersecting pairs near the cut
/// (w = 0: none off the blade, where the two sides' caps do not touch).
void expectCleanRandomCut(const std::string& path, const char* name, uint32_t seed, size_t strokes, double kerf)
{
    HeadStrokeCut cut(path, seed, kerf, strokes);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << name << " seed " << seed << ": " << cut.result.message;
    const Mesh fused = cut.remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << name << " seed " << seed << check.report();
    const TouchStats t = touchesNearCut(fused, cut.remesher, cut.mask, 1e-3);
    const size_t pairs = kerf > 0 ? t.pairs : t.offBlade;
    std::printf("%s seed %u, %zu strokes, w = %.1f mm: %zu cut cells, %zu intersecting pairs%s, %zu pinch contacts\n",
                name, seed, strokes, kerf, cut.remesher.cells().size(), pairs, kerf > 0 ? "" : " off the blade",
                t.pinchContacts);
    EXPECT_EQ(pairs, 0u) << name << " seed " << seed;
}

/// The strokes of `seed` on `path` at `iso` with kerf w before upTo.stroke
/// and that one to upTo.quad, cut from scratch (a state a live stroke was
/// refused in): accepted, a clean fused mesh, and no intersecting pairs
/// near the cut (w = 0: none off the blade).
void expectCleanCutUpToQuad(const std::string& path, uint32_t seed, double kerf, HeadStrokeCut::UpToQuad upTo,
                            float iso = 400.0f, double turn = 0.05)
{
    HeadStrokeCut cut(path, seed, kerf, upTo, iso, turn);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << "seed " << seed << ": " << cut.result.message;
    const Mesh fused = cut.remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << "seed " << seed << check.report();
    const TouchStats t = touchesNearCut(fused, cut.remesher, cut.mask, 1e-3);
    EXPECT_EQ(kerf > 0 ? t.pairs : t.offBlade, 0u) << "seed " << seed;
}

// Random stroke seed 1021, stroke 0 (randomStrokes(frame, 1021, 4): 200 poses,
// 0.6 mm per pose, 30 mm blade) on the 4 mm head at 400 HU, w = 0, on a
// fresh mask: clean, with no triangle of zero area in float. This failed
// after b3916e9 (snap rounding in fusedMesh): the fused mesh had 2 triangles
// of zero area in float in cell (39, 31, 16), because the local check judged
// double positions: GCC 12.2's SLP vectoriser had folded the check's
// double(float(x)) round trip away for two of the three axes. Then it was
// refused: a cap region there is a triangle a few float ulps wide inside the
// slit, and the fan from its centre put the centre between two corners in
// float. Such a triangle is now kept as it is.
TEST(CutPropsDefects, Seed1021Stroke0IsNeverSilentlyDegenerate)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    HeadStrokeCut cut(path, 1021, 0.0);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    const Mesh fused = cut.remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    for (size_t t = 0; t < fused.triangleCount(); ++t) {
        const glm::vec3 a = fused.positions[fused.indices[3 * t]], b = fused.positions[fused.indices[3 * t + 1]],
                        c = fused.positions[fused.indices[3 * t + 2]];
        if (glm::cross(b - a, c - a) == glm::vec3(0.0f))
            ADD_FAILURE() << "degenerate triangle " << t << " in cell (" << fused.triangleVoxels[t].x << ", "
                          << fused.triangleVoxels[t].y << ", " << fused.triangleVoxels[t].z << ")";
    }
}

// Random stroke seed 1025, stroke 0, on the 4 mm head at 400 HU, w = 0.5 mm:
// the blade pivots on a corner, and three quads' prisms meet in one point
// inside a tet of cell (32, 39, 52) where the solid left between them
// touches itself (sampled around the point: the removed region's complement
// falls into 3 parts). It was refused ("a vertex where the surface
// pinches"); now each fan there has its own copy of the vertex: the fused
// mesh is a closed 2-manifold, the copies share the name up to the pinch
// tag and the position, and the only self-intersections near the cut are
// the fans touching at that point.
TEST(CutPropsDefects, PivotPinchIsSplitIntoFans)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    HeadStrokeCut cut(path, 1025, 0.5);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    const CutRemesher& remesher = cut.remesher;
    const Mesh fused = remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    size_t copies = 0;
    const CutCellGeometry& g = remesher.cells().at(Coord(32, 39, 52));
    for (size_t i = 0; i < g.vertexIds.size(); ++i)
        for (size_t j = 0; j < g.vertexIds.size(); ++j) {
            CutVertexId a = g.vertexIds[i], b = g.vertexIds[j];
            if (i == j || a.tagCount != 0 || b.tagCount != 1) continue;
            b.tagCount = 0;
            b.tags = {};
            if (!(a == b)) continue;
            ++copies;
            EXPECT_EQ(a.dim, 3) << "a pinch copy inside a tet only";
            EXPECT_EQ(g.indexPositions[i], g.indexPositions[j]);
        }
    EXPECT_GE(copies, 1u) << "the pinch vertex in cell (32, 39, 52) has copies";
    const TouchStats t = touchesNearCut(fused, remesher, cut.mask, 1e-3);
    std::printf("pivot pinch: %zu vertex copies, %zu pinch contacts, %zu other intersecting pairs\n", copies,
                t.pinchContacts, t.pairs);
    EXPECT_GT(t.pinchContacts, 0u);
    EXPECT_EQ(t.pairs, 0u);
}

// Random stroke seed 1009, stroke 0, on the 4 mm head, w = 0.5 mm: on the
// mitre of quads 22 and 23 the two quads' offset lines are one line by name,
// and conformity put a vertex on an edge of a piece that already had it: the
// piece ran out and back through that vertex, was classified by its spike's
// vertex and dropped, leaving an open edge in cell (31, 23, 27). Split at the
// repeat (pushSimple) the cut gets through to a pivot pinch, which is split
// into fans: now clean, with no intersections but pinch contacts.
TEST(CutPropsDefects, FoldedMitrePieceIsSplitAtItsRepeatedVertex)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    HeadStrokeCut cut(path, 1009, 0.5);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    const Mesh fused = cut.remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    const TouchStats t = touchesNearCut(fused, cut.remesher, cut.mask, 1e-3);
    EXPECT_EQ(t.pairs, 0u);
}

// Random strokes seed 1017, strokes 0..2, on the 4 mm head, w = 0.5 mm: a
// mitre (quads 55 and 56 of stroke 2) holds the line where the two offset
// planes meet, so a point inside a tet on that line and on one plane that
// is not active there (outside its prism) was named by the mitre and the
// two offset planes alone: a line, not a point. Two points of the line
// shared one vertex, the mitre face's pieces overlapped (a sliver triangle
// of the face kept in both orientations cancelled out) and stroke 2 was
// refused: "an edge used 1 time(s) one way and 0 the other" in cell
// (49, 29, 28). Such a name now takes the planes that made the point too.
TEST(CutPropsDefects, PointsOnAMitreLineAreNamedApart)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    HeadStrokeCut cut(path, 1017, 0.5, 3);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    const Mesh fused = cut.remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    EXPECT_GT(cut.remesher.cells().count(Coord(49, 29, 28)), 0u) << "the stroke still crosses the cell";
    const TouchStats t = touchesNearCut(fused, cut.remesher, cut.mask, 1e-3);
    EXPECT_EQ(t.pairs, 0u);
}

// Random strokes on the 2 mm head, w = 0.5 mm, four strokes each: a blade
// pivoting about its tip makes quads with corners sharper than cutRegion()
// grows (kKerfMitreMinCornerGap), and those joints had no mitre, even where
// the two quads are nearly coplanar. The two prisms' end planes then leave a
// notch w/2 deep and (w/2) * bend wide at the stick, 1e-5 mm or less: seed
// 1023 wrote 7 intersecting pairs (the notch's walls crossed in float),
// seeds 1019 and 1028 were refused (a sliver region without outer loop; a
// seam the float repair closed in one cell and not the other). Such a joint
// now takes the mitre, capped at a corner where its reach past the corner
// leaves the clamped growth (tooSharpForMitre): all three are clean.
TEST(CutPropsDefects, NearlyCoplanarSharpJointsAreMitredWithKerf)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    for (uint32_t seed : {1019u, 1023u, 1028u}) expectCleanRandomCut(path, "2 mm head", seed, 4, 0.5);
}

// Random strokes on the tooth at 400 (its noise level: thousands of specks,
// many marching-tetrahedra folds), w = 0.5 mm. Where a tet's isosurface is a
// concave fold, the solid is the union of two half-spaces, so a cap piece
// whose corners are all in the closed solid need not be in it: a triangle of
// an offset face between the two fold planes, its corners on them (2e-3
// voxel across), was kept; it closed a cap region over the crease and left
// the iso surface's edge there open (seeds 1007, 1014, 1022, refused). A cap
// piece there is now kept by its side of the fold planes (inSolid).
TEST(CutPropsDefects, CapPiecesBetweenTheTwoPlanesOfAConcaveFoldAreOutside)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    for (const auto& [seed, strokes] : std::vector<std::pair<uint32_t, size_t>>{{1022, 2}, {1007, 3}, {1014, 4}})
        expectCleanRandomCut(path, "tooth at 400", seed, strokes, 0.5);
}

// Tooth at 400, seed 1009, w = 0.5 mm: in cell (13, 35, 73) a cut line
// passes within 1e-6 voxel of a tet edge, so three vertices on it lie a few
// 1e-7 voxel apart (one in the cell face, two on inner tet faces). The float
// repair took folded triangles in order and moved the middle one 0.19 voxel
// along a long edge, leaving two triangles folded onto each other: 7 pairs
// CGAL found. Short edges now go first, shortest first, over the cell.
TEST(CutPropsDefects, ShortEdgesAreMendedShortestFirst)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanRandomCut(path, "tooth at 400", 1009, 4, 0.5);
}

// Tooth at 400, seed 9076, w = 0.5 mm: an offset plane crossed the grid edge
// (52, 10..11, 71) 6e-6 voxel from the isosurface's vertex X on it, a sliver
// of solid round the edge thinner than float; the float repair's face rule
// pinched it in the two faces opposite each other across the edge, and the
// four cells round it used the edge from the plane's vertex to X twice each
// way (refused, stroke 1). Snap rounding now joins the ends of such an edge
// into X (FloatFolds.OnlyAnIsoVertexAndABladeVertexOfItsGridEdge...), the
// sliver's triangles collapse, and the two parts of the solid that meet at
// X are a pinch that fusion splits (X's triangles are all cut cells').
TEST(CutPropsDefects, AnEdgeAlongAGridEdgeUsedFourTimesIsJoinedIntoItsIsoVertex)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanRandomCut(path, "tooth at 400", 9076, 2, 0.5);
    // The split is a function of the fused triangles: from scratch, the same mesh.
    HeadStrokeCut cut(path, 9076, 0.5, 2);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    CutRemesher scratch(cut.vol, 400.0f, cut.uncut);
    ASSERT_EQ(tryUpdate(scratch, cut.mask).outcome, Outcome::Ok);
    const Mesh fused = cut.remesher.fusedMesh();
    EXPECT_TRUE(sameMesh(scratch.fusedMesh(), fused));
    // X, the marching-tetrahedra vertex at (52, 10.0039, 71) mm, is split: the
    // two parts of the solid meet there, each with its own copy.
    const glm::vec3 x(52.0f, 10.00390625f, 71.0f);
    std::set<uint32_t> atX;
    for (uint32_t v : fused.indices)
        if (fused.positions[v] == x) atX.insert(v);
    EXPECT_EQ(atX.size(), 2u);
}

// The 1 mm head (DICOM) at kerf 0, random strokes seed 2002: a slit copy
// of an iso vertex on a face diagonal lay 2.5e-5 voxel from a cap vertex in
// that face, at z = 1241 mm where a float step is 1.2e-4 mm; the triangle
// they spanned with an inner vertex rounded to zero area, and the float
// repair's face rule took only tet-face pairs (refused). It takes a face's
// diagonal too (FloatFolds.ADiagonalVertexAndAFaceVertex...).
TEST(CutPropsDefects, AFaceDiagonalVertexIsMendedWithTheFace)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectCleanRandomCut(dir, "1 mm head", 2002, 4, 0.0);
}

// The 1 mm head at kerf 0, random strokes seed 2044: a blade plane passed
// 3e-5 mm from a grid vertex at z = 1045 mm, so six vertices on the cube
// edges and face diagonals around it, shared by two to four cells, lay
// closer together than a float step; rounded, they were three points on one
// line and their triangles had zero area (refused). They now go onto the
// grid vertex (snapToGridVertices) and the written mesh's snap rounding
// joins them.
TEST(CutPropsDefects, ASubFloatClusterAtAGridVertexGoesOntoIt)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectCleanRandomCut(dir, "1 mm head", 2044, 4, 0.0);
}

// The 1 mm head at kerf 0.5, random strokes seed 2002: a vertex of a cell
// face lay 3e-5 mm above a vertex on the face's cube edge at z = 1226 mm;
// rounded to float it sat on the edge just past that vertex, and the
// triangles of the cells below touched the segment to it there (10 pairs
// CGAL found). The face rule now also puts a face vertex onto a vertex of
// the face's boundary that close (FloatFolds.AFaceVertexAFloatStepFrom...).
TEST(CutPropsDefects, AFaceVertexNearItsEdgesVertexIsMendedWithTheFace)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectCleanRandomCut(dir, "1 mm head", 2002, 4, 0.5);
}

// The 2 mm head at kerf 0.5, random strokes seed 3023 (also refused at kerf
// 0.1, 1 and 2): two quads of a stroke meet at too sharp a corner for a mitre,
// so each prism ends on its own plane through their common edge, and the
// two planes cut a face 9e-5 mm apart at z = 1018 mm. The cell above merged
// the two face vertices; the one below could not (they closed a tent round
// a vertex inside its tet), and the seam opened (refused).
TEST(CutPropsDefects, AFacePairClosingATentIsMendedInBothCells)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    expectCleanRandomCut(path, "2 mm head", 3023, 4, 0.5);
}

// The 2 mm head at kerf 0, random strokes seed 7039, stroke 1, updated half
// way through (as a haptic session updates at every step): quad 110's plane
// passes within a float step of grid vertex (59, 76, 96), so its names on
// the cube edge below that vertex and on the one beside it go onto the
// vertex (snapToGridVertices) and the local check's snap rounding makes them
// one vertex. An unchanged cell that holds only the second edge used an edge
// of that vertex; the check counted that use only where a changed cell holds
// the first name, so the edge looked open and the update was refused. A
// vertex is now held where any name joined into it is.
TEST(CutPropsDefects, NamesSnappedOntoOneGridVertexAreHeldByAllTheirCells)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    HeadStrokeCut cut(path, 7039, 0.0, 0); // nothing cut yet
    CutMask& mask = cut.mask;
    CutRemesher& remesher = cut.remesher;
    const auto strokes = randomStrokes(mask.frame(), 7039, 2);
    for (size_t s = 0; s < strokes.size(); ++s) {
        mask.beginStroke();
        const std::vector<Quad> quads = filterStroke(strokes[s], mask.frame());
        for (size_t q = 0; q < quads.size(); ++q) {
            mask.addQuad(quads[q]);
            if (q + 1 != quads.size() / 2 && q + 1 != quads.size()) continue;
            const UpdateResult r = tryUpdate(remesher, mask);
            ASSERT_EQ(r.outcome, Outcome::Ok) << "stroke " << s << ", quad " << q << ": " << r.message;
            const MeshCheck check = checkMesh(remesher.fusedMesh());
            EXPECT_TRUE(check.ok()) << "stroke " << s << ", quad " << q << check.report();
        }
    }
    // The case is still there: two blade names, on two cube edges, at the grid vertex.
    size_t onVertex = 0;
    for (const Coord& c : {Coord(58, 75, 95), Coord(59, 75, 96)}) {
        const auto it = remesher.cells().find(c);
        ASSERT_NE(it, remesher.cells().end()) << "the stroke no longer cuts cell " << c;
        const CutCellGeometry& g = it->second;
        for (size_t v = 0; v < g.vertexIds.size(); ++v)
            onVertex += g.vertexIds[v].dim == 1 && !g.vertexIds[v].isIsoEdgeVertex() &&
                        g.indexPositions[v] == glm::dvec3(59, 76, 96);
    }
    EXPECT_GE(onVertex, 2u) << "no two blade names on cube edges were put on grid vertex (59, 76, 96)";
}

// The 4 mm head at kerf 0, random strokes seed 8043: quads 30-32 of stroke 1
// pass through one point (the blade pivots) 4e-5 mm from a cell face, a
// float step at z = 1213 mm. Quad 31's cap there is a triangle that small,
// fanned from its centre; two of its corners are one float point, so snap
// rounding joins them, and the fan became two triangles on one vertex set
// facing opposite ways: each of their edges used twice each way (refused).
// Such a pair, made by snap rounding, now goes (markCancellingPairs), in
// fusedMesh and the local check alike; one the kernel made as it is stays.
TEST(CutPropsDefects, TrianglesThatSnapRoundingFoldsBackOntoEachOtherGo)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_4mm.nhdr");
    expectCleanRandomCut(path, "4 mm head", 8043, 4, 0.0);
}

// Kerf 0, random strokes seed 8006 on the 2 mm head and 8014 on the 4 mm
// head (found updating after every quad; refused just the same updated once
// per stroke): a cap region of three corners a few float steps across, in a
// cell face, was fanned from its centre because not all its corners were
// tagged with the cap's side, and one fan triangle had zero area in float
// mm (refused). A triangle with a corner only its side has needs no centre
// (the other side's triangle cannot have its three vertices): it is kept as
// it is, and both cuts are accepted and clean.
TEST(CutPropsDefects, ACapTriangleWithACornerOfItsOwnSideGetsNoCentre)
{
    MTCUT_REQUIRE_DATA(path2, "vhm_head_2mm.nhdr");
    expectCleanRandomCut(path2, "2 mm head", 8006, 4, 0.0);
    MTCUT_REQUIRE_DATA(path4, "vhm_head_4mm.nhdr");
    expectCleanRandomCut(path4, "4 mm head", 8014, 4, 0.0);
}

// The body CT (NIfTI) at 150 HU, kerf 0, random strokes seed 16285, with
// stroke 2's last quad: in cell (86, 49, 20) a cap region has a reflex
// corner (20 degrees, between edges of about 10 um) where the blade's rim
// turns inside the bone, so it is ear-clipped rather than fanned from its
// centre, and both sides of the slit clipped the same ear of three rim
// points: one triangle back to back, its edges used twice each way
// (refused; the live stroke stepped round it). An ear with no corner of its
// own side now makes the region a fan from its tagged centre where the
// region is star-shaped from it (the GPU pass alike:
// CutKernelGpu.AReflexCapRegionIsFannedAsTheCpu).
TEST(CutPropsDefects, AReflexCapRegionWhoseEarBothSidesShareIsFanned)
{
    MTCUT_REQUIRE_DATA(path, "body-ct.nii.gz");
    expectCleanCutUpToQuad(path, 16285, 0.0, {2, 45}, 150.0f);
}

// The 2 mm head at kerf 1, random strokes seed 16234, stroke 2 to quad 49:
// in tet 4 of cell (110, 90, 91) the prisms of quads 40 to 42 meet nearly
// at one point, on five planes; made by three of them (q40:k2, q41:k2,
// q41:k7, nearly parallel) it came out 1.4e-9 voxel from the vertex named
// by all five, beyond mergeTolerance, so it was a second vertex and an edge
// of the cap round them was used once (refused; the live stroke waited out
// seven updates and stepped round the eighth). A dim-3 point whose name's
// planes are a subset of a near vertex's is that vertex now (the GPU pass
// alike: CutKernelGpu.APointOfNearlyParallelPlanesIsMergedAsTheCpu).
TEST(CutPropsDefects, APointNamedByASubsetOfAnotherVertexsPlanesIsThatVertex)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    expectCleanCutUpToQuad(path, 16234, 1.0, {2, 49});
}

// The tooth at kerf 0, random strokes seed 16215, stroke 3 to quad 22: the
// stick between quads 21 and 22 passes 2e-6 voxel beside the grid edge
// (87, 28..29, 86) where quad 22 crosses it, so the faces x = 87 and z = 86
// each have a vertex of the stick a float step from the edge's vertex, all
// three on the side q22+. Written, they lie on the edge's line, and the cap
// triangle between them has no area (refused; the live stroke waited out
// seven updates and stepped round at quad 29). Snap rounding's rule for two
// such face vertices round a cube edge (joinsRoundCubeEdge) took untagged
// ones only; it takes two with the same side tags now, and the triangle goes.
TEST(CutPropsDefects, TwoFaceVerticesOfOneSideRoundACubeEdgeAreJoined)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanCutUpToQuad(path, 16215, 0.0, {3, 22});
}

// The 1 mm head at kerf 0.5, random strokes seed 16497, stroke 3 to quad
// 78: the joint of quads 77 and 78 is mitred, and quad 78's corner there is
// too sharp for the mitre, so its prism has a cap at that corner, a plane
// named by the lower quad (q77:k5) that quad 77's prism lacks. A plane of
// one quad splits a surface only within that quad's junction zone, and the
// cap was taken for quad 77's by its name, so on quad 78's side of the mitre
// it split nothing: a piece of q78's offset face in tet 1 of cell (206,
// 238, 222) straddled the cap, and the surface round the mitre's line was
// open (an edge used once; the live stroke waited out seven updates, then
// stepped round). A plane that one quad has among its sides is that quad's
// now (the GPU pass alike: CutKernelGpu.ACapOfTheUpperQuadSplitsOnItsSide).
TEST(CutPropsDefects, ACapOnlyTheUpperQuadHasSplitsOnItsSideOfTheMitre)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectCleanCutUpToQuad(dir, 16497, 0.5, {3, 78});
}

// The 1 mm head at kerf 0.5, random strokes seed 60027, stroke 2 to quad
// 66: an offset plane crosses the diagonal of face z = 1163 mm 2.3e-4 mm
// (two float steps there) from the isosurface's vertex on it. The float
// repair's face rule joined the two in the cell above the face, where the
// link condition held, and not in the cell below, where a vertex of its own
// 3.3e-4 mm under the face was joined to both: the seam opened (an edge
// used once in cell (270, 164, 162)) and the live stroke stepped round. A
// common neighbour private to the cell now goes into the survivor with the
// pair. The tooth, kerf 0.5, sharp turns, seed 61013, stroke 3 to quad 202
// opened a seam the same way, on the diagonal of face x = 81 mm (1e-5 mm).
TEST(CutPropsDefects, AFaceRuleMergeTakesTheCellsOwnCommonNeighbourAlong)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    expectCleanCutUpToQuad(dir, 60027, 0.5, {2, 66});
    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    expectCleanCutUpToQuad(tooth, 61013, 0.5, {3, 202}, 400.0f, 1.0);
}

// The tooth at kerf 0, random strokes seed 16929, stroke 3 to quad 83: the
// stroke turns back on itself, and quad 83's blade crosses a rim line of
// quad 81, two quads back, inside cell (76, 16, 116). The point where it
// does lies inside quad 83, off its sides, but was taken as a strip corner
// of quad 83 (onStripRim: on a rim of a quad of its strip), so it was one
// vertex for both sides of 83's slit: a pinch (refused; stepping round by
// 1e-3 and 1e-2 voxel met it too, and the live stroke stopped there). A
// strip corner lies on one of the quad's junctions; off them the point is
// in the slit and has a vertex on each side (the GPU pass alike:
// CutKernelGpu.AQuadCrossingARimTwoQuadsBackSplitsThePointAsTheCpu).
TEST(CutPropsDefects, AQuadCrossingARimTwoQuadsBackSplitsThePoint)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanCutUpToQuad(path, 16929, 0.0, {3, 83});
}

// The 2 mm head at kerf 0, random strokes with sharp turns (bench_strokes
// --turn 1) seed 18088, stroke 3 to quad 57: quads 55, 56 and 57 cut a
// small cone of bone out that touches the rest only at its tip, a vertex in
// cell (78, 61, 118) whose triangles are two closed fans: a pinch of the
// zero-width cut, refused ("a vertex where the surface pinches"), and the
// live stroke stopped there. Pinches are split in fusion at kerf 0 as with
// a kerf (a copy of the vertex per fan but the first).
TEST(CutPropsDefects, ThreeSlitsMeetingAtAPointAreSplitThereAtKerfZero)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    expectCleanCutUpToQuad(path, 18088, 0.0, {3, 57}, 400.0f, 1.0);
}

// The tooth at kerf 0, random strokes with sharp turns seed 18004, stroke 2
// to quad 32 (the commonest stop of the tooth's zigzags at kerf 0, "an edge
// used 1 time one way and 0 the other"): quad 27's slit chord from a rim
// point to its junction with quad 28 lies in the face z = 36 between cells
// (35, 64, 35) and (35, 64, 36). The upper cell closes it with a Steiner
// midpoint; in the lower one a side line of quad 31 (which does not reach
// the upper cell) split the chord inside the slit, each half had one rim
// end, and the lower cell used the chord bare: the two sides' caps did not
// meet. Now the chord is followed through such splits and gets the one
// midpoint of its ends (the GPU pass alike:
// CutKernelGpu.ASlitChordSplitByAnotherQuadGetsItsMidpointAsTheCpu).
TEST(CutPropsDefects, ASlitChordSplitByAnotherQuadsSideLineGetsTheMidpointOfItsEnds)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanCutUpToQuad(path, 18004, 0.0, {2, 32}, 400.0f, 1.0);
}

// The tooth at kerf 0, random strokes with sharp turns, seed 18048, stroke 1
// to quad 87: quad 86 is a dart (its corner on the stick it shares with 87
// lies inside the hull of its other three), and 87's rim along that stick
// lies in 86's plane inside 86's open slit, a T-junction whose points take
// 87's side tag on 86's caps (tJunctionSide). At 87's corner, where its rim
// leaves 86's plane, the T ends and 86's cap goes on round it as one sheet;
// the corner took a side tag too, so the two pieces of that cap either side
// of the line beyond it had different copies of it: an edge used once in
// cell (46, 75, 17), refused. The corner is untagged now (cornerOffPlane).
// Seed 18038, stroke 1 to quad 97, was refused so in cell (11, 51, 110).
TEST(CutPropsDefects, ATJunctionEndsAtTheCornerWhereTheRimLeavesTheOtherQuadsPlane)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanCutUpToQuad(path, 18048, 0.0, {1, 87}, 400.0f, 1.0);
    expectCleanCutUpToQuad(path, 18038, 0.0, {1, 97}, 400.0f, 1.0);
}

// The tooth at kerf 0, sharp turns, seed 18008, stroke 2, quad 127: quad
// 120's slit chord in tet 4 of cell (74, 20, 83) runs along the tet's iso
// triangle A (split by the planes of quads 119 and 121) to the fold between
// the tet's two iso triangles, where it leaves the isosurface. A's plane goes
// on past the fold as a line of the caps' arrangement; the cap's walk
// (splitChord) followed it to a rim point of 120 and gave the chord a
// midpoint, while the isosurface's pieces end at the fold, so theirs could
// not: an edge used once (the live stroke stepped round it). A chord along
// the isosurface now stays on it in every surface's walk.
TEST(CutPropsDefects, AChordAlongTheIsosurfaceEndsWhereTheIsosurfaceFolds)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanCutUpToQuad(path, 18008, 0.0, {2, 127}, 400.0f, 1.0);
}

// The tooth at kerf 0, sharp turns, seed 18018, stroke 3, quad 46: quad 37's
// slit chord in tet 1 of cell (28, 31, 111) runs along quad 39's plane, split
// inside 37's slit by the side of quad 36 and by 39's rim. Past 39's rim the
// line goes on only as a line of 37's cap's arrangement: 37's cap walked it
// to 37's rim and took a midpoint, 39's cap, which ends at its rim, could
// not: an edge used once (the live stroke stepped round it). A chord along
// another quad's plane now stays in that quad's closed extent.
TEST(CutPropsDefects, AChordAlongAnotherQuadEndsAtThatQuadsRim)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanCutUpToQuad(path, 18018, 0.0, {3, 46}, 400.0f, 1.0);
}

// The tooth at kerf 0, random strokes with sharp turns, seed 74005, stroke 2
// to quad 78: the blade pivots about its base (the base sliding along the
// blade), so quads 77 and 78 lie on one side of the stick they share with
// their normals agreeing (makeQuad orients them by the base's motion). The
// junction was a rim of both, and in cell (32, 63, 105) the edges along the
// stick were used twice each way (the live stroke stopped there). It is a
// fold now (AStrokeThatDoublesBackAtAnAngleCutsBothSidesOfEachQuad below).
TEST(CutPropsDefects, AZigzagWhoseQuadsFoldWithAgreeingNormalsIsClean)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanCutUpToQuad(path, 74005, 0.0, {2, 78}, 400.0f, 1.0);
}

// The same on the sphere, made by hand (TestStrokes.h: addRimCrossingStroke):
// three quads, the third across the first's base line. The point where it
// crosses was one vertex for both sides of the third quad's slit (refused:
// a pinch in cell (20, 19, 19)); now the cut is accepted and clean.
TEST(CutPropsDefects, AStrokeTurnedBackAcrossItsStartIsSplitWhereItCrossesTheRim)
{
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh uncut = extractIsosurface(vol, 0.0f, IsosurfaceOptions{nullptr, false});
    CutMask mask(frameOf(vol), 0.0);
    test::addRimCrossingStroke(mask);
    CutRemesher remesher(vol, 0.0f, uncut);
    const UpdateResult u = tryUpdate(remesher, mask);
    ASSERT_EQ(u.outcome, Outcome::Ok) << u.message;
    const Mesh fused = remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    EXPECT_EQ(touchesNearCut(fused, remesher, mask, 1e-3).offBlade, 0u);
}

namespace {

/// The area of the strip t0 <= t <= t1 (across the ball, spanning it up and
/// down) of a plane at distance d from the centre of a ball of radius r: the
/// integral of 2 sqrt(rho^2 - t^2), rho^2 = r^2 - d^2.
double stripSection(double r, double d, double t0, double t1)
{
    const double rho = std::sqrt(r * r - d * d);
    auto f = [rho](double t) {
        t = std::clamp(t, -rho, rho);
        return t * std::sqrt(rho * rho - t * t) + rho * rho * std::asin(t / rho);
    };
    return f(t1) - f(t0);
}

struct FoldedCut
{
    size_t triangles = 0;
    double cutArea = 0.0; ///< mm^2
};

/// The sphere cut at kerf 0 by addFoldedStroke(normalsAgree, straight)
/// (TestStrokes.h), checked: accepted, clean, no touch off the blade, one
/// fragment of the uncut volume (zero kerf removes nothing).
void cutTheSphereWithAFoldedStroke(bool normalsAgree, bool straight, FoldedCut& out)
{
    SCOPED_TRACE(std::string(straight ? "straight" : "folded") + (normalsAgree ? ", normals agree" : ", normals opposite"));
    const vdb::Volume vol = volumeOf(sphereSolid());
    const Mesh uncut = extractIsosurface(vol, 0.0f, IsosurfaceOptions{nullptr, false});
    CutMask mask(frameOf(vol), 0.0);
    test::addFoldedStroke(mask, normalsAgree, straight);
    CutRemesher remesher(vol, 0.0f, uncut);
    const UpdateResult u = tryUpdate(remesher, mask);
    ASSERT_EQ(u.outcome, Outcome::Ok) << u.message;
    std::vector<uint32_t> source;
    const Mesh fused = remesher.fusedMesh(&source);
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    EXPECT_EQ(touchesNearCut(fused, remesher, mask, 1e-3).offBlade, 0u);
    const std::vector<Fragment> frags = fragmentsOf(fused, remesher.bladeTriangles(source));
    ASSERT_EQ(frags.size(), 1u);
    EXPECT_NEAR(frags[0].volume, meshVolume(uncut), 1e-6 * meshVolume(uncut));
    out.triangles = fused.triangleCount();
    out.cutArea = frags[0].cutArea;
    std::printf("%s stroke, normals %s: %zu cut cells, %zu triangles, cut faces %.2f mm^2\n",
                straight ? "straight" : "folded", normalsAgree ? "agree" : "opposite", mask.cutCellCount(),
                out.triangles, out.cutArea);
}

/// Both ways of one cut: cut faces within the sections of radius 14 and 15 mm
/// (the MT surface lies inside the sphere by less than a voxel), and the same
/// triangles and cut area.
void expectOneCutBothWays(const FoldedCut& a, const FoldedCut& b, double section14, double section15)
{
    for (const FoldedCut* c : {&a, &b}) {
        EXPECT_LT(c->cutArea, section15);
        EXPECT_GT(c->cutArea, section14);
    }
    EXPECT_EQ(a.triangles, b.triangles);
    EXPECT_NEAR(a.cutArea, b.cutArea, 1e-9 * a.cutArea);
    std::printf("  sections of radius 14 and 15 mm: %.2f and %.2f mm^2\n", section14, section15);
}

} // namespace

// A stroke that doubles back at an angle on the sphere (TestStrokes.h:
// addFoldedStroke): two quads 20 degrees apart on one side of the stick they
// share. With their normals pointing opposite ways (the base reversed) the
// plane that bisects the two quads' normals parts them, a junction as any.
// With the normals agreeing it does not, and the junction was a rim of both
// quads, so the wedge of solid between them and the solid outside met along
// the stick: each edge there used twice each way (refused; the tooth at kerf
// 0, sharp turns, seed 74005, stroke 2 at quad 78, stopped so in cell (32,
// 63, 105)). Such a junction is a fold now: its plane bisects the wedge, and
// each side of one quad's slit goes on as the other's other side. Zero kerf:
// one fragment of the uncut volume, whose cut faces are both sides of both
// quads' sections of the sphere, the same both ways.
TEST(CutPropsDefects, AStrokeThatDoublesBackAtAnAngleCutsBothSidesOfEachQuad)
{
    FoldedCut opposite, agree;
    ASSERT_NO_FATAL_FAILURE(cutTheSphereWithAFoldedStroke(false, false, opposite));
    ASSERT_NO_FATAL_FAILURE(cutTheSphereWithAFoldedStroke(true, false, agree));
    // The first quad on the plane y = 0.27 from x = -4.69 to 3.31; the second
    // on the plane at distance d1 from the centre, 7 mm on from t1.
    const double a = 20.0 * M_PI / 180.0, bx = 3.31, by = 0.27;
    const double d1 = bx * std::sin(a) + by * std::cos(a), t1 = -bx * std::cos(a) + by * std::sin(a);
    auto both = [&](double r) { return 2.0 * (stripSection(r, by, bx - 8.0, bx) + stripSection(r, d1, t1, t1 + 7.0)); };
    expectOneCutBothWays(opposite, agree, both(14.0), both(15.0));
}

// The fold's other case (TestStrokes.h: addFoldedStroke, straight): two quads
// in one plane, the second going straight on, with their normals exactly
// opposite, so the plane that would bisect theirs is not defined (their sum
// is 0). The junction was a rim of both (refused: the solid either side of
// the slit met along the stick). Now it is a fold mitre across the stick,
// and the cut is the one the same quads make with their normals agreeing: one
// fragment of the uncut volume with one slit, whose cut faces are both sides
// of the strip's section of the sphere, the same triangles both ways.
TEST(CutPropsDefects, AStraightStrokeWhoseNormalsTurnOverIsOneSlit)
{
    FoldedCut agree, opposite;
    ASSERT_NO_FATAL_FAILURE(cutTheSphereWithAFoldedStroke(true, true, agree));
    ASSERT_NO_FATAL_FAILURE(cutTheSphereWithAFoldedStroke(false, true, opposite));
    // Both sides of the strip -4.69 <= x <= 10.31 of the plane y = 0.27.
    auto both = [](double r) { return 2.0 * stripSection(r, 0.27, -4.69, 10.31); };
    expectOneCutBothWays(agree, opposite, both(14.0), both(15.0));
}

// The 2 mm head at kerf 0, random strokes seed 8023, updated after every
// quad: with quad 41 of stroke 3 the blade crosses the grid edge (65..66,
// 37, 83) 8e-5 mm from the isosurface's vertex on it, and the solid between
// them is a sliver round the edge in its four cells, thinner than a float
// step. The float repair's face rule joins the sliver's corner in face
// z = 83 to the iso vertex, in each pair of cells across that face alike,
// which flattens the sliver's cap in cells (65, 36, 82) and (65, 37, 82)
// into their common face y = 37: the same triangle in both, facing opposite
// ways, each of its edges used twice each way (refused, and the live stroke
// stopped at quad 41). The face rule lists such triangles
// (CutCellGeometry::intoFace), and the pair goes in fusion and the local
// check as snap rounding's pairs do (markCancellingPairs). The tooth at kerf
// 0.5, seed 8035, stroke 1, quad 41, was refused the same way (cell (74, 24,
// 11)) and is mended too.
TEST(CutPropsDefects, ASliverFlattenedIntoACellFaceFromBothSidesGoes)
{
    MTCUT_REQUIRE_DATA(path, "vhm_head_2mm.nhdr");
    HeadStrokeCut cut(path, 8023, 0.0, HeadStrokeCut::UpToQuad{3, 41});
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    const CutRemesher& remesher = cut.remesher;
    // The two cells each have a triangle the face rule put into face y = 37,
    // on one vertex set, facing opposite ways.
    std::vector<std::array<CutVertexId, 3>> moved[2];
    const Coord cells[2] = {Coord(65, 36, 82), Coord(65, 37, 82)};
    for (int i = 0; i < 2; ++i) {
        const auto it = remesher.cells().find(cells[i]);
        ASSERT_NE(it, remesher.cells().end());
        const CutCellGeometry& g = it->second;
        for (uint32_t t : g.intoFace)
            moved[i].push_back({g.vertexIds[g.indices[3 * t]], g.vertexIds[g.indices[3 * t + 1]],
                                g.vertexIds[g.indices[3 * t + 2]]});
    }
    ASSERT_EQ(moved[0].size(), 1u);
    ASSERT_EQ(moved[1].size(), 1u);
    const auto& a = moved[0][0];
    const auto& b = moved[1][0];
    const bool reversed = (a[0] == b[0] && a[1] == b[2] && a[2] == b[1]) || (a[0] == b[1] && a[1] == b[0] && a[2] == b[2]) ||
                          (a[0] == b[2] && a[1] == b[1] && a[2] == b[0]);
    EXPECT_TRUE(reversed) << "the two cells' face triangles are not one triangle facing both ways";
    for (const CutVertexId& id : a) EXPECT_EQ(gridVertexCoord(id.feature[0]).y(), 37) << "a corner off the face y = 37";
    const Mesh fused = remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    // Neither is in the fused mesh: the cut cells' triangles there are the
    // cells' less the pair.
    size_t inCells = 0, written = 0;
    for (const Coord& c : cells) inCells += remesher.cells().at(c).indices.size() / 3;
    for (const glm::ivec3& v : fused.triangleVoxels)
        for (const Coord& c : cells) written += v == glm::ivec3(c.x(), c.y(), c.z());
    EXPECT_EQ(written + 2, inCells);

    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    HeadStrokeCut toothCut(tooth, 8035, 0.5, HeadStrokeCut::UpToQuad{1, 41});
    ASSERT_EQ(toothCut.result.outcome, Outcome::Ok) << "tooth: " << toothCut.result.message;
    size_t intoFace = 0;
    for (const auto& [c, g] : toothCut.remesher.cells()) intoFace += g.intoFace.size();
    EXPECT_GE(intoFace, 2u) << "tooth: the face rule put no pair into a cell face";
    const MeshCheck toothCheck = checkMesh(toothCut.remesher.fusedMesh());
    EXPECT_TRUE(toothCheck.ok()) << "tooth:" << toothCheck.report();
}

// The 1 mm head at kerf 0, random strokes seed 2013 (the strokes of
// RandomKerfStrokesOnThe1mmHead...): the blade pivots near its tip, so quad
// 201 of the second stroke is a dart (its sticks cross 1.4 mm from the tip)
// and the kernel cuts its hull, whose edge next to quad 200 is not the
// stick they share. No junction joins them: quad 200's slit ends on a rim
// line that lies inside quad 201's open slit, a T-junction of two zero-width
// slits with three regions round the line. The vertices there had no side
// tags at all (quad 201's were taken away as on a strip rim), six triangles
// used one edge, and the update was refused. They now get quad 201's side
// and, on quad 200's side of quad 201, quad 200's too (tJunctionSide): all
// three strokes are accepted and clean, nothing meets off the blade, and
// the one cell that was refused has vertices with both quads' tags.
TEST(CutPropsDefects, ASlitEndingInsideAnotherSlitGetsACopyPerRegion)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    const vdb::Volume vol = vdb::readVolume(dir);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    CutMask mask(frameOf(vol), 0.0);
    CutRemesher remesher(vol, 400.0f, uncut);
    const uint32_t seed = 2013;
    const auto poses = makeRandomStrokes(mask.frame(), seed, 3, 300, 0.4 + 0.2 * (seed % 4), 20.0 + 10.0 * (seed % 4));
    for (size_t s = 0; s < poses.size(); ++s) {
        mask.beginStroke();
        for (const Quad& q : filterStroke(poses[s], mask.frame())) mask.addQuad(q);
        const UpdateResult r = tryUpdate(remesher, mask);
        ASSERT_EQ(r.outcome, Outcome::Ok) << "stroke " << s << ": " << r.message;
    }
    const Mesh fused = remesher.fusedMesh();
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    EXPECT_EQ(touchesNearCut(fused, remesher, mask, 1e-3).offBlade, 0u);
    const auto it = remesher.cells().find(Coord(240, 213, 243));
    ASSERT_NE(it, remesher.cells().end()) << "the stroke no longer cuts the cell";
    size_t both = 0;
    for (const CutVertexId& id : it->second.vertexIds) {
        bool q200 = false, q201 = false;
        for (int k = 0; k < id.tagCount; ++k) {
            const uint64_t quad = (id.tags[size_t(k)] >> 5) & 0xffffffff;
            q200 = q200 || quad == 200;
            q201 = q201 || quad == 201;
        }
        both += q200 && q201;
    }
    EXPECT_GT(both, 0u) << "no vertex of the cell has both quads' side tags";
}

/// A level stroke across the 1 mm head at 400, cut with `kerf`: `poses`
/// poses 1 ms apart, pose i's base at (xOf(i), 135, z) mm, the blade along
/// +y tilted down by `tilt` rad, `length` mm. Asserts it is accepted and the
/// fused mesh clean; gives the fused mesh and its self-contacts near the cut.
struct LevelStrokeCut
{
    size_t cutCells = 0, uncutVertices = 0;
    Mesh fused;
    TouchStats touches;
};

template <class F>
void cutLevelStroke(const std::string& dir, double kerf, size_t poses, double z, double length, F xOf,
                    LevelStrokeCut& out, double tilt = 0.0)
{
    const vdb::Volume vol = vdb::readVolume(dir);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    CutMask mask(frameOf(vol), kerf);
    std::vector<Pose> stroke(poses);
    for (size_t i = 0; i < stroke.size(); ++i) {
        stroke[i].time = double(i) / 1000.0;
        stroke[i].base = glm::dvec3(xOf(i), 135.0, z);
        stroke[i].direction = tilt == 0.0 ? glm::dvec3(0.0, 1.0, 0.0) : glm::dvec3(0.0, std::cos(tilt), -std::sin(tilt));
        stroke[i].length = length;
    }
    addStroke(mask, stroke);
    CutRemesher remesher(vol, 400.0f, uncut);
    const UpdateResult r = tryUpdate(remesher, mask);
    ASSERT_EQ(r.outcome, Outcome::Ok) << r.message;
    out.fused = remesher.fusedMesh();
    const MeshCheck check = checkMesh(out.fused);
    EXPECT_TRUE(check.ok()) << check.report();
    out.touches = touchesNearCut(out.fused, remesher, mask, 1e-3);
    out.cutCells = remesher.cutCellCount();
    out.uncutVertices = uncut.positions.size();
}

// The 1 mm head at kerf 0.5, a straight stroke at the whole-mm height z =
// 1106 mm with the blade level: the prism's top plane z = 1106.25 holds a
// marching-tetrahedra vertex exactly (integer CT values put it at a quarter
// of its grid edge), and the isosurface round it lies above the plane, so
// the surface touches itself there: a cone of isosurface and a disc of cap
// meeting at one point on the grid edge (222, 184, 1106)-(223, 184, 1107),
// which two cells share. Each cell held part of both; the vertex had two
// fans and the cut was refused ("a vertex where the surface pinches"). The
// cap's triangles at such a vertex now take a copy of it, in both cells.
TEST(CutPropsDefects, AnIsoVertexTouchingAKerfPlaneIsAPinchInEveryCellRoundIt)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    LevelStrokeCut cut;
    ASSERT_NO_FATAL_FAILURE(cutLevelStroke(dir, 0.5, 2001, 1106.0, 110.0,
                                           [](size_t i) { return 212.0 + 0.01 * double(i); }, cut));
    const TouchStats& t = cut.touches;
    std::printf("1 mm head, level stroke at z = 1106 mm, kerf 0.5: %zu cut cells, %zu intersecting pairs, %zu pinch "
                "contacts\n", cut.cutCells, t.pairs, t.pinchContacts);
    EXPECT_EQ(t.pairs, 0u);
    EXPECT_GT(t.pinchContacts, 0u); // the touching cone and disc
}

// The same level stroke at kerf 1, its blade ending at y = 245 mm: the
// prism's tip face lies in the grid plane y = 245, so cell (266, 245, 105)
// holds the prism (it touches the cell's face) while the cell beyond it
// does not. A crossing one grid step beyond the tip, at y = 246, lies on the
// mitre of quads 6 and 7 and on their bottom plane z = 1105.5, outside both
// prisms; the first cell named it by those planes, the next by none, and
// the seam opened (refused: "an edge used 1 time(s) one way and 0 the
// other"). A point in neither prism of a mitre now names none of their
// planes.
TEST(CutPropsDefects, APointBeyondTheTipOnAMitreNamesNoPlaneOfIt)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    LevelStrokeCut cut;
    ASSERT_NO_FATAL_FAILURE(cutLevelStroke(dir, 1.0, 1201, 1106.0, 110.0,
                                           [](size_t i) { return 260.0 + 0.01 * double(i); }, cut));
    std::printf("1 mm head, level stroke at z = 1106 mm to y = 245 mm, kerf 1: %zu cut cells, %zu intersecting pairs\n",
                cut.cutCells, cut.touches.pairs);
    EXPECT_EQ(cut.touches.pairs, 0u);
}

// A stroke at z = 1104 mm, kerf 0, its blade tilted 0.1 rad down and 114.5724
// mm long, so that its tip line runs 1.45e-5 mm (about one float step) above
// the grid plane y = 249. In cell (215, 249, 92) the cap between that plane
// and the tip line is a strip thinner than a float step, fanned from Steiner
// centres that round onto the plane: triangles of zero area once written.
// repairFloatFolds collapses such centres, but it judged float positions
// that GCC 12.2 (-O2) had left unrounded in x and y (it folds the
// vectorised round trip double(float(x)) away), saw nothing folded, and the
// local check refused the stroke ("a triangle of zero area in float mm").
TEST(CutPropsDefects, ACapStripThinnerThanAFloatStepAtTheTipIsMended)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    LevelStrokeCut cut;
    ASSERT_NO_FATAL_FAILURE(cutLevelStroke(dir, 0.0, 2001, 1104.0, 114.5724,
                                           [](size_t i) { return 212.0 + 0.01 * double(i); }, cut, 0.1));
    std::printf("1 mm head, stroke at z = 1104 mm tilted 0.1 rad, tip 1.45e-5 mm above y = 249: %zu cut cells\n",
                cut.cutCells);
    EXPECT_GT(cut.cutCells, 2000u);
    for (size_t t = 0; t < cut.fused.triangleCount(); ++t) {
        const glm::dvec3 a(cut.fused.positions[cut.fused.indices[3 * t]]);
        const glm::dvec3 b(cut.fused.positions[cut.fused.indices[3 * t + 1]]);
        const glm::dvec3 c(cut.fused.positions[cut.fused.indices[3 * t + 2]]);
        if (glm::cross(b - a, c - a) == glm::dvec3(0.0)) { // as the local check judges it
            ADD_FAILURE() << "a triangle of zero area in float, cell (" << cut.fused.triangleVoxels[t].x << ", "
                          << cut.fused.triangleVoxels[t].y << ", " << cut.fused.triangleVoxels[t].z << ")";
            break;
        }
    }
}

// Random strokes whose outcome changed when repairFloatFolds began to judge
// truly rounded positions (ACapStripThinnerThanAFloatStepAtTheTipIsMended):
// the tooth at kerf 0.5, seeds 1002 and 1011, were refused at their second
// stroke ("the surface crosses or touches itself"), and are accepted now;
// the 4 mm head's seed 1019 at kerf 0.5 is re-mended differently. All four
// strokes of each: clean, and no intersecting pairs near the cut (CGAL).
TEST(CutPropsDefects, StrokesMendedOnceFoldsAreJudgedInFloatAreClean)
{
    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    expectCleanRandomCut(tooth, "tooth at 400", 1002, 4, 0.5);
    expectCleanRandomCut(tooth, "tooth at 400", 1011, 4, 0.5);
    MTCUT_REQUIRE_DATA(head, "vhm_head_4mm.nhdr");
    expectCleanRandomCut(head, "4 mm head", 1019, 4, 0.5);
}

// A level stroke at z = 1103 mm, kerf 1: its bottom plane z = 1102.5 passes
// through the marching-tetrahedra vertex at the middle of the face diagonal
// (255, 185, 102)-(255, 184, 103) (values symmetric about 400), where the
// isosurface is a saddle: under the plane the solid is two wedges, towards
// y = 184 and y = 185, that meet only at that vertex, and each of the cells
// (254, 184, 102) and (255, 184, 102) holds part of both. The vertex had one
// name and two fans (refused: "a vertex where the surface pinches"; the same
// without a pose at x = 255, i.e. no mitre in the face). fusedMesh() now
// gives the second fan its own copy; the two wedges touch at one point.
TEST(CutPropsDefects, ASaddleOnAKerfPlaneAcrossACellFaceIsAPinch)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    LevelStrokeCut cut;
    ASSERT_NO_FATAL_FAILURE(cutLevelStroke(dir, 1.0, 1201, 1103.0, 114.0,
                                           [](size_t i) { return double(25000 + i) / 100.0; }, cut));
    const TouchStats& t = cut.touches;
    std::printf("1 mm head, level stroke at z = 1103 mm, kerf 1: %zu cut cells, %zu intersecting pairs, %zu pinch "
                "contacts\n", cut.cutCells, t.pairs, t.pinchContacts);
    EXPECT_EQ(t.pairs, 0u);
    EXPECT_GT(t.pinchContacts, 0u); // the two wedges
    // The copy sits where the vertex is: two new vertices of the fused mesh
    // at (255, 184.5, 1102.5) mm (the uncut mesh's, unused now, stays too).
    size_t at = 0;
    for (size_t v = cut.uncutVertices; v < cut.fused.positions.size(); ++v)
        at += cut.fused.positions[v] == glm::vec3(255.0f, 184.5f, 1102.5f);
    EXPECT_EQ(at, 2u);
}

// The tooth at 400, kerf 0, random strokes seed 1018, stroke 3: in the face
// x = 84 of cells (83, 24, 19) and (84, 24, 19) the iso line and the blade's
// line cross twice, 1e-5 mm apart, on either side of the face's diagonal.
// The face rule merged both crossings into the blade's vertex on the
// diagonal; the second merge failed the link condition (the iso vertex on
// the diagonal was a common neighbour) and 94c87e6's tent rule cancelled
// triangles in both cells, leaving the lens between the two lines as a
// closed bubble in each: the edge between it and the blade's vertex used
// twice each way (refused). The same refused seed 1026 at kerf 0.5. A
// common neighbour inside the face now keeps the pair apart in both cells.
TEST(CutPropsDefects, AFacePairWithACommonNeighbourInTheFaceStaysApart)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    expectCleanRandomCut(path, "tooth at 400", 1018, 4, 0.0);
    expectCleanRandomCut(path, "tooth at 400", 1026, 4, 0.5);
}

/// The first `strokes` random strokes of `seed` at kerf w, stroke by stroke,
/// accepted and clean (expectCleanRandomCut), and equal to the same mask
/// re-meshed from scratch, and, each stroke undone, to the earlier states.
void expectCleanRandomCutEqualFromScratch(const std::string& path, const char* name, uint32_t seed, size_t strokes,
                                          double kerf)
{
    expectCleanRandomCut(path, name, seed, strokes, kerf);
    HeadStrokeCut cut(path, seed, kerf, strokes);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    const Mesh incremental = cut.remesher.fusedMesh();
    CutRemesher scratch(cut.vol, 400.0f, cut.uncut);
    ASSERT_EQ(tryUpdate(scratch, cut.mask).outcome, Outcome::Ok);
    EXPECT_TRUE(sameMesh(scratch.fusedMesh(), incremental)) << name << " seed " << seed << ": from scratch differs";
    // Undo to the first stroke, then redo: the same mesh again.
    std::vector<Mesh> states;
    while (cut.mask.strokeCount() > 1) {
        ASSERT_TRUE(cut.mask.undoStroke());
        ASSERT_EQ(tryUpdate(cut.remesher, cut.mask).outcome, Outcome::Ok);
        CutRemesher fresh(cut.vol, 400.0f, cut.uncut);
        ASSERT_EQ(tryUpdate(fresh, cut.mask).outcome, Outcome::Ok);
        EXPECT_TRUE(sameMesh(fresh.fusedMesh(), cut.remesher.fusedMesh()))
            << name << " seed " << seed << ": undone to " << cut.mask.strokeCount() << " stroke(s), differs from scratch";
    }
    while (cut.mask.redoStroke()) ASSERT_EQ(tryUpdate(cut.remesher, cut.mask).outcome, Outcome::Ok);
    EXPECT_TRUE(sameMesh(cut.remesher.fusedMesh(), incremental)) << name << " seed " << seed << ": redo differs";
}

// Cuts with a width whose removed region has sheets closer than a float step
// inside one cell, which crossed once written; refused by the local check
// until the float repair learnt to mend a cell whose own triangles cross
// (repairFloatFolds with crossings, run by update() when its check fails).
// - The 1 mm head at kerf 1, seed 3015, the first stroke: a non-planar stick
//   split into two triangles, one a 50 mm sliver whose sharp end lies in cell
//   (259, 332, 168); there its prism's two sides and the next quad's end
//   plane nearly coincide, the removed sliver between them 1e-5 mm thick at
//   z = 1169 mm (13 CGAL pairs when it was written without the check).
// - The tooth at kerf 2, seed 3016, stroke 2: two sheets 4e-6 mm apart in
//   cell (13, 82, 55) (6 CGAL pairs when written without the check).
// - The 2 mm head at kerf 0.5, seed 5038, stroke 2: in cell (80, 94, 101)
//   four prism faces of three quads (one a sliver triangle of a split step)
//   meet at one point inside a tet; triangles of two faces a degree apart,
//   20 float steps apart at their far ends, crossed near it once written.
// - The tooth at kerf 1, seed 5006, stroke 2: three vertices within 4 float
//   steps on one inner tet face of cell (73, 47, 130).
// All accepted now, CGAL-clean, and equal from scratch and after undo.
TEST(CutPropsDefects, SheetsCrossingOnceWrittenInsideACellAreMended)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    MTCUT_REQUIRE_DATA(head2, "vhm_head_2mm.nhdr");
    expectCleanRandomCutEqualFromScratch(dir, "1 mm head", 3015, 1, 1.0);
    expectCleanRandomCutEqualFromScratch(tooth, "tooth at 400", 3016, 3, 2.0);
    expectCleanRandomCutEqualFromScratch(head2, "2 mm head", 5038, 3, 0.5);
    expectCleanRandomCutEqualFromScratch(tooth, "tooth at 400", 5006, 3, 1.0);
}

// The 1 mm head, kerf 0.5 mm, random strokes seed 2011, stroke 2: on the
// grid edge (227, 200, 226)-(227, 200, 227) at z = 1227 mm the isosurface and
// the prism's lower offset plane cross 1e-6 mm apart, one float point. The
// two triangles there (an isosurface piece and a prism face) touch at that
// one corner of each and nowhere else: a point contact, which the tests'
// CGAL check counts as a pinch contact, and which the first self-contact
// check refused. Accepted, clean, no intersecting pairs.
TEST(CutPropsDefects, TwoCornersRoundedToOneFloatPointAreAPointContactNotACrossing)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    HeadStrokeCut cut(dir, 2011, 0.5, 3);
    ASSERT_EQ(cut.result.outcome, Outcome::Ok) << cut.result.message;
    const Mesh fused = cut.remesher.fusedMesh();
    EXPECT_TRUE(checkMesh(fused).ok());
    const TouchStats t = touchesNearCut(fused, cut.remesher, cut.mask, 1e-3);
    EXPECT_EQ(t.pairs, 0u);
    EXPECT_GE(t.pinchContacts, 1u) << "the stroke no longer makes the point contact";
}

// The body CT (NIfTI, 3 mm) at kerf 0, random strokes seed 1008: an iso
// region held a crack, a slit whose ends are both inside it, and its
// triangulation failed (refused; Polygon2.ACrackIsBridgedToTheCopy...).
TEST(CutPropsDefects, AnIsoRegionWithACrackInsideIsTriangulated)
{
    MTCUT_REQUIRE_DATA(path, "body-ct.nii.gz");
    expectCleanRandomCut(path, "body CT", 1008, 2, 0.0);
}

// The issue's acceptance cut: `mtcut cut` of the 1 mm VHM head (DICOM) at
// 400 HU with its built-in LeFort stroke and kerf 0.5 mm. Clean, and CGAL
// finds no intersecting triangles near the cut. It found 20: an iso
// region's last four corners were split by the diagonal that left a flat
// sliver (the seam bending slightly on a mitre), and rounding to float
// folded it over; then 3, where a chord of an iso region passed within
// 50 nm of such a seam corner (a grid-edge vertex a few um from the
// seam). Regions of up to 9 corners now take the triangulation whose worst
// triangle is best (bestTriangulation, kerf > 0). The stroke now crosses
// the whole face (LeFortOptions::Path::Across) and frees the lower face:
// the maxilla with the upper teeth and the mandible (65,635 mm^3, 1,031 mm^2
// of cut face), which the 30 mm half ellipse it replaced did not.
TEST(CutPropsDefects, LeFortCutOfThe1mmHeadWithKerfDoesNotIntersectItself)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    const vdb::Volume vol = vdb::readVolume(dir);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    CutMask mask(frameOf(vol), 0.5);
    addStroke(mask, makeLeFortStroke(mask.frame(), leFortOptionsFittedTo(uncut.positions)));
    CutRemesher remesher(vol, 400.0f, uncut);
    UPDATE_OR_SKIP(remesher, mask);
    std::vector<uint32_t> source;
    const Mesh fused = remesher.fusedMesh(&source);
    const MeshCheck check = checkMesh(fused);
    EXPECT_TRUE(check.ok()) << check.report();
    // The freed lower face: the second fragment, a tenth of the skull's
    // volume or more, with a cut face of its own (the rest are specks).
    const std::vector<Fragment> pieces = fragmentsOf(fused, remesher.bladeTriangles(source));
    ASSERT_GE(pieces.size(), 2u);
    std::printf("LeFort, 1 mm head, kerf 0.5: fragments of %.1f and %.1f mm^3, %.1f and %.1f mm^2 cut\n",
                pieces[0].volume, pieces[1].volume, pieces[0].cutArea, pieces[1].cutArea);
    EXPECT_GT(pieces[1].volume, 0.1 * pieces[0].volume) << "the stroke no longer frees the lower face";
    EXPECT_GT(pieces[1].cutArea, 500.0);
    EXPECT_GT(pieces[0].cutArea, 500.0);
    const TouchStats t = touchesNearCut(fused, remesher, mask, 1e-3);
    std::printf("LeFort, 1 mm head, kerf 0.5: %zu cut cells, %zu intersecting pairs near the cut (%.1f s)\n",
                remesher.cells().size(), t.pairs, t.findSeconds);
    EXPECT_EQ(t.pairs, 0u);
}

INSTANTIATE_TEST_SUITE_P(Kerf, CutProps, ::testing::Values(0.0, 0.5),
                         [](const ::testing::TestParamInfo<double>& p) {
                             return p.param > 0 ? std::string("w0p5mm") : std::string("w0");
                         });

// A blade that pivots: every pose of a 1-radian arc aims at one point
// inside the tooth, within 0.4 mm (a smooth wobble) or exactly, so the quads
// fan through the cells there and cross one another (all 26 quads in one
// cell). With kerf 0.5 mm the cut is a clean single fragment. Aimed exactly,
// every stick and so every mitre plane passes through the point: more planes
// than a vertex name holds (it was refused, "a point lies on more than 8
// blade planes"; a point inside a tet is now named by three independent
// planes and the lowest others). It is also the re-mesher's worst case for
// cost: the arrangement of a tet grows with the planes crossing it (the
// wobbling fan took 40 s of re-meshing before the kernel's lookups were
// indexed, about 2.5 s after, on a 2-core machine). Aimed exactly, with kerf
// 0.5 mm, the cut is a clean single fragment with no intersecting triangles
// (CGAL). The wobbling fan with kerf 0.5 mm was accepted with 12 pairs of
// crossing triangles in cell (46, 44, 76) (points of different planes 2e-5
// mm apart, which this test did not ask CGAL about), then refused by the
// self-contact check; the float repair now mends that cell's crossings
// (repairFloatFolds with crossings), and it is a clean single fragment with
// no intersecting triangles too. Kerf 0 (the fan's quads touching, slivers
// between nearly coincident ones): refused or clean, never silent. The
// wobbling fan at kerf 0 is accepted since a point inside a quad off its
// junctions is in its slit (52bfd6d); pieces 10-100 um across between its
// crossing quads overlap the main body by a float step or two next to some
// of their triangles, which checkMesh took for wrong nesting until it judged
// them from the middle of a chord through them (05f75d7).
TEST(CutPropsDefects, PivotingBladeFanIsCleanWithKerfAndCleanOrRefusedWithout)
{
    MTCUT_REQUIRE_DATA(path, "tooth.nhdr");
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 656.0f, IsosurfaceOptions{nullptr, false});
    const glm::dvec3 focus = glm::dvec3(51.3, 47.2, 80.1); // world mm (the scan's origin is 0, 1 mm voxels)
    // (radians, wobble): the 1-radian fans, then a 1.5-radian wobbling one
    // (about 40 quads in one cell), with kerf only.
    for (const auto& [radians, wobble] : std::vector<std::pair<double, double>>{{1.0, 0.4}, {1.0, 0.0}, {1.5, 0.4}}) {
        std::vector<Pose> poses;
        const int n = 100;
        for (int i = 0; i <= n; ++i) {
            const double a = radians * double(i) / n;
            Pose p;
            p.time = 0.001 * i;
            p.base = focus + glm::dvec3(20.0 * std::cos(a), 20.0 * std::sin(a), 12.0);
            const glm::dvec3 aim = focus + wobble * glm::dvec3(std::sin(3 * a), std::cos(2 * a), std::sin(a));
            p.direction = aim - p.base;
            p.length = 30.0;
            poses.push_back(p);
        }
        for (double kerf : {0.5, 0.0}) {
            if (kerf == 0.0 && (wobble == 0.0 || radians > 1.0)) continue; // refused too; not worth the test time
            CutMask mask(frameOf(vol), kerf);
            addStroke(mask, poses);
            std::map<Coord, int> quadsPerCell;
            for (uint32_t q = 0; q < mask.quadCount(1); ++q)
                for (const Coord& c : mask.cellsOf(QuadRef{1, q})) ++quadsPerCell[c];
            int most = 0;
            for (const auto& [c, k] : quadsPerCell) most = std::max(most, k);
            EXPECT_GE(most, 15) << "the stroke no longer fans through one cell";
            CutRemesher remesher(vol, 656.0f, uncut);
            const UpdateResult u = tryUpdate(remesher, mask);
            std::printf("%g rad, wobble %g mm, kerf %g: %u quads, at most %d in one cell: %s\n", radians, wobble, kerf,
                        mask.quadCount(1), most, u.outcome == Outcome::Refused ? u.message.c_str() : "accepted");
            if (kerf > 0) {
                ASSERT_EQ(u.outcome, Outcome::Ok) << u.message;
            }
            if (u.outcome == Outcome::Refused) continue; // refused: not silent
            const Mesh fused = remesher.fusedMesh();
            const MeshCheck check = checkMesh(fused);
            EXPECT_TRUE(check.ok()) << "wobble " << wobble << ", kerf " << kerf << "\n" << check.report();
            if (kerf > 0) {
                EXPECT_EQ(fragmentsOf(fused).size(), 1u);
                EXPECT_EQ(touchesNearCut(fused, remesher, mask, 1e-3).pairs, 0u);
            }
        }
    }
}

// Seeded random kerf strokes on the 1 mm head (DICOM; 512 x 512 x 245, z
// about 1100 mm, where a float step is 0.12 um), three per seed on one mask,
// each seed from scratch: none refused, every fused mesh clean, and CGAL
// finds no intersecting triangles near the cut. Seeds 2001-2040 were all
// clean when this was written (2026-11-23); these are the first eight and
// the two that were refused: 2004 (a slit touching a region's outer loop:
// Polygon2.AHoleTouchingTheOuterLoopIsSplicedWhereItTouches), 2013 (a
// 3-corner cap region with no area in double, then an open edge: the blade
// pivoting about its tip makes triangles with a 1-degree corner, and the
// mitre at such a corner reached a voxel past it, outside the mask; such a
// joint now gets a mitre only when its bend keeps the reach inside,
// tooSharpForMitre).
TEST(CutPropsDefects, RandomKerfStrokesOnThe1mmHeadAreCleanAndDoNotIntersectThemselves)
{
    MTCUT_REQUIRE_DATA(dir, "vhm-head-dicom");
    const vdb::Volume vol = vdb::readVolume(dir);
    const Mesh uncut = extractIsosurface(vol, 400.0f, IsosurfaceOptions{nullptr, false});
    size_t strokes = 0, cells = 0;
    const auto t0 = std::chrono::steady_clock::now();
    for (uint32_t seed : {2001u, 2002u, 2003u, 2004u, 2005u, 2006u, 2007u, 2008u, 2013u}) {
        CutMask mask(frameOf(vol), 0.5);
        CutRemesher remesher(vol, 400.0f, uncut);
        const auto poses = makeRandomStrokes(mask.frame(), seed, 3, 300, 0.4 + 0.2 * (seed % 4), 20.0 + 10.0 * (seed % 4));
        for (size_t s = 0; s < poses.size(); ++s) {
            mask.beginStroke();
            for (const Quad& q : filterStroke(poses[s], mask.frame())) mask.addQuad(q);
            const UpdateResult r = tryUpdate(remesher, mask);
            if (r.outcome == Outcome::KerfTodo) GTEST_SKIP() << r.message;
            EXPECT_EQ(r.outcome, Outcome::Ok) << "seed " << seed << " stroke " << s << ": " << r.message;
            ++strokes;
        }
        const Mesh fused = remesher.fusedMesh();
        const MeshCheck check = checkMesh(fused);
        EXPECT_TRUE(check.ok()) << "seed " << seed << ": " << check.report();
        const TouchStats t = touchesNearCut(fused, remesher, mask, 1e-3);
        EXPECT_EQ(t.pairs, 0u) << "seed " << seed << ": self-intersecting triangle pairs near the cut";
        cells += remesher.cells().size();
    }
    std::printf("1 mm head, random kerf strokes: %zu strokes, %zu cut cells in all, %.1f s\n", strokes, cells,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

