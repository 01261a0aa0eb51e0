// The re-meshing kernel (cutter/RemeshKernel.cpp) ported to GLSL, phase by
// phase, for the GPU cut pass (DESIGN "GPU passes", pass 3). Its output must
// equal the CPU kernel's triangle for triangle, so every decision is made on
// the same doubles in the same order: no fma (Mesa's double fma is not
// fused), no dot()/length()/cross() builtins (their order of operations is
// the driver's), double literals with the lf suffix, and every product that
// feeds a sum or difference computed into a `precise` variable: without it
// Mesa 22.3.6 (llvmpipe) rearranges some of them (the Newell normal's cross
// products differed from the CPU's in 1 % of tets; poly2.glsl saw a sum in a
// loop reassociated), which the C++ (-ffp-contract=off) never does. What the C++ uses that
// GLSL lacks is replaced on both sides before it is ported (atan2, hypot,
// hash maps, exceptions). Ported so far: the input (cutter/KernelInput.h,
// the std430 twins of PackedKernelCell/Quad/Side) and phase one of a tet:
// the quads that can reach it (gatherQuads) and its marching-tetrahedra
// polygons with their planes (isoTriangles); the tet's reaching quads and
// planes gathered once (tetBegin, which callers of the functions after it
// run first); a point's name (the planes makeVertex names it by) and a
// vertex's position from its name (canonicalPosition). Checked bit for bit against the CPU by
// tests/test_render_cut_kernel.cpp. The 2-D polygon helpers are poly2.glsl;
// doubles.glsl (in front of this file) enables 64-bit integers and rounds
// square roots as the C++.

// Doubles in private arrays are kept as their bits (unpackDouble2x32):
// NVIDIA's driver (580.159.04, H100) kept only a float's precision of a
// dvec2 stored in a private array indexed at run time, while buffers,
// functions and arithmetic kept every bit (RenderPoly2.DoublesReachThe-
// ShaderUnrounded). D1/D3/D4GET(array, i) read element i of such an array
// (one uvec2 per double; a dvec3 is three, a dvec4 two uvec4), D*SET(array,
// i, v) write it (a statement; i and v evaluated once). Writing a double
// vector's component at a run-time index (v[i] = x) does not link there
// ("can't find __setVectorIndex"): no shader does.
#define D1GET(a, i) packDouble2x32(a[i])
#define D1SET(a, i, v) a[i] = unpackDouble2x32(v)
#define D3GET(a, i) dvec3(packDouble2x32(a[3 * (i)]), packDouble2x32(a[3 * (i) + 1]), packDouble2x32(a[3 * (i) + 2]))
#define D3SET(a, i, v)                                                                                                 \
    {                                                                                                                  \
        const int at_ = 3 * (i);                                                                                       \
        const dvec3 v_ = (v);                                                                                          \
        a[at_] = unpackDouble2x32(v_.x);                                                                               \
        a[at_ + 1] = unpackDouble2x32(v_.y);                                                                           \
        a[at_ + 2] = unpackDouble2x32(v_.z);                                                                           \
    }
#define D4GET(a, i)                                                                                                    \
    dvec4(packDouble2x32(a[2 * (i)].xy), packDouble2x32(a[2 * (i)].zw), packDouble2x32(a[2 * (i) + 1].xy),            \
          packDouble2x32(a[2 * (i) + 1].zw))
#define D4SET(a, i, v)                                                                                                 \
    {                                                                                                                  \
        const int at_ = 2 * (i);                                                                                       \
        const dvec4 v_ = (v);                                                                                          \
        a[at_] = uvec4(unpackDouble2x32(v_.x), unpackDouble2x32(v_.y));                                                \
        a[at_ + 1] = uvec4(unpackDouble2x32(v_.z), unpackDouble2x32(v_.w));                                            \
    }

// 64-bit integers in private arrays (plane ids, names, features) are kept as
// their bits too: the same driver changed every uint64_t kept in a private
// array (the probe's "double as uint64_t bits": 4,096 of 4,096, so not a
// float's rounding; more like a lost high word), and the GPU's vertex names
// differed from the CPU's. u64(b) reads one, b64(x) makes one. Buffers and
// single variables keep uint64_t. tests/test_render_gl.cpp checks the
// shaders' text for private arrays of 64-bit types.
uint64_t u64(uvec2 b) { return packUint2x32(b); }
uvec2 b64(uint64_t x) { return unpackUint2x32(x); }

struct KernelCell
{
    int x, y, z;
    uint firstQuad, quadCount;
    uint insideMask; // bit c: corner c (x = c & 1, y = c >> 1 & 1, z = c >> 2 & 1) inside
    uint pad0, pad1;
    float values[8];
};
struct KernelQuad
{
    dvec4 plane; // n, d: h(x) = dot(n, x) - d
    uint64_t id;
    uint firstSide, sideCount;
    uint64_t pad0, pad1;
};
struct KernelSide
{
    dvec4 plane;
    uint64_t id;
    uint64_t partnerId;
    double orient; // inside the quad: orient * h >= 0
    int partner;   // junction partner's index in the cell's list (-1: rim)
    int fold;      // zero kerf: a side goes on as the partner's other side (QuadGeom::Side::fold)
    uint64_t cornerSides[4];
};

