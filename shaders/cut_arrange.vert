#version 450 core
// The GPU re-meshing kernel's arrangement of each tet (cut_arrange.glsl)
// of a range of tets (5 per cell), written for the tests that hold it
// equal to the CPU kernel's (tests/test_render_cut_kernel.cpp; record
// layout: render/CutKernelGpu.cpp), each into its own slot of the records
// (a record past its slot: the header alone, failed with bit 9).
//
// A vertex shader drawn as points with the rasterizer off, one vertex per
// tet, uLaneStride vertices apart (the others return at once), as the
// paper ran its kernel: on llvmpipe a compute shader is an LLVM coroutine,
// and splitting this one took LLVM about 8 minutes against 1.5 for the
// vertex shader. llvmpipe also stops every loop of an invocation after
// 65535 loop iterations in all (gallivm's loop limiter, one per shader
// function, all of it inlined here): a tet that could have met it is
// flagged (bit 10) by a probe loop at the end, never returned truncated.
layout(std430, binding = 5) writeonly buffer Records { uint64_t outRecord[]; };
uniform uint uFirstTet;
uniform uint uTetCount;
uniform uint uSlotWords; // words of each invocation's slot of Records
uniform uint uLaneStride; // vertices per tet (one arranging, the rest idle)
uniform int uProbeTrips;  // 2: the probe loop's trip count, unknown to the compiler

const uint kFailSlot = 512u, kFailLoopLimit = 1024u;

/// Whether llvmpipe's loop limiter has run out in this invocation: then
/// every loop stops after one iteration, this one too.
bool loopLimitHit()
{
    int n = 0;
    for (int i = 0; i < uProbeTrips; ++i) ++n;
    return n != uProbeTrips;
}

uint gAt;       // next word of this record
uint gSlotEnd;  // the end of this invocation's slot

void put(uint64_t w)
{
    if (gAt < gSlotEnd) outRecord[gAt] = w;
    ++gAt;
}

void putDouble(double d) { put(doubleBitsToUint64(d)); }

/// Arranges tet `tet` and puts its record at gAt (a tet without solid:
/// ~0 alone).
void emitTet(uint slot, uint tet)
{
    const uint headerAt = gAt;
    if (!arrangeTetBegin(slot, tet / 5u, int(tet % 5u))) {
        put(~0ul);
        return;
    }
    put(uint64_t(tet));
    put(0ul); // vertices | surfaces << 32, once known
    int surfaces = 0;
    for (int s = 0; s < gSurfaceCount && gFail == 0u; ++s) {
        arrangeSurface(s);
        if (gFail != 0u) break;
        ++surfaces;
        put(gSPlane[s]);
        put(uint64_t(gPieceCount[0]));
        for (int i = 0; i < gPieceCount[0]; ++i) {
            const int n = pieceLen(0, i);
            put(uint64_t(n) | uint64_t(gKept[i] ? 1u : 0u) << 32);
            for (int k = 0; k < n; ++k) {
                put(uint64_t(pieceV(0, i, k)));
                put(pieceL(0, i, k));
            }
        }
    }
    if (gFail == 0u) {
        for (int v = 0; v < gVertCount; ++v) {
            put(uint64_t(gVMeta(v)));
            for (int i = 0; i < 3; ++i) put(gVFeature(3 * v + i));
            for (int i = 0; i < 8; ++i) put(gVPlanes(8 * v + i));
            putDouble(gVPos(v).x);
            putDouble(gVPos(v).y);
            putDouble(gVPos(v).z);
        }
    }
    if (gAt > gSlotEnd) gFail |= kFailSlot; // past the slot: the header alone
    if (loopLimitHit()) gFail |= kFailLoopLimit;
    if (gFail != 0u) {
        outRecord[headerAt] = uint64_t(tet) | uint64_t(gFail) << 32;
        outRecord[headerAt + 1u] = 0ul;
        return;
    }
    outRecord[headerAt + 1u] = uint64_t(gVertCount) | uint64_t(surfaces) << 32;
}

void main()
{
    const uint vertex = uint(gl_VertexID);
    if (vertex % uLaneStride != 0u || vertex / uLaneStride >= uTetCount) return;
    const uint slot = vertex / uLaneStride;
    gAt = slot * uSlotWords;
    gSlotEnd = gAt + uSlotWords;
    emitTet(slot, uFirstTet + slot);
}
