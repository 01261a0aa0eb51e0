// The re-meshing kernel's arrangement of one tet (cutter/RemeshKernel.cpp,
// remeshTet up to the regions), ported to GLSL after cut_kernel.glsl (whose
// rules hold here too: the CPU's doubles in the CPU's order, `precise`
// wherever a product feeds a sum). One invocation arranges one tet:
// - the vertex table (makeVertex: a point's name, the lowest vertex of that
//   name, the merge of one inside point made by different planes, a new
//   vertex placed by its name; makeSteiner);
// - sides of planes and membership in the solid (sign, member), computed
//   each time: the CPU memoises them, but they are functions of the vertex
//   table, so the values are the same;
// - the surfaces (isoSurfaces, capSurfaces), the order of the split planes
//   (chooseSplitOrder), and per surface its pieces: split by the planes
//   (splitSurface, splitPoly), made conforming (conformPieces, pushSimple
//   without recursion), classified (classifyPieces) and given their slit
//   midpoints (insertSlitMidpoints).
// The tet's state lives in per-invocation globals (the g* below) with fixed
// capacities; a tet past one of them is flagged (gFail) for the CPU to
// take, never truncated. Lists that a loop reads and writes are kept in
// separate regions (cut_kernel.glsl's sort: there Mesa 22.3.6 seemed to
// read a stale element; more likely, as found here later, llvmpipe's loop
// limiter had cut the loops short: cut_arrange.vert).
// Checked against the CPU, piece for piece and bit for bit, by
// tests/test_render_cut_kernel.cpp.

// Capacities: the host defines them (render/CutKernelGpu.cpp, which sizes
// the scratch buffers by them); these defaults let the file compile alone.
#ifndef ARR_MAX_VERTS
#define ARR_MAX_VERTS 256
#define ARR_MAX_PLANES 96
#define ARR_MAX_SURFACES 24
#define ARR_MAX_PIECES 64  // per region of the piece pool
#define ARR_MAX_POOL 640   // corners per region of the piece pool
#define ARR_MAX_NODES 256  // region corners: (vertex, side tags) (cut_regions.glsl)
#define ARR_MAX_REGIONS 48
#define ARR_MAX_LOOPS 64
#define ARR_MAX_LOOP_CORNERS 768
#endif
#define ARR_MAX_CORNERS 48 // corners of one piece

const uint64_t kBoundaryLabel = 1ul << 63;
// gFail bits: what stopped the tet.
const uint kFailVerts = 1u, kFailPlanes = 2u, kFailSurfaces = 4u, kFailPieces = 8u, kFailPool = 16u,
           kFailCorners = 32u, kFailNameLists = 64u, kFailRegions = 128u;
// The CPU refuses the cell here (a point on more than 8 planes; a region's
// loops that do not close or cannot be triangulated: cut_regions.glsl).
const uint kRefused = 256u;
const uint kFailSlot = 512u, kFailLoopLimit = 1024u; // the record past its slot; llvmpipe's loop limit
const uint kFailMidpoints = 2048u; // insertSlitMidpoints' lists full
uint gFail;

// ---- the tet's record (render/CutKernelGpu.cpp parses it): written at
// gAt, up to its slot's end (a record past it: the header alone, bit 9)
layout(std430, binding = 5) buffer Records { uint64_t outRecord[]; };
uint gAt;      // next word of this record
uint gSlotEnd; // the end of this invocation's slot

void put(uint64_t w)
{
    if (gAt < gSlotEnd) outRecord[gAt] = w;
    ++gAt;
}

void putDouble(double d) { put(doubleBitsToUint64(d)); }

// ---- the staged draws (cut_arrange.vert, cut_regions.vert): one vertex
// per tet, uLaneStride vertices apart, over the slots in tetList
layout(std430, binding = 4) readonly buffer TetList { uint tetList[]; };   // the slots this draw arranges
layout(std430, binding = 9) writeonly buffer TetStatus { int tetStatus[]; }; // per slot: after stage 0, after the end
uniform uint uFirstTet;   // the tet of slot 0
uniform uint uListCount;  // entries of tetList
uniform uint uSlotWords;  // words of each invocation's slot of Records
uniform uint uLaneStride; // vertices per tet (one arranging, the rest idle)
uniform int uStage;       // the stage (each .vert numbers its own)

/// This vertex's slot and tet, gAt at the slot's start; false for the
/// idle lanes and those past the list.
bool stageSlot(out uint slot, out uint tet)
{
    const uint vertex = uint(gl_VertexID);
    slot = 0u;
    tet = 0u;
    if (vertex % uLaneStride != 0u || vertex / uLaneStride >= uListCount) return false;
    slot = tetList[vertex / uLaneStride];
    tet = uFirstTet + slot;
    gAt = slot * uSlotWords;
    gSlotEnd = gAt + uSlotWords;
    return true;
}

// The big per-tet lists live in scratch storage, one slice per invocation
// (the host binds room for its batch): as private arrays they made
// llvmpipe's compile of the compute shader this was first (LLVM's
// coroutine frame) take many minutes.
layout(std430, binding = 6) buffer ArrangeScratchI { int sI[]; };
layout(std430, binding = 7) buffer ArrangeScratchL { uint64_t sL[]; };
layout(std430, binding = 8) buffer ArrangeScratchD { double sD[]; };
const uint kOffVMeta = 0u, kOffPV = kOffVMeta + ARR_MAX_VERTS, kOffPieceStart = kOffPV + 3 * ARR_MAX_POOL,
           kOffPieceLen = kOffPieceStart + 3 * ARR_MAX_PIECES, kOffSplitOwner = kOffPieceLen + 3 * ARR_MAX_PIECES,
           kOffPlaneOrder = kOffSplitOwner + ARR_MAX_PLANES, kOffStateI = kOffPlaneOrder + ARR_MAX_PLANES,
           kOffRegionsI = kOffStateI + 16 + 12 * ARR_MAX_SURFACES,
           kOffKept = kOffRegionsI, // region 0's kept flags, between the finish and trace stages
           // the rest of the regions' part: cut_regions.glsl
           kScratchI = kOffRegionsI + 4 * ARR_MAX_PIECES + 8 + 5 * ARR_MAX_NODES + 2 * ARR_MAX_VERTS +
                       5 * ARR_MAX_REGIONS + 2 * ARR_MAX_LOOPS + ARR_MAX_LOOP_CORNERS + 11 * ARR_MAX_POOL;
const uint kOffVFeature = 0u, kOffVPlanes = kOffVFeature + 3 * ARR_MAX_VERTS, kOffPL = kOffVPlanes + 8 * ARR_MAX_VERTS,
           kOffSplitId = kOffPL + 3 * ARR_MAX_POOL, kOffStateL = kOffSplitId + ARR_MAX_PLANES,
           kOffRegionsL = kOffStateL + 5 * ARR_MAX_SURFACES,
           kScratchL = kOffRegionsL + 4 * ARR_MAX_NODES + ARR_MAX_LOOP_CORNERS + ARR_MAX_POOL;
const uint kOffVPos = 0u, kOffStateD = kOffVPos + 3 * ARR_MAX_VERTS, kOffRegionsD = kOffStateD + 3 * ARR_MAX_SURFACES,
           kScratchD = kOffRegionsD + 3 * ARR_MAX_REGIONS;
#ifdef ARR_SCRATCH_I
// The host's scratch sizes (render/CutKernelGpu.cpp, which allocates by
// them) must be these: an array of size -1 does not compile.
int gHostScratchCheck[kScratchI == ARR_SCRATCH_I && kScratchL == ARR_SCRATCH_L && kScratchD == ARR_SCRATCH_D ? 1 : -1];
#endif
uint gBaseI, gBaseL, gBaseD; // this invocation's slices
#define gVMeta(v) uint(sI[gBaseI + kOffVMeta + uint(v)])
#define gVMetaRef(v) sI[gBaseI + kOffVMeta + uint(v)]
#define gPV(i) sI[gBaseI + kOffPV + uint(i)]
#define gPieceStart(i) sI[gBaseI + kOffPieceStart + uint(i)]
#define gPieceLen(i) sI[gBaseI + kOffPieceLen + uint(i)]
#define gSplitOwner(i) sI[gBaseI + kOffSplitOwner + uint(i)]
#define gPlaneOrder(i) sI[gBaseI + kOffPlaneOrder + uint(i)]
#define gVFeature(i) sL[gBaseL + kOffVFeature + uint(i)]
#define gVPlanes(i) sL[gBaseL + kOffVPlanes + uint(i)]
#define gPL(i) sL[gBaseL + kOffPL + uint(i)]
#define gSplitId(i) sL[gBaseL + kOffSplitId + uint(i)]
dvec3 gVPos(int v)
{
    const uint b = gBaseD + kOffVPos + 3u * uint(v);
    return dvec3(sD[b], sD[b + 1u], sD[b + 2u]);
}
void setVPos(int v, dvec3 p)
{
    const uint b = gBaseD + kOffVPos + 3u * uint(v);
    sD[b] = p.x;
    sD[b + 1u] = p.y;
    sD[b + 2u] = p.z;
}

