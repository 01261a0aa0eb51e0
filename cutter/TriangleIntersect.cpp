#include "cutter/TriangleIntersect.h"

#include <boost/multiprecision/cpp_int.hpp>
#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>

namespace mtcut::cutter {

namespace {

using i128 = __int128;

// Shewchuk, "Adaptive Precision Floating-Point Arithmetic and Fast Robust
// Geometric Predicates" (1997): the bounds of his orient3d/orient2d stage A,
// which evaluate the same expressions as below (differences to a common
// point, then 2x2 minors times the third column), rounding included.
constexpr double kEps = 0x1p-53;
constexpr double kO3dErrBound = (7.0 + 56.0 * kEps) * kEps;
constexpr double kCcwErrBound = (3.0 + 16.0 * kEps) * kEps;

/// x = m 2^(e - 150), m an integer (sign included) below 2^24 in magnitude.
bool decompose(float x, int64_t& m, int& e)
{
    uint32_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    const int biased = int((bits >> 23) & 0xffu);
    if (biased == 0xff) return false; // not finite
    const int64_t mant = int64_t(bits & 0x7fffffu) | (biased ? int64_t(1) << 23 : 0);
    e = biased ? biased : 1;
    m = bits >> 31 ? -mant : mant;
    return true;
}

/// The floats of one axis as arbitrary-precision integers at one scale
/// (slow; for the rare axis whose floats span more than 38 binary orders).
template <int N>
bool bigAxis(const float (&x)[N], boost::multiprecision::cpp_int (&out)[N])
{
    int64_t m[N];
    int e[N], low = INT_MAX;
    for (int i = 0; i < N; ++i) {
        if (!decompose(x[i], m[i], e[i])) return false;
        if (m[i] != 0) low = std::min(low, e[i]);
    }
    for (int i = 0; i < N; ++i) {
        out[i] = m[i];
        if (m[i] != 0) out[i] <<= unsigned(e[i] - low);
    }
    return true;
}

Sign signOf(const boost::multiprecision::cpp_int& v)
{
    return v > 0 ? Sign::Positive : v < 0 ? Sign::Negative : Sign::Zero;
}

/// The floats x[0..N) of one axis as integers x * 2^-low, low = the finest
/// float step among them (a float is a 24-bit integer times a power of two).
/// False when the largest would not fit 62 bits.
template <int N>
bool scaledAxis(const float (&x)[N], int64_t (&out)[N])
{
    int low = INT_MAX, high = INT_MIN;
    int64_t m[N];
    int e[N];
    for (int i = 0; i < N; ++i) {
        if (!decompose(x[i], m[i], e[i])) return false;
        if (m[i] == 0) continue;
        low = std::min(low, e[i]);
        high = std::max(high, e[i]);
    }
    if (low == INT_MAX) {
        std::fill(out, out + N, int64_t(0));
        return true;
    }
    if (high - low > 62 - 24) return false;
    for (int i = 0; i < N; ++i) out[i] = m[i] == 0 ? 0 : m[i] * (int64_t(1) << (e[i] - low)); // < 2^62
    return true;
}

Sign signOf(double v) { return v > 0 ? Sign::Positive : v < 0 ? Sign::Negative : Sign::Zero; }
Sign signOf(i128 v) { return v > 0 ? Sign::Positive : v < 0 ? Sign::Negative : Sign::Zero; }

/// orient3d where the double filter gave up (its differences passed on).
[[gnu::noinline]] Sign orient3dExact(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, const glm::vec3& d,
                                    double ux, double vx, double wx, double uy, double vy, double wy, double uz,
                                    double vz, double wz)
{
    // The four share a coordinate (a cut along a grid plane): a zero column.
    // (A difference of two floats is 0 in double only when they are equal.)
    if ((ux == 0 && vx == 0 && wx == 0) || (uy == 0 && vy == 0 && wy == 0) || (uz == 0 && vz == 0 && wz == 0))
        return Sign::Zero;
    // Exactly: each axis at its own power-of-two scale (a positive factor
    // per column of the determinant: the sign is unchanged).
    int64_t u[3], v[3], w[3];
    bool fits = true;
    for (int k = 0; k < 3 && fits; ++k) {
        const float x[4] = {a[k], b[k], c[k], d[k]};
        int64_t s[4];
        fits = scaledAxis(x, s);
        if (!fits) break;
        u[k] = s[1] - s[0];
        v[k] = s[2] - s[0];
        w[k] = s[3] - s[0];
        constexpr int64_t kMax = int64_t(1) << 41; // 3 x 41 bits + 3 for the six terms < 127
        fits = std::abs(u[k]) < kMax && std::abs(v[k]) < kMax && std::abs(w[k]) < kMax;
    }
    if (!fits) {
        // Arbitrary precision (a point within about 1e-4 mm of a coordinate
        // plane through 0 next to points mm away).
        using boost::multiprecision::cpp_int;
        cpp_int bu[3], bv[3], bw[3];
        for (int k = 0; k < 3; ++k) {
            const float x[4] = {a[k], b[k], c[k], d[k]};
            cpp_int s[4];
            if (!bigAxis(x, s)) return Sign::Unknown;
            bu[k] = s[1] - s[0];
            bv[k] = s[2] - s[0];
            bw[k] = s[3] - s[0];
        }
        return signOf(cpp_int(bu[2] * (bv[0] * bw[1] - bw[0] * bv[1]) + bv[2] * (bw[0] * bu[1] - bu[0] * bw[1]) +
                              bw[2] * (bu[0] * bv[1] - bv[0] * bu[1])));
    }
    const i128 exact = i128(u[2]) * (i128(v[0]) * w[1] - i128(w[0]) * v[1]) +
                       i128(v[2]) * (i128(w[0]) * u[1] - i128(u[0]) * w[1]) +
                       i128(w[2]) * (i128(u[0]) * v[1] - i128(v[0]) * u[1]);
    return signOf(exact);
}

} // namespace

Sign orient3d(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, const glm::vec3& d)
{
    const double ux = double(b.x) - a.x, uy = double(b.y) - a.y, uz = double(b.z) - a.z;
    const double vx = double(c.x) - a.x, vy = double(c.y) - a.y, vz = double(c.z) - a.z;
    const double wx = double(d.x) - a.x, wy = double(d.y) - a.y, wz = double(d.z) - a.z;
    const double vxwy = vx * wy, wxvy = wx * vy;
    const double wxuy = wx * uy, uxwy = ux * wy;
    const double uxvy = ux * vy, vxuy = vx * uy;
    const double det = uz * (vxwy - wxvy) + vz * (wxuy - uxwy) + wz * (uxvy - vxuy);
    const double permanent = (std::abs(vxwy) + std::abs(wxvy)) * std::abs(uz) +
                             (std::abs(wxuy) + std::abs(uxwy)) * std::abs(vz) +
                             (std::abs(uxvy) + std::abs(vxuy)) * std::abs(wz);
    if (std::abs(det) > kO3dErrBound * permanent) return signOf(det);
    return orient3dExact(a, b, c, d, ux, vx, wx, uy, vy, wy, uz, vz, wz);
}

TrianglePlane trianglePlane(const std::array<glm::vec3, 3>& t)
{
    const glm::vec3 &a = t[0], &b = t[1], &c = t[2];
    const double ux = double(b.x) - a.x, uy = double(b.y) - a.y, uz = double(b.z) - a.z;
    const double vx = double(c.x) - a.x, vy = double(c.y) - a.y, vz = double(c.z) - a.z;
    const double uyvz = uy * vz, uzvy = uz * vy, uzvx = uz * vx, uxvz = ux * vz, uxvy = ux * vy, uyvx = uy * vx;
    TrianglePlane p;
    p.n[0] = uyvz - uzvy;
    p.n[1] = uzvx - uxvz;
    p.n[2] = uxvy - uyvx;
    p.perm[0] = std::abs(uyvz) + std::abs(uzvy);
    p.perm[1] = std::abs(uzvx) + std::abs(uxvz);
    p.perm[2] = std::abs(uxvy) + std::abs(uyvx);
    return p;
}

Sign orient3d(const std::array<glm::vec3, 3>& t, const TrianglePlane& plane, const glm::vec3& d)
{
    // det[u, v, w] expanded along w = d - a instead of along the z column:
    // the same three products of a difference and a 2x2 minor of
    // differences (transposed), so Shewchuk's bound holds as it stands.
    const glm::vec3& a = t[0];
    const double wx = double(d.x) - a.x, wy = double(d.y) - a.y, wz = double(d.z) - a.z;
    const double det = wx * plane.n[0] + wy * plane.n[1] + wz * plane.n[2];
    const double permanent = std::abs(wx) * plane.perm[0] + std::abs(wy) * plane.perm[1] + std::abs(wz) * plane.perm[2];
    if (std::abs(det) > kO3dErrBound * permanent) return signOf(det);
    // Every term exactly zero (a computed product of these differences is
    // zero only when a factor is: they are far above double's underflow),
    // so the determinant is: the four points in one axis plane, as the
    // caps of a blade along a grid plane are.
    if (permanent == 0) return Sign::Zero;
    return orient3d(t[0], t[1], t[2], d);
}

Sign orient2d(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, int i, int j)
{
    const double ui = double(b[i]) - a[i], uj = double(b[j]) - a[j];
    const double vi = double(c[i]) - a[i], vj = double(c[j]) - a[j];
    const double left = ui * vj, right = uj * vi;
    const double det = left - right;
    if (std::abs(det) > kCcwErrBound * (std::abs(left) + std::abs(right))) return signOf(det);
    if ((ui == 0 && vi == 0) || (uj == 0 && vj == 0)) return Sign::Zero; // a zero column
    const float xi[3] = {a[i], b[i], c[i]}, xj[3] = {a[j], b[j], c[j]};
    int64_t si[3], sj[3];
    if (!scaledAxis(xi, si) || !scaledAxis(xj, sj)) {
        using boost::multiprecision::cpp_int;
        cpp_int bi[3], bj[3];
        if (!bigAxis(xi, bi) || !bigAxis(xj, bj)) return Sign::Unknown;
        return signOf(cpp_int((bi[1] - bi[0]) * (bj[2] - bj[0]) - (bj[1] - bj[0]) * (bi[2] - bi[0])));
    }
    // Differences below 2^63, products below 2^126: fits.
    return signOf(i128(si[1] - si[0]) * (sj[2] - sj[0]) - i128(sj[1] - sj[0]) * (si[2] - si[0]));
}

namespace {

/// The tests of one triangle pair. A predicate that cannot decide is
/// remembered and answers Zero; the pair is then Undecided unless it
/// intersects anyway.
struct Judge
{
    bool unknown = false;

