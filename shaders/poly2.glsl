// 2-D polygon helpers of the re-meshing kernel (cutter/Polygon2.{h,cpp}) for
// the GPU cut pass: put in front of a shader body by buildProgram's defines,
// as mask.glsl, after doubles.glsl (dSqrt; render::poly2Library). The GPU must choose the same triangles as the CPU, so every
// function repeats the C++ on doubles operation for operation: the same
// expressions in the same order, min(a, b) as std::min (b < a ? b : a, which
// decides which of -0 and +0 survives), double literals (lf: a float literal
// would round 1e-9), no fma. Every double result is assigned to a `precise`
// variable, which keeps the compiler from reassociating or fusing it: without
// it Mesa 22.3.6 (llvmpipe) computes signedArea's a += p.x * q.y - p.y * q.x
// as (a + p.x * q.y) - p.y * q.x, and hundreds of the test's cases differ.
//
// Data lives in per-invocation globals, since GLSL passes arrays by copy:
// the caller calls poly2Reset(), fills the points and loops with poly2AddPoint,
// poly2AddCorner, poly2BeginHole and poly2AddHoleCorner (indices into the
// points), calls a function and reads the globals back. Capacities are fixed
// (the defines below, which a caller may set before this text); anything that
// would exceed one sets poly2Overflow and makes the function return false,
// with its outputs partly written: the CPU fallback takes such a cell.

#ifndef POLY2_MAX
#define POLY2_MAX 64 // corners of a loop, bridged holes included; corners of all holes together
#endif
#ifndef POLY2_MAX_POINTS
#define POLY2_MAX_POINTS POLY2_MAX
#endif
#ifndef POLY2_MAX_HOLES
#define POLY2_MAX_HOLES 8
#endif
#if POLY2_MAX_HOLES > 32
#error "POLY2_MAX_HOLES: poly2BridgeHoles keeps the holes left in a 32-bit mask"
#endif
#ifndef POLY2_MAX_TRIS
#define POLY2_MAX_TRIS POLY2_MAX // triangles in poly2Tri
#endif
// kBestOfAllMax of Polygon2.h: part of the algorithm, not a capacity.
#define POLY2_BEST_MAX 9

// NVIDIA's driver (580.159.04, H100) keeps only a float's precision of a
// double that goes through a private array indexed at run time (through
// buffers, functions, arithmetic it stays whole): RenderPoly2.DoublesReach-
// TheShaderUnrounded. So the arrays of the cut pass's shaders hold their
// doubles as bits, which every driver keeps exactly.
uvec4 dvec2Bits(dvec2 p) { return uvec4(unpackDouble2x32(p.x), unpackDouble2x32(p.y)); }
dvec2 dvec2Of(uvec4 b) { return dvec2(packDouble2x32(b.xy), packDouble2x32(b.zw)); }

uvec4 poly2PtBits[POLY2_MAX_POINTS]; // the points, poly2PtCount of them, as bits
dvec2 poly2Pt(int i) { return dvec2Of(poly2PtBits[i]); }
int poly2PtCount;
// The polygon: the input of poly2SignedArea, poly2BestTriangulation and
// poly2EarClip (which leave it as it is), the outer loop that
// poly2BridgeHoles splices the holes into.
int poly2Poly[POLY2_MAX];
int poly2PolyCount;
// The holes of poly2BridgeHoles, concatenated: hole h is
// poly2Hole[poly2HoleStart[h] .. poly2HoleStart[h + 1]).
int poly2Hole[POLY2_MAX];
int poly2HoleStart[POLY2_MAX_HOLES + 1];
int poly2HoleCount;
// Triangles, 3 point indices each, appended as the C++ appends to `tris`.
int poly2Tri[3 * POLY2_MAX_TRIS];
int poly2TriCount; // indices, not triangles: 3 per triangle
bool poly2Overflow;

