// cutter/TriangleIntersect: the exact float predicates and the triangle pair
// test that CutRemesher's kerf > 0 guard uses, against CGAL (exact
// predicates, and exact constructions to tell "meets only at the shared
// vertex or edge" from more) on thousands of seeded pairs built to be
// degenerate: points on a coarse lattice (coplanar, collinear, touching),
// one float step apart at a head's world coordinates, shared vertices and
// edges, folds.
#include "cutter/TriangleIntersect.h"

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/intersections.h>

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <variant>

namespace {

using namespace mtcut::cutter;
using K = CGAL::Exact_predicates_exact_constructions_kernel;
using Tri = std::array<glm::vec3, 3>;
using Ids = std::array<uint32_t, 3>;
using Coord3 = std::array<int, 3>;

K::Point_3 cg(const glm::vec3& p) { return K::Point_3(double(p.x), double(p.y), double(p.z)); }

bool collinear(const Tri& t) { return CGAL::collinear(cg(t[0]), cg(t[1]), cg(t[2])); }

/// CGAL's answer with the adjacency rules of TriangleIntersect.h (as CGAL's
/// self_intersections applies them): the exact intersection, less what the
/// shared vertex or edge allows.
bool cgalIntersect(const Tri& a, const Ids& ia, const Tri& b, const Ids& ib)
{
    const K::Triangle_3 ta(cg(a[0]), cg(a[1]), cg(a[2])), tb(cg(b[0]), cg(b[1]), cg(b[2]));
    std::vector<glm::vec3> shared;
    for (int k = 0; k < 3; ++k)
        for (int m = 0; m < 3; ++m)
            if (ia[size_t(k)] == ib[size_t(m)]) shared.push_back(a[size_t(k)]);
    if (shared.size() >= 3) return true;
    const auto result = CGAL::intersection(ta, tb);
    if (!result) return false;
    if (shared.empty()) return true;
    if (shared.size() == 1) {
        const K::Point_3* p = boost::get<K::Point_3>(&*result);
        return !(p && *p == cg(shared[0]));
    }
    const K::Segment_3* s = boost::get<K::Segment_3>(&*result);
    const K::Segment_3 edge(cg(shared[0]), cg(shared[1]));
    return !(s && (*s == edge || *s == edge.opposite()));
}

struct PairMaker
{
    std::mt19937_64 rng;
    explicit PairMaker(uint64_t seed) : rng(seed) {}

    int integer(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); }

    /// A lattice point: coarse steps, so coplanar and collinear sets and
    /// touching triangles are common; at `origin` (a head's 1000 mm: the
    /// float step there is 6e-5 mm) with `step` between lattice points.
    glm::vec3 lattice(const glm::vec3& origin, float step)
    {
        return origin + step * glm::vec3(float(integer(0, 3)), float(integer(0, 3)), float(integer(0, 3)));
    }
    /// A point moved by a few float steps on each axis.
    glm::vec3 nudge(glm::vec3 p)
    {
        for (int k = 0; k < 3; ++k)
            for (int n = integer(-2, 2); n != 0; n += n > 0 ? -1 : 1)
                p[k] = std::nextafter(p[k], n > 0 ? INFINITY : -INFINITY);
        return p;
    }
};

