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
// function, all of it inlined here), so a tet is arranged in stages, one
// draw each, its state kept in its scratch slice between them (uStage 0:
// arrangeTetBegin; 1 + 2 s and 2 + 2 s: surface s split, then made
// conforming, classified and written; kStageEnd: the vertex table and the
// header); a stage that could have met the limit flags the tet (bit 10:
// a probe loop at its very end, after its state is saved: flagLoopLimit),
// never returns it truncated. Each draw runs
// the slots in tetList: stage 0 all, then those with surface s (tetStatus:
// the surface count, -1 failed, -2 no solid), the end those with solid.
const int kStageEnd = 1 + 2 * ARR_MAX_SURFACES;

/// Stage 0: the tet's vertex table, surfaces and split order; the record's
/// header (~0 alone for a tet without solid).
void stageBegin(uint slot, uint tet)
{
    if (!arrangeTetBegin(slot, tet / 5u, int(tet % 5u))) {
        put(~0ul);
        saveTetState(gAt, false);
        tetStatus[slot] = -2;
        return;
    }
    put(uint64_t(tet));
    put(0ul); // vertices | surfaces << 32, at the end
    put(0ul); // nodes | triangles << 32 (cut_regions.vert)
    saveTetState(gAt, true);
    flagLoopLimit();
    tetStatus[slot] = gFail == 0u ? gSurfaceCount : -1;
}

/// Stage 1 + 2 s: surface s split by the tet's planes (splitSurface; its
/// pieces stay in region 0 of the pool, their counts in the state).
void stageSplit(uint slot, uint tet, int s)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at) || gFail != 0u || s >= gSurfaceCount) return;
    splitSurface(s);
    saveTetState(at, true);
    gStateI(14) = gPieceCount[0];
    gStateI(15) = gPoolUsed[0];
    flagLoopLimit();
}

/// Stage 2 + 2 s: surface s's pieces made conforming, classified and given
/// their slit midpoints, and written into the record.
void stageFinish(uint slot, uint tet, int s)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at) || gFail != 0u || s >= gSurfaceCount) return;
    gAt = at;
    gPieceCount[0] = gStateI(14);
    gPoolUsed[0] = gStateI(15);
    poolClear(1);
    finishSurface(s);
    if (gFail == 0u) {
        put(u64(gSPlane[s]));
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
    saveTetState(gAt, true);
    savePieces(); // for cut_regions.vert's trace of surface s
    flagLoopLimit();
}

/// The last stage: the vertex table, then the header (a failed tet: the
/// header alone, its fail bits in it); tetStatus then holds the record's
/// length in words.
void stageEnd(uint slot, uint tet, uint headerAt)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at)) return;
    gAt = at;
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
    saveTetState(gAt, true); // its verdict, for cut_regions.vert's kStageEmit
    flagLoopLimit();
    if (gFail != 0u) {
        outRecord[headerAt] = uint64_t(tet) | uint64_t(gFail) << 32;
        outRecord[headerAt + 1u] = 0ul;
        outRecord[headerAt + 2u] = 0ul;
        tetStatus[slot] = 3;
        return;
    }
    outRecord[headerAt + 1u] = uint64_t(gVertCount) | uint64_t(gSurfaceCount) << 32;
    tetStatus[slot] = int(gAt - headerAt); // the record's words, for the host to read only those
}

void main()
{
    uint slot, tet;
    if (!stageSlot(slot, tet)) return;
    if (uStage == 0) stageBegin(slot, tet);
    else if (uStage == kStageEnd) stageEnd(slot, tet, gAt);
    else if ((uStage & 1) == 1) stageSplit(slot, tet, (uStage - 1) / 2);
    else stageFinish(slot, tet, (uStage - 2) / 2);
}