layout(std430, binding = 0) readonly buffer KernelCells { KernelCell kCells[]; };
layout(std430, binding = 1) readonly buffer KernelQuads { KernelQuad kQuads[]; };
layout(std430, binding = 2) readonly buffer KernelSides { KernelSide kSides[]; };
layout(std430, binding = 3) readonly buffer KernelTets { uint kTets[40]; }; // [parity][tet][corner]

uniform float uIsovalue;
uniform bool uPrism; // kerf > 0: the quads are closed prisms

const double kEdgeClamp = 1.0lf / 256.0lf; // cutter/Isosurface.h

// ---- double arithmetic in the CPU's order (glm: dot = (x + y) + z)
double dot3(dvec3 a, dvec3 b)
{
    precise double r = a.x * b.x + a.y * b.y + a.z * b.z;
    return r;
}
dvec3 cross3(dvec3 x, dvec3 y)
{
    precise dvec3 r = dvec3(x.y * y.z - y.y * x.z, x.z * y.x - y.z * x.x, x.x * y.y - y.x * x.y);
    return r;
}
double length3(dvec3 v) { return dSqrt(dot3(v, v)); }
double planeH(dvec4 p, dvec3 x)
{
    precise double r = dot3(p.xyz, x) - p.w;
    return r;
}
/// The kernel's tie for a point: 1e-13 (1 + its largest |coordinate|).
double epsAt(dvec3 x) { return 1e-13lf * (1.0lf + max(max(abs(x.x), abs(x.y)), abs(x.z))); }
/// RemeshKernel.cpp's kApart: farther than kApart (1 + |x|) from a plane is off it.
const double kApart = 1e-9lf;

/// cutter::edgeCrossing: the crossing's fraction from the lower-keyed end.
double edgeCrossing(float valueLo, float valueHi, float isovalue)
{
    const double d = double(valueHi) - double(valueLo);
    double t = d != 0.0lf ? (double(isovalue) - double(valueLo)) / d : 0.5lf;
    if (!(t >= kEdgeClamp)) t = kEdgeClamp;
    if (t > 1.0lf - kEdgeClamp) t = 1.0lf - kEdgeClamp;
    return t;
}

/// cutter::gridVertexId: ordered by (k, j, i).
uint64_t gridVertexId(ivec3 g)
{
    const int64_t off = int64_t(1) << 20;
    return (uint64_t(int64_t(g.z) + off) << 42) | (uint64_t(int64_t(g.y) + off) << 21) | uint64_t(int64_t(g.x) + off);
}

// ---- one tet of a cell (RemeshKernel::loadTet)
struct Tet
{
    uvec2 pBits[12]; // dvec3 p[4] as bits: D3GET(T.pBits, i)
    uvec2 id[4];     // grid vertex ids as bits: u64(T.id[i])
    float value[4];
    bool inside[4];
};

Tet loadTet(uint cell, int t)
{
    const KernelCell c = kCells[cell];
    const int parity = (c.x + c.y + c.z) & 1;
    Tet T;
    for (int i = 0; i < 4; ++i) {
        const uint k = kTets[20 * parity + 4 * t + i];
        const ivec3 g = ivec3(c.x, c.y, c.z) + ivec3(int(k & 1u), int((k >> 1) & 1u), int((k >> 2) & 1u));
        D3SET(T.pBits, i, dvec3(g));
        T.id[i] = b64(gridVertexId(g));
        T.value[i] = c.values[k];
        T.inside[i] = ((c.insideMask >> k) & 1u) != 0u;
    }
    return T;
}

/// RemeshKernel::mtPoint: the crossing on tet edge (a, b).
dvec3 mtPoint(Tet T, int a, int b)
{
    int lo = a, hi = b;
    if (u64(T.id[hi]) < u64(T.id[lo])) {
        lo = b;
        hi = a;
    }
    const double t = edgeCrossing(T.value[lo], T.value[hi], uIsovalue);
    precise dvec3 r = D3GET(T.pBits, lo) + t * (D3GET(T.pBits, hi) - D3GET(T.pBits, lo));
    return r;
}

/// gatherQuads' test: can quad q's region reach the tet?
bool quadReaches(Tet T, uint q)
{
    const KernelQuad Q = kQuads[q];
    if (!uPrism) {
        bool pos = false, neg = false;
        for (int i = 0; i < 4; ++i) {
            const double h = planeH(Q.plane, D3GET(T.pBits, i)), e = epsAt(D3GET(T.pBits, i));
            pos = pos || h >= -e;
            neg = neg || h <= e;
        }
        if (!(pos && neg)) return false;
    }
    bool reach = true;
    for (uint s = Q.firstSide; s < Q.firstSide + Q.sideCount; ++s) {
        bool any = false;
        for (int i = 0; i < 4; ++i) any = any || kSides[s].orient * planeH(kSides[s].plane, D3GET(T.pBits, i)) >= -epsAt(D3GET(T.pBits, i));
        reach = reach && any;
    }
    return reach;
}

