// Blade path filter and conservative voxelisation, against an independent
// brute force: Sutherland-Hodgman clipping of K_q's faces against each cell
// box (not the production separating-axis test).
#include "cutter/BladePath.h"
#include "vdb/Error.h"

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tuple>
#include <vector>

using namespace mtcut::cutter;
using glm::dvec3;
using glm::ivec3;

namespace {

IndexFrame testFrame()
{
    IndexFrame f;
    f.origin = dvec3(-10.25, 3.5, -40.0); // dyadic: index <-> world exact
    f.spacing = dvec3(0.5, 0.5, 2.0);     // anisotropic, as CT
    f.dims = ivec3(40, 40, 16);
    return f;
}

using CellSet = std::set<std::tuple<int, int, int>>;
std::tuple<int, int, int> key(const ivec3& c) { return {c.x, c.y, c.z}; }

// --- brute force -------------------------------------------------------------

using Poly = std::vector<dvec3>;

/// Clips a convex polygon (or segment / point) by x[axis] >= v (sign +1) or <= v (sign -1).
Poly clip(const Poly& in, int axis, double v, double sign)
{
    Poly out;
    const size_t n = in.size();
    for (size_t i = 0; i < n; ++i) {
        const dvec3& cur = in[i];
        const dvec3& prev = in[(i + n - 1) % n];
        const double dc = sign * (cur[axis] - v), dp = sign * (prev[axis] - v);
        if (dc >= 0) {
            if (dp < 0) out.push_back(prev + (cur - prev) * (dp / (dp - dc)));
            out.push_back(cur);
        } else if (dp >= 0 && n > 1) {
            out.push_back(prev + (cur - prev) * (dp / (dp - dc)));
        }
    }
    return out;
}

bool polyTouchesBox(Poly p, const dvec3& lo, const dvec3& hi)
{
    for (int a = 0; a < 3 && !p.empty(); ++a) {
        p = clip(p, a, lo[a], 1.0);
        if (!p.empty()) p = clip(p, a, hi[a], -1.0);
    }
    return !p.empty();
}

/// K in index space: hull(u) + [-h, h], given by the faces (as a union of
/// polygons covering its boundary) and a point-membership test.
struct BruteRegion
{
    std::vector<Poly> faces;
    std::vector<dvec3> u;
    dvec3 h{0.0};
    dvec3 m{0.0}; // plane normal (index space), zero when degenerate
    bool flat = false;

    bool inTriangle(const dvec3& p, const dvec3& a, const dvec3& b, const dvec3& c) const
    {
        const dvec3 n = glm::cross(b - a, c - a);
        const double nn = glm::dot(n, n);
        if (nn == 0.0) return false;
        const double w0 = glm::dot(glm::cross(b - p, c - p), n) / nn;
        const double w1 = glm::dot(glm::cross(c - p, a - p), n) / nn;
        return w0 >= 0 && w1 >= 0 && 1 - w0 - w1 >= 0;
    }
    bool contains(const dvec3& x) const
    {
        if (!flat || glm::dot(m, h) == 0.0) return false; // measure zero: faces decide
        const double t = glm::dot(m, x - u[0]) / glm::dot(m, h);
        if (std::abs(t) > 1.0) return false;
        const dvec3 p = x - t * h;
        for (size_t i = 0; i < u.size(); ++i)
            for (size_t j = i + 1; j < u.size(); ++j)
                for (size_t k = j + 1; k < u.size(); ++k)
                    if (inTriangle(p, u[i], u[j], u[k])) return true;
        return false;
    }
    bool touches(const dvec3& lo, const dvec3& hi) const
    {
        for (const Poly& f : faces)
            if (polyTouchesBox(f, lo, hi)) return true;
        return contains(lo); // box inside K (then no face meets it)
    }
};

BruteRegion bruteRegion(const Quad& q, double kerf, const IndexFrame& f)
{
    BruteRegion r;
    for (uint32_t i = 0; i < q.cornerCount; ++i) r.u.push_back(f.toIndex(q.corners[i]));
    if (!q.degenerate) {
        r.flat = true;
        r.m = q.normal * f.spacing;
        r.h = 0.5 * kerf * q.normal / f.spacing;
    }
    const size_t n = r.u.size();
    std::vector<dvec3> offsets = {dvec3(0.0)};
    if (r.h != dvec3(0.0)) offsets = {r.h, -r.h};
    // Faces: every corner triangle (covers the hull), every edge, every point,
    // at +h and -h; and the side parallelograms edge x [-h, h].
    for (const dvec3& o : offsets) {
        for (size_t i = 0; i < n; ++i) {
            r.faces.push_back({r.u[i] + o});
            for (size_t j = i + 1; j < n; ++j) {
                r.faces.push_back({r.u[i] + o, r.u[j] + o});
                for (size_t k = j + 1; k < n; ++k) r.faces.push_back({r.u[i] + o, r.u[j] + o, r.u[k] + o});
            }
        }
    }
    if (r.h != dvec3(0.0))
        for (size_t i = 0; i < n; ++i)
            for (size_t j = i + 1; j < n; ++j)
                r.faces.push_back({r.u[i] - r.h, r.u[j] - r.h, r.u[j] + r.h, r.u[i] + r.h});
    return r;
}

struct Bracket
{
    CellSet sure, possible;
};

/// sure: cells whose box shrunk by delta (per axis; negative = enlarged) touches K;
/// possible: cells whose box enlarged by delta touches K.
Bracket bruteCells(const Quad& q, double kerf, const IndexFrame& f, dvec3 shrink, double delta)
{
    const BruteRegion r = bruteRegion(q, kerf, f);
    dvec3 lo = r.u[0], hi = r.u[0];
    for (const dvec3& p : r.u) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    lo -= glm::abs(r.h);
    hi += glm::abs(r.h);
    // The cells a cut can reach: the volume's and the ring around it.
    const ivec3 cLo = f.cutCellLo(), cHi = f.cutCellHi();
    Bracket b;
    ivec3 c;
    for (c.x = std::max(cLo.x, int(std::floor(lo.x)) - 2); c.x <= std::min(cHi.x, int(hi.x) + 2); ++c.x)
        for (c.y = std::max(cLo.y, int(std::floor(lo.y)) - 2); c.y <= std::min(cHi.y, int(hi.y) + 2); ++c.y)
            for (c.z = std::max(cLo.z, int(std::floor(lo.z)) - 2); c.z <= std::min(cHi.z, int(hi.z) + 2);
                 ++c.z) {
                const dvec3 bl(c), bh = dvec3(c) + 1.0;
                if (r.touches(bl + shrink, bh - shrink)) {
                    b.sure.insert(key(c));
                    b.possible.insert(key(c));
                } else if (r.touches(bl - delta, bh + delta)) {
                    b.possible.insert(key(c));
                }
            }
    return b;
}

struct CompareStats
{
    size_t quads = 0, cells = 0, ambiguous = 0;
};

void compareWithBrute(const Quad& q, double kerf, const IndexFrame& f, CompareStats& stats,
                      dvec3 shrink = dvec3(1e-7), double delta = 1e-7)
{
    std::vector<ivec3> cells;
    voxelizeQuad(q, kerf, f, cells);
    CellSet got;
    const ivec3 cLo = f.cutCellLo(), cHi = f.cutCellHi();
    for (const ivec3& c : cells) {
        ASSERT_TRUE(c.x >= cLo.x && c.y >= cLo.y && c.z >= cLo.z && c.x <= cHi.x && c.y <= cHi.y && c.z <= cHi.z);
        ASSERT_TRUE(got.insert(key(c)).second) << "duplicate cell";
    }
    const Bracket b = bruteCells(q, kerf, f, shrink, delta);
    for (const auto& c : b.sure)
        ASSERT_TRUE(got.count(c)) << "missed cell " << std::get<0>(c) << "," << std::get<1>(c) << ","
                                  << std::get<2>(c) << " quad stick " << q.stick;
    for (const auto& c : got)
        ASSERT_TRUE(b.possible.count(c)) << "extra cell " << std::get<0>(c) << "," << std::get<1>(c)
                                         << "," << std::get<2>(c);
    ++stats.quads;
    stats.cells += got.size();
    stats.ambiguous += b.possible.size() - b.sure.size();
}

dvec3 randomUnit(std::mt19937_64& rng)
{
    std::normal_distribution<double> g;
    while (true) {
        const dvec3 v(g(rng), g(rng), g(rng));
        const double l = glm::length(v);
        if (l > 1e-3) return v / l;
    }
}

/// A random planar quad/triangle in world mm around centre c (world), size up to `size` mm.
Quad randomPlanarQuad(std::mt19937_64& rng, const dvec3& c, double size, uint32_t count)
{
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    const dvec3 e1 = randomUnit(rng);
    const dvec3 e2 = glm::normalize(glm::cross(e1, randomUnit(rng)));
    dvec3 p[4];
    for (uint32_t i = 0; i < count; ++i) p[i] = c + size * (uni(rng) * e1 + uni(rng) * e2);
    return makeQuad(p, count, 0);
}

} // namespace

// --- voxelisation ------------------------------------------------------------

TEST(Voxelize, RandomQuadsMatchBruteForce)
{
    const IndexFrame f = testFrame();
    std::mt19937_64 rng(1234);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    CompareStats stats;
    for (int i = 0; i < 2500; ++i) {
        const dvec3 c = f.toWorld(dvec3(uni(rng) * 39, uni(rng) * 39, uni(rng) * 15));
        const double kerf = (i % 3 == 0) ? 0.0 : (i % 3 == 1 ? 0.3 : 1.5);
        const Quad q = randomPlanarQuad(rng, c, 0.3 + 2.5 * uni(rng), i % 4 == 0 ? 3 : 4);
        compareWithBrute(q, kerf, f, stats);
        if (HasFatalFailure()) return;
    }
    EXPECT_EQ(stats.quads, 2500u);
    EXPECT_GT(stats.cells, 2500u * 5);
    // The ambiguity band (cells within 1e-7 voxel of K) is tiny for random input.
    EXPECT_LT(stats.ambiguous, stats.cells / 1000 + 5);
}

