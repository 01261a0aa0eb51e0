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

/// The CGAL mesh of `mesh`, face i = triangle i. Throws std::invalid_argument
/// when the triangles do not form an oriented 2-manifold (with or without
/// boundary): run checkMesh first, self-intersection is only asked of meshes
/// that pass it.
inline SiMesh toCgal(const cutter::Mesh& mesh)
{
    namespace PMP = CGAL::Polygon_mesh_processing;
    std::vector<SiKernel::Point_3> points;
    points.reserve(mesh.positions.size());
    for (const glm::vec3& p : mesh.positions) points.emplace_back(double(p.x), double(p.y), double(p.z));
    std::vector<std::array<std::size_t, 3>> faces(mesh.triangleCount());
    for (size_t t = 0; t < faces.size(); ++t)
        for (int j = 0; j < 3; ++j) faces[t][size_t(j)] = mesh.indices[3 * t + size_t(j)];
    if (!PMP::is_polygon_soup_a_polygon_mesh(faces))
        throw std::invalid_argument("selfIntersections: the triangles are not an oriented 2-manifold");
    SiMesh sm;
    PMP::polygon_soup_to_polygon_mesh(points, faces, sm);
    if (sm.number_of_faces() != faces.size())
        throw std::invalid_argument("selfIntersections: CGAL mesh has a different face count");
    // The converter adds the faces in order into a fresh mesh: face i is triangle i.
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

} // namespace detail

/// Every pair of intersecting triangles of `mesh` (an oriented 2-manifold,
/// closed or not). When `only` is given, only pairs of triangles both in
/// `only` are tested (a local check; CGAL's box intersection keeps it
/// O(|only| log |only|) after the O(mesh) conversion).
inline SelfIntersectResult selfIntersections(const cutter::Mesh& mesh, const std::vector<uint32_t>* only = nullptr)
{
    namespace PMP = CGAL::Polygon_mesh_processing;
    const detail::SiMesh sm = detail::toCgal(mesh);
    std::vector<std::pair<detail::SiMesh::Face_index, detail::SiMesh::Face_index>> found;
    if (only) {
        std::vector<detail::SiMesh::Face_index> range;
        range.reserve(only->size());
        for (uint32_t t : *only) range.emplace_back(static_cast<detail::SiMesh::size_type>(t));
        PMP::self_intersections(range, sm, std::back_inserter(found));
    } else {
        PMP::self_intersections(sm, std::back_inserter(found));
    }
    SelfIntersectResult r;
    r.pairs.reserve(found.size());
    for (const auto& fp : found) {
        uint32_t a = uint32_t(std::size_t(fp.first)), b = uint32_t(std::size_t(fp.second));
        if (a > b) std::swap(a, b);
        r.pairs.emplace_back(a, b);
    }
    std::sort(r.pairs.begin(), r.pairs.end());
    return r;
}

} // namespace mtcut::test
