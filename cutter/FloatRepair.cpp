// The float repair (cutter/FloatRepair.h): snapping, lifting and collapsing
// the kernel's vertices so that each cell stays clean once written in float.
#include "cutter/FloatRepair.h"

#include "cutter/RemeshKernel.h"
#include "cutter/TriangleIntersect.h"

#include <boost/container/small_vector.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace mtcut::cutter::remesh_detail {

namespace {
template <class T, size_t N> using SmallVector = boost::container::small_vector<T, N>;

/// The largest world coordinate (mm, absolute) of the grid box [lo, hi]: a
/// cell's, or a face's (lo and hi equal on its axis), as the float repair's
/// reach is judged there.
double boxExtent(const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing, const Coord& lo, const Coord& hi)
{
    double e = 0.0;
    for (int a = 0; a < 3; ++a)
        e = std::max({e, std::abs(origin[a] + spacing[a] * lo[a]), std::abs(origin[a] + spacing[a] * hi[a])});
    return e;
}
} // namespace

double floatShortAt(double extent)
{
    return kFloatStepsShort * extent * double(std::numeric_limits<float>::epsilon());
}

bool joinsAlongGridEdge(const CutVertexId& iso, const CutVertexId& other, const glm::vec3& isoAt, const glm::vec3& otherAt,
                        const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing)
{
    if (!iso.isIsoEdgeVertex() || other.dim != 1 || other.tagCount != 0 || other.planeCount == 0 ||
        other.planes[0] == kIso || other.feature[0] != iso.feature[0] || other.feature[1] != iso.feature[1])
        return false;
    double extent = 0.0;
    for (const uint64_t id : {iso.feature[0], iso.feature[1]}) {
        const Coord g = gridVertexCoord(id);
        const dvec3 w = exactWorldPosition(origin, spacing, dvec3(g.x(), g.y(), g.z()));
        extent = std::max({extent, std::abs(w.x), std::abs(w.y), std::abs(w.z)});
    }
    return glm::length(dvec3(otherAt) - dvec3(isoAt)) < floatShortAt(extent);
}

float snapLookSq(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing)
{
    const double look = kFloatStepsLook * boxExtent(origin, spacing, cell, cell + Coord(1)) *
                        double(std::numeric_limits<float>::epsilon());
    return float(look * look);
}

bool pinchInFaceCandidate(const CutVertexId& keep, const CutVertexId& other)
{
    if (other.dim != 2 || other.tagCount != 0 || keep.tagCount != 0) return false;
    if (keep.dim == 2) return keep.feature == other.feature && keep < other;
    // A vertex of one of the face's edges.
    return keep.dim == 1 && std::count(other.feature.begin(), other.feature.end(), keep.feature[0]) &&
           std::count(other.feature.begin(), other.feature.end(), keep.feature[1]);
}

bool joinsPinchInFace(const CutVertexId& keep, const CutVertexId& other, const glm::vec3& keepAt,
                      const glm::vec3& otherAt, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing)
{
    if (!pinchInFaceCandidate(keep, other)) return false;
    const Coord g0 = gridVertexCoord(other.feature[0]), g1 = gridVertexCoord(other.feature[1]),
                g2 = gridVertexCoord(other.feature[2]);
    const double extent = boxExtent(origin, spacing, Coord::minComponent(g0, Coord::minComponent(g1, g2)),
                                    Coord::maxComponent(g0, Coord::maxComponent(g1, g2)));
    return glm::length(dvec3(otherAt) - dvec3(keepAt)) <
           kFloatStepsPinch * extent * double(std::numeric_limits<float>::epsilon());
}

bool facesMeetAtCubeEdge(const CutVertexId& a, const CutVertexId& b)
{
    if (a.dim != 2 || b.dim != 2 || a.tagCount != b.tagCount || a.planeCount == 0 || a.planeCount != b.planeCount ||
        a.feature == b.feature)
        return false;
    for (uint8_t k = 0; k < a.planeCount; ++k)
        if (a.planes[k] != b.planes[k]) return false;
    for (uint8_t k = 0; k < a.tagCount; ++k)
        if (a.tags[k] != b.tags[k]) return false;
    // Both in cell faces (the three grid vertices share a coordinate), of
    // different axes, with two grid vertices in common: the cube edge.
    auto faceAxis = [](const CutVertexId& v) {
        const Coord g0 = gridVertexCoord(v.feature[0]), g1 = gridVertexCoord(v.feature[1]),
                    g2 = gridVertexCoord(v.feature[2]);
        for (int axis = 0; axis < 3; ++axis)
            if (g0[axis] == g1[axis] && g1[axis] == g2[axis]) return axis;
        return -1;
    };
    const int axisA = faceAxis(a), axisB = faceAxis(b);
    if (axisA < 0 || axisB < 0 || axisA == axisB) return false;
    int common = 0;
    for (const uint64_t f : a.feature) common += int(std::count(b.feature.begin(), b.feature.end(), f));
    return common == 2;
}

bool joinsRoundCubeEdge(const CutVertexId& a, const CutVertexId& b, const glm::vec3& aAt, const glm::vec3& bAt,
                        const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing)
{
    if (!facesMeetAtCubeEdge(a, b)) return false;
    uint64_t edge[2];
    int n = 0;
    for (const uint64_t f : a.feature)
        if (std::count(b.feature.begin(), b.feature.end(), f) && n < 2) edge[n++] = f;
    const Coord g0 = gridVertexCoord(edge[0]), g1 = gridVertexCoord(edge[1]);
    const dvec3 w0 = exactWorldPosition(origin, spacing, dvec3(g0.x(), g0.y(), g0.z()));
    const dvec3 w1 = exactWorldPosition(origin, spacing, dvec3(g1.x(), g1.y(), g1.z()));
    // Both rounded to within the reach of the edge's line, and of each other.
    const double extent = std::max({std::abs(w0.x), std::abs(w0.y), std::abs(w0.z), std::abs(w1.x), std::abs(w1.y),
                                    std::abs(w1.z)});
    const double reach = floatShortAt(extent);
    double offA = 0.0, offB = 0.0;
    for (int axis = 0; axis < 3; ++axis) {
        if (g0[axis] != g1[axis]) continue;
        offA += (double(aAt[axis]) - w0[axis]) * (double(aAt[axis]) - w0[axis]);
        offB += (double(bAt[axis]) - w0[axis]) * (double(bAt[axis]) - w0[axis]);
    }
    return offA < reach * reach && offB < reach * reach && glm::length(dvec3(aAt) - dvec3(bAt)) < reach;
}

size_t snapToGridVertices(const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing, CutCellGeometry& out)
{
    size_t moved = 0;
    for (size_t v = 0; v < out.vertexIds.size(); ++v) {
        if (out.vertexIds[v].isIsoEdgeVertex()) continue; // the uncut mesh's vertex, as it is
        dvec3& p = out.indexPositions[v];
        const dvec3 g = glm::round(p);
        if (p == g) continue;
        const dvec3 wg = exactWorldPosition(origin, spacing, g);
        const double extent = std::max({std::abs(wg.x), std::abs(wg.y), std::abs(wg.z)});
        if (glm::length(exactWorldPosition(origin, spacing, p) - wg) < floatShortAt(extent)) {
            p = g;
            ++moved;
        }
    }
    return moved;
}

