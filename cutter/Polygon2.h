// 2-D polygon helpers of the re-meshing kernel (RemeshKernel.cpp): the cap and
// iso regions of a tetrahedron are loops on their supporting plane, in that
// plane's 2-D coordinates, triangulated here. Plain double arithmetic with
// the relative tolerances stated per function. No GL, no OpenVDB.
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

namespace mtcut::cutter::poly2 {

struct Vec2
{
    double x, y;
};

/// Twice the signed area of triangle (o, a, b): > 0 when it turns CCW.
inline double cross2(const Vec2& o, const Vec2& a, const Vec2& b)
{
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}
inline bool same2(const Vec2& a, const Vec2& b) { return a.x == b.x && a.y == b.y; }

/// Direction u before direction v by polar angle, as std::atan2(y + 0.0, x)
/// would order them, without atan2 (the GPU port has no double atan2): by
/// part of the plane (y < 0; the +x axis and the zero vector; y > 0; the -x
/// axis, pi), then within a half plane by the sign of their cross product.
/// The sign of a zero y is not read (atan2 puts the -x axis with y = -0 at
/// -pi, first): a GPU driver need not keep it (NVIDIA's gave the opposite
/// zero sign in 124 of poly2's orientations), and a cap's corner lies on
/// the -x axis with y = +-0 about 20,000 times in `bench_cut --quick`.
/// Directions that compare equal either way keep their order in a stable
/// sort. (Components whose products underflow, below 1e-154, are beyond it;
/// the kernel's are not.)
inline bool angleLess(const Vec2& u, const Vec2& v)
{
    auto half = [](const Vec2& d) {
        if (d.y == 0 && d.x < 0) return 3;
        return d.y < 0 ? 0 : d.y == 0 ? 1 : 2;
    };
    const int hu = half(u), hv = half(v);
    if (hu != hv) return hu < hv;
    return u.x * v.y - u.y * v.x > 0;
}

/// The turn from direction `back` clockwise to direction d, as a rank that
/// orders like the angle in (0, 2 pi] (d along `back` is 2 pi, the last):
/// clockwiseLess(back, d1, d2) when d1 is reached first turning clockwise
/// from back. Without atan2, for the GPU port; and exact where atan2 is not:
/// a turn too small for atan2 to see (it rounds both directions to one
/// angle) is a small turn here, not a full one.
inline bool clockwiseLess(const Vec2& back, const Vec2& d1, const Vec2& d2)
{
    auto half = [&](const Vec2& d) {
        const double c = back.x * d.y - back.y * d.x, dot = back.x * d.x + back.y * d.y;
        return c < 0 ? 0 : c == 0 && dot < 0 ? 1 : c > 0 ? 2 : 3;
    };
    const int h1 = half(d1), h2 = half(d2);
    if (h1 != h2) return h1 < h2;
    return d1.x * d2.y - d1.y * d2.x < 0; // d2 clockwise of d1
}

/// The length of (dx, dy) as sqrt(dx^2 + dy^2), each operation rounded on its
/// own, not std::hypot: the GPU cut pass (shaders/poly2.glsl) must compute the
/// same bits, and GLSL has no double hypot (its + * sqrt are IEEE-exact).
inline double length2(double dx, double dy) { return std::sqrt(dx * dx + dy * dy); }

/// Do segments ab and cd cross (properly, or touching away from shared endpoints)?
bool segmentsIntersect(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d);

/// Shape of triangle abc: the smallest sine of its angles (negative when it
/// turns CW); -1 when a side has zero length.
double minSine(const Vec2& a, const Vec2& b, const Vec2& c);

/// The most corners bestTriangulation() takes.
constexpr size_t kBestOfAllMax = 9;

/// The triangulation of a simple CCW polygon of at most kBestOfAllMax
/// corners (indices into pts) whose worst triangle has the best shape (the
/// largest smallest sine), by dynamic programming over its diagonals: a
/// triangle counts when it turns CCW by more than 1e-9, holds no other
/// corner (within a relative 1e-9) and its new sides cross no side of the
/// polygon. Appends 3 indices per triangle to `tris`. Returns false (tris
/// unchanged) when the polygon repeats a point or no triangulation passes.
bool bestTriangulation(const std::vector<int>& poly, const std::vector<Vec2>& pts, std::vector<int>& tris);

/// Ear clipping of a weakly simple CCW polygon (indices into pts). Each step
/// clips the valid ear with the best shape (largest smallest sine of its
/// angles), so straight vertices never end up as the tip of a flat ear; the
/// last four corners are split by the diagonal whose two triangles have the
/// better worst shape. Points within a relative 1e-9 of an ear's edges
/// count as inside it. Appends 3 indices per triangle to `tris`; returns
/// false when no ear can be found.
bool earClip(const std::vector<int>& poly, const std::vector<Vec2>& pts, std::vector<int>& tris);

/// Signed area of a loop (indices into pts): > 0 when CCW.
double signedArea(const std::vector<int>& loop, const std::vector<Vec2>& pts);
/// The same for the n indices from `loop` on (same arithmetic, same bits).
double signedArea(const int* loop, size_t n, const std::vector<Vec2>& pts);

/// Splices holes (CW loops inside the CCW `outer`) into `outer` through
/// shortest visible bridges, so earClip() can take it. Returns false when a
/// hole has no visible bridge.
bool bridgeHoles(std::vector<int>& outer, std::vector<std::vector<int>> holes, const std::vector<Vec2>& pts);

} // namespace mtcut::cutter::poly2
