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
    // Each field read from the buffer, not the struct copied: this driver
    // (NVIDIA 580) changed the double of a private copy of the struct, as it
    // changes doubles kept in private arrays (test_render_poly2's probe).
    const uint cell = uQueries[i].cell, tet = uQueries[i].tet;
    const dvec3 pos0 = uQueries[i].pos0.xyz;
    uvec2 planes[8];
    for (int k = 0; k < 8; ++k) planes[k] = uQueries[i].planes[k];
    const Tet T = loadTet(cell, int(tet));
    const IsoPolygons iso = isoTriangles(T);
    tetBegin(T, iso, cell);
    const dvec3 p = canonicalPosition(T, iso, cell, uQueries[i].dim, uQueries[i].planeCount, planes, uQueries[i].support, pos0);
    outPos[3u * i] = p.x;
    outPos[3u * i + 1u] = p.y;
    outPos[3u * i + 2u] = p.z;
}