namespace {

/// The faces of `cell` the vertex lies on (bit 2 * axis + side); 0 for a
/// vertex private to the cell, inside it, which no other cell names. Tet
/// edges all lie on cell faces (the 5-tet split has no inner edge), so only
/// tet-face and inside-tet vertices can be private.
unsigned cellFaces(const CutVertexId& id, const Coord& cell)
{
    if (id.dim == 3) return 0;
    unsigned faces = 0x3fu; // each feature's grid vertex leaves the faces it is on
    for (int f = 0; f <= id.dim && faces != 0; ++f) {
        const Coord g = gridVertexCoord(id.feature[size_t(f)]);
        for (int axis = 0; axis < 3; ++axis) {
            if (g[axis] != cell[axis]) faces &= ~(1u << (2 * axis));
            if (g[axis] != cell[axis] + 1) faces &= ~(1u << (2 * axis + 1));
        }
    }
    return faces;
}

/// An index coordinate on `axis` that writes as `target` (origin + spacing
/// x, rounded to float, as fusedMesh writes it): from the nearest double, a
/// few double steps at most; NaN where none does within 64.
double indexWritingAs(float target, int axis, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing)
{
    auto writes = [&](double x) { return float(origin[axis] + spacing[axis] * x); };
    double x = (double(target) - origin[axis]) / spacing[axis];
    for (int i = 0; i < 64 && writes(x) != target; ++i)
        x = std::nextafter(x, writes(x) < target ? std::numeric_limits<double>::infinity()
                                                 : -std::numeric_limits<double>::infinity());
    return writes(x) == target ? x : std::numeric_limits<double>::quiet_NaN();
}

} // namespace

size_t liftOffCellFaces(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing,
                        CutCellGeometry& out)
{
    const size_t nv = out.indexPositions.size();
    size_t lifted = 0;
    float faceAt[3][2]; // the cell's faces, written
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side)
            faceAt[axis][side] = float(origin[axis] + spacing[axis] * double(cell[axis] + side));
    std::vector<unsigned> faces; // cellFaces of every vertex, once one is a candidate
    for (size_t v = 0; v < nv; ++v) {
        if (out.vertexIds[v].isIsoEdgeVertex()) continue; // the uncut mesh's vertex, on a grid edge
        dvec3& p = out.indexPositions[v];
        for (int axis = 0; axis < 3; ++axis) {
            auto writes = [&](double x) { return float(origin[axis] + spacing[axis] * x); };
            const float at = writes(p[axis]);
            if (at != faceAt[axis][0] && at != faceAt[axis][1]) continue; // (nearly every vertex)
            const int side = at == faceAt[axis][0] ? 0 : 1;
            const double face = double(cell[axis] + side);
            if (side == 0 ? !(p[axis] > face) : !(p[axis] < face)) continue; // on the face: not ours
            if (faces.empty()) {
                faces.resize(nv);
                for (size_t w = 0; w < nv; ++w) faces[w] = cellFaces(out.vertexIds[w], cell);
            }
            if (faces[v] != 0) continue; // another cell has it too
            SmallVector<const uint32_t*, 16> star; // its triangles
            for (size_t k = 0; k + 2 < out.indices.size(); k += 3) {
                const uint32_t* t = &out.indices[k];
                if (t[0] == v || t[1] == v || t[2] == v) star.push_back(t);
            }
            // A tent's apex: every neighbour in this face.
            const unsigned bit = 1u << (2 * axis + side);
            bool tent = true;
            for (const uint32_t* t : star)
                for (int j = 0; j < 3; ++j) tent = tent && (t[j] == v || (faces[t[j]] & bit) != 0);
            if (star.empty() || tent) continue;
            // One float step inside, and an index coordinate that writes there.
            const float target = std::nextafter(faceAt[axis][side], faceAt[axis][1 - side]);
            const double q = indexWritingAs(target, axis, origin, spacing);
            if (!(q > double(cell[axis])) || !(q < double(cell[axis] + 1))) continue; // (NaN: none)
            // Not when a triangle at it would then be folded or of no
            // area once written (a strip of cap thinner than a float step
            // fanned from a centre that rounds into the face: the float
            // repair collapses the centre instead; 1 mm head, kerf 0, the
            // tip line 1.45e-5 mm above y = 249 mm).
            const dvec3 before = p;
            dvec3 after = p;
            after[axis] = q;
            bool folds = false;
            // Held as float on the heap (GCC 12.2 folded the vectorised
            // round trip double(float(x)) away: repairFloatFolds).
            std::vector<glm::vec3> written(3);
            for (size_t i = 0; i < star.size() && !folds; ++i) {
                const uint32_t* t = star[i];
                std::array<dvec3, 3> exact;
                for (int j = 0; j < 3; ++j) {
                    exact[size_t(j)] = exactWorldPosition(origin, spacing, t[j] == v ? before : out.indexPositions[t[j]]);
                    const dvec3 w = exactWorldPosition(origin, spacing, t[j] == v ? after : out.indexPositions[t[j]]);
                    written[size_t(j)] = glm::vec3(float(w.x), float(w.y), float(w.z));
                }
                const dvec3 n = glm::cross(exact[1] - exact[0], exact[2] - exact[0]);
                const dvec3 a(written[0]), b(written[1]), d(written[2]);
                folds = !(glm::dot(glm::cross(b - a, d - a), n) > 0.0);
            }
            if (folds) continue;
            p[axis] = q;
            ++lifted;
        }
    }
    return lifted;
}