// ---- the tet (loadTet, phase one)
Tet gT;
IsoPolygons gIso;
IsoOwnership gOwn;
uint gCell;
int gTetIndex;
bool gFoldConvex;

// ---- the vertex table (mVerts)
int gVertCount;
int gTriVert[8]; // mTriVerts: the vertices of iso polygon k's corners, 4 k + c

uint vDim(int v) { return gVMeta(v) & 15u; }
int vPlaneCount(int v) { return int((gVMeta(v) >> 4) & 15u); }
uint vSupport(int v) { return (gVMeta(v) >> 8) & 15u; }
bool vSteiner(int v) { return ((gVMeta(v) >> 12) & 1u) != 0u; }

/// A Steiner midpoint's word for one end of its chord: midpointWord
/// (RemeshKernel.cpp), splitmix64's finaliser over every field of the name.
uint64_t mixWord(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ul;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebul;
    return x ^ (x >> 31);
}
uint64_t midpointWord(int v)
{
    const int pc = vPlaneCount(v);
    uint64_t h = mixWord(0x9e3779b97f4a7c15ul ^ (uint64_t(vDim(v)) << 16 | uint64_t(pc) << 8));
    for (int i = 0; i < 3; ++i) h = mixWord(h ^ gVFeature(3 * v + i));
    for (int i = 0; i < pc; ++i) h = mixWord(h ^ gVPlanes(8 * v + i));
    return (h >> 2) | (1ul << 62);
}

/// featureKey: the simplex's sorted grid vertex ids (dim < 3), or the cell and tet.
void featureOf(uint support, out uvec2 feature[3])
{
    feature[0] = uvec2(0u);
    feature[1] = uvec2(0u);
    feature[2] = uvec2(0u);
    if (support == 15u) {
        const KernelCell c = kCells[gCell];
        feature[0] = b64(gridVertexId(ivec3(c.x, c.y, c.z)));
        feature[1] = b64(uint64_t(gTetIndex));
        return;
    }
    int n = 0;
    for (int i = 0; i < 4; ++i)
        if (((support >> i) & 1u) != 0u) feature[n++] = gT.id[i];
    // Sort the n (<= 3) ids ascending without writing an element a loop reads.
    uint64_t a = u64(feature[0]), b = u64(feature[1]), c = u64(feature[2]);
    if (n >= 2 && b < a) {
        const uint64_t s = a;
        a = b;
        b = s;
    }
    if (n == 3) {
        if (c < b) {
            const uint64_t s = b;
            b = c;
            c = s;
        }
        if (b < a) {
            const uint64_t s = a;
            a = b;
            b = s;
        }
    }
    feature[0] = b64(a);
    feature[1] = b64(b);
    feature[2] = b64(c);
}

/// findVertex: the lowest vertex with this name, or -1.
int findVertex(uint dim, uvec2 feature[3], int planeCount, uvec2 planes[8])
{
    for (int v = 0; v < gVertCount; ++v) {
        if (vDim(v) != dim || vPlaneCount(v) != planeCount) continue;
        bool same = gVFeature(3 * v) == u64(feature[0]) && gVFeature(3 * v + 1) == u64(feature[1]) &&
                    gVFeature(3 * v + 2) == u64(feature[2]);
        for (int i = 0; i < planeCount && same; ++i) same = gVPlanes(8 * v + i) == u64(planes[i]);
        if (same) return v;
    }
    return -1;
}

double mergeTolerance(dvec3 p) { return 1e-11lf * (1.0lf + max(max(abs(p.x), abs(p.y)), abs(p.z))); }

/// RemeshKernel's subsetMergeTolerance (its kNearCell is 1e-5).
double subsetMergeTolerance(dvec3 p)
{
    precise double t = 1e-8lf * (1.0lf + max(max(abs(p.x), abs(p.y)), abs(p.z)));
    return min(t, 0.5e-5lf);
}

/// Are vertex v's planes and planes[0..count) (both ascending) nested, one
/// a subset of the other?
bool nestedNames(int v, uvec2 planes[8], int count)
{
    const int pc = vPlaneCount(v);
    int i = 0, j = 0, matched = 0;
    while (i < pc && j < count) {
        const uint64_t a = gVPlanes(8 * v + i), b = u64(planes[j]);
        if (a == b) {
            ++matched;
            ++i;
            ++j;
        } else if (a < b) ++i;
        else ++j;
    }
    return matched == min(pc, count);
}

/// mergeCandidate: the lowest tet-inside, non-Steiner vertex with this
/// feature within mergeTolerance of p, or within subsetMergeTolerance when
/// one name's planes are a subset of the other's, or -1.
int mergeCandidate(uvec2 feature[3], uvec2 planes[8], int count, dvec3 p)
{
    for (int v = 0; v < gVertCount; ++v) {
        if (vDim(v) != 3u || vSteiner(v)) continue;
        if (gVFeature(3 * v) != u64(feature[0]) || gVFeature(3 * v + 1) != u64(feature[1]) ||
            gVFeature(3 * v + 2) != u64(feature[2]))
            continue;
        const double d = length3(gVPos(v) - p);
        if (d <= mergeTolerance(p) || (d <= subsetMergeTolerance(p) && nestedNames(v, planes, count))) return v;
    }
    return -1;
}

int pushVertex(uint dim, uint support, bool steiner, uvec2 feature[3], int planeCount, uvec2 planes[8], dvec3 pos)
{
    if (gVertCount == ARR_MAX_VERTS) {
        gFail |= kFailVerts;
        return -1;
    }
    const int v = gVertCount++;
    gVMetaRef(v) = int(dim | uint(planeCount) << 4 | support << 8 | (steiner ? 1u : 0u) << 12);
    for (int i = 0; i < 3; ++i) gVFeature(3 * v + i) = u64(feature[i]);
    for (int i = 0; i < 8; ++i) gVPlanes(8 * v + i) = i < planeCount ? u64(planes[i]) : 0ul;
    setVPos(v, pos);
    return v;
}

/// RemeshKernel::makeVertex: the vertex of the point pos0 of simplex
/// `support` made by `defining` (-1 with gFail set when the tet stops).
int makeVertex(uint support, uvec2 defining[8], int definingCount, dvec3 pos0)
{
    if (gFail != 0u) return -1;
    uvec2 name[8];
    int count;
    bool overflow;
    const bool named = nameOf(gT, gIso, gOwn, gCell, support, defining, definingCount, pos0, name, count, overflow);
    if (overflow) {
        gFail |= kFailNameLists;
        return -1;
    }
    if (!named) {
        gFail |= kRefused;
        return -1;
    }
    const uint dim = uint(bitCount4(support) - 1);
    uvec2 feature[3];
    featureOf(support, feature);
    const int found = findVertex(dim, feature, count, name);
    if (found >= 0) return found;
    const int m = dim == 3u ? mergeCandidate(feature, name, count, pos0) : -1;
    if (m >= 0) {
        // The union of the two names, ascending, when it fits.
        uvec2 all[16];
        int n = 0;
        const int pc = vPlaneCount(m);
        int i = 0, j = 0;
        while (i < pc || j < count) {
            uint64_t next;
            if (j == count || (i < pc && gVPlanes(8 * m + i) < u64(name[j]))) next = gVPlanes(8 * m + i++);
            else if (i == pc || u64(name[j]) < gVPlanes(8 * m + i)) next = u64(name[j++]);
            else {
                next = u64(name[j++]);
                ++i;
            }
            all[n++] = b64(next);
        }
        if (n <= 8) {
            for (int k = 0; k < 8; ++k) gVPlanes(8 * m + k) = k < n ? u64(all[k]) : 0ul;
            gVMetaRef(m) = int((gVMeta(m) & ~(15u << 4)) | uint(n) << 4);
            return m;
        }
    }
    const dvec3 pos = canonicalPosition(gT, gIso, gCell, dim, uint(count), name, support, pos0);
    return pushVertex(dim, support, false, feature, count, name, pos);
}

/// RemeshKernel::makeSteiner: planes (count <= 8) are sorted here.
int makeSteiner(uint support, uvec2 planes[8], int count, dvec3 pos)
{
    if (gFail != 0u) return -1;
    // std::sort as ranks (duplicates keep their order), written once each.
    uvec2 sorted[8];
    for (int i = 0; i < count; ++i) {
        int rank = 0;
        const uint64_t pi = u64(planes[i]);
        for (int j = 0; j < count; ++j) rank += u64(planes[j]) < pi || (u64(planes[j]) == pi && j < i) ? 1 : 0;
        sorted[rank] = planes[i];
    }
    for (int k = count; k < 8; ++k) sorted[k] = uvec2(0u);
    const uint dim = uint(bitCount4(support) - 1);
    uvec2 feature[3];
    featureOf(support, feature);
    const int found = findVertex(dim, feature, count, sorted);
    if (found >= 0) return found;
    return pushVertex(dim, support, true, feature, count, sorted, pos);
}