    /// The side of point d to triangle t's plane, o3(t[0], t[1], t[2], d),
    /// by its precomputed plane when the caller has it.
    int side(const std::array<glm::vec3, 3>& t, const TrianglePlane* plane, const glm::vec3& d)
    {
        return plane ? take(orient3d(t, *plane, d)) : o3(t[0], t[1], t[2], d);
    }

    int o3(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, const glm::vec3& d)
    {
        return take(orient3d(a, b, c, d));
    }
    int o2(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, int i, int j)
    {
        return take(orient2d(a, b, c, i, j));
    }
    int take(Sign s)
    {
        if (s == Sign::Unknown) {
            unknown = true;
            return 0;
        }
        return int(s);
    }

    /// A coordinate plane (i, j) onto which triangle t projects with
    /// non-zero area (false when it has zero area: collinear points), and
    /// t's orientation there; `plane`: t's, when the caller has it.
    bool projection(const std::array<glm::vec3, 3>& t, const TrianglePlane* plane, int& i, int& j, int& sign)
    {
        // The plane across the normal's largest component first (a guess in
        // double; the exact orient2d decides).
        const glm::dvec3 n = plane ? glm::dvec3(plane->n[0], plane->n[1], plane->n[2])
                                   : glm::cross(glm::dvec3(t[1]) - glm::dvec3(t[0]), glm::dvec3(t[2]) - glm::dvec3(t[0]));
        const glm::dvec3 an = glm::abs(n);
        const int first = an.x >= an.y && an.x >= an.z ? 0 : an.y >= an.z ? 1 : 2;
        // The plane's component across (i, j) is orient2d's determinant
        // there, the same products of the same differences, and its perm
        // the terms of orient2d's bound: where that filter decides, so does
        // this (no exact fallback: then orient2d is asked below).
        if (plane && std::abs(plane->n[first]) > kCcwErrBound * plane->perm[first]) {
            i = (first + 1) % 3;
            j = (first + 2) % 3;
            sign = plane->n[first] > 0 ? 1 : -1;
            return true;
        }
        for (int k = 0; k < 3; ++k) {
            const int drop = (first + k) % 3;
            const int pi = (drop + 1) % 3, pj = (drop + 2) % 3;
            sign = o2(t[0], t[1], t[2], pi, pj);
            if (sign != 0) {
                i = pi;
                j = pj;
                return true;
            }
        }
        return false;
    }