size_t keepFaceSidesOnceWritten(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing,
                                CutCellGeometry& out)
{
    // The vertices inside one cell face that are not the isosurface's (the
    // uncut mesh's positions stay): the candidates.
    // (A point of a cell face has the face's coordinate exactly: asked
    // first, it spares most vertices the name's faces.)
    const size_t nv = out.indexPositions.size();
    SmallVector<unsigned, 128> faces(nv, 0u); // (on the stack: this runs for every cell)
    bool any = false;
    for (uint32_t v = 0; v < uint32_t(nv); ++v) {
        const CutVertexId& id = out.vertexIds[v];
        const dvec3& x = out.indexPositions[v];
        bool onFace = false;
        for (int a = 0; a < 3; ++a) onFace = onFace || x[a] == double(cell[a]) || x[a] == double(cell[a] + 1);
        if (id.dim == 3 || !onFace) continue;
        faces[v] = cellFaces(id, cell);
        any = any || (id.dim == 2 && faces[v] != 0 && !id.isIsoEdgeVertex());
    }
    if (!any) return 0;
    // The edges of the cell's triangles that lie in a cell face: (a, b, face
    // bit). An edge of the face's section has a triangle on either side of
    // the face, so the cell across has it too. (An edge of two of this
    // cell's triangles is listed twice; it is asked twice, alike.)
    SmallVector<std::array<uint32_t, 3>, 64> edges;
    for (size_t k = 0; k + 2 < out.indices.size(); k += 3)
        for (int e = 0; e < 3; ++e) {
            const uint32_t a = out.indices[k + size_t(e)], b = out.indices[k + size_t((e + 1) % 3)];
            const unsigned common = faces[a] & faces[b];
            if (!common) continue;
            for (unsigned bit = 0; bit < 6; ++bit)
                if (common >> bit & 1u) edges.push_back({std::min(a, b), std::max(a, b), bit});
        }
    if (edges.empty()) return 0;
    auto exact = [&](uint32_t v) { return exactWorldPosition(origin, spacing, out.indexPositions[v]); };
    auto written = [&](uint32_t v) {
        const dvec3 w = exact(v);
        return glm::vec3(float(w.x), float(w.y), float(w.z));
    };
    struct Near
    {
        glm::vec3 a, b;
        int side; // of the vertex to the edge's line, exactly (as double holds it)
    };
    // Vertex p's face, the two axes across it, and the float repair's reach
    // at the face; the edges of that face whose line p passes within the
    // reach, beside the edge (not beyond its ends), off the line; true when
    // p is written on or across one of them.
    auto nearEdges = [&](uint32_t p, unsigned& bit, int& i, int& j, SmallVector<Near, 8>& near) {
        bit = 0;
        while (!(faces[p] >> bit & 1u)) ++bit;
        const int axis = int(bit / 2);
        i = (axis + 1) % 3;
        j = (axis + 2) % 3;
        Coord lo = cell, hi = cell + Coord(1);
        lo[axis] = hi[axis] = cell[axis] + int(bit % 2);
        const double reach = floatShortAt(boxExtent(origin, spacing, lo, hi));
        near.clear();
        const dvec3 ep = exact(p);
        bool flipped = false;
        for (const auto& e : edges) {
            if (e[2] != bit || e[0] == p || e[1] == p) continue;
            const dvec3 ea = exact(e[0]), eb = exact(e[1]);
            // (Most edges are far: their box grown by the reach misses p.)
            if (ep[i] < std::min(ea[i], eb[i]) - reach || ep[i] > std::max(ea[i], eb[i]) + reach ||
                ep[j] < std::min(ea[j], eb[j]) - reach || ep[j] > std::max(ea[j], eb[j]) + reach)
                continue;
            const double abi = eb[i] - ea[i], abj = eb[j] - ea[j], len2 = abi * abi + abj * abj;
            const double api = ep[i] - ea[i], apj = ep[j] - ea[j];
            const double cross = abi * apj - abj * api, along = abi * api + abj * apj;
            if (!(len2 > 0.0) || along <= 0.0 || along >= len2 || std::abs(cross) >= reach * std::sqrt(len2) ||
                std::abs(cross) <= 1e-12 * len2)
                continue;
            near.push_back({written(e[0]), written(e[1]), cross > 0 ? 1 : -1});
            flipped = flipped || int(orient2d(near.back().a, near.back().b, written(p), i, j)) != near.back().side;
        }
        return flipped;
    };
    // The candidates written on or across such a line, in name order (the
    // two cells of the face take them alike).
    SmallVector<Near, 8> near;
    SmallVector<uint32_t, 8> flipped;
    unsigned bit = 0;
    int i = 0, j = 0;
    for (uint32_t v = 0; v < uint32_t(nv); ++v) {
        const CutVertexId& id = out.vertexIds[v];
        if (id.dim == 2 && faces[v] != 0 && !id.isIsoEdgeVertex() && nearEdges(v, bit, i, j, near)) flipped.push_back(v);
    }
    if (flipped.empty()) return 0;
    std::sort(flipped.begin(), flipped.end(), [&](uint32_t a, uint32_t b) { return out.vertexIds[a] < out.vertexIds[b]; });
    size_t moved = 0;
    for (uint32_t p : flipped) {
        if (!nearEdges(p, bit, i, j, near)) continue; // (an earlier move can mend it)
        // The first of the eight float neighbours of its point in the face
        // (the face's coordinate kept) on the exact side of every such edge.
        const glm::vec3 wp = written(p);
        for (int k = 0; k < 9; ++k) {
            if (k == 4) continue; // (0, 0)
            const int step[2] = {k / 3 - 1, k % 3 - 1};
            glm::vec3 target = wp;
            dvec3 q = out.indexPositions[p];
            bool ok = true;
            for (int d = 0; d < 2 && ok; ++d) {
                if (step[d] == 0) continue;
                const int ax = d == 0 ? i : j;
                constexpr float kInf = std::numeric_limits<float>::infinity();
                target[ax] = std::nextafter(wp[ax], step[d] > 0 ? kInf : -kInf);
                q[ax] = indexWritingAs(target[ax], ax, origin, spacing);
                ok = q[ax] > double(cell[ax]) && q[ax] < double(cell[ax] + 1); // inside the face (NaN: none)
            }
            for (size_t n = 0; n < near.size() && ok; ++n) ok = int(orient2d(near[n].a, near[n].b, target, i, j)) == near[n].side;
            if (!ok) continue;
            out.indexPositions[p] = q;
            ++moved;
            break;
        }
    }
    return moved;
}

namespace {

/// A shell of the cell's own (every vertex private to the cell: no other
/// cell has one of its triangles, so it is closed here) thinner than a short
/// edge (three times its volume over its area, its inradius when it is a
/// tetrahedron) goes as a whole: once written it has no inside, and nothing
/// of it can be told from the solid it touches (2 mm head, kerf 0, a saw
/// swung across its blade, seeds 78113 and 78119: a tetrahedron of solid
/// between three slits' sides and the isosurface, 0.02-0.1 mm long and 1e-7
/// mm thick, judged inside the fragment whose sheets it lies on: wrong way
/// for its nesting). Such a shell need not fold once written (flat, each
/// face keeps its side), so it is looked for in every cell. Returns the
/// vertices removed; the others keep their order, as do the triangles.
size_t dropThinShellsOfTheCell(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing,
                               CutCellGeometry& out)
{
    // (On the stack, and out early: this runs for every cell, and a shell
    // of the cell's own is rare.)
    const size_t nv = out.vertexIds.size(), nt = out.indices.size() / 3;
    SmallVector<char, 128> own(nv, 0);
    for (size_t i = 0; i < nv; ++i) own[i] = cellFaces(out.vertexIds[i], cell) == 0;
    bool any = false;
    for (size_t t = 0; t < nt && !any; ++t)
        any = own[out.indices[3 * t]] && own[out.indices[3 * t + 1]] && own[out.indices[3 * t + 2]];
    if (!any) return 0;
    SmallVector<uint32_t, 128> root(nv);
    for (uint32_t v = 0; v < uint32_t(nv); ++v) root[v] = v;
    auto find = [&](uint32_t v) {
        while (root[v] != v) v = root[v] = root[root[v]];
        return v;
    };
    for (size_t t = 0; t < nt; ++t)
        for (int k = 1; k < 3; ++k) root[find(out.indices[3 * t + size_t(k)])] = find(out.indices[3 * t]);
    // A component is the cell's own when none of its vertices is on a cell
    // face (own[root] cleared otherwise); only its used vertices count.
    SmallVector<char, 128> used(nv, 0);
    for (uint32_t i : out.indices) used[i] = 1;
    SmallVector<char, 128> whole(nv, 0); // by root: used, and every vertex the cell's own
    for (uint32_t v = 0; v < uint32_t(nv); ++v)
        if (used[v]) whole[find(v)] = 1;
    for (uint32_t v = 0; v < uint32_t(nv); ++v)
        if (used[v] && !own[v]) whole[find(v)] = 0;
    any = false;
    for (uint32_t v = 0; v < uint32_t(nv) && !any; ++v) any = whole[v] != 0;
    if (!any) return 0;
    // Per such component: 6 V and 2 A, from its first corner.
    struct Sums
    {
        double volume6 = 0.0, area2 = 0.0;
        dvec3 at{0.0};
        bool seen = false;
    };
    SmallVector<Sums, 8> sums;
    SmallVector<uint32_t, 8> roots;
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t r = find(out.indices[3 * t]);
        if (!whole[r]) continue;
        const size_t i = size_t(std::find(roots.begin(), roots.end(), r) - roots.begin());
        if (i == roots.size()) {
            roots.push_back(r);
            sums.emplace_back();
        }
        std::array<dvec3, 3> c;
        for (int k = 0; k < 3; ++k)
            c[size_t(k)] = exactWorldPosition(origin, spacing, out.indexPositions[out.indices[3 * t + size_t(k)]]);
        Sums& m = sums[i];
        if (!m.seen) m.at = c[0], m.seen = true;
        const dvec3 a = c[0] - m.at, b = c[1] - m.at, d = c[2] - m.at;
        m.volume6 += glm::dot(a, glm::cross(b, d));
        m.area2 += glm::length(glm::cross(b - a, d - a));
    }
    const double shortEdge = floatShortAt(boxExtent(origin, spacing, cell, cell + Coord(1)));
    bool dropping = false;
    for (size_t i = 0; i < roots.size(); ++i) {
        const bool thin = std::abs(sums[i].volume6) < shortEdge * sums[i].area2; // 3 V / A < shortEdge
        whole[roots[i]] = thin ? 1 : 0;
        dropping = dropping || thin;
    }
    if (!dropping) return 0;
    CutCellGeometry kept;
    std::vector<uint32_t> newIndex(nv, UINT32_MAX);
    size_t removed = 0;
    for (uint32_t v = 0; v < uint32_t(nv); ++v) {
        if (used[v] && whole[find(v)]) {
            ++removed;
            continue;
        }
        newIndex[v] = uint32_t(kept.vertexIds.size());
        kept.vertexIds.push_back(out.vertexIds[v]);
        kept.indexPositions.push_back(out.indexPositions[v]);
    }
    size_t k = 0; // out.intoFace (ascending)
    for (size_t t = 0; t < nt; ++t) {
        while (k < out.intoFace.size() && out.intoFace[k] < t) ++k;
        if (whole[find(out.indices[3 * t])]) continue;
        if (k < out.intoFace.size() && out.intoFace[k] == t) kept.intoFace.push_back(uint32_t(kept.indices.size() / 3));
        for (int j = 0; j < 3; ++j) kept.indices.push_back(newIndex[out.indices[3 * t + size_t(j)]]);
        kept.cap.push_back(out.cap[t]);
    }
    kept.crossFree = out.crossFree;
    out = std::move(kept);
    return removed;
}