/// The even permutation of (0, 1, 2, 3) starting with `first` (count 1 or 2)
/// (the isosurface tables' evenPerm).
void evenPerm(int count, int f0, int f1, out int p[4])
{
    p[0] = f0;
    p[1] = f1;
    int n = count;
    for (int v = 0; v < 4; ++v) {
        bool used = false;
        for (int i = 0; i < count; ++i) used = used || p[i] == v;
        if (!used) p[n++] = v;
    }
    int inv = 0;
    for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) inv += p[a] > p[b] ? 1 : 0;
    if ((inv & 1) != 0) {
        const int s = p[2];
        p[2] = p[3];
        p[3] = s;
    }
}

/// RemeshKernel::isoTriangles: the tet's marching-tetrahedra polygons
/// (triCount 0..2; corners 3, or 4 for a flat quad), each corner's tet
/// edge (a | b << 2) and point, and each polygon's plane (n, d).
struct IsoPolygons
{
    int triCount;
    int corners[2];
    int edges[2][4];
    uvec2 ptsBits[24]; // dvec3 pts[2][4] as bits: D3GET(r.ptsBits, 4 * k + c)
    uvec4 planeBits[4]; // dvec4 plane[2] as bits: D4GET(r.planeBits, k)
};

IsoPolygons isoTriangles(Tet T)
{
    IsoPolygons r;
    r.triCount = 0;
    int ni = 0, no = 0, ins[4], outs[4];
    for (int i = 0; i < 4; ++i) {
        if (T.inside[i]) ins[ni++] = i;
        else outs[no++] = i;
    }
    if (ni == 0) return r;
    int p[4];
    if (ni == 1 || ni == 3) {
        evenPerm(1, ni == 1 ? ins[0] : outs[0], 0, p);
        const int a = p[0], b = p[1], c = p[2], d = p[3];
        r.triCount = 1;
        r.corners[0] = 3;
        r.edges[0][0] = a | b << 2;
        if (ni == 1) {
            r.edges[0][1] = a | c << 2;
            r.edges[0][2] = a | d << 2;
        } else {
            r.edges[0][1] = a | d << 2;
            r.edges[0][2] = a | c << 2;
        }
    } else if (ni == 2) {
        evenPerm(2, ins[0], ins[1], p);
        const int a = p[0], b = p[1], c = p[2], d = p[3];
        // The marching-tetrahedra quad; when its corners are not coplanar it
        // is the two triangles of the isosurface, a fold.
        const dvec3 pac = mtPoint(T, a, c), pad = mtPoint(T, a, d), pbd = mtPoint(T, b, d), pbc = mtPoint(T, b, c);
        const dvec3 nrm = cross3(pad - pac, pbd - pac);
        const double dev = dot3(nrm, pbc - pac) / length3(nrm);
        if (abs(dev) <= 1e-7lf) {
            r.triCount = 1;
            r.corners[0] = 4;
            r.edges[0][0] = a | c << 2;
            r.edges[0][1] = a | d << 2;
            r.edges[0][2] = b | d << 2;
            r.edges[0][3] = b | c << 2;
        } else {
            r.triCount = 2;
            r.corners[0] = 3;
            r.corners[1] = 3;
            r.edges[0][0] = a | c << 2;
            r.edges[0][1] = a | d << 2;
            r.edges[0][2] = b | d << 2;
            r.edges[1][0] = a | c << 2;
            r.edges[1][1] = b | d << 2;
            r.edges[1][2] = b | c << 2;
        }
    }
    for (int k = 0; k < r.triCount; ++k) {
        const int n = r.corners[k];
        for (int c = 0; c < n; ++c) D3SET(r.ptsBits, 4 * k + c, mtPoint(T, r.edges[k][c] & 3, r.edges[k][c] >> 2));
        dvec3 nrm = dvec3(0.0lf); // Newell
        for (int c = 0; c < n; ++c) nrm = nrm + cross3(D3GET(r.ptsBits, 4 * k + c), D3GET(r.ptsBits, 4 * k + (c + 1) % n));
        const double len = length3(nrm);
        const dvec3 unit = len > 0.0lf ? (-nrm) / len : dvec3(0.0lf);
        dvec3 centre = dvec3(0.0lf);
        for (int c = 0; c < n; ++c) centre = centre + D3GET(r.ptsBits, 4 * k + c) / double(n);
        D4SET(r.planeBits, k, dvec4(unit, dot3(unit, centre)));
    }
    return r;
}

// ---- llvmpipe's loop limit
uniform int uProbeTrips; // 2, set by the host: a trip count the compiler cannot know

