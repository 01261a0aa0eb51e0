// Test-only: an independent, robust self-intersection check of a cutter::Mesh
// with CGAL (DESIGN "Checks every mesh must pass": no self-intersection for
// kerf > 0). Positions are converted float -> double exactly and tested with
// exact predicates (Exact_predicates_inexact_constructions_kernel), so the
// answer does not depend on rounding.
//
// Adjacency (CGAL::Polygon_mesh_processing::self_intersections, CGAL 5.5):
// two triangles that share an edge intersect only when they overlap beyond it
// (coplanar, on the same side of it: a fold onto itself); two that share one
// vertex intersect only when they meet anywhere else too. Triangles that
// touch without sharing a vertex index (e.g. two coincident points of
// different vertices) do intersect. tests/test_cut_props.cpp checks these
// rules on small meshes.
//
// Link the test with CGAL::CGAL (header-only) and GMP/MPFR; see
// tests/CMakeLists.txt (MTCUT_CGAL_TESTS).
#pragma once

#include "cutter/Mesh.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <iterator>
#include <stdexcept>
#include <utility>
#include <vector>

namespace mtcut::test {

struct SelfIntersectResult
{
    /// Intersecting triangle pairs (triangle indices into the mesh, first < second).
    std::vector<std::pair<uint32_t, uint32_t>> pairs;
    size_t count() const { return pairs.size(); }
};

namespace detail {

using SiKernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using SiMesh = CGAL::Surface_mesh<SiKernel::Point_3>;

/// The CGAL mesh of a triangle soup, face i = faces[i]. Throws
/// std::invalid_argument when the triangles do not form an oriented
/// 2-manifold (with or without boundary): run checkMesh first,
/// self-intersection is only asked of meshes that pass it.
inline SiMesh toCgal(const std::vector<SiKernel::Point_3>& points, const std::vector<std::array<std::size_t, 3>>& faces)
{
    namespace PMP = CGAL::Polygon_mesh_processing;
    if (!PMP::is_polygon_soup_a_polygon_mesh(faces))
        throw std::invalid_argument("selfIntersections: the triangles are not an oriented 2-manifold");
    SiMesh sm;
    PMP::polygon_soup_to_polygon_mesh(points, faces, sm);
    if (sm.number_of_faces() != faces.size())
        throw std::invalid_argument("selfIntersections: CGAL mesh has a different face count");
    // The converter adds the faces in order into a fresh mesh: face i is faces[i].
    for (size_t t = 0; t < faces.size(); t += std::max<size_t>(1, faces.size() / 64)) {
        const SiMesh::Face_index f(static_cast<SiMesh::size_type>(t));
        std::array<std::size_t, 3> got{};
        int n = 0;
        for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) got[size_t(n++ % 3)] = std::size_t(v);
        std::array<std::size_t, 3> want = faces[t];
        std::sort(got.begin(), got.end());
        std::sort(want.begin(), want.end());
        if (n != 3 || got != want) throw std::logic_error("selfIntersections: CGAL face order differs");
    }
    return sm;
}

inline SiKernel::Point_3 toPoint(const glm::vec3& p) { return {double(p.x), double(p.y), double(p.z)}; }

/// The whole mesh, face i = triangle i.
inline SiMesh toCgal(const cutter::Mesh& mesh)
{
    std::vector<SiKernel::Point_3> points;
    points.reserve(mesh.positions.size());
    for (const glm::vec3& p : mesh.positions) points.push_back(toPoint(p));
    std::vector<std::array<std::size_t, 3>> faces(mesh.triangleCount());
    for (size_t t = 0; t < faces.size(); ++t)
        for (int j = 0; j < 3; ++j) faces[t][size_t(j)] = mesh.indices[3 * t + size_t(j)];
    return toCgal(points, faces);
}

/// The part of `mesh` that decides which pairs of the triangles `only`
/// intersect, so that a local check does not convert millions of triangles
/// it never asks about: the triangles `only` (faces 0 .. n-1, in that order,
/// each once; `keep` maps every face back to its triangle) and every other
/// triangle with a vertex of theirs (face n on). A vertex of a triangle in
/// `only` keeps its whole fan and is shared as in `mesh`, so two triangles of
/// `only` share an edge, a vertex or nothing exactly as there, and the
/// adjacency rules above give the same answer for them. The part's outer
/// rim can pinch at a vertex no triangle of `only` has (two pieces of its fan
/// kept, the piece between them not); CGAL's orient_polygon_soup gives each
/// piece a copy of such a vertex, which changes no pair that is asked.
inline SiMesh localCgal(const cutter::Mesh& mesh, const std::vector<uint32_t>& only, std::vector<uint32_t>& keep,
                        size_t& n)
{
    constexpr std::size_t kOutside = ~std::size_t(0);
    const size_t triangles = mesh.triangleCount();
    std::vector<std::size_t> id(mesh.positions.size(), kOutside);
    std::vector<char> kept(triangles, 0);
    std::vector<SiKernel::Point_3> points;
    keep.clear();
    for (uint32_t t : only) {
        if (t >= triangles) throw std::invalid_argument("selfIntersections: triangle index out of range");
        if (kept[t]) continue;
        kept[t] = 1;
        keep.push_back(t);
        for (int j = 0; j < 3; ++j) {
            const uint32_t v = mesh.indices[3 * size_t(t) + size_t(j)];
            if (id[v] == kOutside) {
                id[v] = points.size();
                points.push_back(toPoint(mesh.positions[v]));
            }
        }
    }
    n = keep.size();
    for (size_t t = 0; t < triangles; ++t) {
        if (kept[t]) continue;
        const uint32_t* v = &mesh.indices[3 * t];
        if (id[v[0]] != kOutside || id[v[1]] != kOutside || id[v[2]] != kOutside) keep.push_back(uint32_t(t));
    }
    std::vector<std::array<std::size_t, 3>> faces(keep.size());
    for (size_t f = 0; f < keep.size(); ++f)
        for (int j = 0; j < 3; ++j) {
            const uint32_t v = mesh.indices[3 * size_t(keep[f]) + size_t(j)];
            if (id[v] == kOutside) {
                id[v] = points.size();
                points.push_back(toPoint(mesh.positions[v]));
            }
            faces[f][size_t(j)] = id[v];
        }
    const std::vector<std::array<std::size_t, 3>> asked(faces.begin(), faces.begin() + std::ptrdiff_t(n));
    CGAL::Polygon_mesh_processing::orient_polygon_soup(points, faces);
    for (size_t f = 0; f < n; ++f) {
        std::array<std::size_t, 3> a = asked[f], b = faces[f];
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        if (a != b) throw std::invalid_argument("selfIntersections: a vertex of an asked triangle is not a 2-manifold's");
    }
    return toCgal(points, faces);
}

} // namespace detail