// ---- planes, sides, membership
/// RemeshKernel::sign: the side of vertex v on plane id, 0 on it (by
/// name, or within the tie).
int signOf(int v, uint64_t id)
{
    const int pc = vPlaneCount(v);
    for (int i = 0; i < pc; ++i)
        if (gVPlanes(8 * v + i) == id) return 0;
    const uint dim = vDim(v);
    if ((id == kIsoA || id == kIsoB) && pc > 0 && gVPlanes(8 * v) == kIso && (dim == 1u || dim == 2u)) {
        const int tri = int(id - kIsoA);
        bool on = false;
        if (dim == 1u) {
            for (int c = 0; c < gIso.corners[tri]; ++c) on = on || gTriVert[4 * tri + c] == v;
            for (int c = 0; c < gIso.corners[tri] && !on; ++c) {
                const int w = gTriVert[4 * tri + c];
                on = gVFeature(3 * w) == gVFeature(3 * v) && gVFeature(3 * w + 1) == gVFeature(3 * v + 1) &&
                     gVFeature(3 * w + 2) == gVFeature(3 * v + 2);
            }
        } else {
            int f = 0;
            while (((vSupport(v) >> f) & 1u) != 0u) ++f;
            on = gOwn.faceTri[f] == tri;
        }
        if (on) return 0;
    }
    dvec4 p;
    planeById(id, p);
    const double h = planeH(p, gVPos(v));
    return abs(h) <= epsAt(gVPos(v)) ? 0 : (h > 0.0lf ? 1 : -1);
}

/// RemeshKernel::member: 1 in the solid, -1 outside, 0 on the isosurface.
int memberOf(int v)
{
    const uint dim = vDim(v);
    if (dim == 0u) {
        int i = 0;
        while (((vSupport(v) >> i) & 1u) == 0u) ++i;
        return gT.inside[i] ? 1 : -1;
    }
    if (dim < 3u) {
        if (vPlaneCount(v) > 0 && gVPlanes(8 * v) == kIso) return 0;
        const double d = dim == 1u ? edgeIsoDistance(gT, vSupport(v), gVPos(v)) : faceIsoDistance(gT, vSupport(v), gVPos(v));
        return d > 0.0lf ? 1 : -1;
    }
    if (gIso.triCount == 0) return gT.inside[0] ? 1 : -1;
    const int a = signOf(v, kIsoA);
    if (gIso.triCount == 1) return a;
    const int b = signOf(v, kIsoB);
    return gFoldConvex ? min(a, b) : max(a, b);
}

bool inExtentClosed(int v, int q)
{
    for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s)
        if (kSides[s].orient * double(signOf(v, kSides[s].id)) < 0.0lf) return false;
    return true;
}

bool inSlitOpen(int v, int q)
{
    for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s) {
        const double o = kSides[s].orient * double(signOf(v, kSides[s].id));
        if (kSides[s].partner >= 0 ? o < 0.0lf : o <= 0.0lf) return false;
    }
    return true;
}

/// RemeshKernel::rimLineIn: does quad o's rim line on side s lie in the
/// plane of quad r, which crosses o's?
bool rimLineIn(int o, uint s, int r)
{
    if (!(length3(cross3(kQuads[o].plane.xyz, kQuads[r].plane.xyz)) > 1e-9lf)) return false;
    const dvec3 d = cross3(kQuads[o].plane.xyz, kSides[s].plane.xyz);
    const double len = length3(d);
    return len > 1e-12lf && abs(dot3(d, kQuads[r].plane.xyz)) <= 1e-9lf * len;
}

/// RemeshKernel::onStripRim.
bool onStripRim(int v, int r)
{
    bool onJunction = false; // (a point off r's junctions is r's own)
    for (uint s = kQuads[r].firstSide; s < kQuads[r].firstSide + kQuads[r].sideCount; ++s)
        onJunction = onJunction || (kSides[s].partner >= 0 && signOf(v, kSides[s].id) == 0);
    if (!onJunction) return false;
    const uint64_t rid = kQuads[r].id;
    for (int i = 0; i < gReachCount; ++i) {
        const int o = gReachQuad[i];
        const uint64_t oid = kQuads[o].id;
        if (o == r || (oid >> 36) != (rid >> 36)) continue;
        const int64_t dq = int64_t((oid >> 4) & 0xfffffffful) - int64_t((rid >> 4) & 0xfffffffful);
        if (dq < -2l || dq > 2l || signOf(v, oid) != 0 || !inExtentClosed(v, o)) continue;
        for (uint s = kQuads[o].firstSide; s < kQuads[o].firstSide + kQuads[o].sideCount; ++s)
            if (kSides[s].partner < 0 && signOf(v, kSides[s].id) == 0 && !rimLineIn(o, s, r)) return true;
    }
    return false;
}

/// RemeshKernel::needsMidpoint's last test: u and v not both on one rim
/// line of r (its others: both ends rim points, chordClass 1).
bool apartOnRims(int u, int v, int r)
{
    for (uint s = kQuads[r].firstSide; s < kQuads[r].firstSide + kQuads[r].sideCount; ++s)
        if (kSides[s].partner < 0 && signOf(u, kSides[s].id) == 0 && signOf(v, kSides[s].id) == 0) return false;
    return true;
}

// ---- the piece pool: region 0 the current pieces, 1 the next, 2 a stack
int gPieceCount[3];
int gPoolUsed[3];
bool gKept[ARR_MAX_PIECES]; // of region 0

void poolClear(int r)
{
    gPieceCount[r] = 0;
    gPoolUsed[r] = 0;
}

/// Opens a new piece in region r (its corners follow with poolAdd); false when full.
bool poolOpen(int r)
{
    if (gPieceCount[r] == ARR_MAX_PIECES) {
        gFail |= kFailPieces;
        return false;
    }
    const int p = r * ARR_MAX_PIECES + gPieceCount[r]++;
    gPieceStart(p) = gPoolUsed[r];
    gPieceLen(p) = 0;
    return true;
}

void poolAdd(int r, int v, uint64_t lab)
{
    if (gPoolUsed[r] == ARR_MAX_POOL) {
        gFail |= kFailPool;
        return;
    }
    const int p = r * ARR_MAX_PIECES + gPieceCount[r] - 1;
    gPV(r * ARR_MAX_POOL + gPoolUsed[r]) = v;
    gPL(r * ARR_MAX_POOL + gPoolUsed[r]) = lab;
    ++gPoolUsed[r];
    ++gPieceLen(p);
}

/// Drops the last piece of region r (one of fewer than 3 corners).
void poolDropLast(int r)
{
    const int p = r * ARR_MAX_PIECES + gPieceCount[r] - 1;
    gPoolUsed[r] -= gPieceLen(p);
    --gPieceCount[r];
}

int pieceLen(int r, int i) { return gPieceLen(r * ARR_MAX_PIECES + i); }
int pieceV(int r, int i, int k) { return gPV(r * ARR_MAX_POOL + gPieceStart(r * ARR_MAX_PIECES + i) + k); }
uint64_t pieceL(int r, int i, int k) { return gPL(r * ARR_MAX_POOL + gPieceStart(r * ARR_MAX_PIECES + i) + k); }

/// Copies piece i of region `from` to the end of region `to`.
void poolCopyPiece(int from, int i, int to)
{
    if (!poolOpen(to)) return;
    for (int k = 0; k < pieceLen(from, i); ++k) poolAdd(to, pieceV(from, i, k), pieceL(from, i, k));
}

/// Region 1 becomes region 0.
void poolTakeNext()
{
    poolClear(0);
    for (int i = 0; i < gPieceCount[1]; ++i) poolCopyPiece(1, i, 0);
    poolClear(1);
}

/// RemeshKernel::pieceSign: the side of id that piece i of region r lies on.
int pieceSign(int r, int i, uint64_t id)
{
    for (int k = 0; k < pieceLen(r, i); ++k) {
        const int s = signOf(pieceV(r, i, k), id);
        if (s != 0) return s;
    }
    return 0;
}

// ---- surfaces (mSurfaces)
uvec2 gSPlane[ARR_MAX_SURFACES];
int gSQuad[ARR_MAX_SURFACES]; // cap: its quad (kQuads index); -1: an iso polygon
int gSSides[ARR_MAX_SURFACES];
uvec2 gSNormalBits[3 * ARR_MAX_SURFACES]; // dvec3 normals as bits: D3GET(gSNormalBits, s)
int gSAlso[4 * ARR_MAX_SURFACES]; // kerf > 0: further prisms with this face plane
int gSAlsoCount[ARR_MAX_SURFACES];
int gSPolyV[4 * ARR_MAX_SURFACES];
uvec2 gSPolyLab[4 * ARR_MAX_SURFACES];
int gSPolyLen[ARR_MAX_SURFACES];
int gSurfaceCount;

// ---- the split order (mSplitOrder)
int gSplitCount;