/// Two vertices of a cell with different tags that a round's collapse may
/// still join: neither a copy of a pinch (kPinchTag), not copies of one
/// point (the same name but for the tags), and on no slit on opposite sides
/// (a tag of one quad's plane, minus on one and plus on the other). A
/// vertex on one side of a slit and one off it, or on the same side of it,
/// lie on one sheet there: a tetrahedron-private vertex moved from one onto
/// the other changes only the cell's own triangles, whose link and folds the
/// collapse asks as for any other (tooth at 400, kerf 0, sliding saw seed
/// 75409, stroke 1, quad 62: a slit chord's midpoint 1.5e-5 mm from the
/// junction point of two quads and from a point of the next quad's plane,
/// the three tagged {q54-}, {q54-, q55+} and {}: their triangle had no area
/// once written and nothing could join them).
bool sidesAgree(const CutVertexId& a, const CutVertexId& b)
{
    for (uint8_t i = 0; i < a.tagCount; ++i)
        if (a.tags[i] & kPinchTag) return false;
    for (uint8_t j = 0; j < b.tagCount; ++j)
        if (b.tags[j] & kPinchTag) return false;
    if (a.dim == b.dim && a.feature == b.feature && a.planeCount == b.planeCount && a.planes == b.planes) return false;
    for (uint8_t i = 0; i < a.tagCount; ++i)
        for (uint8_t j = 0; j < b.tagCount; ++j)
            if ((a.tags[i] >> 1) == (b.tags[j] >> 1) && a.tags[i] != b.tags[j]) return false;
    return true;
}

} // namespace

