#version 450 core
// Runs the poly2.glsl helpers on test cases (tests/test_render_poly2.cpp), one
// case per invocation; the library goes in front through buildProgram's
// defines. Case i: uCases[i] names the function, its points
// (uPoints[pointStart ..], indices 0.. in the case's index lists) and lists in
// uIndices: the polygon at polyStart, and holeCount hole sizes at holeStart
// followed by the holes' corners. Its answer is the POLY2_RECORD uints from
// uResults[i * POLY2_RECORD]:
//   0 the function's bool, 1 the second bool (earClip after bridgeHoles),
//   2 poly2Overflow, 3 poly2TriCount, 4 poly2PolyCount, 5-7 zero,
//   8-15 four doubles as unpackDouble2x32 (low word first; segments: the
//   four orientations poly2SegmentsIntersect tests),
//   16.. 3 POLY2_MAX_TRIS triangle indices, then POLY2_MAX corners of poly2Poly.
layout(local_size_x = 16) in;

#define POLY2_FUNC_SEGMENTS 0  // segmentsIntersect(p0 p1, p2 p3)
#define POLY2_FUNC_TRIANGLE 1  // minSine, cross2, length2 of (p0, p1, p2); same2(p0, p1)
#define POLY2_FUNC_AREA 2      // signedArea of the polygon
#define POLY2_FUNC_BEST 3      // bestTriangulation, `repeat` times into the same triangles
#define POLY2_FUNC_EARCLIP 4   // earClip, `repeat` times into the same triangles
#define POLY2_FUNC_BRIDGE 5    // bridgeHoles, then earClip of the bridged polygon when it succeeds
#define POLY2_RECORD (16 + 3 * POLY2_MAX_TRIS + POLY2_MAX)

struct Poly2Case
{
    int func;
    int repeat;
    int pointStart;
    int pointCount;
    int polyStart;
    int polyCount;
    int holeStart;
    int holeCount;
};
layout(std430, binding = 0) readonly buffer Cases { Poly2Case uCases[]; };
layout(std430, binding = 1) readonly buffer Points { dvec2 uPoints[]; };
layout(std430, binding = 2) readonly buffer Indices { int uIndices[]; };
layout(std430, binding = 3) writeonly buffer Results { uint uResults[]; };
uniform uint uCount;

bool load(Poly2Case c)
{
    poly2Reset();
    for (int i = 0; i < c.pointCount; ++i)
        if (poly2AddPoint(uPoints[c.pointStart + i]) < 0) return false;
    for (int i = 0; i < c.polyCount; ++i)
        if (!poly2AddCorner(uIndices[c.polyStart + i])) return false;
    int at = c.holeStart + c.holeCount;
    for (int h = 0; h < c.holeCount; ++h) {
        if (!poly2BeginHole()) return false;
        for (int k = 0; k < uIndices[c.holeStart + h]; ++k)
            if (!poly2AddHoleCorner(uIndices[at++])) return false;
    }
    return true;
}

void main()
{
    uint i = gl_GlobalInvocationID.x;
    if (i >= uCount) return;
    Poly2Case c = uCases[i];
    bool r0 = false, r1 = false;
    uvec2 d[4] = uvec2[4](uvec2(0u), uvec2(0u), uvec2(0u), uvec2(0u)); // the doubles as bits (poly2.glsl)
    if (load(c)) {
        if (c.func == POLY2_FUNC_SEGMENTS) {
            r0 = poly2SegmentsIntersect(poly2Pt(0), poly2Pt(1), poly2Pt(2), poly2Pt(3));
            d[0] = unpackDouble2x32(poly2Cross(poly2Pt(2), poly2Pt(3), poly2Pt(0)));
            d[1] = unpackDouble2x32(poly2Cross(poly2Pt(2), poly2Pt(3), poly2Pt(1)));
            d[2] = unpackDouble2x32(poly2Cross(poly2Pt(0), poly2Pt(1), poly2Pt(2)));
            d[3] = unpackDouble2x32(poly2Cross(poly2Pt(0), poly2Pt(1), poly2Pt(3)));
        } else if (c.func == POLY2_FUNC_TRIANGLE) {
            dvec2 a = poly2Pt(0), b = poly2Pt(1), e = poly2Pt(2);
            d[0] = unpackDouble2x32(poly2MinSine(a, b, e));
            d[1] = unpackDouble2x32(poly2Cross(a, b, e));
            precise double dx = b.x - a.x, dy = b.y - a.y;
            d[2] = unpackDouble2x32(poly2Length(dx, dy));
            r0 = poly2Same(a, b);
        } else if (c.func == POLY2_FUNC_AREA) {
            d[0] = unpackDouble2x32(poly2SignedArea());
        } else if (c.func == POLY2_FUNC_BEST || c.func == POLY2_FUNC_EARCLIP) {
            for (int k = 0; k < c.repeat; ++k) {
                r0 = c.func == POLY2_FUNC_BEST ? poly2BestTriangulation() : poly2EarClip();
                if (!r0) break;
            }
        } else if (c.func == POLY2_FUNC_BRIDGE) {
            r0 = poly2BridgeHoles();
            if (r0) r1 = poly2EarClip();
        }
    }
    uint base = i * uint(POLY2_RECORD);
    uResults[base + 0u] = r0 ? 1u : 0u;
    uResults[base + 1u] = r1 ? 1u : 0u;
    uResults[base + 2u] = poly2Overflow ? 1u : 0u;
    uResults[base + 3u] = uint(poly2TriCount);
    uResults[base + 4u] = uint(poly2PolyCount);
    for (uint k = 5u; k < 8u; ++k) uResults[base + k] = 0u;
    for (int k = 0; k < 4; ++k) {
        uvec2 w = d[k];
        uResults[base + 8u + 2u * uint(k)] = w.x;
        uResults[base + 9u + 2u * uint(k)] = w.y;
    }
    for (int k = 0; k < 3 * POLY2_MAX_TRIS; ++k)
        uResults[base + 16u + uint(k)] = k < poly2TriCount ? uint(poly2Tri[k]) : 0xffffffffu;
    for (int k = 0; k < POLY2_MAX; ++k)
        uResults[base + 16u + uint(3 * POLY2_MAX_TRIS + k)] = k < poly2PolyCount ? uint(poly2Poly[k]) : 0xffffffffu;
}