/// Whether llvmpipe's loop limiter has run out in this invocation: gallivm
/// (Mesa 22.3.6) counts the iterations of every loop of an invocation
/// against one budget of 65,535 (all functions inlined into main) and,
/// once it is spent, stops every loop after one iteration, this one too.
/// Never true on a GPU without such a limit
/// (tests/test_render_cut_kernel.cpp, LoopLimitProbe*).
bool loopLimitHit()
{
    int n = 0;
    for (int i = 0; i < uProbeTrips; ++i) ++n;
    return n != uProbeTrips;
}

// ---- vertex positions from names (RemeshKernel::canonicalPosition)
const uint64_t kIso = 1ul, kIsoA = 2ul, kIsoB = 3ul, kMid = 4ul, kCentroid = 5ul;

// ---- the tet's quads and planes, found once per tet (tetBegin): the
// functions below ask these lists rather than every quad of the cell
// (which, inlined at each call, made the shaders too large to compile
// in reasonable time on llvmpipe).
#define TET_MAX_QUADS 35
#define TET_MAX_PLANES 96
int gReachQuad[TET_MAX_QUADS]; // the quads that can reach the tet (kQuads indices), the cell's order
int gReachCount;
uvec2 gTetPlaneIds[TET_MAX_PLANES]; // RemeshKernel::mPlanes's ids (as uvec2, as gIds), gathered order
uvec4 gTetPlaneBits[2 * TET_MAX_PLANES]; // dvec4 planes as bits: D4GET(gTetPlaneBits, i)
int gTetPlaneCount;
bool gTetOverflow; // more quads or planes than the lists hold
uint64_t gTetPlaneId(int i) { return packUint2x32(gTetPlaneIds[i]); }

void tetAddPlane(uint64_t id, dvec4 plane)
{
    if (gTetPlaneCount == TET_MAX_PLANES) {
        gTetOverflow = true;
        return;
    }
    gTetPlaneIds[gTetPlaneCount] = unpackUint2x32(id);
    D4SET(gTetPlaneBits, gTetPlaneCount, plane);
    ++gTetPlaneCount;
}

/// gatherQuads: the reaching quads, and the tet's planes (its iso
/// polygons', its quads' planes and sides; an id shared by quads more than
/// once, the same plane).
void tetBegin(Tet T, IsoPolygons iso, uint cell)
{
    gReachCount = 0;
    gTetPlaneCount = 0;
    gTetOverflow = false;
    const KernelCell c = kCells[cell];
    for (uint q = c.firstQuad; q < c.firstQuad + c.quadCount; ++q) {
        if (!quadReaches(T, q)) continue;
        if (gReachCount == TET_MAX_QUADS) {
            gTetOverflow = true;
            return;
        }
        gReachQuad[gReachCount++] = int(q);
    }
    // Iso polygons first, then each quad's plane (zero kerf) and sides, in
    // the cell's order: planeById's first match is RemeshKernel's plane.
    for (int k = 0; k < iso.triCount; ++k) tetAddPlane(2ul + uint64_t(k), D4GET(iso.planeBits, k)); // kIsoA, kIsoB
    for (int i = 0; i < gReachCount; ++i) {
        const int q = gReachQuad[i];
        if (!uPrism) tetAddPlane(kQuads[q].id, kQuads[q].plane);
        for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s)
            tetAddPlane(kSides[s].id, kSides[s].plane);
    }
}

/// RemeshKernel::planeById: a plane of the tet by id (tetBegin's list).
bool planeById(uint64_t id, out dvec4 plane)
{
    const uvec2 x = unpackUint2x32(id);
    for (int i = 0; i < gTetPlaneCount; ++i)
        if (gTetPlaneIds[i] == x) {
            plane = D4GET(gTetPlaneBits, i);
            return true;
        }
    plane = dvec4(0.0lf);
    return false;
}

/// The corners of tet face `mask` (3 bits) ascending by grid vertex id,
/// sorted in scalars without a loop (cut_arrange.vert: loops are counted
/// against llvmpipe's loop limit).
void faceCorners(Tet T, uint mask, out int v[3])
{
    int c[3] = int[3](-1, -1, -1);
    int n = 0;
    for (int i = 0; i < 4; ++i)
        if (((mask >> i) & 1u) != 0u) c[n++] = i;
    int a = c[0], b = c[1], d = c[2];
    if (u64(T.id[b]) < u64(T.id[a])) {
        const int s = a;
        a = b;
        b = s;
    }
    if (u64(T.id[d]) < u64(T.id[b])) {
        const int s = b;
        b = d;
        d = s;
    }
    if (u64(T.id[b]) < u64(T.id[a])) {
        const int s = a;
        a = b;
        b = s;
    }
    v = int[3](a, b, d);
}

/// The ends of tet edge `mask` (2 bits), the lower-keyed first.
void edgeEnds(Tet T, uint mask, out int a, out int b)
{
    a = -1;
    b = -1;
    for (int i = 0; i < 4; ++i)
        if (((mask >> i) & 1u) != 0u) {
            if (a < 0) a = i;
            else b = i;
        }
    if (u64(T.id[b]) < u64(T.id[a])) {
        const int s = a;
        a = b;
        b = s;
    }
}

