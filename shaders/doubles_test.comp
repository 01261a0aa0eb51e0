#version 450 core
// Doubles along each path the GPU cut pass's shaders take them, written back
// bit for bit (tests/test_render_poly2.cpp, RenderPoly2.DoublesReach...).
// On NVIDIA 580.159.04 (H100) poly2_test.comp's answers equal double
// arithmetic on points rounded to float: this says on which path a double
// loses its low bits. Record i: kPaths doubles as unpackDouble2x32 pairs.
layout(local_size_x = 16) in;

layout(std430, binding = 0) readonly buffer In { dvec2 uIn[]; };
layout(std430, binding = 1) readonly buffer InScalar { double uInScalar[]; };
layout(std430, binding = 2) writeonly buffer Out { uvec2 uOut[]; };
layout(std430, binding = 3) readonly buffer Index { int uIndex[]; }; // a permutation of the inputs
uniform uint uCount;

#define PATHS 12

dvec2 gArray[16]; // a per-invocation global array, as poly2Pt
int gCount;

dvec2 passThrough(dvec2 p)
{
    return p;
}

int addPoint(dvec2 p) // as poly2AddPoint
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
    int k = int(i % 16u);
    gArray[k] = p;
    put(i, 3, gArray[k].x);               // through a global array, index unknown at compile time
    put(i, 4, passThrough(p).x);          // through a function
    gCount = 0;
    for (uint j = 0u; j < i % 5u; ++j) addPoint(dvec2(0.0lf));
    int at = addPoint(uIn[i]);
    put(i, 5, gArray[at].x);              // stored by a function into a global array, as poly2AddPoint
    precise double d = p.x - p.y;
    put(i, 6, d);                         // a difference
    precise double m = p.x * p.y;
    put(i, 7, m);                         // a product
    precise double c = (p.x - 1.0lf) * (p.y + 1.0lf) - (p.y - 1.0lf) * (p.x + 1.0lf);
    put(i, 8, c);                         // a cross product, as poly2Cross
    dvec2 o = dvec2(1.0lf, -1.0lf), a = dvec2(-1.0lf, -1.0lf);
    put(i, 9, crossPrecise(o, a, gArray[at])); // poly2Cross on a point from the global array
    put(i, 10, crossPlain(o, a, gArray[at]));
    put(i, 11, uIn[uIndex[i]].x);         // at an index read from another buffer, as poly2_test's cases
}