void poly2Reset()
{
    poly2PtCount = 0;
    poly2PolyCount = 0;
    poly2HoleCount = 0;
    poly2HoleStart[0] = 0;
    poly2TriCount = 0;
    poly2Overflow = false;
}

// Index of the new point, or -1 (overflow).
int poly2AddPoint(dvec2 p)
{
    if (poly2PtCount >= POLY2_MAX_POINTS) {
        poly2Overflow = true;
        return -1;
    }
    poly2PtBits[poly2PtCount] = dvec2Bits(p);
    return poly2PtCount++;
}

bool poly2AddCorner(int i)
{
    if (poly2PolyCount >= POLY2_MAX) {
        poly2Overflow = true;
        return false;
    }
    poly2Poly[poly2PolyCount++] = i;
    return true;
}

// Starts a new (empty) hole; poly2AddHoleCorner adds to the last one.
bool poly2BeginHole()
{
    if (poly2HoleCount >= POLY2_MAX_HOLES) {
        poly2Overflow = true;
        return false;
    }
    ++poly2HoleCount;
    poly2HoleStart[poly2HoleCount] = poly2HoleStart[poly2HoleCount - 1];
    return true;
}

bool poly2AddHoleCorner(int i)
{
    if (poly2HoleCount == 0 || poly2HoleStart[poly2HoleCount] >= POLY2_MAX) {
        poly2Overflow = true;
        return false;
    }
    poly2Hole[poly2HoleStart[poly2HoleCount]++] = i;
    return true;
}

bool poly2AddTri(int a, int b, int c)
{
    if (poly2TriCount + 3 > 3 * POLY2_MAX_TRIS) {
        poly2Overflow = true;
        return false;
    }
    poly2Tri[poly2TriCount] = a;
    poly2Tri[poly2TriCount + 1] = b;
    poly2Tri[poly2TriCount + 2] = c;
    poly2TriCount += 3;
    return true;
}

double poly2Min(double a, double b)
{
    precise double r = b < a ? b : a; // precise: not turned into min(), whose -0 and +0 may differ
    return r;
}

double poly2Max(double a, double b)
{
    precise double r = a < b ? b : a;
    return r;
}