/// RemeshKernel::faceIsoLine: the face's iso line p1, p2 (false when the
/// isosurface does not cross the face).
bool faceIsoLine(Tet T, uint mask, out dvec3 p1, out dvec3 p2)
{
    int v[3];
    faceCorners(T, mask, v);
    p1 = dvec3(0.0lf);
    p2 = dvec3(0.0lf);
    const int ni = (T.inside[v[0]] ? 1 : 0) + (T.inside[v[1]] ? 1 : 0) + (T.inside[v[2]] ? 1 : 0);
    if (ni == 0 || ni == 3) return false;
    int k = 0;
    const int ends[6] = int[6](v[0], v[1], v[0], v[2], v[1], v[2]);
    for (int e = 0; e < 3; ++e)
        if (T.inside[ends[2 * e]] != T.inside[ends[2 * e + 1]]) {
            const dvec3 x = mtPoint(T, ends[2 * e], ends[2 * e + 1]);
            if (k++ == 0) p1 = x;
            else p2 = x;
        }
    return true;
}

/// RemeshKernel::canonicalPosition: the position of the vertex named by
/// (dim, planes) on the tet's simplex `support`, made at pos0.
dvec3 canonicalPosition(Tet T, IsoPolygons iso, uint cell, uint dim, uint planeCount, uvec2 planes[8], uint support,
                        dvec3 pos0)
{
    if (dim == 0u) {
        for (int i = 0; i < 4; ++i)
            if (((support >> i) & 1u) != 0u) return D3GET(T.pBits, i);
    }
    if (dim == 3u) return pos0;
    for (uint i = 0u; i < planeCount; ++i)
        if (u64(planes[i]) == kMid || u64(planes[i]) == kCentroid) return pos0;
    dvec4 p, q;
    if (dim == 1u) {
        int a, b;
        edgeEnds(T, support, a, b);
        if (u64(planes[0]) == kIso) return mtPoint(T, a, b);
        for (uint i = 0u; i < planeCount; ++i) {
            if (!planeById(u64(planes[i]), p)) continue;
            const double ha = planeH(p, D3GET(T.pBits, a)), hb = planeH(p, D3GET(T.pBits, b));
            if (!(abs(ha - hb) > 1e-12lf)) continue;
            double t = ha / (ha - hb);
            t = t < 0.0lf ? 0.0lf : 1.0lf < t ? 1.0lf : t; // std::clamp
            precise dvec3 r = D3GET(T.pBits, a) + t * (D3GET(T.pBits, b) - D3GET(T.pBits, a));
            return r;
        }
        return pos0;
    }
    // dim 2: a face.
    if (u64(planes[0]) == kIso) {
        dvec3 p1, p2;
        if (faceIsoLine(T, support, p1, p2)) {
            const double len = length3(p2 - p1);
            for (uint i = 1u; i < planeCount; ++i) {
                if (!planeById(u64(planes[i]), p)) continue;
                const double h1 = planeH(p, p1), h2 = planeH(p, p2);
                if (!(abs(h1 - h2) > 1e-9lf * len)) continue;
                const double u = h1 / (h1 - h2);
                precise dvec3 r = p1 + u * (p2 - p1);
                return r;
            }
        }
        return pos0;
    }
    int v[3];
    faceCorners(T, support, v);
    const dvec3 A = D3GET(T.pBits, v[0]), e1 = D3GET(T.pBits, v[1]) - A, e2 = D3GET(T.pBits, v[2]) - A;
    for (uint i = 0u; i < planeCount; ++i)
        for (uint j = i + 1u; j < planeCount; ++j) {
            if (!planeById(u64(planes[i]), p) || !planeById(u64(planes[j]), q)) continue;
            const double a11 = dot3(p.xyz, e1), a12 = dot3(p.xyz, e2), b1 = -planeH(p, A);
            const double a21 = dot3(q.xyz, e1), a22 = dot3(q.xyz, e2), b2 = -planeH(q, A);
            precise double det = a11 * a22 - a12 * a21;
            if (!(abs(det) > 1e-9lf)) continue;
            precise double s = (b1 * a22 - a12 * b2) / det;
            precise double t = (a11 * b2 - b1 * a21) / det;
            precise dvec3 r = A + s * e1 + t * e2;
            return r;
        }
    return pos0;
}

// ---- naming a point (RemeshKernel::makeVertex, the planes of the name)
#define NAME_LIST_MAX 32 // planes gathered while naming, before the name's 8
const int kJunctionKind = 7, kPlusKind = 8, kMinusKind = 9;

// Plane id lists, ascending once sorted, in per-invocation globals, one row
// per list, each id as two 32-bit halves (uvec2: low, high).
const int kPlanesList = 0, kDefiningList = 1, kOnList = 2, kAddList = 3, kChosenList = 4;
uvec2 gIds[5 * NAME_LIST_MAX]; // list l, entry i: gIds[l * NAME_LIST_MAX + i]
int gIdCount[5];
bool gIdOverflow;

