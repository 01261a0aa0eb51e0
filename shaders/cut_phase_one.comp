#version 450 core
// Phase one of the GPU re-meshing kernel (cut_kernel.glsl) for every tet of
// the packed cells, one invocation per (cell, tet), its results written out
// for the tests that hold it equal to the CPU kernel's
// (tests/test_render_cut_kernel.cpp; layout: render/CutKernelGpu.h).
layout(local_size_x = 64) in;
layout(std430, binding = 4) writeonly buffer OutU { uint outU[]; };
layout(std430, binding = 5) writeonly buffer OutD { double outD[]; };
uniform uint uTetCount;

const uint kStrideU = 48u, kStrideD = 32u, kMaxQuads = 35u;

void main()
{
    const uint g = gl_GlobalInvocationID.x;
    if (g >= uTetCount) return;
    const uint cell = g / 5u;
    const Tet T = loadTet(cell, int(g % 5u));
    const uint u = g * kStrideU, d = g * kStrideD;
    for (uint i = 0u; i < kStrideU; ++i) outU[u + i] = 0u;
    for (uint i = 0u; i < kStrideD; ++i) outD[d + i] = 0.0lf;
    if (!T.inside[0] && !T.inside[1] && !T.inside[2] && !T.inside[3]) return;
    uint flags = 1u, count = 0u;
    const KernelCell c = kCells[cell];
    for (uint q = 0u; q < c.quadCount; ++q) {
        if (!quadReaches(T, c.firstQuad + q)) continue;
        if (count == kMaxQuads) {
            flags |= 2u; // more than the output holds
            break;
        }
        outU[u + 13u + count++] = q;
    }
    const IsoPolygons iso = isoTriangles(T);
    outU[u] = flags;
    outU[u + 1u] = count;
    outU[u + 2u] = uint(iso.triCount);
    for (int k = 0; k < iso.triCount; ++k) {
        outU[u + 3u + uint(k)] = uint(iso.corners[k]);
        for (int i = 0; i < iso.corners[k]; ++i) {
            outU[u + 5u + uint(4 * k + i)] = uint(iso.edges[k][i]);
            for (int j = 0; j < 3; ++j) outD[d + uint(12 * k + 3 * i + j)] = packDouble2x32(iso.ptsBits[3 * (4 * k + i) + j]);
        }
        for (int j = 0; j < 4; ++j) outD[d + 24u + uint(4 * k + j)] = D4GET(iso.planeBits, k)[j];
    }
}