// appendCells skips the rows and columns that the region's outline (seen
// along the inner axis) cannot reach: it must still list exactly the cells
// touchesCell accepts. Long thin quads (a blade across the volume swept by
// about a voxel, any direction, any kerf) are where the skipping matters.
TEST(Voxelize, LongThinQuadsListExactlyTheTouchedCells)
{
    const IndexFrame f = testFrame();
    std::mt19937_64 rng(4321);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    const ivec3 n = f.cellCount();
    const dvec3 size = f.toWorld(dvec3(f.dims - 1)) - f.toWorld(dvec3(0.0));
    size_t listed = 0;
    for (int i = 0; i < 300; ++i) {
        const dvec3 base = f.toWorld(dvec3(0.0)) + size * dvec3(uni(rng), uni(rng), uni(rng));
        const dvec3 dir = randomUnit(rng), move = glm::normalize(glm::cross(dir, randomUnit(rng)));
        const double length = 5.0 + 40.0 * uni(rng), sweep = 0.2 + 1.5 * uni(rng);
        const dvec3 c[4] = {base, base + length * dir, base + length * dir + sweep * move, base + sweep * move};
        const Quad q = makeQuad(c, i % 5 == 0 ? 3 : 4, 0);
        const double kerf = (i % 3 == 0) ? 0.0 : (i % 3 == 1 ? 0.3 : 1.5);
        const CutRegion region = cutRegion(q, kerf, f);
        std::vector<ivec3> got;
        region.appendCells(got);
        std::vector<ivec3> all;
        ivec3 cell;
        for (cell.x = -1; cell.x <= n.x; ++cell.x)
            for (cell.y = -1; cell.y <= n.y; ++cell.y)
                for (cell.z = -1; cell.z <= n.z; ++cell.z)
                    if (region.touchesCell(cell)) all.push_back(cell);
        auto lex = [](const ivec3& a, const ivec3& b) { return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z); };
        std::vector<ivec3> sorted = got;
        std::sort(sorted.begin(), sorted.end(), lex);
        ASSERT_EQ(sorted, all) << "quad " << i;
        listed += got.size();
    }
    EXPECT_GT(listed, 300u * 20);
}

TEST(Voxelize, QuadsOnGridPlanesCutBothLayers)
{
    const IndexFrame f = testFrame();
    std::mt19937_64 rng(77);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    CompareStats stats;
    for (int i = 0; i < 1000; ++i) {
        const int axis = i % 3;
        const int k0 = 2 + int(uni(rng) * (f.dims[axis] - 5));
        // Random polygon in the plane index[axis] == k0 (exact in world too).
        dvec3 p[4];
        const uint32_t count = i % 5 == 0 ? 3 : 4;
        const dvec3 centre(5 + uni(rng) * 28, 5 + uni(rng) * 28, 4 + uni(rng) * 8);
        for (uint32_t v = 0; v < count; ++v) {
            dvec3 ijk = centre + dvec3(uni(rng) * 6 - 3, uni(rng) * 6 - 3, uni(rng) * 6 - 3);
            if (i % 2 == 0) ijk = glm::floor(ijk); // through grid vertices, edges on grid lines
            ijk[axis] = k0;
            ijk = glm::clamp(ijk, dvec3(1.0), dvec3(f.dims - 2));
            p[v] = f.toWorld(ijk);
        }
        const Quad q = makeQuad(p, count, 0);
        // The plane contact along `axis` is exact: sure = box shrunk in the
        // other axes only (enlarged along `axis`), so both layers must be cut.
        dvec3 shrink(1e-7);
        shrink[axis] = -1e-7;
        compareWithBrute(q, i % 4 == 1 ? 0.5 : 0.0, f, stats, shrink);
        if (HasFatalFailure()) return;
    }
    EXPECT_EQ(stats.quads, 1000u);
}

TEST(Voxelize, AxisAlignedRectangleOnGridPlaneExactCount)
{
    const IndexFrame f = testFrame();
    for (int x0 = 2; x0 < 6; ++x0)
        for (int w = 0; w < 4; ++w) {
            // Rectangle [x0, x0+w] x [3, 7] at z = 5 (index), corners on grid vertices.
            const dvec3 p[4] = {f.toWorld(dvec3(x0, 3, 5)), f.toWorld(dvec3(x0 + w, 3, 5)),
                                f.toWorld(dvec3(x0 + w, 7, 5)), f.toWorld(dvec3(x0, 7, 5))};
            const Quad q = makeQuad(p, 4, 0);
            EXPECT_EQ(q.degenerate, w == 0);
            std::vector<ivec3> cells;
            voxelizeQuad(q, 0.0, f, cells);
            // Cells i in [x0-1, x0+w], j in [2, 7], k in {4, 5}.
            EXPECT_EQ(cells.size(), size_t((w + 2) * 6 * 2)) << "x0 " << x0 << " w " << w;
            for (const ivec3& c : cells) {
                EXPECT_TRUE(c.x >= x0 - 1 && c.x <= x0 + w && c.y >= 2 && c.y <= 7 &&
                            (c.z == 4 || c.z == 5));
            }
        }
}

TEST(Voxelize, QuadsThroughGridVerticesCutAllEightCells)
{
    const IndexFrame f = testFrame();
    std::mt19937_64 rng(99);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    CompareStats stats;
    for (int i = 0; i < 1000; ++i) {
        const ivec3 g(3 + int((uni(rng) + 1) * 16), 3 + int((uni(rng) + 1) * 16),
                      3 + int((uni(rng) + 1) * 4));
        const dvec3 gw = f.toWorld(dvec3(g));
        const dvec3 e1 = randomUnit(rng);
        const dvec3 e2 = glm::normalize(glm::cross(e1, randomUnit(rng)));
        dvec3 p[4];
        if (i % 2 == 0) {
            // The grid vertex is a corner.
            p[0] = gw;
            for (int v = 1; v < 4; ++v) p[v] = gw + 2.0 * (uni(rng) * e1 + uni(rng) * e2);
        } else {
            // The grid vertex is inside the quad.
            p[0] = gw + 1.5 * (-e1 - e2);
            p[1] = gw + 1.5 * (e1 - e2);
            p[2] = gw + 1.5 * (e1 + e2);
            p[3] = gw + 1.5 * (-e1 + e2);
        }
        const Quad q = makeQuad(p, 4, 0);
        std::vector<ivec3> cells;
        voxelizeQuad(q, 0.0, f, cells);
        CellSet got;
        for (const ivec3& c : cells) got.insert(key(c));
        for (int dx = -1; dx <= 0; ++dx)
            for (int dy = -1; dy <= 0; ++dy)
                for (int dz = -1; dz <= 0; ++dz)
                    ASSERT_TRUE(got.count(key(g + ivec3(dx, dy, dz)))) << "quad " << i;
        compareWithBrute(q, 0.0, f, stats);
        if (HasFatalFailure()) return;
    }
}

TEST(Voxelize, DegenerateQuadsCutTheCellsTheirSegmentTouches)
{
    const IndexFrame f = testFrame();
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    CompareStats stats;
    for (int i = 0; i < 1000; ++i) {
        const dvec3 a = f.toWorld(dvec3(3 + uni(rng) * 30, 3 + uni(rng) * 30, 3 + uni(rng) * 9));
        const dvec3 d = randomUnit(rng) * (uni(rng) * 3.0);
        dvec3 p[4];
        if (i % 3 == 0) {
            p[0] = p[1] = p[2] = p[3] = a; // a point
        } else {
            // Collinear motion along the blade: base0, tip0, tip1, base1 on one line.
            p[0] = a;
            p[1] = a + d;
            p[2] = a + 1.5 * d;
            p[3] = a + 0.5 * d;
        }
        const Quad q = makeQuad(p, 4, 0);
        ASSERT_TRUE(q.degenerate);
        compareWithBrute(q, 1.0, f, stats); // kerf is not applied to degenerate quads
        if (HasFatalFailure()) return;
    }
    // A segment along a grid line cuts the four cells around it.
    const dvec3 p[4] = {f.toWorld(dvec3(4, 6, 7)), f.toWorld(dvec3(9, 6, 7)), f.toWorld(dvec3(9, 6, 7)),
                        f.toWorld(dvec3(4, 6, 7))};
    std::vector<ivec3> cells;
    voxelizeQuad(makeQuad(p, 4, 0), 0.0, f, cells);
    EXPECT_EQ(cells.size(), size_t(7 * 2 * 2));
}

TEST(Voxelize, OutsideAndHugeQuadsAreClipped)
{
    const IndexFrame f = testFrame();
    std::vector<ivec3> cells;
    const dvec3 far[4] = {dvec3(1e6, 1e6, 1e6), dvec3(1e6 + 5, 1e6, 1e6), dvec3(1e6 + 5, 1e6 + 5, 1e6),
                          dvec3(1e6, 1e6 + 5, 1e6)};
    voxelizeQuad(makeQuad(far, 4, 0), 0.0, f, cells);
    EXPECT_TRUE(cells.empty());
    // Far past int's range, either way, and across it: no cells, and no
    // conversion of such a bound to int (UBSan found one at 2e52 mm).
    for (double d : {1e30, -1e30, 2.1e52}) {
        for (double kerf : {0.0, 0.5}) {
            const dvec3 q[4] = {dvec3(d, d, d), dvec3(d + 5, d, d), dvec3(d + 5, d + 5, d), dvec3(d, d + 5, d)};
            voxelizeQuad(makeQuad(q, 4, 0), kerf, f, cells);
            const dvec3 across[4] = {dvec3(-d, 3, 3), dvec3(d, 3, 3), dvec3(d, 4, 5), dvec3(-d, 4, 5)};
            voxelizeCut(makeQuad(across, 4, 0), kerf, f, cells);
        }
        EXPECT_TRUE(cells.empty()) << d;
    }
    // A huge quad through the whole volume: the plane z = index 5.5 cuts exactly one layer.
    const double z = f.toWorld(dvec3(0, 0, 5.5)).z;
    const dvec3 huge[4] = {dvec3(-1e12, -1e12, z), dvec3(1e12, -1e12, z), dvec3(1e12, 1e12, z),
                           dvec3(-1e12, 1e12, z)};
    voxelizeQuad(makeQuad(huge, 4, 0), 0.0, f, cells);
    const ivec3 n = f.cellCount();
    // The volume's cells and the ring around it (-1 and dims - 1), where
    // the isosurface closes.
    EXPECT_EQ(cells.size(), size_t(n.x + 2) * size_t(n.y + 2));
    for (const ivec3& c : cells) EXPECT_EQ(c.z, 5);
}