void idClear(int l) { gIdCount[l] = 0; }

void idPush(int l, uint64_t id)
{
    if (gIdCount[l] == NAME_LIST_MAX) {
        gIdOverflow = true;
        return;
    }
    gIds[l * NAME_LIST_MAX + gIdCount[l]++] = unpackUint2x32(id);
}

uint64_t idAt(int l, int i) { return packUint2x32(gIds[l * NAME_LIST_MAX + i]); }

bool idLess(uvec2 a, uvec2 b) { return a.y < b.y || (a.y == b.y && a.x < b.x); }

/// std::sort then std::unique, as a selection of the next larger id into a
/// scratch row (an in-place insertion sort lost entries: Mesa 22.3.6 read a
/// stale element after a store to the same array in the loop).
uvec2 gIdScratch[NAME_LIST_MAX];
void idSortUnique(int l)
{
    const int n = gIdCount[l];
    int m = 0;
    bool have = false;
    uvec2 last = uvec2(0u);
    for (int k = 0; k < n; ++k) {
        bool found = false;
        uvec2 best = uvec2(0u);
        for (int i = 0; i < n; ++i) {
            const uvec2 v = gIds[l * NAME_LIST_MAX + i];
            if (have && !idLess(last, v)) continue; // not above the last taken
            if (!found || idLess(v, best)) {
                best = v;
                found = true;
            }
        }
        if (!found) break;
        gIdScratch[m++] = best;
        last = best;
        have = true;
    }
    for (int i = 0; i < m; ++i) gIds[l * NAME_LIST_MAX + i] = gIdScratch[i];
    gIdCount[l] = m;
}

bool idHas(int l, uint64_t id)
{
    const uvec2 x = unpackUint2x32(id);
    for (int i = 0; i < gIdCount[l]; ++i)
        if (gIds[l * NAME_LIST_MAX + i] == x) return true;
    return false;
}

void idCopy(int to, int from)
{
    gIdCount[to] = gIdCount[from];
    for (int i = 0; i < gIdCount[from]; ++i) gIds[to * NAME_LIST_MAX + i] = gIds[from * NAME_LIST_MAX + i];
}

/// What the iso polygons own (RemeshKernel::triOwns once isoSurfaces ran):
/// the tet face each polygon's sides lie on, and its corners' tet edges.
struct IsoOwnership
{
    int faceTri[4];
    uint edgeMask[2][4];
};

IsoOwnership isoOwnership(IsoPolygons iso)
{
    IsoOwnership o;
    for (int f = 0; f < 4; ++f) o.faceTri[f] = -1;
    for (int k = 0; k < 2; ++k)
        for (int c = 0; c < 4; ++c) o.edgeMask[k][c] = 0u;
    for (int k = 0; k < iso.triCount; ++k) {
        const int n = iso.corners[k];
        for (int c = 0; c < n; ++c) o.edgeMask[k][c] = (1u << (iso.edges[k][c] & 3)) | (1u << (iso.edges[k][c] >> 2));
        for (int c = 0; c < n; ++c) {
            const uint m = o.edgeMask[k][c] | o.edgeMask[k][(c + 1) % n];
            if (m == 15u) continue;
            int f = 0;
            while (((m >> f) & 1u) != 0u) ++f;
            o.faceTri[f] = k;
        }
    }
    return o;
}

int bitCount4(uint m) { return int(m & 1u) + int((m >> 1) & 1u) + int((m >> 2) & 1u) + int((m >> 3) & 1u); }

bool triOwns(IsoPolygons iso, IsoOwnership o, int k, uint support)
{
    if (iso.triCount < 2) return true;
    if (bitCount4(support) == 3) {
        int f = 0;
        while (((support >> f) & 1u) != 0u) ++f;
        return o.faceTri[f] == k;
    }
    for (int c = 0; c < iso.corners[k]; ++c)
        if (o.edgeMask[k][c] == support) return true;
    return false;
}

/// RemeshKernel::faceIsoDistance: signed in-plane distance to the face's
/// iso line (+ inside), or +-1e300 when the face is not crossed.
double faceIsoDistance(Tet T, uint mask, dvec3 x)
{
    int v[3];
    faceCorners(T, mask, v);
    const int ni = (T.inside[v[0]] ? 1 : 0) + (T.inside[v[1]] ? 1 : 0) + (T.inside[v[2]] ? 1 : 0);
    if (ni == 0 || ni == 3) {
        int any = 0;
        while (((mask >> any) & 1u) == 0u) ++any;
        return T.inside[any] ? 1e300lf : -1e300lf;
    }
    dvec3 p1, p2;
    faceIsoLine(T, mask, p1, p2);
    const dvec3 nrm = cross3(D3GET(T.pBits, v[1]) - D3GET(T.pBits, v[0]), D3GET(T.pBits, v[2]) - D3GET(T.pBits, v[0]));
    const int inner = T.inside[v[0]] ? v[0] : T.inside[v[1]] ? v[1] : v[2];
    const double s = dot3(cross3(p2 - p1, D3GET(T.pBits, inner) - p1), nrm) > 0.0lf ? 1.0lf : -1.0lf;
    precise double l = length3(p2 - p1) * length3(nrm);
    precise double r = s * dot3(cross3(p2 - p1, x - p1), nrm) / l;
    return r;
}