double poly2Cross(dvec2 o, dvec2 a, dvec2 b)
{
    precise double r = (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    return r;
}

bool poly2Same(dvec2 a, dvec2 b)
{
    return a.x == b.x && a.y == b.y;
}

double poly2Length(double dx, double dy)
{
    precise double r = dSqrt(dx * dx + dy * dy);
    return r;
}

double poly2Dist(dvec2 a, dvec2 b)
{
    precise double dx = a.x - b.x, dy = a.y - b.y;
    return poly2Length(dx, dy);
}

// r on pq, collinear assumed.
bool poly2OnSeg(dvec2 p, dvec2 q, dvec2 r)
{
    return poly2Min(p.x, q.x) <= r.x && r.x <= poly2Max(p.x, q.x) && poly2Min(p.y, q.y) <= r.y &&
           r.y <= poly2Max(p.y, q.y);
}

bool poly2SegmentsIntersect(dvec2 a, dvec2 b, dvec2 c, dvec2 d)
{
    precise double d1 = poly2Cross(c, d, a), d2 = poly2Cross(c, d, b), d3 = poly2Cross(a, b, c),
                   d4 = poly2Cross(a, b, d);
    if (((d1 > 0.0lf && d2 < 0.0lf) || (d1 < 0.0lf && d2 > 0.0lf)) &&
        ((d3 > 0.0lf && d4 < 0.0lf) || (d3 < 0.0lf && d4 > 0.0lf)))
        return true;
    if (d1 == 0.0lf && poly2OnSeg(c, d, a) && !poly2Same(a, c) && !poly2Same(a, d)) return true;
    if (d2 == 0.0lf && poly2OnSeg(c, d, b) && !poly2Same(b, c) && !poly2Same(b, d)) return true;
    if (d3 == 0.0lf && poly2OnSeg(a, b, c) && !poly2Same(c, a) && !poly2Same(c, b)) return true;
    if (d4 == 0.0lf && poly2OnSeg(a, b, d) && !poly2Same(d, a) && !poly2Same(d, b)) return true;
    return false;
}

double poly2MinSine(dvec2 a, dvec2 b, dvec2 c)
{
    precise double lab = poly2Dist(a, b), lbc = poly2Dist(b, c), lca = poly2Dist(c, a);
    if (!(lab > 0.0lf && lbc > 0.0lf && lca > 0.0lf)) return -1.0lf;
    precise double area2 = poly2Cross(a, b, c);
    precise double s0 = area2 / (lab * lbc), s1 = area2 / (lbc * lca), s2 = area2 / (lca * lab);
    return poly2Min(poly2Min(s0, s1), s2);
}

// Signed area of poly2Poly: > 0 when CCW.
double poly2SignedArea()
{
    precise double a = 0.0lf;
    for (int i = 0; i < poly2PolyCount; ++i) {
        dvec2 p = poly2Pt(poly2Poly[i]), q = poly2Pt(poly2Poly[(i + 1) % poly2PolyCount]);
        a += p.x * q.y - p.y * q.x;
    }
    precise double r = 0.5lf * a;
    return r;
}

// bestTriangulation's point at position i of the polygon.
dvec2 poly2BestP(int i)
{
    return poly2Pt(poly2Poly[i]);
}

// bestTriangulation's chordOk: the chord (i, j) of the polygon (positions), not
// a side, crosses no side.
bool poly2BestChordOk(int i, int j, int n)
{
    if ((i + 1) % n == j || (j + 1) % n == i) return true;
    for (int e = 0; e < n; ++e) {
        int f = (e + 1) % n;
        if (e == i || e == j || f == i || f == j) continue;
        if (poly2SegmentsIntersect(poly2BestP(i), poly2BestP(j), poly2BestP(e), poly2BestP(f))) return false;
    }
    return true;
}

// bestTriangulation's shape: the minSine of triangle (a, b, c) (positions), or
// -1 when it may not be part of the triangulation.
double poly2BestShape(int a, int b, int c, int n)
{
    dvec2 pa = poly2BestP(a), pb = poly2BestP(b), pc = poly2BestP(c);
    precise double lab = poly2Dist(pa, pb), lbc = poly2Dist(pb, pc), lca = poly2Dist(pc, pa);
    precise double area2 = poly2Cross(pa, pb, pc);
    precise double flatness = 1e-9lf * lab * lbc;
    if (!(lab > 0.0lf && lbc > 0.0lf && lca > 0.0lf) || !(area2 > flatness)) return -1.0lf;
    precise double tab = -1e-9lf * lab * lab, tbc = -1e-9lf * lbc * lbc, tca = -1e-9lf * lca * lca;
    for (int v = 0; v < n; ++v) {
        if (v == a || v == b || v == c) continue;
        dvec2 q = poly2BestP(v);
        if (poly2Cross(pa, pb, q) >= tab && poly2Cross(pb, pc, q) >= tbc && poly2Cross(pc, pa, q) >= tca)
            return -1.0lf;
    }
    if (!poly2BestChordOk(a, b, n) || !poly2BestChordOk(b, c, n) || !poly2BestChordOk(c, a, n)) return -1.0lf;
    return poly2MinSine(pa, pb, pc);
}

// Polygon2.h bestTriangulation of poly2Poly: appends to poly2Tri.
bool poly2BestTriangulation()
{
    int n = poly2PolyCount;
    if (n < 3 || n > POLY2_BEST_MAX) return false;
    for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j)
            if (poly2Same(poly2BestP(i), poly2BestP(j))) return false;
    // best[i][j]: the chain i..j closed by the chord (j, i), as bits; split[i][j] its apex.
    uvec2 best[POLY2_BEST_MAX * POLY2_BEST_MAX];
    int split[POLY2_BEST_MAX * POLY2_BEST_MAX];
    for (int gap = 1; gap < n; ++gap)
        for (int i = 0; i + gap < n; ++i) {
            int j = i + gap, ij = i * POLY2_BEST_MAX + j;
            double bestIJ = gap == 1 ? 2.0lf : -1.0lf;
            for (int k = i + 1; k < j; ++k) {
                double sub = poly2Min(packDouble2x32(best[i * POLY2_BEST_MAX + k]),
                                      packDouble2x32(best[k * POLY2_BEST_MAX + j]));
                if (!(sub > bestIJ)) continue;
                double q = poly2Min(sub, poly2BestShape(i, k, j, n));
                if (q > bestIJ) {
                    bestIJ = q;
                    split[ij] = k;
                }
            }
            best[ij] = unpackDouble2x32(bestIJ);
        }
    if (!(packDouble2x32(best[n - 1]) > 0.0lf)) return false;
    if (poly2TriCount + 3 * (n - 2) > 3 * POLY2_MAX_TRIS) {
        poly2Overflow = true;
        return false;
    }
    // The C++'s todo stack: pop (i, j), push (i, k) then (k, j).
    ivec2 todo[POLY2_BEST_MAX];
    int top = 0;
    todo[top++] = ivec2(0, n - 1);
    while (top > 0) {
        ivec2 ij = todo[--top];
        if (ij.y - ij.x < 2) continue;
        int k = split[ij.x * POLY2_BEST_MAX + ij.y];
        poly2AddTri(poly2Poly[ij.x], poly2Poly[k], poly2Poly[ij.y]);
        todo[top++] = ivec2(ij.x, k);
        todo[top++] = ivec2(k, ij.y);
    }
    return true;
}