/// gatherQuads and finishPlanes (tetBegin), and the fold's convexity.
void gatherPlanes()
{
    tetBegin(gT, gIso, gCell);
    if (gTetOverflow) gFail |= kFailPlanes;
    gFoldConvex = true;
    if (gIso.triCount == 2) gFoldConvex = planeH(D4GET(gIso.planeBits, 0), D3GET(gIso.ptsBits, 4 * 1 + 2)) >= 0.0lf;
}

bool openSurface(uint64_t plane, int quad, int sides, dvec3 normal)
{
    if (gSurfaceCount == ARR_MAX_SURFACES) {
        gFail |= kFailSurfaces;
        return false;
    }
    const int s = gSurfaceCount++;
    gSPlane[s] = b64(plane);
    gSQuad[s] = quad;
    gSSides[s] = sides;
    D3SET(gSNormalBits, s, normal);
    gSAlsoCount[s] = 0;
    gSPolyLen[s] = 0;
    return true;
}

/// RemeshKernel::isoSurfaces.
void isoSurfaces()
{
    for (int k = 0; k < gIso.triCount; ++k) {
        if (!openSurface(kIsoA + uint64_t(k), -1, 1, -D4GET(gIso.planeBits, k).xyz)) return;
        const int s = gSurfaceCount - 1;
        const int n = gIso.corners[k];
        for (int c = 0; c < n; ++c) {
            const int e = gIso.edges[k][c];
            uvec2 def[8];
            def[0] = b64(kIsoA + uint64_t(k));
            const int v = makeVertex((1u << (e & 3)) | (1u << (e >> 2)), def, 1, D3GET(gIso.ptsBits, 4 * k + c));
            if (v < 0) return;
            gSPolyV[4 * s + c] = v;
            gTriVert[4 * k + c] = v;
        }
        for (int c = 0; c < n; ++c) {
            const uint m = gOwn.edgeMask[k][c] | gOwn.edgeMask[k][(c + 1) % n];
            gSPolyLab[4 * s + c] = b64(m == 15u ? kIsoA + uint64_t(1 - k) : kBoundaryLabel | uint64_t(m));
        }
        gSPolyLen[s] = n;
    }
}

/// poly2::angleLess (atan2's order of directions, without atan2, the sign
/// of a zero y not read: this driver need not keep it).
int angleHalf(dvec2 d)
{
    if (d.y == 0.0lf && d.x < 0.0lf) return 3;
    return d.y < 0.0lf ? 0 : d.y == 0.0lf ? 1 : 2;
}
bool angleLess(dvec2 u, dvec2 v)
{
    const int hu = angleHalf(u), hv = angleHalf(v);
    if (hu != hv) return hu < hv;
    precise double c = u.x * v.y - u.y * v.x;
    return c > 0.0lf;
}

/// One step of the insertion sort by angle: b before a when less (swapped).
bool angleSwap(inout dvec2 a, inout dvec2 b, inout int va, inout int vb)
{
    if (!angleLess(b, a)) return false;
    const dvec2 d = a;
    a = b;
    b = d;
    const int v = va;
    va = vb;
    vb = v;
    return true;
}

/// RemeshKernel::capSurfaces' section of the tet by a face plane: h per
/// corner (ties 0), the corners' simplices ps and positions pp (n, at most
/// four); returns how many tet corners lie on the plane.
int capSection(dvec4 plane, out uvec2 hBits[4], out uint ps[4], out uvec2 ppBits[12], out int n)
{
    int on = 0;
    for (int i = 0; i < 4; ++i) {
        D1SET(hBits, i, planeH(plane, D3GET(gT.pBits, i)));
        if (abs(D1GET(hBits, i)) <= epsAt(D3GET(gT.pBits, i))) {
            D1SET(hBits, i, 0.0lf);
            ++on;
        }
    }
    n = 0;
    for (int i = 0; i < 4; ++i)
        if (D1GET(hBits, i) == 0.0lf && n < 4) {
            ps[n] = 1u << i;
            D3SET(ppBits, n++, D3GET(gT.pBits, i));
        }
    for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j) {
            precise double hh = D1GET(hBits, i) * D1GET(hBits, j);
            if (!(hh < 0.0lf) || n == 4) continue;
            int a = i, b = j;
            if (u64(gT.id[b]) < u64(gT.id[a])) {
                a = j;
                b = i;
            }
            const double t = D1GET(hBits, a) / (D1GET(hBits, a) - D1GET(hBits, b));
            precise dvec3 x = D3GET(gT.pBits, a) + t * (D3GET(gT.pBits, b) - D3GET(gT.pBits, a));
            ps[n] = (1u << i) | (1u << j);
            D3SET(ppBits, n++, x);
        }
    return on;
}

/// RemeshKernel::capOutside's clip buffers: three polygons of up to 16
/// corners (a section has four, and each of at most seven clips adds one).
uvec2 gClipBits[3 * 48]; // dvec3 points as bits: D3GET(gClipBits, i)

double clipGrow(dvec3 x) { return kApart * (1.0lf + max(max(abs(x.x), abs(x.y)), abs(x.z))); }

/// Polygon `src` (n corners) clipped to orient * h(x) + clipGrow(x) >= 0
/// into polygon `dst`; returns its corner count.
int clipTo(int src, int dst, int n, dvec4 plane, double orient)
{
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const dvec3 a = D3GET(gClipBits, 16 * src + i), b = D3GET(gClipBits, 16 * src + (i + 1) % n);
        precise double ha = orient * planeH(plane, a) + clipGrow(a);
        precise double hb = orient * planeH(plane, b) + clipGrow(b);
        if (ha >= 0.0lf && m < 16) D3SET(gClipBits, 16 * dst + m++, a);
        if ((ha >= 0.0lf) != (hb >= 0.0lf) && m < 16) {
            precise dvec3 x = a + (ha / (ha - hb)) * (b - a);
            D3SET(gClipBits, 16 * dst + m++, x);
        }
    }
    return m;
}

/// RemeshKernel::capOutside: can no point of the section (ps, pp, n), by
/// kApart, lie inside both quad q (kerf > 0: its closed prism, face `face`
/// aside) and the solid?
bool capOutside(int q, uint64_t face, uint ps[4], uvec2 ppBits[12], int n)
{
    // The corners in their cyclic order (capSection lists four by edge, and
    // the middle two then share no tet face).
    for (int k = 0; k < 3 * n; ++k) gClipBits[k] = ppBits[k];
    if (n == 4 && bitCount(ps[1] | ps[2]) == 4) {
        D3SET(gClipBits, 2, D3GET(ppBits, 3));
        D3SET(gClipBits, 3, D3GET(ppBits, 2));
    }
    int src = 0, cn = n;
    for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s) {
        if (kSides[s].id == face) continue;
        cn = clipTo(src, 1 - src, cn, kSides[s].plane, kSides[s].orient);
        if (cn == 0) return true;
        src = 1 - src;
    }
    if (gIso.triCount == 0) return false; // solid throughout
    const int an = clipTo(src, 1 - src, cn, D4GET(gIso.planeBits, 0), 1.0lf);
    if (gIso.triCount == 1) return an == 0;
    if (gFoldConvex) return an == 0 || clipTo(1 - src, 2, an, D4GET(gIso.planeBits, 1), 1.0lf) == 0;
    return an == 0 && clipTo(src, 2, cn, D4GET(gIso.planeBits, 1), 1.0lf) == 0;
}

/// RemeshKernel.cpp kCoincident: planes closer than this share of the tie
/// at a tet's corners are one there.
const double kCoincident = 1.0lf / 16.0lf;

/// RemeshKernel::capSurfaces' coincident: planes a and b agree at the tet's
/// corners (so everywhere in it) far inside the tie.
bool coincidentPlanes(dvec4 a, dvec4 b)
{
    for (int i = 0; i < 4; ++i) {
        const dvec3 p = D3GET(gT.pBits, i);
        precise double d = planeH(a, p) - planeH(b, p);
        if (!(abs(d) <= kCoincident * epsAt(p))) return false;
    }
    return true;
}

/// The plane of cap surface s (its quad's plane, or the prism face's).
dvec4 capPlane(int s);

/// RemeshKernel::capSurfaces, first pass: a quad's plane (zero kerf) or
/// each face of its prism (kerf > 0) through the tet as a surface (no
/// polygon yet), or joined to an earlier one facing the same way with its
/// plane or one that coincides with it over the tet (kerf > 0).
void capFace(int q, uint64_t id, dvec4 plane, dvec3 normal, int first)
{
    if (uPrism) {
        for (int o = first; o < gSurfaceCount; ++o)
            if (dot3(D3GET(gSNormalBits, o), normal) > 0.0lf &&
                (u64(gSPlane[o]) == id || coincidentPlanes(capPlane(o), plane))) {
                if (gSAlsoCount[o] == 4) {
                    gFail |= kFailSurfaces;
                    return;
                }
                gSAlso[4 * o + gSAlsoCount[o]++] = q;
                return;
            }
    }
    uvec2 hBits[4];
    uint ps[4];
    uvec2 ppBits[12];
    int n;
    const int on = capSection(plane, hBits, ps, ppBits, n);
    if (n < 3) return;
    int sides = 3;
    if (on == 3) { // the plane is a tet face: only the cap facing away from this tet
        int f = 0;
        while (D1GET(hBits, f) == 0.0lf) ++f;
        sides = D1GET(hBits, f) > 0.0lf ? 1 : 2;
        precise double facing = dot3(normal, plane.xyz) * D1GET(hBits, f);
        if (uPrism && facing > 0.0lf) return; // faces into this tet
    }
    if (uPrism) sides = 1;
    openSurface(id, q, sides, normal);
}

