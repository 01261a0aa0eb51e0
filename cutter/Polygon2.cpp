// 2-D polygon helpers of the re-meshing kernel: see Polygon2.h.
#include "cutter/Polygon2.h"

#include <boost/container/small_vector.hpp>

#include <algorithm>
#include <cmath>
#include <utility>

namespace mtcut::cutter::poly2 {

bool segmentsIntersect(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d)
{
    const double d1 = cross2(c, d, a), d2 = cross2(c, d, b), d3 = cross2(a, b, c), d4 = cross2(a, b, d);
    if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
    auto onSeg = [](const Vec2& p, const Vec2& q, const Vec2& r) { // r on pq (collinear assumed)
        return std::min(p.x, q.x) <= r.x && r.x <= std::max(p.x, q.x) && std::min(p.y, q.y) <= r.y &&
               r.y <= std::max(p.y, q.y);
    };
    if (d1 == 0 && onSeg(c, d, a) && !same2(a, c) && !same2(a, d)) return true;
    if (d2 == 0 && onSeg(c, d, b) && !same2(b, c) && !same2(b, d)) return true;
    if (d3 == 0 && onSeg(a, b, c) && !same2(c, a) && !same2(c, b)) return true;
    if (d4 == 0 && onSeg(a, b, d) && !same2(d, a) && !same2(d, b)) return true;
    return false;
}

double minSine(const Vec2& a, const Vec2& b, const Vec2& c)
{
    const double lab = length2(a.x - b.x, a.y - b.y), lbc = length2(b.x - c.x, b.y - c.y),
                 lca = length2(c.x - a.x, c.y - a.y);
    if (!(lab > 0 && lbc > 0 && lca > 0)) return -1.0;
    const double area2 = cross2(a, b, c);
    return std::min({area2 / (lab * lbc), area2 / (lbc * lca), area2 / (lca * lab)});
}

bool bestTriangulation(const std::vector<int>& poly, const std::vector<Vec2>& pts, std::vector<int>& tris)
{
    const size_t n = poly.size();
    if (n < 3 || n > kBestOfAllMax) return false;
    auto P = [&](size_t i) -> const Vec2& { return pts[size_t(poly[i])]; };
    for (size_t i = 0; i < n; ++i)
        for (size_t j = i + 1; j < n; ++j)
            if (same2(P(i), P(j))) return false;
    auto len = [](const Vec2& a, const Vec2& b) { return length2(a.x - b.x, a.y - b.y); };
    // A chord (i, j) of the polygon, not a side: crosses no side.
    auto chordOk = [&](size_t i, size_t j) {
        if ((i + 1) % n == j || (j + 1) % n == i) return true;
        for (size_t e = 0; e < n; ++e) {
            const size_t f = (e + 1) % n;
            if (e == i || e == j || f == i || f == j) continue;
            if (segmentsIntersect(P(i), P(j), P(e), P(f))) return false;
        }
        return true;
    };
    auto shape = [&](size_t a, size_t b, size_t c) {
        const double lab = len(P(a), P(b)), lbc = len(P(b), P(c)), lca = len(P(c), P(a));
        const double area2 = cross2(P(a), P(b), P(c));
        if (!(lab > 0 && lbc > 0 && lca > 0) || !(area2 > 1e-9 * lab * lbc)) return -1.0;
        for (size_t v = 0; v < n; ++v) {
            if (v == a || v == b || v == c) continue;
            const Vec2& q = P(v);
            if (cross2(P(a), P(b), q) >= -1e-9 * lab * lab && cross2(P(b), P(c), q) >= -1e-9 * lbc * lbc &&
                cross2(P(c), P(a), q) >= -1e-9 * lca * lca)
                return -1.0;
        }
        if (!chordOk(a, b) || !chordOk(b, c) || !chordOk(c, a)) return -1.0;
        return minSine(P(a), P(b), P(c));
    };
    // best[i][j]: the chain i..j closed by the chord (j, i); split[i][j] its apex.
    double best[kBestOfAllMax][kBestOfAllMax];
    size_t split[kBestOfAllMax][kBestOfAllMax];
    for (size_t gap = 1; gap < n; ++gap)
        for (size_t i = 0; i + gap < n; ++i) {
            const size_t j = i + gap;
            best[i][j] = gap == 1 ? 2.0 : -1.0; // a side: no triangle
            for (size_t k = i + 1; k < j; ++k) {
                // The apex k can only win when both sub-chains beat the best so far.
                if (!(std::min(best[i][k], best[k][j]) > best[i][j])) continue;
                const double q = std::min(std::min(best[i][k], best[k][j]), shape(i, k, j));
                if (q > best[i][j]) {
                    best[i][j] = q;
                    split[i][j] = k;
                }
            }
        }
    if (!(best[0][n - 1] > 0.0)) return false;
    // The chains still to emit, a stack: they are disjoint runs of the
    // chain 0 .. n - 1, each of one side at least, so at most n - 1 at once.
    std::pair<size_t, size_t> todo[kBestOfAllMax + 1];
    size_t depth = 0;
    todo[depth++] = {0, n - 1};
    while (depth > 0) {
        const auto [i, j] = todo[--depth];
        if (j - i < 2) continue;
        const size_t k = split[i][j];
        tris.insert(tris.end(), {poly[i], poly[k], poly[j]});
        todo[depth++] = {i, k};
        todo[depth++] = {k, j};
    }
    return true;
}

bool earClip(const std::vector<int>& polyIn, const std::vector<Vec2>& pts, std::vector<int>& tris)
{
    // The corners still to clip; a region's polygon has a few dozen at most.
    boost::container::small_vector<int, 32> poly(polyIn.begin(), polyIn.end());
    auto P = [&](int i) -> const Vec2& { return pts[size_t(i)]; };
    auto len = [](const Vec2& a, const Vec2& b) { return length2(a.x - b.x, a.y - b.y); };
    while (poly.size() > 3) {
        const size_t n = poly.size();
        if (n == 4) {
            // The last four: the diagonal whose two triangles have the better
            // worst shape. Clipping the best ear first would leave the other
            // triangle, flat when a corner is nearly straight (a seam bending
            // slightly on a mitre): a sliver that rounding to float folds over.
            double split[2];
            for (int d = 0; d < 2; ++d) {
                const int a = poly[size_t(d)], b = poly[size_t(d + 1)], c = poly[size_t(d + 2)], e = poly[size_t(d + 3) % 4];
                split[d] = std::min(minSine(P(a), P(b), P(c)), minSine(P(a), P(c), P(e)));
            }
            const int d = split[1] > split[0] ? 1 : 0;
            if (split[d] > 1e-9 && !same2(P(poly[size_t(d)]), P(poly[size_t(d + 2)]))) {
                const int a = poly[size_t(d)], b = poly[size_t(d + 1)], c = poly[size_t(d + 2)], e = poly[size_t(d + 3) % 4];
                tris.insert(tris.end(), {a, b, c, a, c, e});
                return true;
            }
        }
        size_t best = n;
        double bestScore = -1.0;
        for (double tol : {1e-9, 0.0}) {
            for (size_t i = 0; i < n; ++i) {
                const int a = poly[(i + n - 1) % n], b = poly[i], c = poly[(i + 1) % n];
                const double lab = len(P(a), P(b)), lbc = len(P(b), P(c)), lca = len(P(c), P(a));
                const double area2 = cross2(P(a), P(b), P(c));
                if (!(area2 > tol * lab * lbc) || lab == 0 || lbc == 0 || lca == 0) continue;
                bool ok = true;
                for (size_t j = 0; j < n && ok; ++j) {
                    const int v = poly[j];
                    if (j == i || j == (i + n - 1) % n || j == (i + 1) % n) continue;
                    const Vec2& p = P(v);
                    if (same2(p, P(a)) || same2(p, P(b)) || same2(p, P(c))) {
                        // A copy of a corner (slit or bridge): the ear must not cut
                        // the polygon there; reject when that copy's wedge enters the ear.
                        if (!same2(p, P(b))) continue;
                        const Vec2 &pp = P(poly[(j + n - 1) % n]), &pn = P(poly[(j + 1) % n]);
                        auto inside = [&](const Vec2& q) {
                            return cross2(P(a), P(b), q) > 0 && cross2(P(b), P(c), q) > 0 && cross2(P(c), P(a), q) > 0;
                        };
                        if (inside(pp) || inside(pn)) ok = false;
                        continue;
                    }
                    if (cross2(P(a), P(b), p) >= -tol * lab * lab && cross2(P(b), P(c), p) >= -tol * lbc * lbc &&
                        cross2(P(c), P(a), p) >= -tol * lca * lca)
                        ok = false;
                }
                if (!ok) continue;
                const double score = minSine(P(a), P(b), P(c));
                if (score > bestScore) {
                    bestScore = score;
                    best = i;
                }
            }
            if (best < n) break;
        }
        if (best == n) return false;
        tris.push_back(poly[(best + n - 1) % n]);
        tris.push_back(poly[best]);
        tris.push_back(poly[(best + 1) % n]);
        poly.erase(poly.begin() + long(best));
    }
    if (poly.size() == 3) {
        if (!(cross2(P(poly[0]), P(poly[1]), P(poly[2])) > 0.0)) return false;
        tris.insert(tris.end(), poly.begin(), poly.end());
    }
    return true;
}

double signedArea(const std::vector<int>& loop, const std::vector<Vec2>& pts)
{
    return signedArea(loop.data(), loop.size(), pts);
}

double signedArea(const int* loop, size_t n, const std::vector<Vec2>& pts)
{
    double a = 0.0;
    for (size_t i = 0; i < n; ++i) {
        const Vec2& p = pts[size_t(loop[i])];
        const Vec2& q = pts[size_t(loop[(i + 1) % n])];
        a += p.x * q.y - p.y * q.x;
    }
    return 0.5 * a;
}

bool bridgeHoles(std::vector<int>& outer, std::vector<std::vector<int>> holes, const std::vector<Vec2>& pts)
{
    auto P = [&](int i) -> const Vec2& { return pts[size_t(i)]; };
    // Is x inside the wedge of `loop` at its corner k (the region on the loop's left)?
    auto inWedge = [&](const std::vector<int>& loop, size_t k, const Vec2& x) {
        const size_t n = loop.size();
        const Vec2 &prev = P(loop[(k + n - 1) % n]), &at = P(loop[k]), &next = P(loop[(k + 1) % n]);
        const bool l1 = cross2(at, next, x) > 0, l2 = cross2(prev, at, x) > 0;
        return cross2(prev, at, next) > 0 ? l1 && l2 : l1 || l2;
    };
    while (!holes.empty()) {
        // A hole that touches the outer loop (a slit from a boundary corner:
        // a point of each at one position) is spliced there, with no bridge:
        // outer[o] -> the hole from past its copy of that point round to it
        // -> on along the outer loop.
        bool touched = false;
        for (size_t h = 0; h < holes.size() && !touched; ++h)
            for (size_t j = 0; j < holes[h].size() && !touched; ++j)
                for (size_t o = 0; o < outer.size() && !touched; ++o) {
                    if (!same2(P(holes[h][j]), P(outer[o]))) continue;
                    const std::vector<int>& hole = holes[h];
                    std::vector<int> splice;
                    for (size_t k = 1; k <= hole.size(); ++k) splice.push_back(hole[(j + k) % hole.size()]);
                    outer.insert(outer.begin() + long(o) + 1, splice.begin(), splice.end());
                    holes.erase(holes.begin() + long(h));
                    touched = true;
                }
        if (touched) continue;
        double best = 1e300;
        size_t bh = 0, bo = 0, bj = 0;
        for (size_t h = 0; h < holes.size(); ++h) {
            for (size_t j = 0; j < holes[h].size(); ++j) {
                const Vec2& hp = P(holes[h][j]);
                for (size_t o = 0; o < outer.size(); ++o) {
                    const Vec2& op = P(outer[o]);
                    const double dx = op.x - hp.x, dy = op.y - hp.y, d2 = dx * dx + dy * dy;
                    if (d2 >= best || d2 == 0.0) continue;
                    // Inside the wedge of the outer loop at o (CCW: interior on
                    // the left), and inside the region's wedge at the hole's
                    // corner (a hole is CW: the region on the left too): of two
                    // copies of a point (the two sides of a crack, a zero-width
                    // slit inside the region), the one facing the outer corner.
                    if (!inWedge(outer, o, hp) || !inWedge(holes[h], j, op)) continue;
                    bool clear = true;
                    auto check = [&](const std::vector<int>& loop) {
                        for (size_t k = 0; k < loop.size() && clear; ++k) {
                            const Vec2& c = P(loop[k]);
                            const Vec2& d = P(loop[(k + 1) % loop.size()]);
                            if (segmentsIntersect(hp, op, c, d)) clear = false;
                        }
                    };
                    check(outer);
                    for (const auto& hl : holes) check(hl);
                    if (!clear) continue;
                    best = d2;
                    bh = h;
                    bo = o;
                    bj = j;
                }
            }
        }
        if (best == 1e300) return false;
        const std::vector<int>& hole = holes[bh];
        // outer[bo] -> the hole from bj round to bj -> back to (a copy of) outer[bo].
        std::vector<int> splice;
        for (size_t k = 0; k <= hole.size(); ++k) splice.push_back(hole[(bj + k) % hole.size()]);
        splice.push_back(outer[bo]);
        outer.insert(outer.begin() + long(bo) + 1, splice.begin(), splice.end());
        holes.erase(holes.begin() + long(bh));
    }
    return true;
}

} // namespace mtcut::cutter::poly2