// Polygon2.h earClip of poly2Poly (left as it is, the C++ takes a copy):
// appends to poly2Tri, also the ears clipped before it fails.
bool poly2EarClip()
{
    int poly[POLY2_MAX];
    int n = poly2PolyCount;
    for (int i = 0; i < n; ++i) poly[i] = poly2Poly[i];
    while (n > 3) {
        if (n == 4) {
            // The last four: the diagonal whose two triangles have the better worst shape.
            // (d = 0: the diagonal poly[0]-poly[2]; d = 1: poly[1]-poly[3])
            const double split0 = poly2Min(poly2MinSine(poly2Pt(poly[0]), poly2Pt(poly[1]), poly2Pt(poly[2])),
                                           poly2MinSine(poly2Pt(poly[0]), poly2Pt(poly[2]), poly2Pt(poly[3])));
            const double split1 = poly2Min(poly2MinSine(poly2Pt(poly[1]), poly2Pt(poly[2]), poly2Pt(poly[3])),
                                           poly2MinSine(poly2Pt(poly[1]), poly2Pt(poly[3]), poly2Pt(poly[0])));
            const int d = split1 > split0 ? 1 : 0;
            const double splitD = d == 1 ? split1 : split0;
            if (splitD > 1e-9lf && !poly2Same(poly2Pt(poly[d]), poly2Pt(poly[d + 2]))) {
                int a = poly[d], b = poly[d + 1], c = poly[d + 2], e = poly[(d + 3) % 4];
                return poly2AddTri(a, b, c) && poly2AddTri(a, c, e);
            }
        }
        int best = n;
        double bestScore = -1.0lf;
        for (int pass = 0; pass < 2; ++pass) {
            precise double tol = pass == 0 ? 1e-9lf : 0.0lf;
            for (int i = 0; i < n; ++i) {
                dvec2 pa = poly2Pt(poly[(i + n - 1) % n]), pb = poly2Pt(poly[i]), pc = poly2Pt(poly[(i + 1) % n]);
                precise double lab = poly2Dist(pa, pb), lbc = poly2Dist(pb, pc), lca = poly2Dist(pc, pa);
                precise double area2 = poly2Cross(pa, pb, pc);
                precise double flatness = tol * lab * lbc;
                if (!(area2 > flatness) || lab == 0.0lf || lbc == 0.0lf || lca == 0.0lf) continue;
                precise double tab = -tol * lab * lab, tbc = -tol * lbc * lbc, tca = -tol * lca * lca;
                bool ok = true;
                for (int j = 0; j < n && ok; ++j) {
                    if (j == i || j == (i + n - 1) % n || j == (i + 1) % n) continue;
                    dvec2 p = poly2Pt(poly[j]);
                    if (poly2Same(p, pa) || poly2Same(p, pb) || poly2Same(p, pc)) {
                        // A copy of a corner (slit or bridge): the ear must not cut
                        // the polygon there; reject when that copy's wedge enters the ear.
                        if (!poly2Same(p, pb)) continue;
                        dvec2 pp = poly2Pt(poly[(j + n - 1) % n]), pn = poly2Pt(poly[(j + 1) % n]);
                        bool inPp = poly2Cross(pa, pb, pp) > 0.0lf && poly2Cross(pb, pc, pp) > 0.0lf &&
                                    poly2Cross(pc, pa, pp) > 0.0lf;
                        bool inPn = poly2Cross(pa, pb, pn) > 0.0lf && poly2Cross(pb, pc, pn) > 0.0lf &&
                                    poly2Cross(pc, pa, pn) > 0.0lf;
                        if (inPp || inPn) ok = false;
                        continue;
                    }
                    if (poly2Cross(pa, pb, p) >= tab && poly2Cross(pb, pc, p) >= tbc && poly2Cross(pc, pa, p) >= tca)
                        ok = false;
                }
                if (!ok) continue;
                double score = poly2MinSine(pa, pb, pc);
                if (score > bestScore) {
                    bestScore = score;
                    best = i;
                }
            }
            if (best < n) break;
        }
        if (best == n) return false;
        if (!poly2AddTri(poly[(best + n - 1) % n], poly[best], poly[(best + 1) % n])) return false;
        for (int i = best; i + 1 < n; ++i) poly[i] = poly[i + 1];
        --n;
    }
    if (n == 3) {
        if (!(poly2Cross(poly2Pt(poly[0]), poly2Pt(poly[1]), poly2Pt(poly[2])) > 0.0lf)) return false;
        return poly2AddTri(poly[0], poly[1], poly[2]);
    }
    return true;
}