// --- path filter -------------------------------------------------------------

namespace {

/// Random strokes with a controllable twist rate (radians per pose).
std::vector<Pose> twistingStroke(std::mt19937_64& rng, const IndexFrame& f, int steps, double twist)
{
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::vector<Pose> poses;
    dvec3 p = f.toWorld(dvec3(5 + uni(rng) * 30, 5 + uni(rng) * 30, 3 + uni(rng) * 10));
    dvec3 dir = randomUnit(rng), vel = glm::normalize(glm::cross(dir, randomUnit(rng)));
    double t = 0;
    for (int i = 0; i < steps; ++i) {
        Pose pose;
        pose.time = t;
        pose.base = p;
        pose.direction = dir * (0.5 + uni(rng)); // non-unit on purpose: normalised
        pose.length = 5.0 + 10 * uni(rng);
        poses.push_back(pose);
        t += (i % 7 == 0) ? 0.0 : 0.001; // equal times are allowed
        vel = glm::normalize(vel + 0.2 * randomUnit(rng));
        dir = glm::normalize(dir + twist * randomUnit(rng));
        p += (0.05 + 0.6 * uni(rng)) * vel;
        if (i % 50 == 0) p += dir * 0.7; // some motion along the blade (plunge)
    }
    return poses;
}

/// Rule 2b's bound, checked independently: do the base and tip of `pose`
/// lie within `tol` voxels of one of `quads` (of its plane, and inside its
/// outline's bounding box grown by `tol`)?
bool nearOneQuad(const IndexFrame& f, const std::vector<Quad>& quads, const Pose& pose, double tol)
{
    const dvec3 b = f.toIndex(pose.base);
    const dvec3 tip = f.toIndex(pose.base + pose.length * glm::normalize(pose.direction));
    for (const Quad& quad : quads) {
        dvec3 c[4], nrm(0.0), lo(1e300), hi(-1e300);
        for (uint32_t j = 0; j < quad.cornerCount; ++j) c[j] = f.toIndex(quad.corners[j]);
        for (uint32_t j = 0; j < quad.cornerCount; ++j) {
            nrm += glm::cross(c[j], c[(j + 1) % quad.cornerCount]);
            lo = glm::min(lo, c[j] - tol);
            hi = glm::max(hi, c[j] + tol);
        }
        nrm = glm::normalize(nrm);
        auto ok = [&](const dvec3& x) {
            return std::abs(glm::dot(nrm, x - c[0])) <= tol + 1e-9 && glm::all(glm::greaterThanEqual(x, lo)) &&
                   glm::all(glm::lessThanEqual(x, hi));
        };
        if (ok(b) && ok(tip)) return true;
    }
    return false;
}

/// Whether the sticks of a one-plane quad {base0, tip0, tip1, base1} cross
/// (its outline crosses itself), by the sides of each stick's ends to the
/// other's line in the quad's plane.
bool sticksCrossForTest(const Quad& q)
{
    if (q.degenerate || q.cornerCount != 4) return false;
    const dvec3 n = glm::normalize(glm::cross(q.corners[1] - q.corners[0], q.corners[2] - q.corners[0]) +
                                   glm::cross(q.corners[2] - q.corners[0], q.corners[3] - q.corners[0]));
    auto side = [&](const dvec3& a, const dvec3& b, const dvec3& x) {
        const double o = glm::dot(glm::cross(b - a, x - a), n);
        return o > 0 ? 1 : o < 0 ? -1 : 0;
    };
    const auto& c = q.corners;
    return side(c[0], c[1], c[3]) * side(c[0], c[1], c[2]) < 0 && side(c[3], c[2], c[0]) * side(c[3], c[2], c[1]) < 0;
}

} // namespace

TEST(PathFilter, GuaranteesOnThousandsOfPoses)
{
    const IndexFrame f = testFrame();
    std::mt19937_64 rng(2024);
    PathFilterOptions opt;
    opt.slideTolerance = -1.0; // rule 2c has its own test (ASlideAlongTheBlade...)
    size_t kept = 0, dropped = 0, retraced = 0, adjusted = 0, split = 0, quadsTotal = 0, restarts = 0;
    size_t turnable = 0; // rule 3 (a') off: quads whose sticks cross by a turn within maxTwist
    double maxAdjust = 0;
    for (int s = 0; s < 60; ++s) {
        opt.turnCrossingSticks = s % 2 == 1; // each twist with the rule off and on
        const double twist = s % 3 == 0 ? 0.001 : (s % 3 == 1 ? 0.02 : 0.2);
        const std::vector<Pose> poses = twistingStroke(rng, f, 500, twist);
        PathFilter filter(f, opt);
        std::vector<Quad> quads;
        for (size_t i = 0; i < poses.size(); ++i) {
            size_t before = filter.sticks().size();
            const size_t quadsBefore = quads.size();
            const size_t restartsBefore = filter.restarts();
            const bool k = filter.push(poses[i], quads);
            // Leaving a retrace may restart the strip at the last retracing
            // stick (rule 2b): kept before the new one; the quads join the two.
            const size_t restarted = filter.restarts() - restartsBefore;
            ASSERT_LE(restarted, k ? 1u : 0u);
            restarts += restarted;
            before += restarted;
            ASSERT_EQ(filter.sticks().size(), before + (k ? 1 : 0));
            if (!k) {
                ++dropped;
                ASSERT_EQ(quads.size(), quadsBefore);
                // Dropped only when in the same cell as the last kept stick, or
                // (retracing, rule 2b) when base and tip lie within the tolerance
                // of one of the stroke's quads (checked here by the plane distance
                // and the outline's bounding box grown by the tolerance).
                if (f.cellOf(f.toIndex(poses[i].base)) == f.cellOf(f.toIndex(filter.sticks().back().base))) continue;
                ++retraced;
                ASSERT_TRUE(nearOneQuad(f, quads, poses[i], opt.retraceTolerance))
                    << "pose " << i << " dropped but neither in the last stick's cell nor retracing";
                continue;
            }
            ++kept;
            const Stick& st = filter.sticks().back();
            // Base, length and time are the user's; direction within maxTwist.
            ASSERT_EQ(st.base, poses[i].base);
            ASSERT_EQ(st.length, poses[i].length);
            ASSERT_NEAR(glm::length(st.direction), 1.0, 1e-12);
            const dvec3 user = glm::normalize(poses[i].direction);
            const double angle = std::acos(std::clamp(glm::dot(user, st.direction), -1.0, 1.0));
            ASSERT_NEAR(angle, st.adjustAngle, 1e-6);
            ASSERT_LE(st.adjustAngle, opt.maxTwist + 1e-12);
            maxAdjust = std::max(maxAdjust, st.adjustAngle);
            if (st.adjustAngle > 0) ++adjusted;
            if (before == 0) {
                ASSERT_EQ(quads.size(), quadsBefore);
                continue;
            }
            const Stick& s0 = filter.sticks()[before - 1];
            // One stick per cell: consecutive sticks in different cells (but
            // a restart's stick may share the new stick's cell).
            if (!restarted) {
                ASSERT_NE(f.cellOf(f.toIndex(s0.base)), f.cellOf(f.toIndex(st.base)));
            }
            const size_t made = quads.size() - quadsBefore;
            ASSERT_TRUE(made == 1 || made == 2);
            if (made == 2) ++split;
            for (size_t qi = quadsBefore; qi < quads.size(); ++qi) {
                const Quad& q = quads[qi];
                ASSERT_EQ(q.stick, uint32_t(before - 1));
                // Planar within the stated tolerance.
                if (!q.degenerate) {
                    double ext = 0;
                    for (uint32_t a = 0; a < q.cornerCount; ++a)
                        for (uint32_t b = 0; b < q.cornerCount; ++b)
                            ext = std::max(ext, glm::length(q.corners[a] - q.corners[b]));
                    for (uint32_t a = 0; a < q.cornerCount; ++a)
                        ASSERT_LE(std::abs(glm::dot(q.normal, q.corners[a]) - q.offset),
                                  opt.planarTolerance * (ext + 1.0));
                }
            }
            // The pieces join the two sticks: no gap in the strip.
            if (made == 1) {
                const Quad& q = quads.back();
                // Rule 3 (a'): the sticks cross only where the user's stick
                // turned from the last by more than maxTwist.
                if (sticksCrossForTest(q)) {
                    const double turn = std::acos(std::clamp(glm::dot(user, s0.direction), -1.0, 1.0));
                    if (opt.turnCrossingSticks) ASSERT_GT(turn, opt.maxTwist);
                    else turnable += turn <= opt.maxTwist;
                }
                ASSERT_EQ(q.corners[0], s0.base);
                ASSERT_EQ(q.corners[1], s0.tip());
                ASSERT_EQ(q.corners[2], st.tip());
                ASSERT_EQ(q.corners[3], st.base);
            } else {
                const Quad& a = quads[quads.size() - 2];
                const Quad& b = quads.back();
                ASSERT_EQ(a.corners[0], s0.base);
                ASSERT_EQ(a.corners[1], s0.tip());
                ASSERT_EQ(a.corners[2], st.tip());
                ASSERT_EQ(b.corners[0], s0.base);
                ASSERT_EQ(b.corners[1], st.tip());
                ASSERT_EQ(b.corners[2], st.base);
            }
        }
        quadsTotal += quads.size();
    }
    std::printf("kept %zu, dropped %zu (%zu retracing), adjusted %zu, split %zu, %zu restarts; rule 3 (a') off: %zu quads "
                "whose sticks cross by a turn within maxTwist\n",
                kept, dropped, retraced, adjusted, split, restarts, turnable);
    EXPECT_GT(turnable, 10u); // what rule 3 (a') turns, on the strokes it is off for
    EXPECT_GT(kept, 10000u);
    EXPECT_GT(dropped, 1000u);
    EXPECT_GT(adjusted, 100u); // case (b) exercised
    EXPECT_GT(split, 100u);    // case (c) exercised
    EXPECT_LE(maxAdjust, opt.maxTwist);
    EXPECT_GT(quadsTotal, kept - 60);
}