/// The plane of cap surface s (its quad's plane, or the prism face's).
dvec4 capPlane(int s)
{
    const int q = gSQuad[s];
    if (!uPrism) return kQuads[q].plane;
    for (uint x = kQuads[q].firstSide; x < kQuads[q].firstSide + kQuads[q].sideCount; ++x)
        if (kSides[x].id == u64(gSPlane[s])) return kSides[x].plane;
    return kQuads[q].plane; // not reached: the face is one of the quad's sides
}

/// Second pass: cap surface s's polygon, its corners by angle; false (no
/// polygon made) when capOutside holds for its quad and every joined one.
bool capPolygon(int s)
{
    const dvec4 plane = capPlane(s);
    uvec2 hBits[4];
    uint ps[4];
    uvec2 ppBits[12];
    int n;
    capSection(plane, hBits, ps, ppBits, n);
    bool outside = capOutside(gSQuad[s], u64(gSPlane[s]), ps, ppBits, n);
    for (int k = 0; k < gSAlsoCount[s]; ++k)
        outside = outside && capOutside(gSAlso[4 * s + k], u64(gSPlane[s]), ps, ppBits, n);
    if (outside) return false;
    uvec2 def[8];
    def[0] = gSPlane[s];
    int pv[4];
    for (int k = 0; k < n; ++k) pv[k] = makeVertex(ps[k], def, 1, D3GET(ppBits, k));
    if (gFail != 0u) return false;
    const dvec3 normal = D3GET(gSNormalBits, s);
    dvec3 c = dvec3(0.0lf);
    for (int i = 0; i < n; ++i) c = c + D3GET(ppBits, i);
    c = c / double(n);
    const dvec3 d0 = D3GET(ppBits, 0) - c;
    const double inv = 1.0lf / dSqrt(dot3(d0, d0));
    const dvec3 e1 = d0 * inv; // glm::normalize
    const dvec3 e2 = cross3(normal, e1);
    dvec2 a0 = dvec2(dot3(D3GET(ppBits, 0) - c, e1), dot3(D3GET(ppBits, 0) - c, e2));
    dvec2 a1 = dvec2(dot3(D3GET(ppBits, 1) - c, e1), dot3(D3GET(ppBits, 1) - c, e2));
    dvec2 a2 = dvec2(dot3(D3GET(ppBits, 2) - c, e1), dot3(D3GET(ppBits, 2) - c, e2));
    dvec2 a3 = n == 4 ? dvec2(dot3(D3GET(ppBits, 3) - c, e1), dot3(D3GET(ppBits, 3) - c, e2)) : dvec2(0.0lf);
    int v0 = pv[0], v1 = pv[1], v2 = pv[2], v3 = n == 4 ? pv[3] : -1;
    // The CPU's stable insertion sort, unrolled (at most four corners).
    angleSwap(a0, a1, v0, v1);
    if (angleSwap(a1, a2, v1, v2)) angleSwap(a0, a1, v0, v1);
    if (n == 4 && angleSwap(a2, a3, v2, v3))
        if (angleSwap(a1, a2, v1, v2)) angleSwap(a0, a1, v0, v1);
    const int order[4] = int[4](v0, v1, v2, v3);
    for (int i = 0; i < n; ++i) gSPolyV[4 * s + i] = order[i];
    for (int i = 0; i < n; ++i)
        gSPolyLab[4 * s + i] = b64(kBoundaryLabel | uint64_t(vSupport(order[i]) | vSupport(order[(i + 1) % n])));
    gSPolyLen[s] = n;
    return true;
}

/// Copies surface `from` into slot `to` (capSurfaces' compaction).
void moveSurface(int from, int to)
{
    gSPlane[to] = gSPlane[from];
    gSQuad[to] = gSQuad[from];
    gSSides[to] = gSSides[from];
    D3SET(gSNormalBits, to, D3GET(gSNormalBits, from));
    gSAlsoCount[to] = gSAlsoCount[from];
    gSPolyLen[to] = gSPolyLen[from];
    for (int i = 0; i < 4; ++i) {
        gSAlso[4 * to + i] = gSAlso[4 * from + i];
        gSPolyV[4 * to + i] = gSPolyV[4 * from + i];
        gSPolyLab[4 * to + i] = gSPolyLab[4 * from + i];
    }
}

void capSurfaces()
{
    const int first = gSurfaceCount;
    for (int i = 0; i < gReachCount && gFail == 0u; ++i) {
        const int q = gReachQuad[i];
        if (!uPrism) {
            capFace(q, kQuads[q].id, kQuads[q].plane, kQuads[q].plane.xyz, first);
            continue;
        }
        for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount && gFail == 0u; ++s) {
            precise dvec3 normal = kSides[s].orient * kSides[s].plane.xyz;
            capFace(q, kSides[s].id, kSides[s].plane, normal, first);
        }
    }
    int kept = first;
    for (int s = first; s < gSurfaceCount && gFail == 0u; ++s) {
        if (!capPolygon(s)) continue;
        if (kept != s) moveSurface(s, kept);
        ++kept;
    }
    if (gFail == 0u) gSurfaceCount = kept;
}

/// chooseSplitOrder's test: the whole tet strictly on one side of the plane.
bool apart(dvec4 p)
{
    bool pos = true, neg = true;
    for (int i = 0; i < 4; ++i) {
        const double h = planeH(p, D3GET(gT.pBits, i));
        const dvec3 x = D3GET(gT.pBits, i);
        const double e = kApart * (1.0lf + max(max(abs(x.x), abs(x.y)), abs(x.z)));
        pos = pos && h > e;
        neg = neg && h < -e;
    }
    return pos || neg;
}

/// The tet's planes as RemeshKernel::mPlanes holds them: ascending by id,
/// one per id (a plane gathered from several quads is the same plane):
/// gPlaneOrder(k), k < the count returned, indexes gTetPlane.
int sortTetPlanes()
{
    int count = 0;
    uint64_t last = 0ul; // ids are >= kIsoA
    for (;;) {
        int best = -1;
        uint64_t bestId = 0ul;
        for (int i = 0; i < gTetPlaneCount; ++i) {
            const uint64_t id = gTetPlaneId(i);
            if (id > last && (best < 0 || id < bestId)) {
                best = i;
                bestId = id;
            }
        }
        if (best < 0) return count;
        gPlaneOrder(count++) = best;
        last = bestId;
    }
}

/// RemeshKernel::chooseSplitOrder: iso planes, junction planes, the rest,
/// each group ascending by id.
void chooseSplitOrder()
{
    gSplitCount = 0;
    const int planes = sortTetPlanes();
    for (int k = 0; k < planes; ++k) {
        const int i = gPlaneOrder(k);
        if (gTetPlaneId(i) <= kIsoB) {
            gSplitId(gSplitCount) = gTetPlaneId(i);
            gSplitOwner(gSplitCount++) = -1;
        }
    }
    for (int k = 0; k < planes; ++k) {
        const int i = gPlaneOrder(k);
        if (gTetPlaneId(i) > kIsoB && int(gTetPlaneId(i) & 15ul) == kJunctionKind && !apart(D4GET(gTetPlaneBits, i))) {
            gSplitId(gSplitCount) = gTetPlaneId(i);
            gSplitOwner(gSplitCount++) = -1;
        }
    }
    for (int k = 0; k < planes; ++k) {
        const int i = gPlaneOrder(k);
        const uint64_t id = gTetPlaneId(i);
        if (id <= kIsoB || int(id & 15ul) == kJunctionKind || apart(D4GET(gTetPlaneBits, i))) continue;
        int owner = -1;
        for (int r = 0; r < gReachCount; ++r)
            if ((kQuads[gReachQuad[r]].id >> 4) == (id >> 4)) owner = gReachQuad[r];
        if (uPrism && owner >= 0) {
            // Shared: everywhere; one user: within that quad's junction zone
            // (a cap named by the lower quad may be the upper quad's alone).
            int users = 0, user = -1;
            for (int r = 0; r < gReachCount; ++r) {
                const int q = gReachQuad[r];
                for (uint s = kQuads[q].firstSide; s < kQuads[q].firstSide + kQuads[q].sideCount; ++s)
                    if (kSides[s].id == id) {
                        ++users;
                        user = q;
                    }
            }
            if (users > 1) owner = -1;
            else if (users == 1) owner = user;
        }
        gSplitId(gSplitCount) = id;
        gSplitOwner(gSplitCount++) = owner;
    }
}