    /// Closed segments [p, q] and [r, s] in the plane (i, j) intersect.
    bool segmentsMeet2d(const glm::vec3& p, const glm::vec3& q, const glm::vec3& r, const glm::vec3& s, int i, int j)
    {
        const int d1 = o2(p, q, r, i, j), d2 = o2(p, q, s, i, j);
        const int d3 = o2(r, s, p, i, j), d4 = o2(r, s, q, i, j);
        if (d1 * d2 < 0 && d3 * d4 < 0) return true;
        return (d1 == 0 && onSegment2d(p, q, r, i, j)) || (d2 == 0 && onSegment2d(p, q, s, i, j)) ||
               (d3 == 0 && onSegment2d(r, s, p, i, j)) || (d4 == 0 && onSegment2d(r, s, q, i, j));
    }
    static bool onSegment2d(const glm::vec3& p, const glm::vec3& q, const glm::vec3& x, int i, int j)
    {
        return std::min(p[i], q[i]) <= x[i] && x[i] <= std::max(p[i], q[i]) && std::min(p[j], q[j]) <= x[j] &&
               x[j] <= std::max(p[j], q[j]);
    }

    /// Closed segment [s, t] and closed triangle tri, coplanar, in the plane
    /// (i, j) where tri has orientation `sign` (non-zero).
    bool segmentMeetsTriangle2d(const glm::vec3& s, const glm::vec3& t, const std::array<glm::vec3, 3>& tri, int i,
                                int j, int sign)
    {
        auto inside = [&](const glm::vec3& x) {
            for (int k = 0; k < 3; ++k) {
                const int o = o2(tri[size_t(k)], tri[size_t((k + 1) % 3)], x, i, j);
                if (o != 0 && o != sign) return false;
            }
            return true;
        };
        if (inside(s) || inside(t)) return true;
        for (int k = 0; k < 3; ++k)
            if (segmentsMeet2d(s, t, tri[size_t(k)], tri[size_t((k + 1) % 3)], i, j)) return true;
        return false;
    }