/// Runs `count` pairs from `make` (which fills a, ia, b, ib), skipping
/// zero-area triangles (not judged, see TriangleIntersect.h), and checks
/// every answer against CGAL. Returns (pairs compared, of which intersecting).
template <class Make>
std::pair<int, int> compareWithCgal(int count, Make make)
{
    int compared = 0, hits = 0, failures = 0;
    for (int n = 0; n < count; ++n) {
        Tri a, b;
        Ids ia, ib;
        make(a, ia, b, ib);
        if (collinear(a) || collinear(b)) continue; // not judged (and CGAL's test requires area)
        const bool want = cgalIntersect(a, ia, b, ib);
        const Contact got = trianglesIntersect(a, ia, b, ib);
        // The local check's form, with the planes computed once: the same answer.
        EXPECT_EQ(int(trianglesIntersect(a, ia, trianglePlane(a), b, ib, trianglePlane(b))), int(got)) << "pair " << n;
        EXPECT_EQ(int(trianglesCross(a, ia, trianglePlane(a), b, ib, trianglePlane(b))), int(trianglesCross(a, ia, b, ib)))
            << "pair " << n;
        ++compared;
        hits += want;
        if (got != (want ? Contact::Intersect : Contact::None) && ++failures <= 5) {
            ADD_FAILURE() << "pair " << n << ": CGAL says " << want << ", got " << int(got) << "\n a: (" << a[0].x
                          << "," << a[0].y << "," << a[0].z << ") (" << a[1].x << "," << a[1].y << "," << a[1].z
                          << ") (" << a[2].x << "," << a[2].y << "," << a[2].z << ") ids " << ia[0] << " " << ia[1]
                          << " " << ia[2] << "\n b: (" << b[0].x << "," << b[0].y << "," << b[0].z << ") (" << b[1].x
                          << "," << b[1].y << "," << b[1].z << ") (" << b[2].x << "," << b[2].y << "," << b[2].z
                          << ") ids " << ib[0] << " " << ib[1] << " " << ib[2];
        }
    }
    EXPECT_EQ(failures, 0);
    return {compared, hits};
}

TEST(TriangleIntersect, Orient3dAgreesWithCgalOnNearlyCoplanarFloats)
{
    PairMaker m(7);
    int zero = 0;
    for (int n = 0; n < 20000; ++n) {
        const glm::vec3 origin(74.0f, 134.0f, 1000.0f);
        const float step = n % 2 ? 0.5f : 1e-3f;
        glm::vec3 p[4];
        for (glm::vec3& q : p) q = m.lattice(origin, step);
        if (n % 3 == 0) p[3] = m.nudge(p[3]);
        const CGAL::Orientation want = CGAL::orientation(cg(p[0]), cg(p[1]), cg(p[2]), cg(p[3]));
        const Sign got = orient3d(p[0], p[1], p[2], p[3]);
        ASSERT_EQ(int(got), int(want)) << "case " << n;
        const std::array<glm::vec3, 3> tri{p[0], p[1], p[2]};
        ASSERT_EQ(int(orient3d(tri, trianglePlane(tri), p[3])), int(want)) << "case " << n;
        zero += want == CGAL::COPLANAR;
        for (auto [i, j] : {std::pair{0, 1}, std::pair{1, 2}, std::pair{2, 0}}) {
            const CGAL::Orientation w2 = CGAL::orientation(K::Point_2(double(p[0][i]), double(p[0][j])),
                                                           K::Point_2(double(p[1][i]), double(p[1][j])),
                                                           K::Point_2(double(p[2][i]), double(p[2][j])));
            ASSERT_EQ(int(orient2d(p[0], p[1], p[2], i, j)), int(w2)) << "case " << n;
        }
    }
    EXPECT_GT(zero, 2000) << "the lattice should make many coplanar sets (where the double filter gives up)";
}