/// RemeshKernel::splitPoly: piece i of region 0 split by plane p into region 1.
void splitPoly(int i, uint64_t polyPlane, uint64_t p)
{
    const int n = pieceLen(0, i);
    if (n > ARR_MAX_CORNERS) {
        gFail |= kFailCorners;
        return;
    }
    int sv[ARR_MAX_CORNERS];
    bool pos = false, neg = false;
    for (int k = 0; k < n; ++k) {
        sv[k] = signOf(pieceV(0, i, k), p);
        pos = pos || sv[k] > 0;
        neg = neg || sv[k] < 0;
    }
    if (!(pos && neg)) {
        poolCopyPiece(0, i, 1);
        return;
    }
    dvec4 pl;
    planeById(p, pl);
    int cut[ARR_MAX_CORNERS];
    for (int k = 0; k < n; ++k) {
        cut[k] = -1;
        const int j = (k + 1) % n;
        if (sv[k] * sv[j] >= 0) continue;
        const int a = pieceV(0, i, k), b = pieceV(0, i, j);
        const double ha = planeH(pl, gVPos(a)), hb = planeH(pl, gVPos(b));
        double t = (ha - hb) != 0.0lf ? ha / (ha - hb) : 0.5lf;
        if (!(t > 0.0lf && t < 1.0lf)) t = 0.5lf;
        precise dvec3 x = gVPos(a) + t * (gVPos(b) - gVPos(a));
        uvec2 def[8];
        int dc = 0;
        def[dc++] = b64(p);
        if (polyPlane != 0ul) def[dc++] = b64(polyPlane);
        const uint64_t lab = pieceL(0, i, k);
        if ((lab & kBoundaryLabel) == 0ul) def[dc++] = b64(lab);
        cut[k] = makeVertex(vSupport(a) | vSupport(b), def, dc, x);
        if (cut[k] < 0) return;
    }
    for (int keep = 1; keep >= -1; keep -= 2) {
        bool strict = false;
        for (int k = 0; k < n; ++k) strict = strict || keep * sv[k] > 0;
        if (!poolOpen(1)) return;
        for (int k = 0; k < n; ++k) {
            const int j = (k + 1) % n;
            const int sa = keep * sv[k], sb = keep * sv[j];
            const uint64_t lab = pieceL(0, i, k);
            if (sa >= 0) poolAdd(1, pieceV(0, i, k), sa == 0 && sb < 0 ? p : lab);
            if (cut[k] >= 0) poolAdd(1, cut[k], sa > 0 ? p : lab);
        }
        if (!(strict && pieceLen(1, gPieceCount[1] - 1) >= 3)) poolDropLast(1);
    }
}

/// RemeshKernel::splitSurface: region 0 holds surface s's pieces.
void splitSurface(int s)
{
    poolClear(0);
    poolClear(1);
    if (!poolOpen(0)) return;
    for (int c = 0; c < gSPolyLen[s]; ++c) poolAdd(0, gSPolyV[4 * s + c], u64(gSPolyLab[4 * s + c]));
    const bool iso = gSQuad[s] < 0;
    for (int k = 0; k < gSplitCount && gFail == 0u; ++k) {
        const uint64_t id = gSplitId(k);
        if (id == u64(gSPlane[s])) continue;
        if (iso && (id == kIsoA || id == kIsoB)) continue;
        const int owner = gSplitOwner(k);
        for (int i = 0; i < gPieceCount[0] && gFail == 0u; ++i) {
            // A quad's plane and rim sides split only inside its junction zone.
            bool outside = false;
            if (owner >= 0)
                for (uint sd = kQuads[owner].firstSide; sd < kQuads[owner].firstSide + kQuads[owner].sideCount; ++sd)
                    if (kSides[sd].partner >= 0 && kSides[sd].orient * double(pieceSign(0, i, kSides[sd].id)) < 0.0lf)
                        outside = true;
            if (outside) poolCopyPiece(0, i, 1);
            else splitPoly(i, u64(gSPlane[s]), id);
        }
        poolTakeNext();
    }
}

uint gVertMark[ARR_MAX_VERTS / 32];

/// RemeshKernel::conformPieces: the vertices of all pieces that lie on an
/// edge's line inside it go into the edge (ascending along it), then a
/// piece that visits a vertex twice is split into simple loops.
void conformPieces()
{
    for (int w = 0; w < ARR_MAX_VERTS / 32; ++w) gVertMark[w] = 0u;
    for (int i = 0; i < gPieceCount[0]; ++i)
        for (int k = 0; k < pieceLen(0, i); ++k) {
            const int v = pieceV(0, i, k);
            gVertMark[v >> 5] |= 1u << (v & 31);
        }
    poolClear(1);
    for (int i = 0; i < gPieceCount[0] && gFail == 0u; ++i) {
        if (!poolOpen(1)) return;
        const int n = pieceLen(0, i);
        for (int k = 0; k < n; ++k) {
            const int u = pieceV(0, i, k), w = pieceV(0, i, (k + 1) % n);
            const uint64_t L = pieceL(0, i, k);
            poolAdd(1, u, L);
            const dvec3 a = gVPos(u), d = gVPos(w) - a;
            const double dd = dot3(d, d);
            // The vertices on the edge, by (t, vertex) ascending: each next
            // one the least above the last taken.
            double lastT = 0.0lf;
            int lastX = -1;
            for (;;) {
                bool found = false;
                double bestT = 0.0lf;
                int bestX = -1;
                for (int x = 0; x < gVertCount; ++x) {
                    if (((gVertMark[x >> 5] >> (x & 31)) & 1u) == 0u || x == u || x == w) continue;
                    const bool onLine = (L & kBoundaryLabel) != 0ul ? (vSupport(x) & ~uint(L & 15ul)) == 0u
                                                                    : signOf(x, L) == 0;
                    if (!onLine) continue;
                    const double t = dot3(gVPos(x) - a, d) / dd;
                    if (!(t > 1e-12lf && t < 1.0lf - 1e-12lf)) continue;
                    precise dvec3 foot = a + t * d;
                    if (length3(gVPos(x) - foot) > 1e-9lf * (1.0lf + dSqrt(dd))) continue;
                    const bool above = lastX < 0 || t > lastT || (t == lastT && x > lastX);
                    if (!above) continue;
                    if (!found || t < bestT || (t == bestT && x < bestX)) {
                        bestT = t;
                        bestX = x;
                        found = true;
                    }
                }
                if (!found) break;
                poolAdd(1, bestX, L);
                lastT = bestT;
                lastX = bestX;
            }
        }
    }
    poolTakeNext();
    // pushSimple without recursion: a stack (region 2) of loops to look at,
    // the first part of a split on top, so the order is the recursion's.
    for (int i = 0; i < gPieceCount[0] && gFail == 0u; ++i) {
        poolClear(2);
        poolCopyPiece(0, i, 2);
        while (gPieceCount[2] > 0 && gFail == 0u) {
            const int top = gPieceCount[2] - 1;
            const int n = pieceLen(2, top);
            int ri = -1, rj = -1;
            for (int a = 0; a < n && ri < 0; ++a)
                for (int b = a + 1; b < n; ++b)
                    if (pieceV(2, top, a) == pieceV(2, top, b)) {
                        ri = a;
                        rj = b;
                        break;
                    }
            if (ri < 0) {
                poolCopyPiece(2, top, 1);
                poolDropLast(2);
                continue;
            }
            // Split the top into A = [ri, rj) and B = [rj, n + ri): stage
            // them in region 1's free end, then push B, then A.
            const int firstFree = gPieceCount[1];
            if (!poolOpen(1)) return;
            for (int k = rj; k < n + ri; ++k) poolAdd(1, pieceV(2, top, k % n), pieceL(2, top, k % n));
            if (!poolOpen(1)) return;
            for (int k = ri; k < rj; ++k) poolAdd(1, pieceV(2, top, k), pieceL(2, top, k));
            poolDropLast(2);
            for (int part = firstFree; part < firstFree + 2; ++part)
                if (pieceLen(1, part) >= 3) poolCopyPiece(1, part, 2);
            poolDropLast(1);
            poolDropLast(1);
        }
    }
    poolTakeNext();
}

/// A piece inside the solid P (classifyPieces' inSolid).
bool inSolid(int i)
{
    for (int k = 0; k < pieceLen(0, i); ++k)
        if (memberOf(pieceV(0, i, k)) < 0) return false;
    if (gIso.triCount == 2 && !gFoldConvex) return max(pieceSign(0, i, kIsoA), pieceSign(0, i, kIsoB)) >= 0;
    return true;
}

bool insidePrism(int i, int q)
{
    for (uint sd = kQuads[q].firstSide; sd < kQuads[q].firstSide + kQuads[q].sideCount; ++sd)
        if (kSides[sd].orient * double(pieceSign(0, i, kSides[sd].id)) < 0.0lf) return false;
    return true;
}