/// RemeshKernel::edgeIsoDistance.
double edgeIsoDistance(Tet T, uint mask, dvec3 x)
{
    int a, b;
    edgeEnds(T, mask, a, b);
    if (T.inside[a] == T.inside[b]) return T.inside[a] ? 1e300lf : -1e300lf;
    const dvec3 e = D3GET(T.pBits, b) - D3GET(T.pBits, a);
    const double len = length3(e);
    precise double t = dot3(x - D3GET(T.pBits, a), e) / (len * len);
    const double ti = edgeCrossing(T.value[a], T.value[b], uIsovalue);
    precise double r = (T.inside[a] ? (ti - t) : (t - ti)) * len;
    return r;
}

/// RemeshKernel::independentPlanes: the first of `l` (with a plane in the
/// tet) whose normals are independent, at most three.
int independentPlanes(Tet T, IsoPolygons iso, uint cell, int l, out uvec2 chosen[3])
{
    int n = 0;
    dvec3 n0 = dvec3(0.0lf), n1 = dvec3(0.0lf);
    for (int i = 0; i < gIdCount[l]; ++i) {
        dvec4 pl;
        if (!planeById(idAt(l, i), pl)) continue;
        const dvec3 nn = pl.xyz;
        const bool independent = n == 0 ? length3(nn) > 0.5lf
                                 : n == 1 ? length3(cross3(n0, nn)) > 1e-6lf
                                          : abs(dot3(cross3(n0, n1), nn)) > 1e-6lf;
        if (!independent) continue;
        if (n == 0) n0 = nn;
        else n1 = nn;
        chosen[n++] = b64(idAt(l, i));
        if (n == 3) break;
    }
    return n;
}

/// The quad of the cell reaching the tet with this id, or -1 (quadById).
int reachingQuadById(uint64_t id)
{
    for (int i = 0; i < gReachCount; ++i)
        if (kQuads[gReachQuad[i]].id == id) return gReachQuad[i];
    return -1;
}

bool inClosedPrism(int q, dvec3 x, double eps)
{
    if (q < 0) return false;
    for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s)
        if (kSides[s].orient * planeH(kSides[s].plane, x) < -eps) return false;
    return true;
}