// Rule 2b: a saw going back over its cut (in its plane, or within the
// tolerance of it) makes no quad, so the strip never folds onto itself; going
// on past the cut, or back off the plane by more than the tolerance, cuts
// again; a negative tolerance keeps every stick (the old behaviour).
TEST(PathFilter, RetracingTheLastQuadsCutsNothingNew)
{
    const IndexFrame f = testFrame();
    // Index x: 2 -> 12 -> 5 -> 18 at y = 4.25, z = 6.5; blade along +y, 6 mm (12 voxels).
    auto stroke = [&](double offPlaneVoxels) {
        std::vector<Pose> poses;
        double t = 0.0;
        auto go = [&](double x0, double x1, double z) {
            const int n = int(std::abs(x1 - x0) * 4);
            for (int i = 0; i <= n; ++i) {
                Pose p;
                p.time = (t += 0.001);
                p.base = f.toWorld(dvec3(x0 + (x1 - x0) * i / n, 4.25, z));
                p.direction = dvec3(0, 1, 0);
                p.length = 6.0;
                poses.push_back(p);
            }
        };
        go(2.0, 12.0, 6.5);
        go(12.0, 5.0, 6.5 + offPlaneVoxels);
        go(5.0, 18.0, 6.5);
        return poses;
    };
    auto maxX = [&](const Quad& q) {
        double m = -1e300;
        for (uint32_t i = 0; i < q.cornerCount; ++i) m = std::max(m, f.toIndex(q.corners[i]).x);
        return m;
    };
    for (double off : {0.0, 0.2}) {
        const std::vector<Quad> quads = filterStroke(stroke(off), f);
        // Forward only: every quad starts where the cut so far ends.
        double reach = -1e300;
        for (const Quad& q : quads) {
            double lo = 1e300;
            for (uint32_t i = 0; i < q.cornerCount; ++i) lo = std::min(lo, f.toIndex(q.corners[i]).x);
            EXPECT_GE(lo, reach - 1e-9) << "off " << off << ": the strip folds back";
            reach = std::max(reach, maxX(q));
        }
        EXPECT_NEAR(reach, 18.0, 1e-9) << off;
        EXPECT_EQ(quads.size(), 16u) << off; // one stick per cell: x 2, 3, ..., 18
    }
    // 0.3 voxel off the plane (beyond the tolerance): the way back cuts.
    const std::vector<Quad> off = filterStroke(stroke(0.3), f);
    EXPECT_GT(off.size(), 16u);
    // Rule 2b off: the way back makes quads too.
    PathFilterOptions opt;
    opt.retraceTolerance = -1.0;
    EXPECT_GT(filterStroke(stroke(0.0), f, opt).size(), 16u);
}

// Rule 2b over the whole stroke: a saw going forth over 150 cells and back
// over all of them (more than the 64 quads the rule used to look at) and
// forth again makes the forward quads only; so does a stroke whose end comes
// back over its start.
TEST(PathFilter, RetracingAnyQuadOfTheStrokeCutsNothingNew)
{
    IndexFrame f;
    f.spacing = dvec3(1.0);
    f.dims = ivec3(200, 40, 40);
    auto go = [&](std::vector<Pose>& poses, double x0, double x1) {
        const int n = int(std::abs(x1 - x0) * 3);
        for (int i = 0; i <= n; ++i) {
            Pose p;
            p.time = 0.001 * double(poses.size());
            p.base = f.toWorld(dvec3(x0 + (x1 - x0) * i / n, 4.25, 20.5));
            p.direction = dvec3(0.1, 1, 0);
            p.length = 20.0;
            poses.push_back(p);
        }
    };
    std::vector<Pose> saw;
    go(saw, 10.0, 160.0);
    go(saw, 160.0, 10.0);
    go(saw, 10.0, 160.0);
    const std::vector<Quad> quads = filterStroke(saw, f);
    EXPECT_EQ(quads.size(), 150u) << "one stick per cell on the way forth, none back";
    PathFilterOptions off;
    off.retraceTolerance = -1.0;
    EXPECT_GT(filterStroke(saw, f, off).size(), 400u) << "without the rule the way back folds the strip";
    // A stroke whose last poses jump back over its first 13 cells, 97 quads later.
    std::vector<Pose> loop;
    go(loop, 10.0, 120.0);
    for (Pose p : std::vector<Pose>(loop.begin(), loop.begin() + 40)) {
        p.time = 0.001 * double(loop.size());
        loop.push_back(p); // the first 13 cells again, long after they were cut
    }
    EXPECT_EQ(filterStroke(loop, f).size(), 110u);
}

// Rule 2b, leaving a retrace: forth along an arc, back along it to its
// start and on past the start. Joining the first stick past the start to the
// last one kept (at the far end of the arc) would cut straight across the
// circle; the strip restarts at the last retracing stick instead, so every
// quad spans one step of the way the blade went. So does a straight saw going
// back and out past its start (its chord would lie on the cut, overlapping
// it); a saw that comes back to its end and goes on restarts nothing.
TEST(PathFilter, LeavingARetracedCurveCutsNoChord)
{
    IndexFrame f;
    f.spacing = dvec3(1.0);
    f.dims = ivec3(200, 200, 40);
    const dvec3 centre(100.3, 100.2, 5.5);
    const double radius = 60.0;
    auto arc = [&](std::vector<Pose>& poses, double a0, double a1) {
        const int n = int(std::abs(a1 - a0) * radius * 3); // a third of a voxel per pose
        for (int i = 0; i <= n; ++i) {
            const double a = a0 + (a1 - a0) * i / n;
            Pose p;
            p.time = 0.001 * double(poses.size());
            p.base = f.toWorld(centre + radius * dvec3(std::cos(a), std::sin(a), 0.0));
            p.direction = dvec3(0.1 * std::cos(a), 0.1 * std::sin(a), 1.0);
            p.length = 30.0;
            poses.push_back(p);
        }
    };
    auto longestStep = [&](const std::vector<Quad>& quads) {
        double longest = 0.0;
        for (const Quad& q : quads) // corners {base0, tip0, tip1, base1} or a triangle of them
            for (uint32_t i = 0; i < q.cornerCount; ++i)
                for (uint32_t j = 0; j < i; ++j) {
                    const dvec3 a = f.toIndex(q.corners[i]), b = f.toIndex(q.corners[j]);
                    if (std::abs(a.z - b.z) < 1.0) longest = std::max(longest, glm::length(a - b)); // base or tip edges
                }
        return longest;
    };
    std::vector<Pose> out;
    arc(out, 0.0, M_PI);
    arc(out, M_PI, 0.0);
    arc(out, 0.0, -0.3);
    PathFilter filter(f);
    std::vector<Quad> quads;
    for (const Pose& p : out) filter.push(p, quads);
    EXPECT_EQ(filter.restarts(), 1u);
    EXPECT_LT(longestStep(quads), 3.0) << "a quad spans more than a step of the blade: a chord";
    // About one quad per cell along the arc (pi * 60 + 18 voxels), none back.
    EXPECT_GT(quads.size(), 150u);
    EXPECT_LT(quads.size(), 300u); // the way back would double it

    // Forth, back to the middle and forth past the end: the chord from the
    // end lies on the cut; no restart.
    std::vector<Pose> saw;
    arc(saw, 0.0, M_PI);
    arc(saw, M_PI, 0.5 * M_PI);
    arc(saw, 0.5 * M_PI, M_PI + 0.3);
    PathFilter again(f);
    quads.clear();
    for (const Pose& p : saw) again.push(p, quads);
    EXPECT_EQ(again.restarts(), 0u);
    EXPECT_LT(longestStep(quads), 3.0);

    // A straight saw back and out past its start: the chord lies on the cut.
    std::vector<Pose> line;
    for (double x : {10.0, 150.0, 5.0}) {
        const double x0 = line.empty() ? x : f.toIndex(line.back().base).x;
        const int n = line.empty() ? 0 : int(std::abs(x - x0) / 0.3); // a pose lands 0.2 voxel outside the start
        for (int i = line.empty() ? 0 : 1; i <= n; ++i) {
            Pose p;
            p.time = 0.001 * double(line.size());
            p.base = f.toWorld(dvec3(n ? x0 + (x - x0) * i / n : x, 30.25, 5.5));
            p.direction = dvec3(0.1, 0.2, 1.0);
            p.length = 30.0;
            line.push_back(p);
        }
    }
    PathFilter straight(f);
    quads.clear();
    for (const Pose& p : line) straight.push(p, quads);
    EXPECT_EQ(straight.restarts(), 1u);
    EXPECT_LT(longestStep(quads), 3.0) << "no chord from x = 150 to 4.7";
    // The restart starts inside the old cut (at x = 10, not at the last pose
    // near it, 9.80): the base lines of the quads cover x = 5..150 with no gap.
    std::vector<std::pair<double, double>> spans;
    for (const Quad& q : quads) {
        double lo = 1e300, hi = -1e300;
        for (uint32_t i = 0; i < q.cornerCount; ++i) {
            const dvec3 c = f.toIndex(q.corners[i]);
            if (std::abs(c.z - 5.5) > 1e-9) continue; // a tip
            lo = std::min(lo, c.x);
            hi = std::max(hi, c.x);
        }
        if (lo <= hi) spans.push_back({lo, hi});
    }
    std::sort(spans.begin(), spans.end());
    double reach = spans.front().second;
    for (const auto& [lo, hi] : spans) {
        EXPECT_LE(lo, reach) << "a gap in the cut from x = " << reach << " to " << lo;
        reach = std::max(reach, hi);
    }
    EXPECT_NEAR(reach, 150.0, 1e-9);
    EXPECT_LT(spans.front().first, 6.0); // the last kept stick (one per cell)
}