/// Every pair of intersecting triangles of `mesh` (an oriented 2-manifold,
/// closed or not). When `only` is given, only pairs of triangles both in
/// `only` are tested (a local check: one O(mesh) pass picks the part that
/// decides them, `detail::localCgal`, and only that part is converted; CGAL's
/// box intersection keeps the rest O(|only| log |only|)).
inline SelfIntersectResult selfIntersections(const cutter::Mesh& mesh, const std::vector<uint32_t>* only = nullptr)
{
    namespace PMP = CGAL::Polygon_mesh_processing;
    using Face = detail::SiMesh::Face_index;
    std::vector<std::pair<Face, Face>> found;
    std::vector<uint32_t> keep; // face -> triangle of mesh, for a local check
    if (only) {
        size_t n = 0;
        const detail::SiMesh sm = detail::localCgal(mesh, *only, keep, n);
        std::vector<Face> range;
        range.reserve(n);
        for (size_t f = 0; f < n; ++f) range.emplace_back(static_cast<detail::SiMesh::size_type>(f));
        PMP::self_intersections(range, sm, std::back_inserter(found));
    } else {
        const detail::SiMesh sm = detail::toCgal(mesh);
        PMP::self_intersections(sm, std::back_inserter(found));
    }
    SelfIntersectResult r;
    r.pairs.reserve(found.size());
    for (const auto& fp : found) {
        uint32_t a = uint32_t(std::size_t(fp.first)), b = uint32_t(std::size_t(fp.second));
        if (only) a = keep[a], b = keep[b];
        if (a > b) std::swap(a, b);
        r.pairs.emplace_back(a, b);
    }
    std::sort(r.pairs.begin(), r.pairs.end());
    return r;
}

} // namespace mtcut::test