    /// Closed segment [s, t] and closed triangle tri (non-zero area) meet;
    /// os, ot: the sides of s and t to tri's plane, o3(tri[0], tri[1],
    /// tri[2], s) and of t (the callers have them already).
    bool segmentMeetsTriangle(const glm::vec3& s, const glm::vec3& t, const std::array<glm::vec3, 3>& tri,
                              const TrianglePlane* triPlane, int os, int ot)
    {
        if (os * ot > 0) return false; // both strictly on one side
        if (os == 0 && ot == 0) {
            int i = 0, j = 1, sign = 0;
            if (!projection(tri, triPlane, i, j, sign)) {
                unknown = true; // tri has zero area: not judged
                return false;
            }
            return segmentMeetsTriangle2d(s, t, tri, i, j, sign);
        }
        // The line st crosses the plane at one point of the segment; it lies
        // in the closed triangle when the line passes every edge on one side.
        const int u = o3(s, t, tri[0], tri[1]), v = o3(s, t, tri[1], tri[2]), w = o3(s, t, tri[2], tri[0]);
        return (u >= 0 && v >= 0 && w >= 0) || (u <= 0 && v <= 0 && w <= 0);
    }
};

/// Coplanar triangles t (orientation `orient` in (i, j)) and o are apart
/// when an edge of t has all of o strictly outside its line (separating
/// axes of two triangles).
bool separates(Judge& judge, const std::array<glm::vec3, 3>& t, int orient, const std::array<glm::vec3, 3>& o, int i, int j)
{
    for (int k = 0; k < 3; ++k) {
        const glm::vec3 &p = t[size_t(k)], &q = t[size_t((k + 1) % 3)];
        if (judge.o2(p, q, o[0], i, j) * orient < 0 && judge.o2(p, q, o[1], i, j) * orient < 0 &&
            judge.o2(p, q, o[2], i, j) * orient < 0)
            return true;
    }
    return false;
}

/// Shared vertex ids: sa[k] is the position in b of a's vertex k (-1:
/// none); returns how many.
int sharedIds(const std::array<uint32_t, 3>& ia, const std::array<uint32_t, 3>& ib, int (&sa)[3])
{
    int shared = 0;
    for (int k = 0; k < 3; ++k) {
        sa[k] = -1;
        for (int m = 0; m < 3; ++m)
            if (ia[size_t(k)] == ib[size_t(m)]) {
                sa[k] = m;
                ++shared;
            }
    }
    return shared;
}

Contact intersect(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia, const TrianglePlane* planeA,
                  const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib, const TrianglePlane* planeB)
{
    Judge judge;
    int sa[3];
    const int shared = sharedIds(ia, ib, sa);
    bool hit = false;
    if (shared >= 3) {
        hit = true; // the same three vertices
    } else if (shared == 2) {
        // An edge in common: they meet beyond it only when coplanar and on
        // the same side of it (one folded onto the other).
        const int other = sa[0] < 0 ? 0 : sa[1] < 0 ? 1 : 2;
        const glm::vec3& e0 = a[size_t((other + 1) % 3)];
        const glm::vec3& e1 = a[size_t((other + 2) % 3)];
        int m = 0;
        while (m < 3 && (ib[size_t(m)] == ia[size_t((other + 1) % 3)] || ib[size_t(m)] == ia[size_t((other + 2) % 3)])) ++m;
        const glm::vec3& pa = a[size_t(other)];
        const glm::vec3& pb = b[size_t(m)];
        // (e0, e1, pa) is a's corners rotated: the side of pb to a's plane.
        if (judge.side(a, planeA, pb) == 0 && !judge.unknown) {
            int pi = 0, pj = 1, signP = 0;
            if (!judge.projection(a, planeA, pi, pj, signP)) return Contact::Undecided; // a has zero area
            const int sideA = judge.o2(e0, e1, pa, pi, pj), sideB = judge.o2(e0, e1, pb, pi, pj);
            hit = sideA != 0 && sideA == sideB;
        }
    } else if (shared == 1) {
        // One vertex v in common: A and B meet elsewhere exactly when the
        // edge of either opposite v meets the other triangle (their common
        // part is convex and holds v; its far end lies on such an edge).
        const int ka = sa[0] >= 0 ? 0 : sa[1] >= 0 ? 1 : 2;
        const int kb = sa[ka];
        // Quick: the other two vertices of one strictly on one side of the
        // other's plane, so it meets that plane only at v.
        const glm::vec3 &a1 = a[size_t((ka + 1) % 3)], &a2 = a[size_t((ka + 2) % 3)];
        const glm::vec3 &b1 = b[size_t((kb + 1) % 3)], &b2 = b[size_t((kb + 2) % 3)];
        const int s1 = judge.side(a, planeA, b1), s2 = judge.side(a, planeA, b2);
        if (s1 * s2 > 0) return judge.unknown ? Contact::Undecided : Contact::None;
        if (s1 == 0 && s2 == 0 && !judge.unknown) {
            // Coplanar: they meet beyond v exactly when their corners at v
            // (convex, under 180 degrees) share a direction, i.e. an edge
            // of one at v points into the other's closed corner.
            int pi = 0, pj = 1, sign = 0;
            if (!judge.projection(a, planeA, pi, pj, sign)) return Contact::Undecided;
            const glm::vec3& v = a[size_t(ka)];
            const int signB = judge.o2(v, b1, b2, pi, pj);
            if (signB == 0) return Contact::Undecided; // b has zero area
            // Corner (v; from, to) counter-clockwise in the projection. Every
            // test is the sign of det[x - v, y - v] for x an edge end of A
            // and y one of B, or of its negation (swapped): four signs at
            // most, each evaluated once (2 = not yet).
            const glm::vec3* ends[2][2] = {{&a1, &a2}, {&b1, &b2}};
            int det[2][2] = {{2, 2}, {2, 2}}; // [A end][B end]
            auto turn = [&](int i, int j) {
                if (det[i][j] == 2) det[i][j] = judge.o2(v, *ends[0][i], *ends[1][j], pi, pj);
                return det[i][j];
            };
            // Does A's corner hold B's end j; B's corner A's end i?
            const int fa = sign > 0 ? 0 : 1, fb = signB > 0 ? 0 : 1;
            auto aHolds = [&](int j) { return turn(fa, j) >= 0 && turn(1 - fa, j) <= 0; };
            auto bHolds = [&](int i) { return -turn(i, fb) >= 0 && -turn(i, 1 - fb) <= 0; };
            hit = aHolds(0) || aHolds(1) || bHolds(0) || bHolds(1);
        } else {
            const int t1 = judge.side(b, planeB, a1), t2 = judge.side(b, planeB, a2);
            if (t1 * t2 > 0) return judge.unknown ? Contact::Undecided : Contact::None;
            hit = judge.segmentMeetsTriangle(a1, a2, b, planeB, t1, t2) ||
                  judge.segmentMeetsTriangle(b1, b2, a, planeA, s1, s2);
        }
    } else {
        // Quick: one strictly on one side of the other's plane.
        int side[2][3];
        for (int k = 0; k < 3; ++k) side[0][k] = judge.side(a, planeA, b[size_t(k)]);
        if (side[0][0] * side[0][1] > 0 && side[0][1] * side[0][2] > 0)
            return judge.unknown ? Contact::Undecided : Contact::None;
        for (int k = 0; k < 3; ++k) side[1][k] = judge.side(b, planeB, a[size_t(k)]);
        if (side[1][0] * side[1][1] > 0 && side[1][1] * side[1][2] > 0)
            return judge.unknown ? Contact::Undecided : Contact::None;
        if (side[0][0] == 0 && side[0][1] == 0 && side[0][2] == 0 && !judge.unknown) {
            // Coplanar: apart exactly when an edge of one has the other
            // strictly outside its line (separating axes of two triangles).
            int pi = 0, pj = 1, sign = 0;
            if (!judge.projection(a, planeA, pi, pj, sign)) return Contact::Undecided;
            const int signB = judge.o2(b[0], b[1], b[2], pi, pj);
            if (signB == 0) return Contact::Undecided; // b has zero area
            hit = !separates(judge, a, sign, b, pi, pj) && !separates(judge, b, signB, a, pi, pj);
        } else {
            // Two closed triangles meet exactly when an edge of one meets the
            // other (their common part is bounded by points of their edges).
            // (Each end's side of the other's plane is known from above.)
            for (int k = 0; k < 3 && !hit; ++k) {
                const int n = (k + 1) % 3;
                hit = judge.segmentMeetsTriangle(a[size_t(k)], a[size_t(n)], b, planeB, side[1][k], side[1][n]) ||
                      judge.segmentMeetsTriangle(b[size_t(k)], b[size_t(n)], a, planeA, side[0][k], side[0][n]);
            }
        }
    }
    if (hit) return Contact::Intersect;
    return judge.unknown ? Contact::Undecided : Contact::None;
}

Contact cross(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia, const TrianglePlane* planeA,
              const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib, const TrianglePlane* planeB)
{
    const Contact contact = intersect(a, ia, planeA, b, ib, planeB);
    if (contact == Contact::None) return contact;
    int same = 0, ka = -1, kb = -1;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            if (ia[size_t(i)] == ib[size_t(j)]) return contact; // a vertex in common: judged as it is
            if (a[size_t(i)] == b[size_t(j)]) {
                ++same;
                ka = i;
                kb = j;
            }
        }
    if (same != 1) return contact;
    std::array<uint32_t, 3> joined = ib;
    joined[size_t(kb)] = ia[size_t(ka)]; // as if one vertex: do they meet anywhere else?
    return intersect(a, ia, planeA, b, joined, planeB) == Contact::None ? Contact::None : contact;
}

} // namespace