// Rule 2's exception and rule 2b coming into the cut: the cut reaches where
// the blade stopped. A stroke whose last poses share the last kept stick's
// cell ends at its last pose (not up to a cell short), unless the blade only
// pivoted there; a second stroke coming back to the first one's end keeps
// its step into the first cut, so the two strokes' base lines cover the
// whole way with no gap (before: a gap of 0.6 voxel).
TEST(PathFilter, TheCutReachesWhereTheBladeStopped)
{
    IndexFrame f;
    f.spacing = dvec3(1.0);
    f.dims = ivec3(200, 60, 40);
    auto line = [&](double x0, double x1, int n) {
        std::vector<Pose> poses;
        for (int i = 0; i <= n; ++i) {
            Pose p;
            p.time = 0.001 * i;
            p.base = f.toWorld(dvec3(x0 + (x1 - x0) * i / n, 10.25, 5.5));
            p.direction = dvec3(0.0, 0.2, 1.0);
            p.length = 20.0;
            poses.push_back(p);
        }
        return poses;
    };
    auto baseSpan = [&](const std::vector<Quad>& quads) {
        double lo = 1e300, hi = -1e300;
        for (const Quad& q : quads)
            for (uint32_t c = 0; c < q.cornerCount; ++c) {
                const dvec3 x = f.toIndex(q.corners[c]);
                if (std::abs(x.z - 5.5) > 1e-9) continue; // a tip
                lo = std::min(lo, x.x);
                hi = std::max(hi, x.x);
            }
        return std::make_pair(lo, hi);
    };
    // 20.5 to 60.2 a third of a voxel apart, then the blade stops at 60.9: the
    // last pose shares the last kept stick's cell (60) and lies 0.7 voxel on.
    std::vector<Pose> a = line(20.5, 60.2, 119);
    a.push_back(a.back());
    a.back().time += 0.001;
    a.back().base = f.toWorld(dvec3(60.9, 10.25, 5.5));
    std::vector<Stick> sticks;
    const std::vector<Quad> quads = filterStroke(a, f, {}, &sticks);
    EXPECT_DOUBLE_EQ(baseSpan(quads).second, 60.9) << "the cut ends at the last pose";
    EXPECT_DOUBLE_EQ(f.toIndex(sticks.back().base).x, 60.9);
    PathFilter filter(f);
    const std::vector<Quad> viaEnd = filter.pushStroke(a);
    EXPECT_EQ(viaEnd.size(), quads.size()) << "pushStroke and endStroke place the last pose too";
    // A blade that only pivots on its last stick's base adds nothing.
    std::vector<Pose> pivot = line(20.5, 60.2, 119);
    pivot.push_back(pivot.back());
    pivot.back().time += 0.001;
    pivot.back().direction = dvec3(0.3, 0.2, 1.0);
    const std::vector<Quad> pivoted = filterStroke(pivot, f);
    EXPECT_DOUBLE_EQ(baseSpan(pivoted).second, 60.2);
    EXPECT_EQ(pivoted.size(), quads.size() - 1);

    // Two strokes meeting: the first 20.5 -> 60.9, the second from 100.2 to
    // the first one's end, and to 0.6 voxel inside the first cut.
    for (const double end : {60.9, 60.3}) {
        for (const Quad& q : quads) filter.addEarlierQuad(q);
        const std::vector<Quad> b = filter.pushStroke(line(100.2, end, int(std::round((100.2 - end) / 0.33))));
        const auto span = baseSpan(b);
        EXPECT_LE(span.first, 60.9 + 1e-9) << "no gap between the strokes, ending at " << end;
        EXPECT_GE(span.first, end - 1.0) << end;
        filter.clearEarlierQuads();
    }
}

// Rule 2b across strokes: quads of earlier strokes handed in with
// addEarlierQuad are retraced like the stroke's own. The same stroke again
// adds nothing; a stroke that goes back into the cut and on past its end adds
// only the part past the end (restarting at the last pose on the cut, so no
// quad spans the old cut); the stroke's own quads are forgotten at endStroke,
// the earlier ones only by clearEarlierQuads; both only between strokes.
TEST(PathFilter, EarlierStrokesAreRetracedToo)
{
    IndexFrame f;
    f.spacing = dvec3(1.0);
    f.dims = ivec3(200, 60, 40);
    auto line = [&](double x0, double x1, double jitter, uint32_t seed) {
        std::mt19937_64 rng(seed);
        std::uniform_real_distribution<double> j(-jitter, jitter);
        std::vector<Pose> poses;
        const int n = int(std::abs(x1 - x0) * 3);
        for (int i = 0; i <= n; ++i) {
            Pose p;
            p.time = 0.001 * i;
            p.base = f.toWorld(dvec3(x0 + (x1 - x0) * i / n + j(rng), 10.25 + j(rng), 5.5 + j(rng)));
            p.direction = dvec3(0.1 + 0.01 * j(rng), 1.0, 0.2);
            p.length = 30.0;
            poses.push_back(p);
        }
        return poses;
    };
    auto run = [&](PathFilter& filter, const std::vector<Pose>& poses) { return filter.pushStroke(poses); };
    for (double jitter : {0.0, 0.05}) {
        PathFilter filter(f);
        const std::vector<Quad> first = run(filter, line(20.0, 120.0, jitter, 1));
        ASSERT_GT(first.size(), 90u);
        for (const Quad& q : first) filter.addEarlierQuad(q);
        EXPECT_EQ(filter.earlierQuadCount(), first.size());
        EXPECT_TRUE(run(filter, line(20.0, 120.0, jitter, 2)).empty()) << "the same stroke again, jitter " << jitter;
        EXPECT_TRUE(run(filter, line(120.0, 20.0, jitter, 3)).empty()) << "back over it, jitter " << jitter;
        // On past the end: quads from x ~ 120 only.
        const std::vector<Quad> more = run(filter, line(20.0, 160.0, jitter, 4));
        EXPECT_GE(more.size(), 38u);
        EXPECT_LE(more.size(), 46u);
        for (const Quad& q : more)
            for (uint32_t c = 0; c < q.cornerCount; ++c) EXPECT_GT(f.toIndex(q.corners[c]).x, 118.0) << jitter;
        EXPECT_EQ(filter.restarts(), 1u) << jitter;
        // Without the earlier quads the same strokes cut again.
        filter.clearEarlierQuads();
        EXPECT_EQ(filter.earlierQuadCount(), 0u);
        EXPECT_GT(run(filter, line(20.0, 120.0, jitter, 2)).size(), 90u);
    }
    // Only between strokes.
    PathFilter filter(f);
    std::vector<Quad> quads;
    const std::vector<Pose> poses = line(20.0, 30.0, 0.0, 1);
    filter.push(poses[0], quads);
    Quad q = makeQuad(std::array<dvec3, 4>{dvec3(0, 0, 0), dvec3(0, 1, 0), dvec3(1, 1, 0), dvec3(1, 0, 0)}.data(), 4, 0);
    EXPECT_THROW(filter.addEarlierQuad(q), std::logic_error);
    EXPECT_THROW(filter.clearEarlierQuads(), std::logic_error);
    EXPECT_TRUE(filter.endStroke().empty()); // one pose: no last quad
    EXPECT_NO_THROW(filter.addEarlierQuad(q));
    // pushStroke ends the stroke even when a pose is bad.
    std::vector<Pose> bad = line(20.0, 30.0, 0.0, 1);
    bad[5].length = -1.0;
    EXPECT_THROW(filter.pushStroke(bad), mtcut::InputError);
    EXPECT_NO_THROW(filter.addEarlierQuad(q));
}