// bridgeHoles's inWedge: is x inside the wedge prev -> at -> next (the region
// on the loop's left)?
bool poly2InWedge(dvec2 prev, dvec2 at, dvec2 next, dvec2 x)
{
    bool l1 = poly2Cross(at, next, x) > 0.0lf, l2 = poly2Cross(prev, at, x) > 0.0lf;
    return poly2Cross(prev, at, next) > 0.0lf ? l1 && l2 : l1 || l2;
}

// Inserts hole h's corners from position `from` on, `count` of them (round the
// hole), then `tail` unless it is -1, into poly2Poly after position o.
bool poly2Splice(int o, int h, int from, int count, int tail)
{
    int hs = poly2HoleStart[h], hn = poly2HoleStart[h + 1] - hs;
    int len = count + (tail < 0 ? 0 : 1);
    if (poly2PolyCount + len > POLY2_MAX) {
        poly2Overflow = true;
        return false;
    }
    for (int i = poly2PolyCount - 1; i > o; --i) poly2Poly[i + len] = poly2Poly[i];
    for (int k = 0; k < count; ++k) poly2Poly[o + 1 + k] = poly2Hole[hs + (from + k) % hn];
    if (tail >= 0) poly2Poly[o + 1 + count] = tail;
    poly2PolyCount += len;
    return true;
}