/// The planes of the name makeVertex gives the point pos0 of simplex
/// `support` made by `defining`: false (refused) when more than eight
/// remain, or when a list overflows (then `overflow`).
bool nameOf(Tet T, IsoPolygons iso, IsoOwnership own, uint cell, uint support, uvec2 defining[8], int definingCount,
            dvec3 pos0, out uvec2 name[8], out int nameCount, out bool overflow)
{
    nameCount = 0;
    gIdOverflow = false;
    const int dim = bitCount4(support) - 1;
    const double eps = epsAt(pos0);
    idClear(kPlanesList);
    idClear(kDefiningList);
    for (int i = 0; i < definingCount; ++i) {
        uint64_t p = u64(defining[i]);
        if (dim < 3 && (p == kIsoA || p == kIsoB) && triOwns(iso, own, int(p - kIsoA), support)) p = kIso;
        idPush(kDefiningList, p);
        if (p <= kIsoB) idPush(kPlanesList, p);
    }
    if (dim == 2 && abs(faceIsoDistance(T, support, pos0)) <= eps) idPush(kPlanesList, kIso);
    if (dim == 1 && abs(edgeIsoDistance(T, support, pos0)) <= eps) idPush(kPlanesList, kIso);
    for (int r = 0; r < gReachCount; ++r) {
        const uint q = uint(gReachQuad[r]);
        const uint s0 = kQuads[q].firstSide, s1 = s0 + kQuads[q].sideCount;
        if (uPrism) {
            bool inside = true, onAny = false;
            for (uint s = s0; s < s1; ++s) {
                const double h = kSides[s].orient * planeH(kSides[s].plane, pos0);
                inside = inside && h >= -eps;
                onAny = onAny || abs(h) <= eps;
            }
            if (!inside || !onAny) continue;
            for (uint s = s0; s < s1; ++s)
                if (abs(planeH(kSides[s].plane, pos0)) <= eps) idPush(kPlanesList, kSides[s].id);
        } else {
            if (!(abs(planeH(kQuads[q].plane, pos0)) <= eps)) continue;
            bool inside = true;
            for (uint s = s0; s < s1; ++s) inside = inside && kSides[s].orient * planeH(kSides[s].plane, pos0) >= -eps;
            if (!inside) continue;
            idPush(kPlanesList, kQuads[q].id);
            for (uint s = s0; s < s1; ++s)
                if (abs(planeH(kSides[s].plane, pos0)) <= eps) idPush(kPlanesList, kSides[s].id);
        }
    }
    idSortUnique(kPlanesList);
    // `on`: the planes the point lies on (made by them, or within eps).
    idCopy(kOnList, kDefiningList);
    for (int r = 0; r < gReachCount; ++r) {
        const uint q = uint(gReachQuad[r]);
        if (!uPrism && abs(planeH(kQuads[q].plane, pos0)) <= eps) idPush(kOnList, kQuads[q].id);
        for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s)
            if (abs(planeH(kSides[s].plane, pos0)) <= eps) idPush(kOnList, kSides[s].id);
    }
    for (int i = 0; i < gIdCount[kPlanesList]; ++i) idPush(kOnList, idAt(kPlanesList, i));
    idSortUnique(kOnList);
    if (uPrism) {
        // Offset planes of two quads meet on their mitre (makeVertex).
        for (int r = 0; r < gReachCount; ++r) {
            const uint q = uint(gReachQuad[r]);
            for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s) {
                const uint64_t sideId = kSides[s].id, partnerId = kSides[s].partnerId;
                if (partnerId == 0ul || !idHas(kOnList, sideId)) continue;
                if (!inClosedPrism(int(q), pos0, eps) && !inClosedPrism(reachingQuadById(partnerId), pos0, eps))
                    continue;
                for (int kind = kPlusKind; kind <= kMinusKind; ++kind) {
                    const uint64_t mine = (kQuads[q].id & ~uint64_t(15)) | uint64_t(kind);
                    const uint64_t theirs = (partnerId & ~uint64_t(15)) | uint64_t(kind);
                    if (idHas(kOnList, mine) || idHas(kOnList, theirs)) {
                        idPush(kPlanesList, sideId);
                        idPush(kPlanesList, mine);
                        idPush(kPlanesList, theirs);
                    }
                }
            }
        }
        idSortUnique(kPlanesList);
    }
    for (int round = 0; round < 4 && !uPrism; ++round) {
        idClear(kAddList);
        for (int r = 0; r < gReachCount; ++r) {
            const uint q = uint(gReachQuad[r]);
            for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s) {
                const uint64_t sideId = kSides[s].id, partnerId = kSides[s].partnerId;
                if (kSides[s].partner < 0 || !idHas(kOnList, sideId) ||
                    !(idHas(kOnList, kQuads[q].id) || idHas(kOnList, partnerId)) ||
                    reachingQuadById(partnerId) < 0)
                    continue;
                idPush(kAddList, sideId);
                idPush(kAddList, kQuads[q].id);
                idPush(kAddList, partnerId);
                for (int e = 0; e < 2; ++e) {
                    const uint64_t first = kSides[s].cornerSides[2 * e], second = kSides[s].cornerSides[2 * e + 1];
                    if (first != 0ul && second != 0ul && (idHas(kOnList, first) || idHas(kOnList, second))) {
                        idPush(kAddList, first);
                        idPush(kAddList, second);
                    }
                }
            }
        }
        if (gIdCount[kAddList] == 0) break;
        const int before = gIdCount[kOnList];
        for (int i = 0; i < gIdCount[kAddList]; ++i) idPush(kOnList, idAt(kAddList, i));
        idSortUnique(kOnList);
        for (int i = 0; i < gIdCount[kAddList]; ++i) idPush(kPlanesList, idAt(kAddList, i));
        idSortUnique(kPlanesList);
        if (gIdCount[kOnList] == before) break;
    }
    uvec2 chosen3[3];
    if (gIdCount[kPlanesList] < dim || (dim == 3 && independentPlanes(T, iso, cell, kPlanesList, chosen3) < 3)) {
        for (int i = 0; i < gIdCount[kDefiningList]; ++i) idPush(kPlanesList, idAt(kDefiningList, i));
        idSortUnique(kPlanesList);
    }
    if (gIdCount[kPlanesList] > 8 && dim == 3) {
        // A point inside the tet on more planes than a name holds: three
        // independent ones, then the lowest others.
        if (independentPlanes(T, iso, cell, kPlanesList, chosen3) == 3) {
            idClear(kChosenList);
            for (int i = 0; i < 3; ++i) idPush(kChosenList, u64(chosen3[i]));
            for (int i = 0; i < gIdCount[kPlanesList]; ++i)
                if (gIdCount[kChosenList] < 8 && !idHas(kChosenList, idAt(kPlanesList, i)))
                    idPush(kChosenList, idAt(kPlanesList, i));
            idSortUnique(kChosenList);
            idCopy(kPlanesList, kChosenList);
        }
    }
    overflow = gIdOverflow || gTetOverflow;
    for (int i = 0; i < 8; ++i) name[i] = b64(i < gIdCount[kPlanesList] ? idAt(kPlanesList, i) : 0ul);
    if (gIdCount[kPlanesList] > 8) return false;
    nameCount = gIdCount[kPlanesList];
    return true;
}