TEST(PathFilter, BadPosesThrowAndLeaveStateUnchanged)
{
    const IndexFrame f = testFrame();
    PathFilter filter(f);
    std::vector<Quad> quads;
    Pose ok;
    ok.time = 1.0;
    ok.base = f.toWorld(dvec3(10, 10, 5));
    ok.direction = dvec3(0, 0, -3); // non-unit: normalised
    ok.length = 10;
    ASSERT_TRUE(filter.push(ok, quads));
    EXPECT_EQ(filter.sticks().back().direction, dvec3(0, 0, -1));

    auto expectThrow = [&](Pose p, const char* what) {
        const size_t n = filter.sticks().size();
        try {
            filter.push(p, quads);
            ADD_FAILURE() << "no exception for " << what;
        } catch (const mtcut::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
        }
        EXPECT_EQ(filter.sticks().size(), n);
    };
    Pose p = ok;
    p.base.x = std::nan("");
    expectThrow(p, "base");
    p = ok;
    p.direction = dvec3(0.0);
    expectThrow(p, "direction");
    p = ok;
    p.direction.y = INFINITY;
    expectThrow(p, "direction");
    p = ok;
    p.length = 0;
    expectThrow(p, "length");
    p = ok;
    p.length = -2;
    expectThrow(p, "length");
    p = ok;
    p.time = std::nan("");
    expectThrow(p, "time");
    // Beyond kMaxPoseMm (libFuzzer: a 1.8e307 mm blade made the voxeliser
    // convert NaN to int); the limit itself is accepted.
    p = ok;
    p.length = 1.8e307;
    expectThrow(p, "blade length is beyond 1e6 mm");
    p = ok;
    p.base.z = -1.0000001e6;
    expectThrow(p, "base point (x,y,z) is beyond 1e6 mm");
    p = ok;
    p.time = 1.5;
    p.length = mtcut::cutter::kMaxPoseMm;
    EXPECT_NO_THROW(filter.push(p, quads));
    p = ok;
    p.time = 0.5;
    expectThrow(p, "time goes backwards");
    // Outside the volume: kept, no crash, nothing cut beyond the ring of
    // cells around it (where the isosurface closes).
    p = ok;
    p.time = 2.0;
    p.base = dvec3(1e6, -1e6, 1e6);
    EXPECT_TRUE(filter.push(p, quads));
    for (const Quad& q : quads) {
        std::vector<ivec3> cells;
        voxelizeQuad(q, 0.5, f, cells);
        const ivec3 n = f.cellCount();
        for (const ivec3& c : cells) EXPECT_TRUE(c.x >= -1 && c.x <= n.x && c.y >= -1 && c.y <= n.y);
    }
}

TEST(PathFilter, NoGapsAlongTheSweptSurface)
{
    // Every point of the swept surface (and of the kerf slab) lies in a cut
    // cell, so any segment crossing the surface passes through a cut cell.
    const IndexFrame f = testFrame();
    std::mt19937_64 rng(31337);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    for (double kerf : {0.0, 0.8}) {
        size_t checked = 0;
        for (int s = 0; s < 20; ++s) {
            const std::vector<Pose> poses = twistingStroke(rng, f, 300, 0.05);
            const std::vector<Quad> quads = filterStroke(poses, f);
            CellSet cut;
            for (const Quad& q : quads) {
                std::vector<ivec3> cells;
                voxelizeQuad(q, kerf, f, cells);
                for (const ivec3& c : cells) cut.insert(key(c));
            }
            const ivec3 n = f.cellCount();
            for (const Quad& q : quads) {
                for (int k = 0; k < 20; ++k) {
                    // Random point of the quad (a random corner triangle), plus a
                    // random offset within the kerf along the normal.
                    const uint32_t a = 0, b = 1 + uint32_t(uni(rng) * (q.cornerCount - 2)), c = b + 1;
                    double w0 = uni(rng), w1 = uni(rng);
                    if (w0 + w1 > 1) {
                        w0 = 1 - w0;
                        w1 = 1 - w1;
                    }
                    dvec3 x = q.corners[a] + w0 * (q.corners[b] - q.corners[a]) +
                              w1 * (q.corners[c] - q.corners[a]);
                    x += (uni(rng) - 0.5) * kerf * q.normal;
                    const ivec3 cell = f.cellOf(f.toIndex(x));
                    if (glm::any(glm::lessThan(cell, ivec3(0))) || glm::any(glm::greaterThanEqual(cell, n)))
                        continue;
                    ASSERT_TRUE(cut.count(key(cell)));
                    ++checked;
                }
            }
        }
        EXPECT_GT(checked, 5000u);
    }
}

// Rule 3 (a'): a blade sliding along its own line while it turns a little
// about a point of itself gives two sticks that cross. Their quad's outline
// crosses itself, and its hull has the sticks as diagonals, so it would join
// neither the quad before nor the one after (2 mm head, kerf 0, sawing along
// the blade, seeds 75101 and 75107 stopped: "coplanar overlapping quads").
// The new stick is turned about its base to the last one's direction when
// that turn is within maxTwist; a wider turn (a blade pivoting in its plane)
// is kept as the user gave it, and so is every turn with the rule off.
TEST(PathFilter, ASawSlidingWithCrossingSticksMakesATrapezoid)
{
    const IndexFrame f = testFrame();
    for (double turn : {0.01, 0.03, 0.1}) {
        for (bool rule : {true, false}) {
            SCOPED_TRACE("turn " + std::to_string(turn) + (rule ? ", rule on" : ", rule off"));
            Pose p0, p1;
            p0.base = dvec3(-8.0, 5.0, -30.0);
            p0.direction = dvec3(1.0, 0.0, 0.0);
            p0.length = 10.0;
            p1 = p0;
            p1.time = 0.001;
            p1.base = dvec3(-6.5, 5.01, -30.0); // 1.5 mm along the blade, 0.01 mm across it
            p1.direction = dvec3(std::cos(turn), -std::sin(turn), 0.0);
            PathFilterOptions opt;
            opt.turnCrossingSticks = rule;
            opt.slideTolerance = -1.0; // rule 2c would hold p1 back (0.2 voxel off p0's line)
            PathFilter filter(f, opt);
            std::vector<Quad> quads;
            ASSERT_TRUE(filter.push(p0, quads));
            ASSERT_TRUE(filter.push(p1, quads));
            ASSERT_EQ(quads.size(), 1u);
            const Quad& q = quads[0];
            ASSERT_FALSE(q.degenerate);
            const Stick& st = filter.sticks().back();
            EXPECT_EQ(st.base, p1.base);
            EXPECT_EQ(st.length, p1.length);
            const Quad user = [&] {
                const dvec3 c[4] = {p0.base, p0.base + p0.length * p0.direction, p1.base + p1.length * p1.direction, p1.base};
                return makeQuad(c, 4, 0);
            }();
            ASSERT_TRUE(sticksCrossForTest(user)) << "the poses' sticks do not cross";
            const bool turned = rule && turn <= opt.maxTwist;
            if (turned) {
                EXPECT_EQ(st.direction, p0.direction);
                EXPECT_NEAR(st.adjustAngle, turn, 1e-12);
                EXPECT_FALSE(sticksCrossForTest(q));
                // A trapezoid: both sticks are edges of its hull.
                const std::vector<int> hull = convexHullOrder(q.corners.data(), 4, q.normal);
                ASSERT_EQ(hull.size(), 4u);
                auto edge = [&](int a, int b) {
                    for (size_t i = 0; i < 4; ++i) {
                        const int u = hull[i], v = hull[(i + 1) % 4];
                        if ((u == a && v == b) || (u == b && v == a)) return true;
                    }
                    return false;
                };
                EXPECT_TRUE(edge(0, 1) && edge(2, 3));
            } else {
                EXPECT_NEAR(glm::dot(st.direction, p1.direction), 1.0, 1e-15);
                EXPECT_EQ(st.adjustAngle, 0.0);
                EXPECT_TRUE(sticksCrossForTest(q));
            }
            EXPECT_EQ(q.corners[2], st.tip());
        }
    }
}

// The retrace tolerance is the user's trade (mtcut cut --retrace): a pose
// dropped for going back over the cut lies within it of the swept surface,
// whatever it is, and a saw worked back and forth, whose passes each deepen
// the cut a little and would lay a quad over the whole blade, makes far
// fewer quads with a wider one (benchmarks/RESULTS.md, "The retrace
// tolerance"). Options out of range are refused when the filter is made.
TEST(PathFilter, AWiderRetraceToleranceBoundsTheLagAndSawsWithFewerQuads)
{
    IndexFrame head;
    head.dims = ivec3(128, 128, 128);
    head.spacing = dvec3(2.0);
    const std::vector<glm::vec3> bone{glm::vec3(120.0f, 130.0f, 110.0f), glm::vec3(100.0f, 90.0f, 140.0f)};
    size_t quadsAt[2] = {0, 0}, droppedNear = 0;
    for (uint32_t seed = 100; seed < 112; ++seed) {
        for (const std::vector<Pose>& poses : makeSawingStrokes(bone, seed, 2, SawMotion::Both)) {
            for (int wide = 0; wide < 2; ++wide) {
                PathFilterOptions opt;
                opt.retraceTolerance = wide ? 1.0 : 0.25;
                opt.slideTolerance = -1.0; // rule 2b's trade alone (2c: ASlideAlongTheBlade...)
                PathFilter filter(head, opt);
                std::vector<Quad> quads;
                for (size_t i = 0; i < poses.size(); ++i) {
                    const size_t before = quads.size();
                    if (filter.push(poses[i], quads)) continue;
                    ASSERT_EQ(quads.size(), before);
                    if (head.cellOf(head.toIndex(poses[i].base)) == head.cellOf(head.toIndex(filter.sticks().back().base)))
                        continue; // rule 2: one stick a cell
                    ++droppedNear;
                    ASSERT_TRUE(nearOneQuad(head, quads, poses[i], opt.retraceTolerance))
                        << "seed " << seed << " tolerance " << opt.retraceTolerance << " pose " << i;
                }
                for (const Quad& q : filter.endStroke()) quads.push_back(q);
                quadsAt[wide] += quads.size();
            }
        }
    }
    EXPECT_GT(droppedNear, 4000u);
    EXPECT_LT(quadsAt[1] * 3, quadsAt[0]) << quadsAt[1] << " quads with 1 voxel, " << quadsAt[0] << " with 0.25";

    for (const double bad : {std::nan(""), 4.5, std::numeric_limits<double>::infinity()}) {
        PathFilterOptions opt;
        opt.retraceTolerance = bad;
        EXPECT_THROW(PathFilter(head, opt), std::invalid_argument) << bad;
    }
    for (const double good : {-1.0, 0.0, kMaxRetraceTolerance}) {
        PathFilterOptions opt;
        opt.retraceTolerance = good;
        EXPECT_NO_THROW(PathFilter(head, opt)) << good;
    }
    PathFilterOptions twist;
    twist.maxTwist = std::nan("");
    EXPECT_THROW(PathFilter(head, twist), std::invalid_argument);
}

