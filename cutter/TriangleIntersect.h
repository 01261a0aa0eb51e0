// Exact intersection tests of triangles given by float points (the mesh as
// written: world mm in float). For the re-mesher's guard that a kerf > 0 cut
// never writes a surface that crosses or touches itself (DESIGN invariant
// 7): CutRemesher::update refuses such a step instead of writing it.
//
// Exact: every decision is the sign of an orientation determinant of the
// float inputs. A double evaluation with Shewchuk's static error bound
// decides almost all of them; the rest are evaluated exactly in 128-bit
// integers (each axis scaled by a power of two so its floats become
// integers), or, when an axis's floats span too many binary orders for that
// (a point within about 1e-4 mm of a coordinate plane through 0 next to
// points mm away), in arbitrary precision (Boost.Multiprecision, headers
// only). Only a non-finite input gives Sign::Unknown.
//
// Adjacency follows CGAL's Polygon_mesh_processing::self_intersections, so
// this check and the tests' CGAL check (tests/SelfIntersect.h) agree: two
// triangles that share an edge (two vertex ids) intersect only when they
// overlap beyond it (coplanar, on the same side: a fold); two that share one
// vertex id only when they meet anywhere else too; otherwise any common
// point, touching included, is an intersection. No GL.
#pragma once

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <optional>

namespace mtcut::cutter {

enum class Sign : int8_t
{
    Negative = -1,
    Zero = 0,
    Positive = 1,
    Unknown = 2, ///< an input is not finite
};

/// Sign of det[b - a, c - a, d - a] = ((b - a) x (c - a)) . (d - a):
/// positive when d lies on the side of the plane (a, b, c) its normal
/// (b - a) x (c - a) points to, zero when the four points are coplanar.
Sign orient3d(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, const glm::vec3& d);

/// A triangle's plane, for many orient3d tests against it (the local
/// check tests each triangle against a dozen others): the cross product of
/// its edges from t[0] and the terms of its error bound, as orient3d
/// computes them.
struct TrianglePlane
{
    double n[3] = {0, 0, 0};    ///< (t[1] - t[0]) x (t[2] - t[0]), rounded
    double perm[3] = {0, 0, 0}; ///< per axis, the sum of the two products' magnitudes
};
TrianglePlane trianglePlane(const std::array<glm::vec3, 3>& t);

/// orient3d(t[0], t[1], t[2], d) with t's plane computed once: the same sign
/// (the same filter, by the cofactors of d - t[0]; the same exact fallback),
/// and Zero without the exact path when every term is zero (the four points
/// in one axis plane, as a blade along a grid plane puts its kerf faces).
Sign orient3d(const std::array<glm::vec3, 3>& t, const TrianglePlane& plane, const glm::vec3& d);

/// Sign of det[b - a, c - a] of the points' coordinates (x, y) = (p[i], p[j]).
Sign orient2d(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, int i, int j);

/// The result of trianglesIntersect.
enum class Contact : uint8_t
{
    None,        ///< no common point (beyond what adjacency allows)
    Intersect,   ///< they cross, touch or overlap
    Undecided,   ///< not judged (a non-finite point, or zero area where it matters): treat as Intersect
};

/// Whether closed triangles A = (a[0], a[1], a[2]) and B intersect, with
/// the vertex ids `ia`, `ib` deciding adjacency (file comment). A triangle
/// whose points are collinear (zero area; the mesh checks refuse those on
/// their own) is not judged: the answer is then Intersect or Undecided
/// wherever the test needs its plane, and otherwise what its edges decide.
/// Cost: 2 to about 30 orientation tests.
Contact trianglesIntersect(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia,
                           const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib);

/// trianglesIntersect, except that two triangles that share no vertex id
/// and meet only at one corner of each, the two corners at one float
/// position, do not (an iso point and a kerf plane's point on one grid edge
/// 1e-6 mm apart at z = 1227 mm: 1 mm head, kerf 0.5, random strokes seed
/// 2011): a surface touching itself at one point, as at a pinch (Remesh.h),
/// not crossing. The tests' CGAL check counts those as pinch contacts. What
/// the re-mesher's self-contact check and its float repair ask.
Contact trianglesCross(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia,
                       const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib);

/// trianglesIntersect and trianglesCross with the triangles' planes
/// (trianglePlane) given: the same answers, fewer operations.
Contact trianglesIntersect(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia, const TrianglePlane& pa,
                           const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib, const TrianglePlane& pb);
Contact trianglesCross(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia, const TrianglePlane& pa,
                       const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib, const TrianglePlane& pb);

/// Whether triangle t has non-zero area (its points are not collinear),
/// decided exactly; `plane` is t's (trianglePlane). False for a non-finite point.
bool hasArea(const std::array<glm::vec3, 3>& t, const TrianglePlane& plane);

/// trianglesCross for two triangles of non-zero area (hasArea) that lie,
/// exactly in float, in two closed axis-aligned boxes which meet only in a
/// common face, edge or corner (two neighbouring cells of the local check):
/// their common points lie there, so only the corners of each on it decide.
/// Bit k of `onA` says that a[k] lies on the common part (its coordinates
/// equal the part's fixed ones), likewise `onB`. Axes i, j span the part
/// (for an edge: its axis first, then any other; for a corner: any two).
/// The answer equals trianglesCross's; std::nullopt where this shortcut does
/// not apply (the same three vertex ids; a shared vertex id off the part):
/// then ask trianglesCross. A pair with no corner on the part is apart: the
/// caller need not ask.
std::optional<Contact> trianglesCrossOnBoundary(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia,
                                                unsigned onA, const std::array<glm::vec3, 3>& b,
                                                const std::array<uint32_t, 3>& ib, unsigned onB, int i, int j);

} // namespace mtcut::cutter