size_t repairFloatFolds(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing,
                        CutCellGeometry& out, bool crossings, bool flattenFoldedTents)
{
    if (out.cap.size() != out.indices.size() / 3)
        throw std::logic_error("repairFloatFolds: one cap flag per triangle expected");
    const size_t thin = dropThinShellsOfTheCell(cell, origin, spacing, out);
    const size_t nv = out.indexPositions.size(), nt = out.indices.size() / 3;
    out.crossFree = false;
    if (nt == 0) return thin;
    // Exact (double) and written (float) world positions, as fusedMesh.
    // Held as float: GCC 12.2 at -O2 and above folded the round trip
    // dvec3(double(float(x)), double(float(y)), ..) of the two lanes it
    // vectorised away (x and y kept unrounded, z rounded), so a triangle
    // degenerate once written looked sound here (1 mm head, kerf 0, a tip
    // line 1.45e-5 mm above the grid plane y = 249: a cap fan thinner than
    // a float step, refused by the local check). LocalCheck.cpp met the same.
    std::vector<dvec3> exact(nv);
    std::vector<glm::vec3> written(nv);
    for (size_t i = 0; i < nv; ++i) {
        const dvec3& p = out.indexPositions[i];
        exact[i] = exactWorldPosition(origin, spacing, p);
        written[i] = glm::vec3(float(exact[i].x), float(exact[i].y), float(exact[i].z));
    }
    std::vector<std::array<uint32_t, 3>> tris(nt);
    std::vector<dvec3> normal(nt); // exact orientation, from the exact corners as the kernel made them
    for (size_t t = 0; t < nt; ++t) {
        tris[t] = {out.indices[3 * t], out.indices[3 * t + 1], out.indices[3 * t + 2]};
        normal[t] = glm::cross(exact[tris[t][1]] - exact[tris[t][0]], exact[tris[t][2]] - exact[tris[t][0]]);
    }
    // Folded once written: degenerate in float, or facing against its exact normal.
    auto folded = [&](const std::array<uint32_t, 3>& v, const dvec3& n) {
        const dvec3 a(written[v[0]]), b(written[v[1]]), c(written[v[2]]);
        const dvec3 f = glm::cross(b - a, c - a);
        return !(glm::dot(f, n) > 0.0);
    };
    // Shorter than a few float steps at the largest coordinate of the box
    // [lo, hi] holding it: the ends may round together or across each other.
    // A cell's edges are judged by the cell; a pair inside a cell face by the
    // face, as the cell on its other side judges it (a cell's own extent
    // differs across a face whose coordinate is its larger one; tooth seed
    // 1002 at z = 98 mm).
    auto extentOf = [&](const Coord& lo, const Coord& hi) { return boxExtent(origin, spacing, lo, hi); };
    const double shortEdge = floatShortAt(extentOf(cell, cell + Coord(1)));
    auto isShort = [&](uint32_t a, uint32_t b) { return glm::length(exact[a] - exact[b]) < shortEdge; };
    const double lookReach = shortEdge * (kFloatStepsLook / kFloatStepsShort);
    // face: bit 2 * axis + side (cellFaces).
    auto isShortInFace = [&](uint32_t a, uint32_t b, unsigned face) {
        int axis = 0;
        while (!(face >> (2 * axis) & 3u)) ++axis;
        const int side = (face >> (2 * axis) & 1u) ? 0 : 1;
        Coord lo = cell, hi = cell + Coord(1);
        lo[axis] = hi[axis] = cell[axis] + side;
        return glm::length(exact[a] - exact[b]) < floatShortAt(extentOf(lo, hi));
    };
    auto needsMending = [&](size_t t) {
        const auto& v = tris[t];
        return folded(v, normal[t]) || isShort(v[0], v[1]) || isShort(v[1], v[2]) || isShort(v[2], v[0]);
    };
    std::vector<char> alive(nt, 1);
    // crossings: the triangles that cross or touch another of the cell's
    // once written, judged as the local check judges a cut with a width
    // (trianglesCross, after the snap rounding of fusedMesh: the ends of an
    // edge at one float position are one vertex; the pinch copies of a name
    // are one vertex). Ascending, each once.
    auto crossingTriangles = [&](std::vector<size_t>& hit) {
        hit.clear();
        std::vector<uint32_t> rep(nv);
        bool pinches = false; // (most cells have no pinch copy: each vertex is its own)
        for (uint32_t v = 0; v < uint32_t(nv); ++v) {
            rep[v] = v;
            const CutVertexId& id = out.vertexIds[v];
            for (uint8_t k = 0; k < id.tagCount; ++k) pinches = pinches || (id.tags[k] & kPinchTag) != 0;
        }
        if (pinches) {
            std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash> plain;
            for (uint32_t v = 0; v < uint32_t(nv); ++v) {
                CutVertexId id = out.vertexIds[v];
                uint8_t n = 0;
                for (uint8_t k = 0; k < id.tagCount; ++k)
                    if (!(id.tags[k] & kPinchTag)) id.tags[n++] = id.tags[k];
                for (uint8_t k = n; k < id.tagCount; ++k) id.tags[k] = 0;
                id.tagCount = n;
                rep[v] = plain.emplace(id, v).first->second;
            }
        }
        auto find = [&](uint32_t x) {
            while (rep[x] != x) x = rep[x] = rep[rep[x]];
            return x;
        };
        for (size_t t = 0; t < nt; ++t)
            for (int e = 0; alive[t] && e < 3; ++e) {
                const uint32_t a = find(tris[t][size_t(e)]), b = find(tris[t][size_t((e + 1) % 3)]);
                if (a != b && written[a] == written[b]) rep[std::max(a, b)] = std::min(a, b);
            }
        struct Tri
        {
            size_t t;
            std::array<uint32_t, 3> id;
            std::array<glm::vec3, 3> p;
            glm::vec3 lo, hi;
            TrianglePlane plane;
        };
        std::vector<Tri> live;
        for (size_t t = 0; t < nt; ++t) {
            if (!alive[t]) continue;
            Tri x{t, {find(tris[t][0]), find(tris[t][1]), find(tris[t][2])}, {}, {}, {}, {}};
            if (x.id[0] == x.id[1] || x.id[1] == x.id[2] || x.id[0] == x.id[2]) continue; // snapped away
            for (int k = 0; k < 3; ++k) x.p[size_t(k)] = written[tris[t][size_t(k)]];
            x.lo = glm::min(x.p[0], glm::min(x.p[1], x.p[2]));
            x.hi = glm::max(x.p[0], glm::max(x.p[1], x.p[2]));
            x.plane = trianglePlane(x.p);
            live.push_back(x);
        }
        for (size_t i = 0; i < live.size(); ++i)
            for (size_t j = i + 1; j < live.size(); ++j) {
                const Tri &a = live[i], &b = live[j];
                if (a.hi.x < b.lo.x || b.hi.x < a.lo.x || a.hi.y < b.lo.y || b.hi.y < a.lo.y || a.hi.z < b.lo.z ||
                    b.hi.z < a.lo.z)
                    continue;
                if (trianglesCross(a.p, a.id, a.plane, b.p, b.id, b.plane) == Contact::None) continue;
                hit.push_back(a.t);
                hit.push_back(b.t);
            }
        std::sort(hit.begin(), hit.end());
        hit.erase(std::unique(hit.begin(), hit.end()), hit.end());
    };
    std::vector<unsigned> faces(nv);
    bool facesKnown = false;
    auto knowFaces = [&] {
        if (facesKnown) return;
        for (size_t i = 0; i < nv; ++i) faces[i] = cellFaces(out.vertexIds[i], cell);
        facesKnown = true;
    };
    auto inOneFace = [&](uint32_t v) { return faces[v] != 0 && (faces[v] & (faces[v] - 1)) == 0; };
    // Spikes of a face's section (tooth, kerf 0.5, random strokes seeds
    // 9074, 9082, 9160; 9099 with its base on the face's diagonal): a vertex C inside one cell face joined along the
    // face to exactly two vertices A and B inside it, which share no edge and
    // are one float point once written. The line of two faces of one quad's
    // prism pokes through the next quad's offset face by 2e-5 mm (3e-4 in
    // 9082): the face's section runs along the offset face's line to A, out
    // to C and back to B, A and B 1e-6 mm apart. Written, the spike has no
    // width, and in the cell where the section's two edges at C bound
    // triangles on the same side, those two triangles lie on each other. A
    // function of the section and the rounding, which the two cells of the
    // face share, so both find it. (tip, survivor, merged): A the lesser name.
    struct Spike
    {
        uint32_t tip, a, b;
    };
    // A base vertex: inside a tet face, or on a grid edge but not the
    // isosurface's own vertex there (inside one cell face, below, for both:
    // in a tet face there or on its diagonal). The search's trigger asks the
    // same, so both cells of the face look.
    auto baseCandidate = [&](uint32_t v) {
        const CutVertexId& id = out.vertexIds[v];
        return id.dim == 2 || (id.dim == 1 && !id.isIsoEdgeVertex());
    };
    auto findSpikes = [&](std::vector<Spike>& spikes) {
        spikes.clear();
        knowFaces();
        std::vector<std::pair<uint32_t, uint32_t>> along; // both ways, both ends inside one same face
        for (size_t t = 0; t < nt; ++t)
            for (int e = 0; alive[t] && e < 3; ++e) {
                const uint32_t u = tris[t][size_t(e)], v = tris[t][size_t((e + 1) % 3)];
                if (!inOneFace(u) || faces[u] != faces[v]) continue;
                along.push_back({u, v});
                along.push_back({v, u});
            }
        std::sort(along.begin(), along.end());
        along.erase(std::unique(along.begin(), along.end()), along.end());
        auto joined = [&](uint32_t u, uint32_t v) {
            for (size_t t = 0; t < nt; ++t)
                if (alive[t] && std::count(tris[t].begin(), tris[t].end(), u) && std::count(tris[t].begin(), tris[t].end(), v))
                    return true;
            return false;
        };
        for (size_t i = 0; i + 1 < along.size(); ++i) {
            const uint32_t c = along[i].first;
            if ((i > 0 && along[i - 1].first == c) || along[i + 1].first != c ||
                (i + 2 < along.size() && along[i + 2].first == c))
                continue; // not exactly two neighbours along the face
            uint32_t a = along[i].second, b = along[i + 1].second;
            const CutVertexId &ia = out.vertexIds[a], &ib = out.vertexIds[b];
            if (ia.tagCount != ib.tagCount || ia.tags != ib.tags) continue; // copies of one point stay apart
            if (!baseCandidate(a) || !baseCandidate(b) || written[a] != written[b] || joined(a, b)) continue;
            if (ib < ia) std::swap(a, b);
            spikes.push_back({c, a, b});
        }
        std::sort(spikes.begin(), spikes.end(), [&](const Spike& x, const Spike& y) {
            if (out.vertexIds[x.a] < out.vertexIds[y.a]) return true;
            if (out.vertexIds[y.a] < out.vertexIds[x.a]) return false;
            return out.vertexIds[x.b] < out.vertexIds[y.b];
        });
    };
    std::vector<size_t> crossing;
    std::vector<Spike> spikes;
    bool any = false;
    for (size_t t = 0; t < nt && !any; ++t) any = needsMending(t);
    if (crossings && !any) {
        crossingTriangles(crossing);
        any = !crossing.empty();
    }
    {
        // A spike's base is two such vertices at one float point: rare, so
        // looked for first (a few dozen vertices a cell).
        SmallVector<uint32_t, 64> candidates;
        for (uint32_t v = 0; v < uint32_t(nv); ++v)
            if (baseCandidate(v)) candidates.push_back(v);
        auto less = [&](uint32_t u, uint32_t v) {
            const glm::vec3 &x = written[u], &y = written[v];
            return x.x != y.x ? x.x < y.x : x.y != y.y ? x.y < y.y : x.z < y.z;
        };
        std::sort(candidates.begin(), candidates.end(), less);
        bool onePoint = false;
        for (size_t i = 1; i < candidates.size() && !onePoint; ++i)
            onePoint = written[candidates[i - 1]] == written[candidates[i]];
        if (onePoint) findSpikes(spikes);
        any = any || !spikes.empty();
    }
    if (!any) {
        out.crossFree = crossings; // (crossingTriangles found none)
        return thin;
    }

    knowFaces();
    auto canMove = [&](uint32_t v) { return faces[v] == 0; };
    std::vector<uint32_t> mergedInto(nv);
    for (size_t i = 0; i < nv; ++i) mergedInto[i] = uint32_t(i);
    size_t removed = 0;
    // The triangles the face rule moves into a cell face (out.intoFace:
    // kept from an earlier repair of this geometry).
    std::vector<char> intoFace(nt, 0);
    for (uint32_t t : out.intoFace)
        if (t < nt) intoFace[t] = 1;
    auto inCellFace = [&](const std::array<uint32_t, 3>& v) { return (faces[v[0]] & faces[v[1]] & faces[v[2]]) != 0; };
    // Triangles at a vertex, rebuilt after each collapse (cells hold tens to
    // a few hundred triangles, and collapses are rare).
    auto trianglesAt = [&](uint32_t v, std::vector<size_t>& list) {
        list.clear();
        for (size_t t = 0; t < nt; ++t)
            if (alive[t] && (tris[t][0] == v || tris[t][1] == v || tris[t][2] == v)) list.push_back(t);
    };
    std::vector<size_t> atP, atQ;
    // Whether one of `list`'s triangles is `v` facing the other way.
    auto reversedAmong = [&](const std::array<uint32_t, 3>& v, const std::vector<size_t>& list) {
        for (size_t u : list) {
            const auto& o = tris[u];
            for (int r = 0; r < 3; ++r)
                if (o[size_t(r)] == v[0] && o[size_t((r + 1) % 3)] == v[2] && o[size_t((r + 2) % 3)] == v[1]) return true;
        }
        return false;
    };
    auto neighbours = [&](const std::vector<size_t>& list, uint32_t v) {
        std::vector<uint32_t> n;
        for (size_t t : list)
            for (uint32_t w : tris[t])
                if (w != v) n.push_back(w);
        std::sort(n.begin(), n.end());
        n.erase(std::unique(n.begin(), n.end()), n.end());
        return n;
    };
    /// The face rule's collapse where the link condition fails because p and
    /// q close a small tent of the cell's own (2 mm head, kerf 0.5, seed 3023:
    /// a vertex inside a tet whose only triangles run to p, q and one vertex
    /// inside the tet's face; the cell on the face's other side merged p into
    /// q, this one could not, and the seam opened). p becomes q; triangles
    /// that then coincide with opposite orientations go in pairs, and so do
    /// the vertices left without a triangle, which must be the cell's own.
    /// Done only when every edge of the changed triangles is then used at most
    /// once each way, and one used only once lies in a cell face.
    /// `tip`: a vertex of a cell face that may be left without a triangle
    /// (a spike's, below), as the cell's own vertices may.
    /// `with`: vertices private to the cell that become q along with p (the
    /// face rule's, below); a triangle they leave with two corners alike goes.
    auto collapseCancelling = [&](uint32_t p, uint32_t q, const std::vector<size_t>& onEdge,
                                  uint32_t tip = UINT32_MAX, const std::vector<uint32_t>& with = {}) {
        std::vector<size_t> touched;
        for (const std::vector<size_t>* list : {&atP, &atQ})
            for (size_t t : *list)
                if (std::find(onEdge.begin(), onEdge.end(), t) == onEdge.end()) touched.push_back(t);
        std::vector<size_t> atWith;
        for (uint32_t w : with) {
            trianglesAt(w, atWith);
            for (size_t t : atWith)
                if (std::find(onEdge.begin(), onEdge.end(), t) == onEdge.end()) touched.push_back(t);
        }
        std::sort(touched.begin(), touched.end());
        touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
        std::vector<std::array<uint32_t, 3>> moved(touched.size());
        std::vector<char> keep(touched.size(), 1);
        for (size_t i = 0; i < touched.size(); ++i) {
            moved[i] = tris[touched[i]];
            for (uint32_t& w : moved[i])
                if (w == p || std::find(with.begin(), with.end(), w) != with.end()) w = q;
            const auto& m = moved[i];
            if (m[0] == m[1] || m[1] == m[2] || m[0] == m[2]) keep[i] = 0; // (only with `with`)
        }
        // Rotated to start at the least vertex: two triangles on one vertex set
        // face opposite ways when their second corners differ.
        auto rotated = [](std::array<uint32_t, 3> v) {
            while (v[0] > v[1] || v[0] > v[2]) std::rotate(v.begin(), v.begin() + 1, v.end());
            return v;
        };
        for (size_t i = 0; i < touched.size(); ++i)
            for (size_t j = i + 1; j < touched.size(); ++j) {
                if (!keep[i] || !keep[j]) continue;
                const auto a = rotated(moved[i]), b = rotated(moved[j]);
                if (a[0] != b[0] || std::minmax(a[1], a[2]) != std::minmax(b[1], b[2])) continue;
                if (a[1] == b[1]) return false; // the same triangle twice
                keep[i] = keep[j] = 0;
            }
        std::vector<std::array<uint32_t, 3>> after;
        for (size_t t = 0; t < nt; ++t)
            if (alive[t] && std::find(onEdge.begin(), onEdge.end(), t) == onEdge.end() &&
                !std::binary_search(touched.begin(), touched.end(), t))
                after.push_back(tris[t]);
        for (size_t i = 0; i < touched.size(); ++i)
            if (keep[i]) after.push_back(moved[i]);
        auto uses = [&](uint32_t u, uint32_t v) {
            size_t n = 0;
            for (const auto& tri : after)
                for (int e = 0; e < 3; ++e) n += tri[size_t(e)] == u && tri[size_t((e + 1) % 3)] == v;
            return n;
        };
        auto used = [&](uint32_t v) {
            for (const auto& tri : after)
                if (tri[0] == v || tri[1] == v || tri[2] == v) return true;
            return false;
        };
        std::vector<uint32_t> dropped;
        for (const auto& tri : moved)
            for (int e = 0; e < 3; ++e) {
                const uint32_t u = tri[size_t(e)], v = tri[size_t((e + 1) % 3)];
                const size_t there = uses(u, v), back = uses(v, u);
                if (there > 1 || back > 1 || (there + back == 1 && !(faces[u] & faces[v]))) return false;
                if (u != q && !used(u)) {
                    if (faces[u] != 0 && u != tip) return false;
                    dropped.push_back(u);
                }
            }
        for (size_t t : onEdge) alive[t] = 0;
        for (size_t i = 0; i < touched.size(); ++i) {
            if (keep[i] && !inCellFace(tris[touched[i]]) && inCellFace(moved[i])) intoFace[touched[i]] = 1;
            tris[touched[i]] = moved[i];
            alive[touched[i]] = keep[i];
        }
        mergedInto[p] = q;
        for (uint32_t v : with) mergedInto[v] = q;
        for (uint32_t v : dropped) mergedInto[v] = q;
        removed += 1 + with.size();
        return true;
    };
    /// Collapses p onto q when that keeps a 2-manifold and (unless `onFace`)
    /// folds nothing and puts no triangle into a cell face (unless
    /// `intoFaceOk`: such a triangle is marked, out.intoFace); true if done.
    /// onFace: p and q lie inside one cell face and the edge is on the
    /// cell's boundary (one triangle).
    auto collapse = [&](uint32_t p, uint32_t q, bool onFace, bool intoFaceOk = false) {
        const CutVertexId &ip = out.vertexIds[p], &iq = out.vertexIds[q];
        if ((ip.tagCount != iq.tagCount || ip.tags != iq.tags) && (onFace || !sidesAgree(ip, iq))) return false;
        trianglesAt(p, atP);
        trianglesAt(q, atQ);
        std::vector<size_t> onEdge;
        for (size_t t : atP)
            if (tris[t][0] == q || tris[t][1] == q || tris[t][2] == q) onEdge.push_back(t);
        if (onEdge.size() != (onFace ? 1u : 2u)) return false;
        std::vector<uint32_t> apexes;
        for (size_t t : onEdge)
            for (uint32_t w : tris[t])
                if (w != p && w != q) apexes.push_back(w);
        std::sort(apexes.begin(), apexes.end());
        const std::vector<uint32_t> np = neighbours(atP, p), nq = neighbours(atQ, q);
        std::vector<uint32_t> common;
        std::set_intersection(np.begin(), np.end(), nq.begin(), nq.end(), std::back_inserter(common));
        // The face rule makes no new edge along a cube edge (q and another
        // vertex w of p's triangles on one, two faces in common) longer than
        // a short edge: four cells share that edge, and the two across the
        // cube edge's other face may make it too, by the same rule there
        // (0.8 x 0.8 x 2.4 mm voxels, skin at -300, kerf 0.5, random
        // strokes seed 10023: an offset plane crosses grid edge
        // (92, 145, 21)-(92, 145, 22) 2.3e-3 mm from the isosurface's vertex
        // there, and the line where they meet passes the edge a float step
        // away; each of the four cells round it merged that line's point in
        // one of its two faces there into the plane's vertex, which joined
        // the plane's vertex to the iso vertex along the edge in all four:
        // used twice each way). Asked where p-w is an edge of the face's
        // section (used once in the cell), which the cell across has alike,
        // so both keep p and q apart. A short one stays allowed: two blade
        // planes' vertices on the cube edge a float step apart or less,
        // which snap rounding joins once written (0.45 x 0.45 x 1.25 mm
        // voxels, seeds 11021 and 11042: at one float point).
        if (onFace)
            for (size_t t : atP)
                for (uint32_t w : tris[t]) {
                    const unsigned both = faces[q] & faces[w];
                    if (w == p || w == q || (both & (both - 1)) == 0 || std::binary_search(nq.begin(), nq.end(), w) ||
                        isShortInFace(q, w, faces[p]))
                        continue;
                    size_t uses = 0; // of the edge p-w, either way
                    for (size_t u : atP) uses += std::count(tris[u].begin(), tris[u].end(), w);
                    if (uses == 1) return false;
                }
        if (common != apexes) { // the link condition
            if (!onFace) return false;
            // A common neighbour in the face closes a triangle of the face's
            // section with p and q: both cells of the face see it, and both
            // keep p and q apart (tooth, kerf 0, seed 1018: the iso line and
            // the blade's line crossing twice in a face 1e-5 mm apart, the
            // lens between them left as a bubble in each cell once merged).
            // Not when this cell uses one of its two edges both ways (a
            // triangle of its own lies in the face there): the cell across
            // then has no such edge, sees no such triangle and merges p into
            // q, and so must this one (0.45 x 0.45 x 1.25 mm voxels, the
            // skin, kerf 0.5, seed 11042: three end planes of a folding
            // stroke within 2e-5 voxel in face y = 32 of cell (84, 31, 88)).
            auto uses = [&](const std::vector<size_t>& at, uint32_t w) {
                size_t n = 0;
                for (size_t t : at) n += tris[t][0] == w || tris[t][1] == w || tris[t][2] == w;
                return n;
            };
            for (uint32_t w : common)
                if ((faces[w] & faces[p]) && uses(atP, w) == 1 && uses(atQ, w) == 1) return false;
            if (collapseCancelling(p, q, onEdge)) return true;
            // The rest of the link is the cell's own: common neighbours
            // private to it, within a few float steps, which the cell across
            // does not see (its own rounds may have collapsed theirs, and it
            // merges p into q). They become q too (1 mm head, kerf 0.5, seed
            // 60027, stroke 2, quad 66: the isosurface's vertex and an
            // offset plane's 2.3e-4 mm apart on the diagonal of face
            // z = 1163 mm; the cell below has a vertex of its own 3.3e-4 mm
            // under the face joined to both, the cell above merged them, and
            // the seam opened).
            std::vector<uint32_t> with;
            for (uint32_t w : common)
                if (!std::binary_search(apexes.begin(), apexes.end(), w)) {
                    if (faces[w] != 0 || glm::length(exact[w] - exact[q]) >= lookReach) return false;
                    with.push_back(w);
                }
            return !with.empty() && collapseCancelling(p, q, onEdge, UINT32_MAX, with);
        }
        // A tetrahedron of the cell's own with a short edge (a spike of solid
        // 2e-3 voxel thin between three prisms that pivot on its tip: the
        // 2 mm head at 0.8 x 0.8 x 2.4 mm, kerf 0.5, seed 10054): the link
        // condition holds, but p's one other triangle would lie on q's
        // facing the other way, a shell of no volume. Every triangle of p
        // moved that way goes, with its twin: the spike goes as a whole.
        // Only along a short edge: a crossing's collapse of a long one must
        // not remove a real piece of the solid (the local check refuses it).
        if (!onFace && atP.size() > onEdge.size() && isShort(p, q)) {
            bool allCancel = true;
            for (size_t t : atP) {
                if (!allCancel) break;
                if (std::find(onEdge.begin(), onEdge.end(), t) != onEdge.end()) continue;
                std::array<uint32_t, 3> moved = tris[t];
                for (uint32_t& w : moved)
                    if (w == p) w = q;
                allCancel = reversedAmong(moved, atQ);
            }
            if (allCancel) return collapseCancelling(p, q, onEdge);
        }
        for (size_t t : atP) {
            if (onFace) break;
            if (std::find(onEdge.begin(), onEdge.end(), t) != onEdge.end()) continue;
            std::array<uint32_t, 3> moved = tris[t];
            for (uint32_t& w : moved)
                if (w == p) w = q;
            if (folded(moved, normal[t])) return false;
            // Nor onto a triangle of q's facing the other way: the edge was
            // one of a tetrahedron (the link condition holds there), which
            // would be crushed into a shell of two triangles and no volume
            // (2 mm head, kerf 0, sawing across the blade, seed 78105: a
            // fold's collapse of a 2e-3 mm edge between points of three
            // slits' sides). Along a short edge such a tetrahedron goes as a
            // whole (above).
            if (reversedAmong(moved, atQ)) return false;
            if (intoFaceOk) continue;
            // A triangle in a cell face: the next cell may have it too.
            if (faces[moved[0]] & faces[moved[1]] & faces[moved[2]]) return false;
            // A new edge in a cell face: the cell across may make it too,
            // by the same collapse of its own, and the edge is then used
            // twice each way (0.45 x 0.45 x 1.25 mm voxels, skin at -300,
            // kerf 0.5, random strokes seed 11033: an offset plane nearly
            // parallel to the isosurface crosses a face's diagonal 2e-3
            // voxel from its marching-tetrahedra vertex, and each cell of
            // the face collapsed a vertex of its own inner tet face onto the
            // plane's vertex there, joining the two along the diagonal).
            for (uint32_t w : moved)
                if (w != q && (faces[q] & faces[w]) && !std::binary_search(nq.begin(), nq.end(), w)) return false;
        }
        for (size_t t : onEdge) alive[t] = 0;
        for (size_t t : atP) {
            const bool wasInFace = inCellFace(tris[t]);
            for (uint32_t& w : tris[t])
                if (w == p) w = q;
            // (Only the face rule and a crossing's last resort can: a round's
            // collapse refuses it above.)
            if (alive[t] && !wasInFace && inCellFace(tris[t])) intoFace[t] = 1;
        }
        mergedInto[p] = q;
        ++removed;
        return true;
    };
    // A vertex inside one cell face (inside a tet face there, or on the
    // face's diagonal, a grid edge no other cell has) joined by a short edge
    // to another vertex of that closed face: the two cells of the face, and
    // only they, hold the first, they both hold the second, and both have
    // the edge on their common boundary. The first becomes the second; of
    // two inside the face, the greater name becomes the lesser. Pairs in
    // name order (survivor, then the other), in both cells alike: only the
    // link condition is asked (a fold or face check could be judged
    // otherwise by the next cell; the local check judges the fused result).
    // A face vertex 3e-5 mm above a cube edge vertex (1 mm head, kerf 0.5,
    // seed 2002, z = 1226 mm) rounded onto the edge beyond it, and the next
    // cells' triangles touched the edge between them there (CGAL).
    {
        std::vector<std::pair<uint32_t, uint32_t>> onFace; // (survivor, merged)
        for (size_t t = 0; t < nt; ++t)
            for (int e = 0; e < 3; ++e) {
                uint32_t a = tris[t][size_t(e)], b = tris[t][size_t((e + 1) % 3)];
                // b inside the face; a inside it too, or on its boundary.
                if (!inOneFace(b) || (inOneFace(a) && out.vertexIds[b] < out.vertexIds[a])) std::swap(a, b);
                if (!inOneFace(b) || (faces[a] & faces[b]) != faces[b] || !isShortInFace(a, b, faces[b])) continue;
                onFace.push_back({a, b});
            }
        auto byName = [&](const std::pair<uint32_t, uint32_t>& x, const std::pair<uint32_t, uint32_t>& y) {
            if (out.vertexIds[x.first] < out.vertexIds[y.first]) return true;
            if (out.vertexIds[y.first] < out.vertexIds[x.first]) return false;
            return out.vertexIds[x.second] < out.vertexIds[y.second];
        };
        std::sort(onFace.begin(), onFace.end(), byName);
        for (const auto& [a, b] : onFace)
            if (mergedInto[a] == a && mergedInto[b] == b) collapse(b, a, true);
    }
    // A spike's two ends become one (B into A), in both cells of the face
    // alike: where the two triangles at C lay on each other they now coincide
    // facing opposite ways and go, with C (the cell across keeps C, its two
    // edges there now one edge used both ways); only the link of a 2-manifold
    // is asked, as for the face rule.
    if (!spikes.empty()) findSpikes(spikes); // as the face rule left the section
    for (const Spike& k : spikes) {
        if (mergedInto[k.a] != k.a || mergedInto[k.b] != k.b || mergedInto[k.tip] != k.tip) continue;
        trianglesAt(k.b, atP);
        trianglesAt(k.a, atQ);
        collapseCancelling(k.b, k.a, {}, k.tip);
    }
    // Then rounds: every short edge, shortest first (exact length, then
    // names), its private end moving; only when none can go, a folded
    // triangle may lose any of its edges, shortest first. Short edges first:
    // where a cut line passes within 1e-6 voxel of a tet edge, three
    // vertices a few 1e-7 apart chain there, and taking the triangles in
    // order moved the middle one far along a long edge of a folded sliver,
    // leaving two triangles folded onto each other (tooth seed 1009).
    std::vector<std::pair<double, std::pair<uint32_t, uint32_t>>> shortEdges; // (exact length, (a, b))
    // Shortest first, then by the ends' names; each edge once.
    auto sortEdges = [&] {
        std::sort(shortEdges.begin(), shortEdges.end(), [&](const auto& x, const auto& y) {
            if (x.first != y.first) return x.first < y.first;
            if (out.vertexIds[x.second.first] < out.vertexIds[y.second.first]) return true;
            if (out.vertexIds[y.second.first] < out.vertexIds[x.second.first]) return false;
            return out.vertexIds[x.second.second] < out.vertexIds[y.second.second];
        });
        shortEdges.erase(std::unique(shortEdges.begin(), shortEdges.end()), shortEdges.end());
    };
    // The first folded triangle (in triangle order) that loses an edge,
    // shortest first: any edge, or with `intoFaceOk` only a short one whose
    // collapse may lay a triangle into a cell face (marked). True if one did;
    // anyFolded says whether it met one.
    bool anyFolded = false;
    auto collapseAFoldedTrianglesEdge = [&](bool intoFaceOk) {
        anyFolded = false;
        for (size_t t = 0; t < nt; ++t) {
            if (!alive[t] || !folded(tris[t], normal[t])) continue;
            anyFolded = true;
            std::array<std::pair<double, int>, 3> edges;
            for (int e = 0; e < 3; ++e)
                edges[size_t(e)] = {glm::length(exact[tris[t][size_t((e + 1) % 3)]] - exact[tris[t][size_t(e)]]), e};
            std::sort(edges.begin(), edges.end());
            for (const auto& [len, e] : edges) {
                const uint32_t a = tris[t][size_t(e)], b = tris[t][size_t((e + 1) % 3)];
                if (intoFaceOk && !isShort(a, b)) break; // shortest first
                if ((canMove(a) && collapse(a, b, false, intoFaceOk)) || (canMove(b) && collapse(b, a, false, intoFaceOk)))
                    return true;
            }
        }
        return false;
    };
    for (int round = 0; round < 16; ++round) {
        bool mended = false;
        shortEdges.clear();
        for (size_t t = 0; t < nt; ++t) {
            if (!alive[t]) continue;
            for (int e = 0; e < 3; ++e) {
                uint32_t a = tris[t][size_t(e)], b = tris[t][size_t((e + 1) % 3)];
                if (!isShort(a, b)) continue;
                if (out.vertexIds[b] < out.vertexIds[a]) std::swap(a, b);
                shortEdges.push_back({glm::length(exact[a] - exact[b]), {a, b}});
            }
        }
        sortEdges(); // each once (its two triangles listed it twice)
        for (const auto& [len, ab] : shortEdges) {
            const auto [a, b] = ab;
            if (mergedInto[a] != a || mergedInto[b] != b) continue;
            if ((canMove(a) && collapse(a, b, false)) || (canMove(b) && collapse(b, a, false))) mended = true;
        }
        if (mended) continue;
        mended = collapseAFoldedTrianglesEdge(false);
        // Zero kerf: a folded triangle's short edge whose collapse lays a
        // triangle into a cell face (a tent flattened: the header).
        if (!mended && anyFolded && flattenFoldedTents) mended = collapseAFoldedTrianglesEdge(true);
        if (!mended && crossings) {
            // Last: an edge of a triangle that crosses another of the cell's
            // once written, shortest first (exact length, then names), one a
            // round. Sheets of the removed region's boundary on planes a
            // degree apart meet at a point inside the tet, and near it lie
            // closer than a float step (2 mm head, kerf 0.5, random strokes
            // seed 5038: four prism faces of three quads at one point, and
            // triangles of two of them 20 float steps apart crossed once
            // written; the exact ones are apart).
            crossingTriangles(crossing);
            shortEdges.clear();
            for (size_t t : crossing)
                for (int e = 0; e < 3; ++e) {
                    uint32_t a = tris[t][size_t(e)], b = tris[t][size_t((e + 1) % 3)];
                    if (out.vertexIds[b] < out.vertexIds[a]) std::swap(a, b);
                    shortEdges.push_back({glm::length(exact[a] - exact[b]), {a, b}});
                }
            sortEdges();
            for (const auto& [len, ab] : shortEdges) {
                const auto [a, b] = ab;
                if ((canMove(a) && collapse(a, b, false)) || (canMove(b) && collapse(b, a, false))) {
                    mended = true;
                    break;
                }
            }
            // Then a short one whose collapse lays a triangle into a cell
            // face, marked as the face rule marks its own (the cell across
            // may make it too, facing the other way: a pair that goes). A
            // tent of three triangles over a triangle of a cell face, its
            // apex inside the cell 6e-5 mm below the face, rounds flat into
            // the face and overlaps itself there (1 mm head, kerf 0.5, seed
            // 9202, z = 1135 mm: the isosurface, a kerf plane and the face's
            // diagonal bound the face triangle); with the apex on a corner,
            // the face triangle is left, its rim as the tent's.
            for (size_t i = 0; i < shortEdges.size() && !mended; ++i) {
                const auto [a, b] = shortEdges[i].second;
                if (!isShort(a, b)) break; // shortest first
                if ((canMove(a) && collapse(a, b, false, true)) || (canMove(b) && collapse(b, a, false, true)))
                    mended = true;
            }
        }
        if (!mended) break;
    }
    if (!removed) return thin;
    // Compact: drop the merged vertices (keeping the others' order) and the collapsed triangles.
    std::vector<uint32_t> newIndex(nv, UINT32_MAX);
    CutCellGeometry kept;
    for (size_t i = 0; i < nv; ++i) {
        if (mergedInto[i] != i) continue;
        newIndex[i] = uint32_t(kept.vertexIds.size());
        kept.vertexIds.push_back(out.vertexIds[i]);
        kept.indexPositions.push_back(out.indexPositions[i]);
    }
    for (size_t t = 0; t < nt; ++t) {
        if (!alive[t]) continue;
        if (intoFace[t]) kept.intoFace.push_back(uint32_t(kept.indices.size() / 3));
        for (uint32_t w : tris[t]) kept.indices.push_back(newIndex[w]);
        kept.cap.push_back(out.cap[t]);
    }
    out = std::move(kept);
    return removed + thin;
}

} // namespace mtcut::cutter::remesh_detail