TEST(Generators, LeFortAndRandomStrokesAreValidPaths)
{
    IndexFrame head;
    head.dims = ivec3(512, 512, 245);
    head.spacing = dvec3(0.5, 0.5, 1.0);
    const std::vector<Pose> lefort = makeLeFortStroke(head);
    ASSERT_GT(lefort.size(), 1000u);
    std::vector<Stick> sticks;
    const std::vector<Quad> quads = filterStroke(lefort, head, {}, &sticks);
    EXPECT_GT(quads.size(), 100u);
    // Horizontal cut on the face side (-y half of the box).
    const double midY = head.toWorld(dvec3(head.dims) * 0.5).y;
    for (const Stick& s : sticks) {
        EXPECT_LT(s.base.y, midY);
        EXPECT_NEAR(s.direction.z, 0.0, 0.05);
    }
    const auto strokes = makeRandomStrokes(head, 7, 5, 200);
    ASSERT_EQ(strokes.size(), 5u);
    for (const auto& st : strokes) EXPECT_NO_THROW(filterStroke(st, head));
}

// The stroke fitted to a bone box (mtcut cut's default on a head scan): the
// base runs straight along x from 10 mm left of the box to 10 mm right of
// it, 10 mm in front of it, at 42 % of its height; every blade points
// posteriorly, 0.1 rad down, its tip at 52 % of the box depth.
TEST(Generators, FittedLeFortStrokeCrossesTheWholeBoxToItsReach)
{
    const std::vector<glm::vec3> bone{{186.0f, 145.0f, 1000.0f}, {322.0f, 342.0f, 1244.0f}, {250.0f, 200.0f, 1100.0f}};
    const LeFortOptions o = leFortOptionsFittedTo(bone);
    EXPECT_EQ(o.path, LeFortOptions::Path::Across);
    IndexFrame head;
    head.dims = ivec3(512, 512, 245);
    head.origin = dvec3(0.0, 0.0, 1000.0);
    const std::vector<Pose> poses = makeLeFortStroke(head, o);
    ASSERT_EQ(poses.size(), 15600u); // 156 mm at 10 mm/s, 1 kHz
    EXPECT_DOUBLE_EQ(poses.front().base.x, 176.0);
    EXPECT_DOUBLE_EQ(poses.back().base.x, 332.0);
    const double z = 1000.0 + 0.42 * 244.0, reachY = 145.0 + 0.52 * 197.0;
    for (size_t i = 0; i < poses.size(); ++i) {
        const Pose& p = poses[i];
        ASSERT_EQ(p.base.y, 135.0) << i;
        ASSERT_EQ(p.base.z, z) << i;
        ASSERT_NEAR(p.direction.y, std::cos(0.1), 1e-15) << i;
        ASSERT_NEAR(p.direction.z, -std::sin(0.1), 1e-15) << i;
        ASSERT_EQ(p.direction.x, 0.0) << i;
        ASSERT_NEAR((p.base + p.length * p.direction).y, reachY, 1e-9) << i;
        if (i > 0) {
            ASSERT_GT(p.base.x, poses[i - 1].base.x) << i;
        }
        ASSERT_DOUBLE_EQ(p.time, double(i) / 1000.0) << i;
    }
    EXPECT_NO_THROW(filterStroke(poses, head));
    // No bone, no box: the phantom's half ellipse, as before.
    EXPECT_EQ(leFortOptionsFittedTo({}).path, LeFortOptions::Path::HalfEllipse);
}

// A saw worked back and forth (benchmarks' `bench_strokes --saw`): without
// tremor every blade lies in one plane, the blade swings exactly the
// amplitude each way and advances the feed a pose, and the middle pose's
// blade is centred on the given point; with tremor the poses stay within a
// few tremors of that and are a function of the seed alone.
TEST(Generators, SawingStrokeWorksBackAndForthInOnePlane)
{
    IndexFrame head;
    head.dims = ivec3(128, 128, 128);
    head.spacing = dvec3(2.0);
    const dvec3 centre(120.0, 130.0, 110.0);
    for (bool slide : {false, true}) {
        SCOPED_TRACE(slide ? "slide" : "across");
        SawingOptions o;
        o.slide = slide;
        o.poses = 400;
        o.amplitudeMm = 4.0;
        o.feedMm = 0.03;
        o.posesPerCycle = 16.0;
        o.bladeLength = 20.0;
        o.tremorMm = o.tremorRad = 0.0;
        const std::vector<Pose> poses = makeSawingStroke(centre, 5, o);
        ASSERT_EQ(poses.size(), 400u);
        const dvec3 d = poses[0].direction;
        // The first step, less its part along the blade, is across it: the
        // swing (across) or the feed (slide).
        const dvec3 step = poses[1].base - poses[0].base;
        const dvec3 off = glm::normalize(step - glm::dot(step, d) * d);
        const dvec3 swing = slide ? d : off, feed = slide ? off : d;
        const dvec3 n = glm::cross(d, off); // the cut's plane
        double swingLo = 1e300, swingHi = -1e300;
        for (size_t i = 0; i < poses.size(); ++i) {
            const Pose& p = poses[i];
            ASSERT_EQ(p.direction, d) << i;
            ASSERT_EQ(p.length, 20.0) << i;
            ASSERT_NEAR(glm::dot(n, p.base - poses[0].base), 0.0, 1e-9) << i;
            ASSERT_NEAR(glm::dot(n, p.base + p.length * p.direction - poses[0].base), 0.0, 1e-9) << i;
            if (i > 0) {
                ASSERT_GT(p.time, poses[i - 1].time) << i;
            }
            // Less the feed, the base only swings.
            const dvec3 moved = p.base - 0.03 * double(i) * feed - poses[0].base;
            ASSERT_NEAR(glm::dot(moved, feed), 0.0, 1e-9) << i;
            swingLo = std::min(swingLo, glm::dot(moved, swing));
            swingHi = std::max(swingHi, glm::dot(moved, swing));
        }
        EXPECT_NEAR(swingHi - swingLo, 8.0, 1e-9);
        // The middle pose (a whole number of half cycles in): the blade's middle on the centre.
        const Pose& mid = poses[200];
        EXPECT_NEAR(glm::length(mid.base + 0.5 * mid.length * mid.direction - centre), 0.0, 1e-9);
        EXPECT_NO_THROW(filterStroke(poses, head));
    }
    // With tremor: the same seed, the same poses; another seed, others.
    SawingOptions o;
    const std::vector<Pose> a = makeSawingStroke(centre, 9, o), b = makeSawingStroke(centre, 9, o),
                            c = makeSawingStroke(centre, 10, o);
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a[i].base, b[i].base) << i;
        ASSERT_EQ(a[i].direction, b[i].direction) << i;
    }
    EXPECT_NE(a[5].base, c[5].base);
    double worst = 0.0;
    for (const Pose& p : a) {
        // Distance of the blade's middle from the line the centre feeds along, less the swing.
        const dvec3 m = p.base + 0.5 * p.length * p.direction - centre;
        worst = std::max(worst, glm::length(m));
    }
    // Amplitude 4 mm, feed 0.02 mm x 200 poses each way, tremor 0.05 mm and 0.004 rad over half the blade.
    EXPECT_LT(worst, std::hypot(4.0, 4.0) + 10 * 0.05 + 7.5 * 10 * 0.004);
    EXPECT_NO_THROW(filterStroke(a, head));

    // A seed's worth (the sweeps' and tests'): the motion asked for, through
    // the given points; none to go through is an error.
    const std::vector<glm::vec3> bone{glm::vec3(centre), glm::vec3(centre + dvec3(5.0))};
    for (SawMotion m : {SawMotion::Across, SawMotion::Slide, SawMotion::Both}) {
        const uint32_t seed = 41;
        const auto strokes = makeSawingStrokes(bone, seed, 4, m, 0.0);
        ASSERT_EQ(strokes.size(), 4u);
        for (size_t k = 0; k < strokes.size(); ++k) {
            const std::vector<Pose>& p = strokes[k];
            ASSERT_EQ(p.size(), 400u);
            // Without tremor the first step is the swing's: along the blade when it slides.
            const dvec3 step = p[1].base - p[0].base;
            const bool slides = std::abs(glm::dot(step, p[0].direction)) > 0.5 * glm::length(step);
            EXPECT_EQ(slides, m == SawMotion::Slide || (m == SawMotion::Both && (seed + k) % 2 == 1)) << k;
            // The middle pose's blade is centred on one of the points, but for the swing (at most 6 mm).
            const dvec3 mid = p[200].base + 0.5 * p[200].length * p[200].direction;
            EXPECT_LE(std::min(glm::length(mid - dvec3(bone[0])), glm::length(mid - dvec3(bone[1]))), 6.0 + 1e-9) << k;
        }
    }
    EXPECT_THROW(makeSawingStrokes({}, 1, 4, SawMotion::Both), std::invalid_argument);
}

