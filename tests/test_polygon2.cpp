// The re-meshing kernel's 2-D triangulation (cutter/Polygon2.h): every
// triangle CCW, the area preserved exactly as a sum, and the shape rules that
// keep slivers out of the cut (a sliver rounds to float and folds over).
#include "cutter/Polygon2.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

using namespace mtcut::cutter::poly2;

namespace {

/// Area of the triangles, checking each turns CCW; the worst shape in `worst`.
double triangleArea(const std::vector<int>& tris, const std::vector<Vec2>& pts, double& worst)
{
    double area = 0.0;
    worst = 1.0;
    for (size_t t = 0; t + 2 < tris.size(); t += 3) {
        const Vec2 &a = pts[size_t(tris[t])], &b = pts[size_t(tris[t + 1])], &c = pts[size_t(tris[t + 2])];
        EXPECT_GT(cross2(a, b, c), 0.0) << "triangle " << t / 3 << " does not turn CCW";
        area += 0.5 * cross2(a, b, c);
        worst = std::min(worst, minSine(a, b, c));
    }
    return area;
}

std::vector<int> iota(size_t n)
{
    std::vector<int> v(n);
    std::iota(v.begin(), v.end(), 0);
    return v;
}

} // namespace

TEST(Polygon2, MinSineOfKnownTriangles)
{
    EXPECT_NEAR(minSine({0, 0}, {1, 0}, {0, 1}), std::sqrt(0.5), 1e-15); // 45-45-90
    EXPECT_NEAR(minSine({0, 0}, {1, 0}, {0.5, std::sqrt(0.75)}), std::sqrt(0.75), 1e-15); // equilateral
    EXPECT_LT(minSine({0, 0}, {0, 1}, {1, 0}), 0.0);                                    // CW
    EXPECT_EQ(minSine({0, 0}, {0, 0}, {1, 0}), -1.0);                                   // a zero side
}

TEST(Polygon2, SegmentsIntersectCountsTouchingButNotSharedEnds)
{
    EXPECT_TRUE(segmentsIntersect({0, 0}, {2, 2}, {0, 2}, {2, 0}));   // a proper crossing
    EXPECT_FALSE(segmentsIntersect({0, 0}, {1, 1}, {1, 1}, {2, 0}));  // a shared end
    EXPECT_TRUE(segmentsIntersect({0, 0}, {2, 0}, {1, 0}, {1, 1}));   // a T: an end on the other's inside
    EXPECT_FALSE(segmentsIntersect({0, 0}, {1, 0}, {0, 1}, {1, 1}));  // parallel
    EXPECT_TRUE(segmentsIntersect({0, 0}, {2, 0}, {1, 0}, {3, 0}));   // overlapping, collinear
}

// The last four corners: ear clipping by best ear alone clips the right
// angle at p1 first and leaves (p2, p3, p0), flat because p3 bulges out of
// the segment p2 p0 by 1e-6 (a seam bending slightly on a mitre). The rule
// for four corners takes the other diagonal, p1 p3: two fair triangles.
TEST(Polygon2, EarClipSplitsTheLastFourCornersByTheBetterDiagonal)
{
    const double bulge = 1e-6 / std::sqrt(2.0);
    const std::vector<Vec2> pts = {{0, 0}, {2, 0}, {1, 1}, {0.5 - bulge, 0.5 + bulge}};
    ASSERT_GT(minSine(pts[0], pts[1], pts[2]), 0.7) << "the ear at p1 is the best single ear";
    ASSERT_LT(minSine(pts[2], pts[3], pts[0]), 1e-5) << "and clipping it first leaves a sliver";
    std::vector<int> tris;
    ASSERT_TRUE(earClip(iota(4), pts, tris));
    ASSERT_EQ(tris.size(), 6u);
    double worst = 0;
    EXPECT_NEAR(triangleArea(tris, pts, worst), 1.0 + 0.5 * std::sqrt(2.0) * 1e-6, 1e-12); // + the bulge
    EXPECT_GT(worst, 0.3) << "a sliver was made";
    for (size_t t = 0; t < 2; ++t) {
        const int* tri = tris.data() + 3 * t;
        EXPECT_TRUE(std::count(tri, tri + 3, 1) && std::count(tri, tri + 3, 3)) << "not split by the diagonal p1 p3";
    }
}

