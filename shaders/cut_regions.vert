#version 450 core
// The regions and triangles of each tet (cut_regions.glsl) after its
// arrangement (cut_arrange.vert), as further stages over the same slots,
// scratch and records, drawn as cut_arrange.vert is (points, rasterizer
// off, one tet per uLaneStride vertices; a stage that could have met
// llvmpipe's loop limit flags the tet, bit 10). The host interleaves them:
// cut_arrange.vert splits and finishes surface s, then stage s here traces
// its regions (before the next surface's split takes the piece pool);
// once every surface is traced, kStageCorners marks the corners, stage
// kStageCorners + 1 + s triangulates surface s's regions into the record,
// kStageClose writes the node table (and the header's node and triangle
// counts), and cut_arrange.vert's last stage the vertex table; when the
// host draws the cut geometry from this output, kStageEmit then writes
// each tet's triangles into the draw buffers (cut_regions.glsl, pass 3).
const int kStageCorners = ARR_MAX_SURFACES, kStageClose = 2 * ARR_MAX_SURFACES + 1, kStageEmit = kStageClose + 1;

/// Stage s < kStageCorners: surface s's regions traced.
void stageTrace(uint slot, uint tet, int s)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at) || gFail != 0u || s >= gSurfaceCount) return;
    restorePieces();
    if (s == 0) regionsReset();
    traceSurface(s);
    saveTetState(at, true);
    flagLoopLimit();
}

/// kStageCorners: the corners of every loop (markCorners).
void stageCorners(uint slot, uint tet)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at) || gFail != 0u) return;
    markCorners();
    gRC(6) = int(at); // the triangles follow
    saveTetState(at, true);
    flagLoopLimit();
}

/// kStageCorners + 1 + s: surface s's regions triangulated into the record.
void stageTriangulate(uint slot, uint tet, int s)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at) || gFail != 0u || s >= gSurfaceCount) return;
    gAt = at;
    triangulateSurface(s);
    saveTetState(gAt, true);
    flagLoopLimit();
}

/// kStageClose: the node table, and the header's counts.
void stageClose(uint slot, uint tet, uint headerAt)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at) || gFail != 0u) return;
    gAt = at;
    // kStageEmit stays within the loop limit by far (some 100 loop trips a
    // triangle); a tet of more triangles is left to the CPU.
    if (gRC(4) > 256) gFail |= kFailRegions;
    putNodes();
    outRecord[headerAt + 2u] = uint64_t(gRC(0)) | uint64_t(gRC(4)) << 32;
    saveTetState(gAt, true);
    flagLoopLimit();
}

/// kStageEmit, after cut_arrange.vert's last stage: the tet's triangles
/// into the draw buffers, when no tet of its cell was flagged (the CPU
/// re-meshes such a cell whole).
void stageEmit(uint slot, uint tet)
{
    uint at;
    if (!restoreTetState(slot, tet / 5u, int(tet % 5u), at) || gFail != 0u || !cellComplete(slot, tet)) return;
    emitTriangles(tet);
}

void main()
{
    uint slot, tet;
    if (!stageSlot(slot, tet)) return;
    if (uStage < kStageCorners) stageTrace(slot, tet, uStage);
    else if (uStage == kStageCorners) stageCorners(slot, tet);
    else if (uStage < kStageClose) stageTriangulate(slot, tet, uStage - kStageCorners - 1);
    else if (uStage == kStageClose) stageClose(slot, tet, gAt);
    else stageEmit(slot, tet);
}