// Rule 2c: a blade slid along its own line (a reciprocating saw) sweeps a
// line; each pose whose base moved to a new cell made a quad before, a
// sliver as wide as the tremor, and on the sliding-saw sweeps those were
// 80-97 % of the quads and the source of their crossing sticks and folds.
// Now the slide is held back and its last pose placed when the blade leaves
// the line: one sliver for the run, and the swing starts where the blade
// was. A slide to the end of a stroke makes one quad; a drift wider than the
// tolerance is kept pose by pose; off (negative) it is as before.
TEST(PathFilter, ASlideAlongTheBladeIsHeldBackAndPlacedWhenTheBladeLeavesItsLine)
{
    const IndexFrame f = testFrame(); // 0.5 mm voxels across x and y
    auto stroke = [](double drift) {
        std::vector<Pose> poses;
        for (int i = 0; i < 10; ++i) { // slides 0.9 mm a pose along x, the tremor 0.02 mm in y
            Pose p;
            p.time = 0.001 * i;
            p.base = dvec3(-8.0 + 0.9 * i, 5.0 + (i % 2 ? 0.02 : 0.0) + drift * i, -30.0);
            p.direction = dvec3(1.0, 0.0, 0.0);
            p.length = 6.0;
            poses.push_back(p);
        }
        for (int i = 1; i <= 5; ++i) { // then swings across: 1.5 mm a pose in y
            Pose p = poses[9];
            p.time += 0.001 * i;
            p.base.y += 1.5 * i;
            poses.push_back(p);
        }
        return poses;
    };
    for (double tol : {0.25, -1.0}) {
        SCOPED_TRACE("slide tolerance " + std::to_string(tol));
        PathFilterOptions opt;
        opt.slideTolerance = tol;
        const std::vector<Pose> poses = stroke(0.0);
        PathFilter filter(f, opt);
        std::vector<Quad> quads;
        std::vector<bool> kept;
        for (const Pose& p : poses) kept.push_back(filter.push(p, quads));
        const std::vector<Stick> sticks = filter.sticks();
        for (const Quad& q : filter.endStroke()) quads.push_back(q);
        if (tol < 0) {
            EXPECT_EQ(quads.size(), 14u); // one a pose
            EXPECT_EQ(sticks.size(), 15u);
            continue;
        }
        for (size_t i = 1; i < 10; ++i) EXPECT_FALSE(kept[i]) << "pose " << i << " slides";
        for (size_t i = 10; i < 15; ++i) EXPECT_TRUE(kept[i]) << "pose " << i << " swings";
        ASSERT_EQ(sticks.size(), 7u); // the first, the slide's last, the five swings
        EXPECT_EQ(sticks[0].base, poses[0].base);
        EXPECT_EQ(sticks[1].base, poses[9].base);
        EXPECT_EQ(sticks[1].poseIndex, 9u);
        for (size_t k = 2; k < 7; ++k) EXPECT_EQ(sticks[k].base, poses[8 + k].base);
        ASSERT_EQ(quads.size(), 6u);
        // The sliver: from the first stick to the slide's last, at most the tremor wide.
        const Quad& sliver = quads[0];
        EXPECT_EQ(sliver.corners[0], poses[0].base);
        EXPECT_EQ(sliver.corners[3], poses[9].base);
        // The swing's first quad starts where the blade was.
        EXPECT_EQ(quads[1].corners[0], poses[9].base);
        EXPECT_EQ(quads[1].corners[3], poses[10].base);
    }
    {   // A slide to the stroke's end: one quad, to the last pose.
        std::vector<Pose> poses = stroke(0.0);
        poses.resize(10);
        PathFilter filter(f);
        const std::vector<Quad> quads = filter.pushStroke(poses);
        ASSERT_EQ(quads.size(), 1u);
        EXPECT_EQ(quads[0].corners[0], poses[0].base);
        EXPECT_EQ(quads[0].corners[3], poses[9].base);
    }
    {   // Drifting 0.15 mm (0.3 voxel) off the line a pose: not a slide.
        std::vector<Pose> poses = stroke(0.15);
        poses.resize(10);
        PathFilter filter(f);
        EXPECT_EQ(filter.pushStroke(poses).size(), 9u);
    }
    for (double bad : {std::nan(""), kMaxRetraceTolerance + 0.5}) {
        PathFilterOptions opt;
        opt.slideTolerance = bad;
        EXPECT_THROW(PathFilter(f, opt), std::invalid_argument);
    }
}

// A slide held back (rule 2c) that comes back into the last kept stick's
// cell (rule 2) is given up: the blade is back where the cut was, and all it
// slid along lies within the tolerance of that stick's line. The next quad
// starts from the kept stick, not from the far end of the slide, whether the
// blade then swings off its line or the stroke ends there.
TEST(PathFilter, ASlideThatComesBackIntoTheKeptSticksCellIsGivenUp)
{
    const IndexFrame f = testFrame(); // 0.5 mm voxels across x and y
    std::vector<Pose> poses;
    for (const double x : {-8.0, -7.1, -6.2, -7.9}) { // out 1.8 mm along the blade, back to 0.1 mm of the start
        Pose p;
        p.time = 0.001 * double(poses.size());
        p.base = dvec3(x, 5.0, -30.0);
        p.direction = dvec3(1.0, 0.0, 0.0);
        p.length = 6.0;
        poses.push_back(p);
    }
    ASSERT_EQ(f.cellOf(f.toIndex(poses[3].base)), f.cellOf(f.toIndex(poses[0].base)));
    std::vector<Pose> swing = poses;
    for (int i = 1; i <= 3; ++i) { // then across: 1.5 mm a pose in y
        Pose p = poses[3];
        p.time += 0.001 * i;
        p.base.y += 1.5 * i;
        swing.push_back(p);
    }
    {   // The swing's first quad joins the kept stick to the first pose off the line.
        PathFilter filter(f);
        std::vector<Quad> quads;
        std::vector<bool> kept;
        for (const Pose& p : swing) kept.push_back(filter.push(p, quads));
        for (size_t i = 1; i < 4; ++i) EXPECT_FALSE(kept[i]) << "pose " << i;
        for (size_t i = 4; i < swing.size(); ++i) EXPECT_TRUE(kept[i]) << "pose " << i;
        for (const Quad& q : filter.endStroke()) quads.push_back(q);
        ASSERT_EQ(quads.size(), 3u);
        EXPECT_EQ(quads[0].corners[0], swing[0].base);
        EXPECT_EQ(quads[0].corners[3], swing[4].base);
        for (const Quad& q : quads)
            for (uint32_t c = 0; c < q.cornerCount; ++c) EXPECT_NE(q.corners[c], swing[2].base) << "the slide's far end";
    }
    {   // Ending there: one quad from the kept stick to the last pose.
        PathFilter filter(f);
        const std::vector<Quad> quads = filter.pushStroke(poses);
        ASSERT_EQ(quads.size(), 1u);
        EXPECT_EQ(quads[0].corners[0], poses[0].base);
        EXPECT_EQ(quads[0].corners[3], poses[3].base);
    }
}

// Rule 2c on thousands of poses of sawing strokes (sliding and swinging,
// with tremor): a pose dropped lies in the last kept stick's cell (rule 2),
// retraces a quad (2b), or lies within slideTolerance of the last kept
// stick's line (2c); every kept stick is a pose's own (base, length), the
// slide's last placed before the pose that leaves the line; and the sliding
// strokes make far fewer quads than with the rule off.
TEST(PathFilter, SlidesHeldBackOnThousandsOfSawingPoses)
{
    IndexFrame head;
    head.dims = ivec3(128, 128, 128);
    head.spacing = dvec3(2.0);
    const std::vector<glm::vec3> bone{glm::vec3(120.0f, 130.0f, 110.0f), glm::vec3(100.0f, 90.0f, 140.0f)};
    size_t quadsOn = 0, quadsOff = 0, slid = 0, poses = 0;
    for (uint32_t seed = 300; seed < 312; ++seed)
        for (const std::vector<Pose>& stroke : makeSawingStrokes(bone, seed, 2, SawMotion::Slide)) {
            {
                PathFilterOptions off;
                off.slideTolerance = -1.0;
                quadsOff += filterStroke(stroke, head, off).size();
            }
            PathFilterOptions opt;
            PathFilter filter(head, opt);
            std::vector<Quad> quads;
            for (size_t i = 0; i < stroke.size(); ++i) {
                ++poses;
                const size_t sticksBefore = filter.sticks().size(), quadsBefore = quads.size();
                const bool kept = filter.push(stroke[i], quads);
                const std::vector<Stick>& st = filter.sticks();
                for (size_t k = sticksBefore; k < st.size(); ++k) { // the poses' own, a held slide's before this one
                    ASSERT_LE(st[k].poseIndex, i);
                    EXPECT_EQ(st[k].base, stroke[st[k].poseIndex].base);
                    EXPECT_EQ(st[k].length, stroke[st[k].poseIndex].length);
                }
                if (kept) {
                    EXPECT_EQ(st.back().poseIndex, i);
                    continue;
                }
                // Dropped: judged against the last kept stick (the held slide,
                // when the pose left the line and that one was placed first).
                if (st.size() == sticksBefore) {
                    ASSERT_EQ(quads.size(), quadsBefore);
                }
                const Stick& s0 = st.back();
                if (head.cellOf(head.toIndex(stroke[i].base)) == head.cellOf(head.toIndex(s0.base))) continue;
                const dvec3 a = head.toIndex(s0.base), d = glm::normalize(head.toIndex(s0.tip()) - a);
                auto off = [&](const dvec3& w) { return glm::length(glm::cross(head.toIndex(w) - a, d)); };
                const dvec3 tip = stroke[i].base + stroke[i].length * glm::normalize(stroke[i].direction);
                if (off(stroke[i].base) <= opt.slideTolerance && off(tip) <= opt.slideTolerance) {
                    ++slid;
                    continue;
                }
                EXPECT_TRUE(nearOneQuad(head, quads, stroke[i], opt.retraceTolerance))
                    << "seed " << seed << " pose " << i << " dropped, neither rule 2, 2b nor 2c";
            }
            for (const Quad& q : filter.endStroke()) quads.push_back(q);
            quadsOn += quads.size();
        }
    std::printf("sliding saws: %zu poses, %zu held back as slides; quads %zu with rule 2c, %zu without\n", poses, slid,
                quadsOn, quadsOff);
    EXPECT_GT(slid, poses / 4);
    EXPECT_LT(2 * quadsOn, quadsOff); // 660 against 1,850 when written
}