TEST(TriangleIntersect, Orient3dIsExactWhereDoubleGivesUp)
{
    // b - a, c - a, d - a: the rows of an integer matrix of determinant +-1
    // with entries up to 2^22 (products of elementary row operations), in
    // units of the float step 2^-13 of [1024, 2048) mm: every point is a
    // float, the exact determinant is +-2^-39 mm^3, while its terms are up
    // to 2^27. Double rounding cannot tell its sign; the exact path must.
    std::mt19937_64 rng(19);
    std::uniform_int_distribution<int64_t> multiplier(2, 9);
    int positive = 0, negative = 0;
    for (int n = 0; n < 2000; ++n) {
        int64_t r[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        // Add a multiple of the previous row to each row in turn while every
        // entry stays below 2^22 (so a + entry * 2^-13 stays a float).
        for (int row = 1;; row = (row + 1) % 3) {
            const int64_t k = multiplier(rng);
            int64_t next[3];
            bool fits = true;
            for (int i = 0; i < 3; ++i) {
                next[i] = r[row][i] + k * r[(row + 2) % 3][i];
                fits = fits && next[i] >= 0 && next[i] < (int64_t(1) << 22);
            }
            if (!fits) break;
            std::copy(next, next + 3, r[row]);
        }
        const int swap = int(rng() % 3); // an odd or even row order: either sign
        if (swap) std::swap(r[0], r[swap]);
        const glm::vec3 a(1024.0f, 1024.0f, 1024.0f);
        glm::vec3 p[3];
        for (int row = 0; row < 3; ++row)
            for (int i = 0; i < 3; ++i) p[row][i] = a[i] + float(std::ldexp(double(r[row][i]), -13));
        for (int row = 0; row < 3; ++row)
            for (int i = 0; i < 3; ++i) ASSERT_EQ(double(p[row][i]) - 1024.0, std::ldexp(double(r[row][i]), -13));
        const CGAL::Orientation want = CGAL::orientation(cg(a), cg(p[0]), cg(p[1]), cg(p[2]));
        ASSERT_NE(want, CGAL::COPLANAR);
        ASSERT_EQ(int(orient3d(a, p[0], p[1], p[2])), int(want)) << "case " << n;
        const std::array<glm::vec3, 3> tri{a, p[0], p[1]};
        ASSERT_EQ(int(orient3d(tri, trianglePlane(tri), p[2])), int(want)) << "case " << n;
        (want == CGAL::POSITIVE ? positive : negative)++;
    }
    EXPECT_GT(positive, 500);
    EXPECT_GT(negative, 500);
}

TEST(TriangleIntersect, AgreesWithCgalOnLatticePairsWithoutSharedVertices)
{
    PairMaker m(11);
    const auto [compared, hits] = compareWithCgal(6000, [&](Tri& a, Ids& ia, Tri& b, Ids& ib) {
        const glm::vec3 origin(74.0f, 134.0f, 1000.0f);
        for (auto& p : a) p = m.lattice(origin, 0.5f);
        for (auto& p : b) p = m.lattice(origin, 0.5f);
        ia = {0, 1, 2};
        ib = {3, 4, 5};
    });
    EXPECT_GT(compared, 3000);
    EXPECT_GT(hits, compared / 10);
    EXPECT_LT(hits, compared - compared / 10);
}

TEST(TriangleIntersect, AgreesWithCgalOnPairsAFloatStepApart)
{
    PairMaker m(13);
    const auto [compared, hits] = compareWithCgal(6000, [&](Tri& a, Ids& ia, Tri& b, Ids& ib) {
        const glm::vec3 origin(74.0f, 134.0f, 1000.0f);
        for (auto& p : a) p = m.lattice(origin, 0.25f);
        // b: a's points (or lattice points) nudged by float steps: sheets
        // that touch, cross or miss by one rounding.
        for (int k = 0; k < 3; ++k) b[size_t(k)] = m.nudge(m.integer(0, 2) ? a[size_t(m.integer(0, 2))] : m.lattice(origin, 0.25f));
        ia = {0, 1, 2};
        ib = {3, 4, 5};
    });
    EXPECT_GT(compared, 3000);
    EXPECT_GT(hits, compared / 10);
    EXPECT_LT(hits, compared - compared / 10);
}

TEST(TriangleIntersect, AgreesWithCgalOnPairsSharingAVertexOrAnEdge)
{
    PairMaker m(17);
    int sharedEdge = 0;
    const auto [compared, hits] = compareWithCgal(8000, [&](Tri& a, Ids& ia, Tri& b, Ids& ib) {
        const glm::vec3 origin(74.0f, 134.0f, 1000.0f);
        const float step = m.integer(0, 1) ? 0.5f : 6.103515625e-05f; // the float step at 1000 mm
        for (auto& p : a) p = m.lattice(origin, step);
        ia = {0, 1, 2};
        ib = {3, 4, 5};
        for (auto& p : b) p = m.lattice(origin, step);
        // Share one or two of a's vertices (by id, so at a's positions), in a
        // random place and order of b.
        const int share = m.integer(1, 2);
        const int from = m.integer(0, 2), to = m.integer(0, 2);
        for (int s = 0; s < share; ++s) {
            const size_t k = size_t((from + s) % 3), t = size_t((to + s) % 3);
            b[t] = a[k];
            ib[t] = ia[k];
        }
        sharedEdge += share == 2;
    });
    EXPECT_GT(compared, 4000);
    EXPECT_GT(sharedEdge, 2000);
    EXPECT_GT(hits, compared / 20);
    EXPECT_LT(hits, compared - compared / 10);
}

TEST(TriangleIntersect, NamedCasesHoldExactly)
{
    const Tri a{glm::vec3(0, 0, 0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0)};
    const Ids ia{0, 1, 2};
    // A fold: b shares a's edge 1-2 and lies in its plane on a's side.
    EXPECT_EQ(trianglesIntersect(a, ia, {a[1], a[2], glm::vec3(0.25f, 0.25f, 0)}, {1, 2, 9}), Contact::Intersect);
    // The same edge, b on the other side (a flat continuation): fine.
    EXPECT_EQ(trianglesIntersect(a, ia, {a[2], a[1], glm::vec3(1, 1, 0)}, {2, 1, 9}), Contact::None);
    // The same edge, b tilted a float step out of the plane: fine.
    EXPECT_EQ(trianglesIntersect(a, ia, {a[1], a[2], glm::vec3(0.25f, 0.25f, 1e-30f)}, {1, 2, 9}), Contact::None);
    // One vertex in common, b pointing away: fine; b's far edge through a: not.
    EXPECT_EQ(trianglesIntersect(a, ia, {a[0], glm::vec3(-1, 0, 1), glm::vec3(0, -1, 1)}, {0, 7, 8}), Contact::None);
    EXPECT_EQ(trianglesIntersect(a, ia, {a[0], glm::vec3(0.2f, 0.2f, 1), glm::vec3(0.2f, 0.2f, -1)}, {0, 7, 8}),
              Contact::Intersect);
    // Two different vertices at one position: touching is an intersection.
    EXPECT_EQ(trianglesIntersect(a, ia, {glm::vec3(0, 0, 0), glm::vec3(-1, 0, 1), glm::vec3(0, -1, 1)}, {6, 7, 8}),
              Contact::Intersect);
    // A sheet one float step above a: apart.
    const float up = std::nextafter(0.0f, 1.0f);
    EXPECT_EQ(trianglesIntersect(a, ia, {glm::vec3(0, 0, up), glm::vec3(1, 0, up), glm::vec3(0, 1, up)}, {6, 7, 8}),
              Contact::None);
    // Zero area: not judged where its plane is needed (a's edges against a
    // segment through a's plane beside it), never a wrong "no" (a segment in
    // a's plane across it); a's plane alone still tells one above it apart.
    EXPECT_EQ(trianglesIntersect(a, ia, {glm::vec3(2, 2, -1), glm::vec3(2, 2, 0), glm::vec3(2, 2, 1)}, {6, 7, 8}),
              Contact::Undecided);
    EXPECT_NE(trianglesIntersect(a, ia, {glm::vec3(0.1f, 0.1f, 0), glm::vec3(0.2f, 0.1f, 0), glm::vec3(0.3f, 0.1f, 0)}, {6, 7, 8}),
              Contact::None);
    EXPECT_EQ(trianglesIntersect(a, ia, {glm::vec3(0.1f, 0.1f, 1), glm::vec3(0.2f, 0.1f, 1), glm::vec3(0.3f, 0.1f, 1)}, {6, 7, 8}),
              Contact::None);
}

TEST(TriangleIntersect, Orient3dWithAPlaneInAnAxisPlane)
{
    // The caps of a blade along a grid plane: three points with one z, the
    // fourth on it (coplanar: every term of the determinant is zero, which
    // orient3d with a precomputed plane answers without the exact path) or a
    // float step or more off it; and the same about x and y.
    PairMaker m(31);
    int zero = 0, nonzero = 0;
    for (int n = 0; n < 6000; ++n) {
        const int axis = n % 3;
        const glm::vec3 origin(74.25f, 134.5f, 1078.25f);
        glm::vec3 p[4];
        for (glm::vec3& q : p) {
            q = m.lattice(origin, n % 2 ? 0.5f : 1e-3f);
            q[axis] = origin[axis];
        }
        if (n % 4 == 1) p[3][axis] = std::nextafter(p[3][axis], INFINITY);
        if (n % 4 == 2) p[3] = m.nudge(p[3]);
        const std::array<glm::vec3, 3> tri{p[0], p[1], p[2]};
        const CGAL::Orientation want = CGAL::orientation(cg(p[0]), cg(p[1]), cg(p[2]), cg(p[3]));
        ASSERT_EQ(int(orient3d(tri, trianglePlane(tri), p[3])), int(want)) << "case " << n;
        ASSERT_EQ(int(orient3d(p[0], p[1], p[2], p[3])), int(want)) << "case " << n;
        (want == CGAL::COPLANAR ? zero : nonzero)++;
    }
    EXPECT_GT(zero, 2000);
    EXPECT_GT(nonzero, 1000);
}

TEST(TriangleIntersect, ExactAcrossAnyRangeOfExponents)
{
    // Points within a few float steps of the coordinate planes through 0
    // (down to subnormals) next to points mm away: an axis spans far more
    // binary orders than 128-bit integers hold, and the arbitrary-precision
    // path decides. Coplanar sets: on the plane z = x, and nudged off it.
    std::mt19937_64 rng(23);
    PairMaker m(29);
    const float tiny[] = {std::nextafter(0.0f, 1.0f), 1e-30f, 3e-12f, 1e-7f, 0.0f, -1e-20f};
    int zero = 0, nonzero = 0;
    for (int n = 0; n < 4000; ++n) {
        glm::vec3 p[4];
        for (glm::vec3& q : p) {
            const float x = rng() % 2 ? tiny[rng() % 6] : float(int(rng() % 7) - 3);
            q = glm::vec3(x, float(int(rng() % 7) - 3), x);
            if (rng() % 4 == 0) q = m.nudge(q);
        }
        const CGAL::Orientation want = CGAL::orientation(cg(p[0]), cg(p[1]), cg(p[2]), cg(p[3]));
        ASSERT_EQ(int(orient3d(p[0], p[1], p[2], p[3])), int(want)) << "case " << n;
        const std::array<glm::vec3, 3> tri{p[0], p[1], p[2]};
        ASSERT_EQ(int(orient3d(tri, trianglePlane(tri), p[3])), int(want)) << "case " << n;
        (want == CGAL::COPLANAR ? zero : nonzero)++;
        const CGAL::Orientation w2 = CGAL::orientation(K::Point_2(double(p[0].x), double(p[0].y)),
                                                       K::Point_2(double(p[1].x), double(p[1].y)),
                                                       K::Point_2(double(p[2].x), double(p[2].y)));
        ASSERT_EQ(int(orient2d(p[0], p[1], p[2], 0, 1)), int(w2)) << "case " << n;
    }
    EXPECT_GT(zero, 1000);
    EXPECT_GT(nonzero, 1000);
    // Not finite: not judged, never "no".
    const glm::vec3 nan(std::numeric_limits<float>::quiet_NaN());
    EXPECT_EQ(orient3d(nan, glm::vec3(1, 0, 0), glm::vec3(0, 1, 0), glm::vec3(0, 0, 1)), Sign::Unknown);
    EXPECT_NE(trianglesIntersect({nan, glm::vec3(1, 0, 0), glm::vec3(0, 1, 0)}, {0, 1, 2},
                                 {glm::vec3(0, 0, 1), glm::vec3(1, 0, 1), glm::vec3(0, 1, 1)}, {3, 4, 5}),
              Contact::None);
}


TEST(TriangleIntersect, OnACommonCellBoundaryItsCornersThereDecideAsTheWholeTestDoes)
{
    // Two cells of a head's 1 mm grid (at 1000 mm: float steps of 6e-5 mm)
    // that share a face, an edge or a corner; a triangle in each, on a 0.25
    // mm lattice with corners often on the common part, sharing one or two
    // vertices or a position there, or a few coordinates off the lattice.
    // Wherever the boundary shortcut answers, its answer is the whole test's;
    // a pair with no corner on the part is apart.
    PairMaker m(37);
    const glm::vec3 origin(1000.0f, -200.0f, 1227.0f);
    const float step = 0.25f;
    int decided = 0, apart = 0, pairs = 0;
    int hits[3] = {0, 0, 0}, nones[3] = {0, 0, 0}; // by shared vertex count
    for (int n = 0; n < 100000; ++n) {
        Coord3 o;
        do {
            o = {m.integer(-1, 1), m.integer(-1, 1), m.integer(-1, 1)};
        } while (o[0] == 0 && o[1] == 0 && o[2] == 0);
        // Lattice index 0..4 across cell a, 4 o .. 4 o + 4 across cell b.
        auto corner = [&](int cellOffsetSign) {
            glm::vec3 p;
            for (int k = 0; k < 3; ++k) {
                const int base = cellOffsetSign * 4 * o[k];
                const int part = o[k] > 0 ? 4 : 0; // the common part's index, if fixed on k
                int idx = base + m.integer(0, 4);
                if (o[k] != 0 && m.integer(0, 1)) idx = part;
                p[k] = origin[k] + step * float(idx);
                if (m.integer(0, 7) == 0 && idx != part) // off the lattice, still inside
                    p[k] = origin[k] + step * (float(idx) + (idx < base + 4 ? 0.37f : -0.37f));
            }
            return p;
        };
        Tri a{corner(0), corner(0), corner(0)}, b{corner(1), corner(1), corner(1)};
        Ids ia{0, 1, 2}, ib{3, 4, 5};
        auto onPart = [&](const glm::vec3& p) {
            for (int k = 0; k < 3; ++k)
                if (o[k] != 0 && p[k] != origin[k] + step * float(o[k] > 0 ? 4 : 0)) return false;
            return true;
        };
        // b takes one or two of a's corners on the part (by id or only by position).
        const int share = m.integer(0, 5);
        for (int k = 0, taken = 0; k < 3 && taken < (share >= 4 ? 2 : share >= 1 ? 1 : 0); ++k) {
            if (!onPart(a[size_t(k)])) continue;
            b[size_t(taken)] = a[size_t(k)];
            if (share != 3) ib[size_t(taken)] = ia[size_t(k)];
            ++taken;
        }
        if (m.integer(0, 1)) std::swap(b[0], b[2]), std::swap(ib[0], ib[2]);
        const TrianglePlane pa = trianglePlane(a), pb = trianglePlane(b);
        if (!hasArea(a, pa) || !hasArea(b, pb)) {
            EXPECT_TRUE(collinear(a) || collinear(b)) << "pair " << n;
            continue;
        }
        ++pairs;
        unsigned onA = 0, onB = 0;
        for (unsigned k = 0; k < 3; ++k) {
            onA |= unsigned(onPart(a[k])) << k;
            onB |= unsigned(onPart(b[k])) << k;
        }
        int axes[3], count = 0;
        for (int k = 0; k < 3; ++k)
            if (o[k] == 0) axes[count++] = k;
        for (int k = 0; k < 3; ++k)
            if (o[k] != 0) axes[count++] = k;
        const Contact whole = trianglesCross(a, ia, pa, b, ib, pb);
        int shared = 0;
        for (uint32_t x : ia) shared += int(std::count(ib.begin(), ib.end(), x));
        if (onA == 0 || onB == 0) {
            EXPECT_EQ(int(whole), int(Contact::None)) << "pair " << n;
            ++apart;
            continue;
        }
        const std::optional<Contact> quick = trianglesCrossOnBoundary(a, ia, onA, b, ib, onB, axes[0], axes[1]);
        if (!quick) continue;
        ++decided;
        ASSERT_EQ(int(*quick), int(whole)) << "pair " << n << " offset " << o[0] << " " << o[1] << " " << o[2]
                                           << " shared " << shared;
        if (whole == Contact::None) nones[std::min(shared, 2)]++;
        else hits[std::min(shared, 2)]++;
    }
    // Every kind met often: the test can tell.
    EXPECT_GT(pairs, 60000);
    EXPECT_GT(apart, 10000);
    EXPECT_GT(decided, pairs / 2);
    for (int s = 0; s < 3; ++s) {
        EXPECT_GT(hits[s], 400) << "shared " << s;
        EXPECT_GT(nones[s], 400) << "shared " << s;
    }
}

} // namespace