Contact trianglesIntersect(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia,
                           const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib)
{
    return intersect(a, ia, nullptr, b, ib, nullptr);
}

Contact trianglesIntersect(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia, const TrianglePlane& pa,
                           const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib, const TrianglePlane& pb)
{
    return intersect(a, ia, &pa, b, ib, &pb);
}

Contact trianglesCross(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia,
                       const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib)
{
    return cross(a, ia, nullptr, b, ib, nullptr);
}

Contact trianglesCross(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia, const TrianglePlane& pa,
                       const std::array<glm::vec3, 3>& b, const std::array<uint32_t, 3>& ib, const TrianglePlane& pb)
{
    return cross(a, ia, &pa, b, ib, &pb);
}

bool hasArea(const std::array<glm::vec3, 3>& t, const TrianglePlane& plane)
{
    // plane.n[k] is orient2d's determinant in the axes (k + 1, k + 2), and
    // plane.perm[k] the terms of its bound: where the filter decides, done.
    for (int k = 0; k < 3; ++k)
        if (std::abs(plane.n[k]) > kCcwErrBound * plane.perm[k]) return true;
    for (int k = 0; k < 3; ++k) {
        const Sign s = orient2d(t[0], t[1], t[2], (k + 1) % 3, (k + 2) % 3);
        if (s == Sign::Positive || s == Sign::Negative) return true;
    }
    return false;
}

