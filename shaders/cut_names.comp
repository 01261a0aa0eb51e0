#version 450 core
// The GPU re-meshing kernel's names (nameOf in cut_kernel.glsl: the planes
// makeVertex names a point by) for a list of calls the CPU kernel made, one
// invocation each, for the tests that hold them equal
// (tests/test_render_cut_kernel.cpp; layout: render/CutKernelGpu.h).
layout(local_size_x = 64) in;
struct NameQuery
{
    uint cell, tet, support, definingCount, pad0, pad1, pad2, pad3;
    uvec2 defining[8]; // uint64_t as bits (cut_kernel.glsl, u64): the layout of uint64_t[8]
    dvec4 pos0;
};
layout(std430, binding = 4) readonly buffer Queries { NameQuery uQueries[]; };
layout(std430, binding = 5) writeonly buffer Names { uint64_t outNames[]; }; // 10 per query
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
    uvec2 defining[8];
    for (int k = 0; k < 8; ++k) defining[k] = uQueries[i].defining[k];
    const Tet T = loadTet(cell, int(tet));
    const IsoPolygons iso = isoTriangles(T);
    tetBegin(T, iso, cell);
    const IsoOwnership own = isoOwnership(iso);
    uvec2 name[8];
    int count;
    bool overflow;
    const bool named = nameOf(T, iso, own, cell, uQueries[i].support, defining, int(uQueries[i].definingCount), pos0, name, count,
                              overflow);
    outNames[10u * i] = uint64_t((named ? 1u : 0u) | (overflow ? 2u : 0u));
    outNames[10u * i + 1u] = uint64_t(count);
    for (int k = 0; k < 8; ++k) outNames[10u * i + 2u + uint(k)] = u64(name[k]);
}