TEST(Polygon2, EarClipTriangulatesAConcavePolygonAndAHole)
{
    // An L: 6 corners, area 3.
    const std::vector<Vec2> l = {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
    std::vector<int> tris;
    ASSERT_TRUE(earClip(iota(l.size()), l, tris));
    EXPECT_EQ(tris.size(), 3 * (l.size() - 2));
    double worst = 0;
    EXPECT_DOUBLE_EQ(triangleArea(tris, l, worst), 3.0);
    EXPECT_DOUBLE_EQ(signedArea(iota(l.size()), l), 3.0);

    // A 4 x 4 square with a 1 x 1 square hole (CW): area 15 once bridged.
    const std::vector<Vec2> pts = {{0, 0}, {4, 0}, {4, 4}, {0, 4}, {1, 1}, {1, 2}, {2, 2}, {2, 1}};
    std::vector<int> outer = {0, 1, 2, 3};
    const std::vector<std::vector<int>> holes = {{4, 5, 6, 7}};
    EXPECT_DOUBLE_EQ(signedArea(holes[0], pts), -1.0);
    ASSERT_TRUE(bridgeHoles(outer, holes, pts));
    EXPECT_EQ(outer.size(), 4u + 4u + 2u) << "the hole and a bridge there and back";
    tris.clear();
    ASSERT_TRUE(earClip(outer, pts, tris));
    EXPECT_DOUBLE_EQ(triangleArea(tris, pts, worst), 15.0);
}

// A hole that touches the outer loop at a point (a slit from a boundary
// corner into the region: the kernel's loops hold the corner twice, once in
// each) is spliced there with no bridge. The bridge that was built instead,
// from the nearest other corner, left the corner three times in one polygon
// and ear clipping failed (the 1 mm head, random kerf stroke seed 2004).
TEST(Polygon2, AHoleTouchingTheOuterLoopIsSplicedWhereItTouches)
{
    // A 4 x 4 square; a thin CW triangle from a copy of its corner (0, 0).
    for (double width : {0.1, 1e-6}) {
        const std::vector<Vec2> pts = {{0, 0}, {4, 0}, {4, 4}, {0, 4}, {0, 0}, {2, 2 + width}, {2 + width, 2}};
        std::vector<int> outer = {0, 1, 2, 3};
        const std::vector<std::vector<int>> holes = {{4, 5, 6}};
        const double holeArea = signedArea(holes[0], pts);
        ASSERT_LT(holeArea, 0.0);
        ASSERT_TRUE(bridgeHoles(outer, holes, pts)) << width;
        EXPECT_EQ(outer, (std::vector<int>{0, 5, 6, 4, 1, 2, 3})) << "spliced at the corner, no bridge";
        std::vector<int> tris;
        ASSERT_TRUE(earClip(outer, pts, tris)) << width;
        EXPECT_EQ(tris.size(), 3u * 5u);
        double worst = 0;
        EXPECT_NEAR(triangleArea(tris, pts, worst), 16.0 + holeArea, 1e-12) << width;
    }
}

// A crack: a zero-width slit whose two ends are inside the region (a blade
// that stops inside an iso piece at kerf 0), with a Steiner point midway,
// two copies of it at one position, one per side. As a hole it is
// 3 -> m+ -> 5 -> m- (zero area). The bridge went to the first copy of the
// nearest point, whichever side it was on, and ear clipping found no ear
// (the body CT at kerf 0, random stroke seed 1008). It now goes to the copy
// whose side faces it, and every triangle stays on one side of the crack.
TEST(Polygon2, ACrackIsBridgedToTheCopyOnTheSideFacingTheBridge)
{
    // Corners as the body CT's cell (98, 51, 32) had them, in its face's plane.
    const std::vector<Vec2> pts = {{59.7836456654, 60.4113036488}, {60.63203734, 59.6629485626},
                                   {60.63203734, 60.9363385125},  {60.2394047612, 60.2156341509},
                                   {60.447380912, 60.0909334751}, {60.5844215691, 60.1344726631},
                                   {60.447380912, 60.0909334751}};
    const int up = 4, down = 6; // the crack's midpoint, on each side
    std::vector<int> outer = {0, 1, 2};
    const std::vector<std::vector<int>> holes = {{up, 5, down, 3}};
    ASSERT_EQ(signedArea(holes[0], pts), 0.0);
    ASSERT_TRUE(bridgeHoles(outer, holes, pts));
    EXPECT_EQ(outer, (std::vector<int>{0, 1, down, 3, up, 5, down, 1, 2})) << "bridged from corner 1, below the crack";
    std::vector<int> tris;
    ASSERT_TRUE(earClip(outer, pts, tris));
    double worst = 0;
    EXPECT_NEAR(triangleArea(tris, pts, worst), 0.5 * cross2(pts[0], pts[1], pts[2]), 1e-12);
    // No triangle joins the two sides' copies.
    for (size_t t = 0; t < tris.size(); t += 3) {
        const bool hasUp = tris[t] == up || tris[t + 1] == up || tris[t + 2] == up;
        const bool hasDown = tris[t] == down || tris[t + 1] == down || tris[t + 2] == down;
        EXPECT_FALSE(hasUp && hasDown) << "triangle " << t / 3 << " spans the crack";
    }
}

// bestTriangulation maximises the worst triangle's shape over all
// triangulations: on a fan of nearly straight corners no triangulation can
// be better than it, and ear clipping's is never better.
TEST(Polygon2, BestTriangulationIsNoWorseThanEarClipping)
{
    // A regular hexagon, and one with two corners pushed nearly straight.
    for (double push : {0.0, 0.49}) {
        std::vector<Vec2> pts;
        for (int i = 0; i < 6; ++i) {
            const double a = M_PI / 3 * i;
            const double r = (i == 1 || i == 4) ? 1.0 - push : 1.0;
            pts.push_back({r * std::cos(a), r * std::sin(a)});
        }
        std::vector<int> best, ears;
        ASSERT_TRUE(bestTriangulation(iota(6), pts, best));
        ASSERT_TRUE(earClip(iota(6), pts, ears));
        ASSERT_EQ(best.size(), 12u);
        double worstBest = 0, worstEars = 0;
        const double area = triangleArea(best, pts, worstBest);
        EXPECT_NEAR(area, triangleArea(ears, pts, worstEars), 1e-14);
        EXPECT_NEAR(area, signedArea(iota(6), pts), 1e-14);
        EXPECT_GE(worstBest, worstEars) << "push " << push;
        if (push == 0.0) {
            EXPECT_NEAR(worstBest, std::sin(M_PI / 6), 1e-12) << "the regular hexagon's best: 30-30-120 or better";
        }
    }
    // A repeated point or too many corners: refused, tris unchanged.
    std::vector<int> tris = {7};
    const std::vector<Vec2> twice = {{0, 0}, {1, 0}, {1, 1}, {1, 0}};
    EXPECT_FALSE(bestTriangulation(iota(4), twice, tris));
    std::vector<Vec2> many;
    for (size_t i = 0; i <= kBestOfAllMax; ++i)
        many.push_back({std::cos(2 * M_PI * double(i) / double(kBestOfAllMax + 1)),
                        std::sin(2 * M_PI * double(i) / double(kBestOfAllMax + 1))});
    EXPECT_FALSE(bestTriangulation(iota(many.size()), many, tris));
    EXPECT_EQ(tris, std::vector<int>{7});
}

// angleLess and clockwiseLess replace std::atan2 in the kernel (a cap's
// corners ordered about its centre, a region's loop turning most clockwise)
// because the GPU port has no double atan2. They must order as atan2 does
// wherever atan2 tells two directions apart, except that the sign of a zero
// y is not read (a corner opposite the first one of a parallelogram cap sits
// on the -x axis with y = -0 or +0, where atan2 says -pi or pi; a GPU driver
// need not keep the sign of a zero, so both are pi, last).
TEST(Polygon2, AngleOrdersAsAtan2WithoutIt)
{
    std::vector<Vec2> dirs;
    uint64_t state = 12345;
    auto next = [&]() {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return double(state >> 11) / double(1ull << 53) * 2.0 - 1.0;
    };
    for (int i = 0; i < 2000; ++i) dirs.push_back({next(), next()});
    // (Components of the kernel's directions are differences of coordinates
    // of 1e-6 to 1e4 voxels: their products never underflow, as 1e-300's would.)
    for (double x : {-1.0, -0.5, 0.0, 0.5, 1.0, 1e-9, -1e-9})
        for (double y : {-1.0, -0.0, 0.0, 1.0, 1e-9, -1e-9}) dirs.push_back({x, y});
    dirs.push_back({-2.0, -0.0});
    dirs.push_back({-2.0, 0.0});
    size_t pairs = 0;
    for (const Vec2& u : dirs)
        for (size_t k = 0; k < 40; ++k) {
            const Vec2& v = dirs[(&u - dirs.data() + 7919 * k) % dirs.size()];
            if (u.x == 0 && u.y == 0) continue; // atan2(0, -0) is pi: a zero vector has no angle
            if (v.x == 0 && v.y == 0) continue;
            const double au = std::atan2(u.y + 0.0, u.x), av = std::atan2(v.y + 0.0, v.x);
            if (au != av) {
                EXPECT_EQ(angleLess(u, v), au < av) << u.x << "," << u.y << " vs " << v.x << "," << v.y;
                ++pairs;
            }
            // Clockwise from u: as the kernel's old rank, back - atan2(d) in (0, 2 pi].
            auto rank = [&](const Vec2& d) {
                double a = au - std::atan2(d.y, d.x);
                while (a <= 0) a += 2 * M_PI;
                while (a > 2 * M_PI) a -= 2 * M_PI;
                return a;
            };
            const Vec2& w = dirs[(&u - dirs.data() + 104729 * k + 1) % dirs.size()];
            if (w.x == 0 && w.y == 0) continue;
            const double rv = rank(v), rw = rank(w);
            if (std::abs(rv - rw) > 1e-12) {
                EXPECT_EQ(clockwiseLess(u, v, w), rv < rw) << u.x << "," << u.y << " to " << v.x << "," << v.y << " or " << w.x << "," << w.y;
            }
        }
    EXPECT_GT(pairs, 50000u);
    EXPECT_FALSE(angleLess({-1.0, -0.0}, {1.0, -1e-9})); // pi (not atan2's -pi), last
    EXPECT_FALSE(angleLess({-1.0, 0.0}, {-1.0, 1e9}));    // pi last
    EXPECT_FALSE(angleLess({-1.0, -0.0}, {-2.0, 0.0}));   // the same angle either way
    EXPECT_FALSE(angleLess({-2.0, 0.0}, {-1.0, -0.0}));
    // Where atan2 rounds two directions to one angle, the cross product
    // still tells them apart: (0, 1) is a turn of 1e-20 rad clockwise from
    // (-1e-20, 1), which atan2 makes a full turn (back where it came from).
    EXPECT_TRUE(clockwiseLess({-1e-20, 1.0}, {0.0, 1.0}, {1.0, 0.0}));
}