namespace {

/// The corners of a triangle on the common part (trianglesCrossOnBoundary).
struct Part
{
    std::array<const glm::vec3*, 3> p{};
    int n = 0;
    void add(const glm::vec3& x) { p[size_t(n++)] = &x; }
};

/// The corners of `t` of mask `on`, but corner `skip` (-1: none).
Part partOf(const std::array<glm::vec3, 3>& t, unsigned on, int skip)
{
    Part part;
    for (int k = 0; k < 3; ++k)
        if ((on >> k & 1) && k != skip) part.add(t[size_t(k)]);
    return part;
}

/// -1, 0, 1: the sign of y - x.
int signOfDifference(float x, float y) { return y > x ? 1 : y < x ? -1 : 0; }

/// Two convex sets of one plane (the hulls of the Parts in (i, j)) with a
/// common corner v: do they share a point other than v? `ra`, `rb`: each
/// set's other corners (none: the set is v alone; one: a segment from v; two:
/// a triangle's corner at v, of non-zero area). Their cones at v share a
/// direction exactly when a ray bounding one lies in the other's closed
/// cone (each under 180 degrees).
std::optional<bool> conesMeet(Judge& judge, const glm::vec3& v, const Part& ra, const Part& rb, int i, int j)
{
    if (ra.n == 0 || rb.n == 0) return false;
    if (ra.n == 1 && rb.n == 1) {
        const glm::vec3 &x = *ra.p[0], &y = *rb.p[0];
        return judge.o2(v, x, y, i, j) == 0 && signOfDifference(v[i], x[i]) == signOfDifference(v[i], y[i]) &&
               signOfDifference(v[j], x[j]) == signOfDifference(v[j], y[j]);
    }
    // Does the closed cone (v; c.p[0], c.p[1]) hold the direction x - v?
    auto holds = [&](const Part& c, int orient, const glm::vec3& x) {
        return judge.o2(v, *c.p[0], x, i, j) * orient >= 0 && judge.o2(v, x, *c.p[1], i, j) * orient >= 0;
    };
    int orientA = 0, orientB = 0;
    if (ra.n == 2 && (orientA = judge.o2(v, *ra.p[0], *ra.p[1], i, j)) == 0) return std::nullopt;
    if (rb.n == 2 && (orientB = judge.o2(v, *rb.p[0], *rb.p[1], i, j)) == 0) return std::nullopt;
    bool hit = false;
    if (rb.n == 2)
        for (int k = 0; k < ra.n && !hit; ++k) hit = holds(rb, orientB, *ra.p[size_t(k)]);
    if (ra.n == 2)
        for (int k = 0; k < rb.n && !hit; ++k) hit = holds(ra, orientA, *rb.p[size_t(k)]);
    return hit;
}

/// The hulls of two Parts in (i, j) (one to three points each, a triangle
/// of non-zero area there) share a point.
std::optional<bool> hullsMeet(Judge& judge, const Part& a, const Part& b, int i, int j)
{
    if (a.n == 0 || b.n == 0) return false;
    if (a.n > b.n) return hullsMeet(judge, b, a, i, j);
    auto triangle = [](const Part& x) { return std::array<glm::vec3, 3>{*x.p[0], *x.p[1], *x.p[2]}; };
    if (a.n == 1) {
        const glm::vec3& x = *a.p[0];
        if (b.n == 1) return x == *b.p[0];
        if (b.n == 2) return judge.o2(*b.p[0], *b.p[1], x, i, j) == 0 && Judge::onSegment2d(*b.p[0], *b.p[1], x, i, j);
        const int orient = judge.o2(*b.p[0], *b.p[1], *b.p[2], i, j);
        if (orient == 0) return std::nullopt;
        for (int k = 0; k < 3; ++k) {
            const int o = judge.o2(*b.p[size_t(k)], *b.p[size_t((k + 1) % 3)], x, i, j);
            if (o != 0 && o != orient) return false;
        }
        return true;
    }
    if (a.n == 2) {
        if (b.n == 2) return judge.segmentsMeet2d(*a.p[0], *a.p[1], *b.p[0], *b.p[1], i, j);
        const int orient = judge.o2(*b.p[0], *b.p[1], *b.p[2], i, j);
        if (orient == 0) return std::nullopt;
        return judge.segmentMeetsTriangle2d(*a.p[0], *a.p[1], triangle(b), i, j, orient);
    }
    const std::array<glm::vec3, 3> ta = triangle(a), tb = triangle(b);
    const int orientA = judge.o2(ta[0], ta[1], ta[2], i, j), orientB = judge.o2(tb[0], tb[1], tb[2], i, j);
    if (orientA == 0 || orientB == 0) return std::nullopt;
    return !separates(judge, ta, orientA, tb, i, j) && !separates(judge, tb, orientB, ta, i, j);
}

} // namespace

