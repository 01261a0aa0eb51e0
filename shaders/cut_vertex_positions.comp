#version 450 core
// The GPU re-meshing kernel's vertex positions from names
// (canonicalPosition in cut_kernel.glsl) for a list of vertices the CPU
// kernel made, one invocation each, for the tests that hold them equal
// (tests/test_render_cut_kernel.cpp; layout: render/CutKernelGpu.h).
layout(local_size_x = 64) in;
struct VertexQuery
{
    uint cell, tet, dim, planeCount, support, pad0, pad1, pad2;
    uvec2 planes[8]; // uint64_t as bits (cut_kernel.glsl, u64): the layout of uint64_t[8]
    dvec4 pos0;
};
layout(std430, binding = 4) readonly buffer Queries { VertexQuery uQueries[]; };
layout(std430, binding = 5) writeonly buffer Positions { double outPos[]; };
uniform uint uQueryCount;

void main()
{
    const uint i = gl_GlobalInvocationID.x;
    if (i >= uQueryCount) return;
    const VertexQuery q = uQueries[i];
    const Tet T = loadTet(q.cell, int(q.tet));
    const IsoPolygons iso = isoTriangles(T);
    tetBegin(T, iso, q.cell);
    const dvec3 p = canonicalPosition(T, iso, q.cell, q.dim, q.planeCount, q.planes, q.support, q.pos0.xyz);
    outPos[3u * i] = p.x;
    outPos[3u * i + 1u] = p.y;
    outPos[3u * i + 2u] = p.z;
}