/// classifyPieces' keptBy: the prism `own` keeps piece i of surface s.
bool keptBy(int i, int s, int own)
{
    bool k = insidePrism(i, own);
    for (int j = 0; j < gReachCount && k; ++j) {
        const int q = gReachQuad[j];
        if (q == own || !insidePrism(i, q)) continue;
        bool sameFace = false;
        for (uint sd = kQuads[q].firstSide; sd < kQuads[q].firstSide + kQuads[q].sideCount; ++sd) {
            precise dvec3 n = kSides[sd].orient * kSides[sd].plane.xyz;
            sameFace = sameFace || (pieceSign(0, i, kSides[sd].id) == 0 && dot3(n, D3GET(gSNormalBits, s)) > 0.0lf);
        }
        k = sameFace && kQuads[q].id > kQuads[own].id;
    }
    return k;
}

/// RemeshKernel::classifyPieces: gKept for region 0's pieces of surface s.
void classifyPieces(int s)
{
    const int quad = gSQuad[s];
    for (int i = 0; i < gPieceCount[0]; ++i) {
        bool ok = true;
        if (uPrism) {
            if (quad < 0) {
                for (int j = 0; j < gReachCount; ++j) ok = ok && !insidePrism(i, gReachQuad[j]);
            } else {
                ok = inSolid(i);
                bool any = ok && keptBy(i, s, quad);
                for (int a = 0; a < gSAlsoCount[s]; ++a) any = any || (ok && keptBy(i, s, gSAlso[4 * s + a]));
                ok = any;
            }
        } else if (quad >= 0) {
            ok = inSolid(i);
            for (uint sd = kQuads[quad].firstSide; sd < kQuads[quad].firstSide + kQuads[quad].sideCount; ++sd)
                ok = ok && kSides[sd].orient * double(pieceSign(0, i, kSides[sd].id)) >= 0.0lf;
        }
        gKept[i] = ok;
    }
}

/// RemeshKernel::chordEnd and slitInterior of v about quad r at once: 1 a
/// rim point (chordEnd), 2 inside r's open slit (slitInterior), 0 neither.
int chordClass(int v, int r)
{
    if (signOf(v, kQuads[r].id) != 0 || !inExtentClosed(v, r)) return 0;
    return inSlitOpen(v, r) && !onStripRim(v, r) ? 2 : 1; // the open slit lies in the closed extent
}

/// RemeshKernel::splitChord's next: the kept pieces' edge (region 0) that
/// goes on from `cur` along `dir` (off its line by 1e-9 of the edge's length
/// or two ties at most) on quad r's plane, or -1 (-2: more such neighbours
/// than it holds). The neighbours along dir first, in the CPU's
/// order, then the first on r's plane: signOf's loops stay out of the loop
/// over the pieces.
int chordNext(int cur, dvec3 dir, int r)
{
    const precise dvec3 c = gVPos(cur);
    const double len = length3(dir), tie = 2.0lf * epsAt(c);
    int along[4];
    int n = 0;
    bool more = false;
    for (int i = 0; i < gPieceCount[0]; ++i) {
        if (!gKept[i]) continue;
        const int m = pieceLen(0, i);
        for (int k = 0; k < m; ++k) {
            if (pieceV(0, i, k) != cur) continue;
            for (int h = 0; h < 2; ++h) {
                const int y = pieceV(0, i, h == 0 ? (k + 1) % m : (k + m - 1) % m);
                const precise dvec3 e = gVPos(y) - c;
                const double el = length3(e);
                if (!(el > 0.0lf && dot3(e, dir) > 0.0lf && length3(cross3(e, dir)) <= (1e-9lf * el + tie) * len)) continue;
                if (n < 4) along[n++] = y;
                else more = true;
            }
        }
    }
    for (int f = 0; f < n; ++f)
        if (signOf(along[f], kQuads[r].id) == 0) return along[f];
    return more ? -2 : -1;
}

// splitChord's keeps: the surface whose line with r's plane the chord is
// (the isosurface when gChordOnIso; the quads gChordAlong) holds the point.
bool gChordOnIso;
int gChordAlong[4];
int gChordAlongCount;
bool chordKeeps(int y)
{
    if (gChordOnIso && memberOf(y) != 0) return false;
    for (int k = 0; k < gChordAlongCount; ++k)
        if (!inExtentClosed(y, gChordAlong[k])) return false;
    return true;
}

/// One end of RemeshKernel::splitChord's walk: from `from` (of chordClass
/// `cls`, entered from `prev`) along `dir` through points inside r's open
/// slit that the chord's other surface holds (chordKeeps) to a rim point;
/// -1 when the chord leaves the tet, stops or ends elsewhere first.
int chordWalk(int from, int prev, int cls, dvec3 dir, int r)
{
    int cur = from;
    for (int hops = 0; cls == 2; ++hops) {
        // (On from prev through cur stays in the tet only if prev lies in
        // the smallest face that holds cur.)
        // (Within the tet's vertices: each hop goes on along the line.)
        if (hops == gVertCount || (vSupport(prev) & ~vSupport(cur)) != 0u) return -1;
        prev = cur;
        cur = chordNext(cur, dir, r);
        if (cur == -2) gFail |= kFailMidpoints;
        if (cur < 0 || !chordKeeps(cur)) return -1;
        cls = chordClass(cur, r);
    }
    return cls == 1 ? cur : -1;
}

// insertSlitMidpoints' list: the (edge, quad) pairs that may take a midpoint,
// in the CPU's order (kept piece, edge, quad up to the first that does).
#define MID_MAX 24
int gMidPiece[MID_MAX]; // the edge: its kept piece of region 0, and its start corner there
int gMidCorner[MID_MAX];
int gMidQuad[MID_MAX]; // kQuads index
int gMidA[MID_MAX];    // the chord a -> b whose midpoint the edge takes; -1 none
int gMidB[MID_MAX];    // (-2 - the ends' classes (chordClass, u's times 4) while a piece of a split chord to follow)
int gMidCount;

/// RemeshKernel::insertSlitMidpoints: a Steiner midpoint on every slit
/// chord of a kept piece between two rim points, one per chord however
/// other planes split it (splitChord). In three passes, so that no loop of
/// the walk sits inside the loop over edges and quads (llvmpipe charges
/// every loop an inlined call reaches, its lanes active or not, against
/// one budget): each end classed once per quad, listing the edges that
/// take a midpoint and the pieces of split chords; the list's chords
/// followed; then region 1 written with the midpoints, made in the CPU's
/// order (their vertex numbers agree).
void insertSlitMidpoints()
{
    gMidCount = 0;
    for (int i = 0; i < gPieceCount[0] && !uPrism && gFail == 0u; ++i) {
        if (!gKept[i]) continue;
        const int n = pieceLen(0, i);
        for (int k = 0; k < n; ++k) {
            const int u = pieceV(0, i, k), w = pieceV(0, i, (k + 1) % n);
            for (int j = 0; j < gReachCount; ++j) {
                const int r = gReachQuad[j];
                const int cu = chordClass(u, r), cw = chordClass(w, r);
                const bool direct = cu == 1 && cw == 1 && apartOnRims(u, w, r);
                // (A piece of a split chord: each end a rim point or inside
                // the slit, one inside, and the walk from an end inside
                // stays in the tet there.)
                if (!direct && (cu == 0 || cw == 0 || (cu == 1 && cw == 1) ||
                                (cu == 2 && (vSupport(w) & ~vSupport(u)) != 0u) ||
                                (cw == 2 && (vSupport(u) & ~vSupport(w)) != 0u)))
                    continue;
                if (gMidCount == MID_MAX) {
                    gFail |= kFailMidpoints;
                    return;
                }
                gMidPiece[gMidCount] = i;
                gMidCorner[gMidCount] = k;
                gMidQuad[gMidCount] = r;
                gMidA[gMidCount] = direct ? u : -1;
                gMidB[gMidCount] = direct ? w : -2 - (4 * cu + cw);
                ++gMidCount;
                if (direct) break;
            }
        }
    }
    // The split chords' pieces: the whole chord, if it needs a midpoint that
    // lies inside this piece.
    for (int m = 0; m < gMidCount; ++m) {
        if (gMidB[m] >= 0) continue;
        const int cls = -2 - gMidB[m];
        const int i = gMidPiece[m], k = gMidCorner[m], r = gMidQuad[m], n = pieceLen(0, i);
        const int u = pieceV(0, i, k), w = pieceV(0, i, (k + 1) % n);
        gMidA[m] = gMidB[m] = -1;
        const precise dvec3 d = gVPos(w) - gVPos(u);
        if (!(length3(d) > 0.0lf)) continue;
        gChordOnIso = memberOf(u) == 0 && memberOf(w) == 0;
        gChordAlongCount = 0;
        for (int j = 0; j < gReachCount; ++j) {
            const int q = gReachQuad[j];
            if (q == r || signOf(u, kQuads[q].id) != 0 || signOf(w, kQuads[q].id) != 0) continue;
            if (gChordAlongCount == 4) {
                gFail |= kFailMidpoints;
                return;
            }
            gChordAlong[gChordAlongCount++] = q;
        }
        const int a = chordWalk(u, w, cls / 4, -d, r);
        const int b = chordWalk(w, u, cls % 4, d, r);
        if (a < 0 || b < 0 || !apartOnRims(a, b, r)) continue; // (needsMidpoint(a, b): a and b rim points)
        const precise dvec3 mid = 0.5lf * (gVPos(a) + gVPos(b));
        const double t = dot3(mid - gVPos(u), d) / dot3(d, d);
        if (!(t > 0.0lf && t < 1.0lf)) continue;
        gMidA[m] = a;
        gMidB[m] = b;
    }
    poolClear(1);
    int m = 0;
    for (int i = 0; i < gPieceCount[0] && gFail == 0u; ++i) {
        if (!gKept[i]) {
            poolCopyPiece(0, i, 1);
            continue;
        }
        if (!poolOpen(1)) return;
        const int n = pieceLen(0, i);
        for (int k = 0; k < n && gFail == 0u; ++k) {
            const uint64_t lab = pieceL(0, i, k);
            poolAdd(1, pieceV(0, i, k), lab);
            int a = -1, b = -1, r = -1;
            for (; m < gMidCount && gMidPiece[m] == i && gMidCorner[m] == k; ++m)
                if (a < 0 && gMidA[m] >= 0) {
                    a = gMidA[m];
                    b = gMidB[m];
                    r = gMidQuad[m];
                }
            if (a < 0) continue;
            const uint64_t ha = midpointWord(a), hb = midpointWord(b);
            uvec2 planes[8];
            int count = 0;
            planes[count++] = b64(kMid);
            planes[count++] = b64(kQuads[r].id);
            planes[count++] = b64(min(ha, hb));
            planes[count++] = b64(max(ha, hb));
            const uint sup = vSupport(a) | vSupport(b);
            if (bitCount4(sup) < 4) {
                const bool isoA = vPlaneCount(a) > 0 && gVPlanes(8 * a) == kIso;
                const bool isoB = vPlaneCount(b) > 0 && gVPlanes(8 * b) == kIso;
                if (isoA && isoB) planes[count++] = b64(kIso);
            }
            precise dvec3 mid = 0.5lf * (gVPos(a) + gVPos(b));
            const int made = makeSteiner(sup, planes, count, mid);
            if (made < 0) return;
            poolAdd(1, made, lab);
        }
    }
    poolTakeNext();
}