std::optional<Contact> trianglesCrossOnBoundary(const std::array<glm::vec3, 3>& a, const std::array<uint32_t, 3>& ia,
                                                unsigned onA, const std::array<glm::vec3, 3>& b,
                                                const std::array<uint32_t, 3>& ib, unsigned onB, int i, int j)
{
    Judge judge;
    int sa[3];
    const int shared = sharedIds(ia, ib, sa);
    if (shared >= 3) return std::nullopt;
    for (int k = 0; k < 3; ++k)
        if (sa[k] >= 0 && (!(onA >> k & 1) || !(onB >> sa[k] & 1))) return std::nullopt; // (in both boxes: on the part)
    std::optional<bool> hit;
    if (shared == 2) {
        // Adjacent along an edge: they overlap beyond it only when both lie
        // in the part (a face; coplanar) with their third corners on one side.
        if (onA != 7 || onB != 7) return Contact::None;
        const int other = sa[0] < 0 ? 0 : sa[1] < 0 ? 1 : 2;
        const glm::vec3& e0 = a[size_t((other + 1) % 3)];
        const glm::vec3& e1 = a[size_t((other + 2) % 3)];
        const int m = 3 - sa[(other + 1) % 3] - sa[(other + 2) % 3];
        const int sideA = judge.o2(e0, e1, a[size_t(other)], i, j), sideB = judge.o2(e0, e1, b[size_t(m)], i, j);
        hit = sideA != 0 && sideA == sideB;
    } else if (shared == 1) {
        const int ka = sa[0] >= 0 ? 0 : sa[1] >= 0 ? 1 : 2;
        hit = conesMeet(judge, a[size_t(ka)], partOf(a, onA, ka), partOf(b, onB, sa[ka]), i, j);
    } else {
        hit = hullsMeet(judge, partOf(a, onA, -1), partOf(b, onB, -1), i, j);
        if (hit && *hit) {
            // trianglesCross: two corners at one float position, no other
            // pair, meet as one vertex (do they meet anywhere else?).
            int same = 0, ka = -1, kb = -1;
            for (int k = 0; k < 3; ++k)
                for (int m = 0; m < 3; ++m)
                    if (a[size_t(k)] == b[size_t(m)]) {
                        ++same;
                        ka = k;
                        kb = m;
                    }
            if (same == 1) {
                if (!(onA >> ka & 1) || !(onB >> kb & 1)) return std::nullopt;
                hit = conesMeet(judge, a[size_t(ka)], partOf(a, onA, ka), partOf(b, onB, kb), i, j);
            }
        }
    }
    if (!hit || judge.unknown) return std::nullopt;
    return *hit ? Contact::Intersect : Contact::None;
}

} // namespace mtcut::cutter