// Does segment hp op cross a side of poly2Poly or of a hole still alive?
bool poly2BridgeClear(dvec2 hp, dvec2 op, uint alive)
{
    for (int k = 0; k < poly2PolyCount; ++k)
        if (poly2SegmentsIntersect(hp, op, poly2Pt(poly2Poly[k]), poly2Pt(poly2Poly[(k + 1) % poly2PolyCount])))
            return false;
    for (int h = 0; h < poly2HoleCount; ++h) {
        if ((alive >> uint(h) & 1u) == 0u) continue;
        int hs = poly2HoleStart[h], hn = poly2HoleStart[h + 1] - hs;
        for (int k = 0; k < hn; ++k)
            if (poly2SegmentsIntersect(hp, op, poly2Pt(poly2Hole[hs + k]), poly2Pt(poly2Hole[hs + (k + 1) % hn])))
                return false;
    }
    return true;
}

// Polygon2.h bridgeHoles: splices the holes into poly2Poly. The C++ erases a
// hole from its vector once spliced; here its bit in `alive` is cleared, and
// the holes still alive are visited in the same order. A bit mask, not a local
// bool (or int) array: Mesa 22.3.6 llvmpipe miscompiled the array version (a
// hole cleared in the touching loop read as alive on the next round, when
// that loop began with `if (!alive[h]) continue;`), and spliced it again.
bool poly2BridgeHoles()
{
    uint alive = poly2HoleCount == 32 ? ~0u : (1u << uint(poly2HoleCount)) - 1u;
    int left = poly2HoleCount;
    while (left > 0) {
        // A hole that touches the outer loop is spliced there, with no bridge.
        bool touched = false;
        for (int h = 0; h < poly2HoleCount && !touched; ++h) {
            int hs = poly2HoleStart[h], hn = (alive >> uint(h) & 1u) != 0u ? poly2HoleStart[h + 1] - hs : 0;
            for (int j = 0; j < hn && !touched; ++j)
                for (int o = 0; o < poly2PolyCount && !touched; ++o) {
                    if (!poly2Same(poly2Pt(poly2Hole[hs + j]), poly2Pt(poly2Poly[o]))) continue;
                    if (!poly2Splice(o, h, j + 1, hn, -1)) return false;
                    alive &= ~(1u << uint(h));
                    --left;
                    touched = true;
                }
        }
        if (touched) continue;
        precise double best = 1e300lf;
        int bh = 0, bo = 0, bj = 0;
        for (int h = 0; h < poly2HoleCount; ++h) {
            if ((alive >> uint(h) & 1u) == 0u) continue;
            int hs = poly2HoleStart[h], hn = poly2HoleStart[h + 1] - hs;
            for (int j = 0; j < hn; ++j) {
                dvec2 hp = poly2Pt(poly2Hole[hs + j]);
                for (int o = 0; o < poly2PolyCount; ++o) {
                    int n = poly2PolyCount;
                    dvec2 op = poly2Pt(poly2Poly[o]);
                    precise double dx = op.x - hp.x, dy = op.y - hp.y, d2 = dx * dx + dy * dy;
                    if (d2 >= best || d2 == 0.0lf) continue;
                    if (!poly2InWedge(poly2Pt(poly2Poly[(o + n - 1) % n]), op, poly2Pt(poly2Poly[(o + 1) % n]), hp) ||
                        !poly2InWedge(poly2Pt(poly2Hole[hs + (j + hn - 1) % hn]), hp,
                                      poly2Pt(poly2Hole[hs + (j + 1) % hn]), op))
                        continue;
                    if (!poly2BridgeClear(hp, op, alive)) continue;
                    best = d2;
                    bh = h;
                    bo = o;
                    bj = j;
                }
            }
        }
        if (best == 1e300lf) return false;
        // outer[bo] -> the hole from bj round to bj -> back to (a copy of) outer[bo].
        int bhn = poly2HoleStart[bh + 1] - poly2HoleStart[bh];
        if (!poly2Splice(bo, bh, bj, bhn + 1, poly2Poly[bo])) return false;
        alive &= ~(1u << uint(bh));
        --left;
    }
    return true;
}