/// The arrangement of tet t of cell `cell` up to the regions, in scratch
/// slot `slot` (one per invocation); per surface
/// (in order) `emitSurface(s)` is called with region 0 and gKept final.
/// Returns false when the tet holds no solid.
bool arrangeTetBegin(uint slot, uint cell, int t)
{
    gFail = 0u;
    gBaseI = slot * kScratchI;
    gBaseL = slot * kScratchL;
    gBaseD = slot * kScratchD;
    gCell = cell;
    gTetIndex = t;
    gT = loadTet(cell, t);
    if (!gT.inside[0] && !gT.inside[1] && !gT.inside[2] && !gT.inside[3]) return false;
    gIso = isoTriangles(gT);
    gOwn = isoOwnership(gIso);
    gVertCount = 0;
    gSurfaceCount = 0;
    gatherPlanes();
    if (gFail != 0u) return true;
    isoSurfaces();
    capSurfaces();
    chooseSplitOrder();
    return true;
}

// ---- the tet's state between draws (cut_arrange.vert arranges a tet in
// several draws, each invocation within llvmpipe's loop limit): what
// arrangeTetBegin leaves in the globals, kept in the scratch slice.
#define gStateI(i) sI[gBaseI + kOffStateI + uint(i)]
#define gStateL(i) sL[gBaseL + kOffStateL + uint(i)]
#define gStateD(i) sD[gBaseD + kOffStateD + uint(i)]

/// Saves the tet's state; `at` is the record's next word, `solid` whether
/// the tet holds solid (else nothing else is kept).
void saveTetState(uint at, bool solid)
{
    gStateI(0) = solid ? 1 : 0;
    gStateI(1) = int(gFail);
    gStateI(2) = int(at);
    if (!solid) return;
    gStateI(3) = gVertCount;
    gStateI(4) = gSurfaceCount;
    gStateI(5) = gSplitCount;
    for (int i = 0; i < 8; ++i) gStateI(6 + i) = gTriVert[i];
    // 14, 15: region 0's piece and corner counts (cut_arrange.vert, between its stages)
    for (int s = 0; s < gSurfaceCount; ++s) {
        const int b = 16 + 12 * s;
        gStateI(b) = gSQuad[s];
        gStateI(b + 1) = gSSides[s];
        gStateI(b + 2) = gSAlsoCount[s];
        gStateI(b + 3) = gSPolyLen[s];
        for (int i = 0; i < 4; ++i) {
            gStateI(b + 4 + i) = gSAlso[4 * s + i];
            gStateI(b + 8 + i) = gSPolyV[4 * s + i];
            gStateL(5 * s + 1 + i) = u64(gSPolyLab[4 * s + i]);
        }
        gStateL(5 * s) = u64(gSPlane[s]);
        gStateD(3 * s) = D3GET(gSNormalBits, s).x;
        gStateD(3 * s + 1) = D3GET(gSNormalBits, s).y;
        gStateD(3 * s + 2) = D3GET(gSNormalBits, s).z;
    }
}

/// The tet's state as saveTetState left it, and what arrangeTetBegin
/// derives from the input again (the tet, its iso polygons, quads and
/// planes). Returns false when the tet holds no solid; `at`: the
/// record's next word.
bool restoreTetState(uint slot, uint cell, int t, out uint at)
{
    gBaseI = slot * kScratchI;
    gBaseL = slot * kScratchL;
    gBaseD = slot * kScratchD;
    gFail = uint(gStateI(1));
    at = uint(gStateI(2));
    if (gStateI(0) == 0) return false;
    gCell = cell;
    gTetIndex = t;
    gVertCount = gStateI(3);
    gSurfaceCount = gStateI(4);
    gSplitCount = gStateI(5);
    for (int i = 0; i < 8; ++i) gTriVert[i] = gStateI(6 + i);
    for (int s = 0; s < gSurfaceCount; ++s) {
        const int b = 16 + 12 * s;
        gSQuad[s] = gStateI(b);
        gSSides[s] = gStateI(b + 1);
        gSAlsoCount[s] = gStateI(b + 2);
        gSPolyLen[s] = gStateI(b + 3);
        for (int i = 0; i < 4; ++i) {
            gSAlso[4 * s + i] = gStateI(b + 4 + i);
            gSPolyV[4 * s + i] = gStateI(b + 8 + i);
            gSPolyLab[4 * s + i] = b64(gStateL(5 * s + 1 + i));
        }
        gSPlane[s] = b64(gStateL(5 * s));
        D3SET(gSNormalBits, s, dvec3(gStateD(3 * s), gStateD(3 * s + 1), gStateD(3 * s + 2)));
    }
    gT = loadTet(cell, t);
    gIso = isoTriangles(gT);
    gOwn = isoOwnership(gIso);
    const uint fail = gFail;
    gatherPlanes(); // the same lists as in the first draw (it may flag nothing new)
    gFail = fail;
    return true;
}

/// A stage's last word on llvmpipe's loop limit, after every loop of the
/// stage, saving its state included (a loop cut short there, say in
/// savePieces, leaves the next stage a wrong state as surely as one cut
/// short in the work: phantom, kerf 0.5, seed 4, cell (46, 61, 62) lost the
/// kept flags of three pieces so): flags the tet in the saved state.
void flagLoopLimit()
{
    if (!loopLimitHit()) return;
    gFail |= kFailLoopLimit;
    gStateI(1) = int(gFail);
}

/// Region 0's piece and corner counts and kept flags, kept between the
/// draws that finish a surface and trace its regions.
void savePieces()
{
    gStateI(14) = gPieceCount[0];
    gStateI(15) = gPoolUsed[0];
    for (int i = 0; i < gPieceCount[0]; ++i) sI[gBaseI + kOffKept + uint(i)] = gKept[i] ? 1 : 0;
}
void restorePieces()
{
    gPieceCount[0] = gStateI(14);
    gPoolUsed[0] = gStateI(15);
    for (int i = 0; i < gPieceCount[0]; ++i) gKept[i] = sI[gBaseI + kOffKept + uint(i)] != 0;
}

/// Surface s's pieces in region 0, once split (splitSurface): conforming,
/// classified and with their midpoints.
void finishSurface(int s)
{
    if (gFail != 0u) return;
    conformPieces();
    if (gFail != 0u) return;
    classifyPieces(s);
    insertSlitMidpoints();
}
