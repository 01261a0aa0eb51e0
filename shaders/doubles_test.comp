#version 450 core
// Doubles along each path and in each kind of storage a shader can keep them
// in, written back bit for bit (tests/test_render_poly2.cpp,
// RenderPoly2.DoublesReachTheShaderUnrounded). On NVIDIA 580.159.04 (H100) a
// dvec2 kept in a private array indexed at run time came back rounded to
// float (paths 3 and 5), while buffers, functions and arithmetic kept every
// bit: this says which storage the cut pass's shaders may use for doubles.
// A uint64_t kept in a private array came back changed too (4,096 of 4,096,
// third H100 lease), so the shaders keep 64-bit integers there as uvec2.
// There, writing a dvec3's component at a run-time index (v[k] = x) does not
// link ("fatal error C9999: can't find __setVectorIndex function in
// stdlib"), so it is not among the paths. Division and square root: GLSL
// asks no correct rounding of them; the driver's are recorded, and
// doubles.glsl's corrections (dDivFrom, dSqrtFrom, put in front of this file)
// from a quotient and a root an ulp off.
// Record i: PATHS doubles as unpackDouble2x32 pairs.
layout(local_size_x = 16) in;

layout(std430, binding = 0) readonly buffer In { dvec2 uIn[]; };
layout(std430, binding = 1) readonly buffer InScalar { double uInScalar[]; };
layout(std430, binding = 2) writeonly buffer Out { uvec2 uOut[]; };
layout(std430, binding = 3) readonly buffer Index { int uIndex[]; }; // a permutation of the inputs
uniform uint uCount;

#define PATHS 29

dvec2 gArray[16]; // a per-invocation global array
int gCount;
double gScalars[16];
dvec3 gVec3[16];
dvec4 gVec4[16];
uvec4 gBits2[16];  // dvec2 as bits (poly2.glsl's poly2PtBits)
uvec2 gBits[16];   // double as bits
uint64_t gU64[16]; // double as doubleBitsToUint64
struct WithArray
{
    dvec3 p[4];
    int n;
};
WithArray gStruct;

dvec2 passThrough(dvec2 p)
{
    return p;
}

int addPoint(dvec2 p) // a function storing into a global array
{
    gArray[gCount] = p;
    return gCount++;
}

double crossPrecise(dvec2 o, dvec2 a, dvec2 b) // as poly2Cross
{
    precise double r = (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    return r;
}

double crossPlain(dvec2 o, dvec2 a, dvec2 b) // the same without precise (may fuse: compared loosely)
{
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

void fillOut(dvec3 v, int k, out dvec3 pp[4]) // an out array parameter (as cut_arrange's capSection had)
{
    for (int j = 0; j < 4; ++j) pp[j] = dvec3(0.0lf);
    pp[k] = v;
}

void put(uint i, int path, double v)
{
    uOut[i * uint(PATHS) + uint(path)] = unpackDouble2x32(v);
}

void main()
{
    uint i = gl_GlobalInvocationID.x;
    if (i >= uCount) return;
    dvec2 p = uIn[i];
    put(i, 0, p.x);                       // a dvec2 from a buffer
    put(i, 1, p.y);
    put(i, 2, uInScalar[2u * i]);         // a double from a buffer
    int k = int(i % 16u);                 // an index known at run time only
    gArray[k] = p;
    put(i, 3, gArray[k].x);               // a global dvec2 array
    put(i, 4, passThrough(p).x);          // through a function
    gCount = 0;
    for (uint j = 0u; j < i % 5u; ++j) addPoint(dvec2(0.0lf));
    int at = addPoint(uIn[i]);
    put(i, 5, gArray[at].x);              // stored by a function into a global dvec2 array
    precise double d = p.x - p.y;
    put(i, 6, d);                         // a difference
    precise double m = p.x * p.y;
    put(i, 7, m);                         // a product
    precise double c = (p.x - 1.0lf) * (p.y + 1.0lf) - (p.y - 1.0lf) * (p.x + 1.0lf);
    put(i, 8, c);                         // a cross product, as poly2Cross
    gBits2[at] = uvec4(unpackDouble2x32(p.x), unpackDouble2x32(p.y));
    const dvec2 q = dvec2(packDouble2x32(gBits2[at].xy), packDouble2x32(gBits2[at].zw));
    dvec2 o = dvec2(1.0lf, -1.0lf), a = dvec2(-1.0lf, -1.0lf);
    put(i, 9, crossPrecise(o, a, q));     // poly2Cross on a point kept as bits
    put(i, 10, crossPlain(o, a, q));
    put(i, 11, uIn[uIndex[i]].x);         // at an index read from another buffer
    gScalars[k] = p.x;
    put(i, 12, gScalars[k]);              // a global double array
    gVec3[k] = dvec3(p.y, p.x, p.y);
    put(i, 13, gVec3[k].y);               // a global dvec3 array (as cut_arrange's gSNormal was)
    gVec4[k] = dvec4(p.y, p.y, p.x, p.y);
    put(i, 14, gVec4[k].z);               // a global dvec4 array (as cut_kernel's gTetPlane was)
    dvec2 local2[16];
    local2[k] = p;
    put(i, 15, local2[k].x);              // a function's dvec2 array
    double local1[16];
    local1[k] = p.x;
    put(i, 16, local1[k]);                // a function's double array (as poly2's best was)
    gStruct.p[k % 4] = dvec3(p.y, p.y, p.x);
    put(i, 17, gStruct.p[k % 4].z);       // an array in a global struct (as cut_kernel's Tet.p was)
    const dvec3 v = dvec3(p.x, 2.0lf * p.x, 4.0lf * p.x);
    put(i, 18, v[k % 3]);                 // a vector's component read at a run-time index: 2^(k % 3) x
    put(i, 19, q.x);                      // a dvec2 kept as bits (uvec4)
    gBits[k] = unpackDouble2x32(p.x);
    put(i, 20, packDouble2x32(gBits[k])); // a double kept as bits (uvec2)
    gU64[k] = doubleBitsToUint64(p.x);
    put(i, 21, uint64BitsToDouble(gU64[k])); // a double kept as uint64_t bits
    dvec3 pp[4];
    fillOut(dvec3(p.x, p.y, p.y), k % 4, pp);
    put(i, 22, pp[k % 4].x);              // through an out array parameter
    precise double quotient = p.x / p.y;
    put(i, 23, quotient);                 // the driver's division
    precise double root = sqrt(abs(p.x));
    put(i, 24, root);                     // the driver's square root
    // The corrections from a quotient and a root an ulp off (every other
    // input; the rest from the driver's), so that they are tested anywhere.
    const bool off = (i & 1u) == 1u, up = (i & 2u) != 0u;
    const bool qOff = off && quotient != 0.0lf && !isinf(quotient) && !isnan(quotient);
    const bool rOff = off && root != 0.0lf && !isinf(root) && !isnan(root);
    put(i, 25, dDivFrom(p.x, p.y, qOff ? dNext(quotient, up) : quotient));
    put(i, 26, dSqrtFrom(abs(p.x), rOff ? dNext(root, up) : root));
    put(i, 27, crossPrecise(p, dvec2(-1.0lf, 2.0lf), p)); // (a - p) x (p - p): zero, its sign as the C++'s
    put(i, 28, dSqrt(abs(p.x)));          // the root the shaders take
}
