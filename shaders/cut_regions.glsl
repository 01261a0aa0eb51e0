// The re-meshing kernel's regions and triangles of one tet
// (cutter/RemeshKernel.cpp: traceRegions, markCorners, triangulateRegions),
// ported to GLSL after cut_arrange.glsl, whose state (the vertex table and
// region 0 of the piece pool, a surface's pieces once finished) they read;
// poly2.glsl triangulates. The rules of cut_kernel.glsl hold: the CPU's
// doubles in the CPU's order, `precise` wherever a product feeds a sum.
// - traceRegions, per surface: the kept pieces joined across shared edges
//   that are not slits (union-find, each later use of an edge joining its
//   piece to the edge's first piece), corners as nodes (a vertex and the
//   sorted side tags of the slits it lies in), per region (root piece,
//   ascending) its directed edges, those whose reverse it lacks, and loops
//   walked from them taking the most clockwise edge from the way back.
// - markCorners: the loop nodes that stay corners (a label change, a turn
//   back, a Steiner point, a quad's own rim).
// - triangulateRegions, per surface: each region's loops of corners
//   projected on its plane, outer loops and holes, holes bridged into
//   their outer loop, a cap region fanned from a Steiner centre, others by
//   bestTriangulation (kerf > 0) or earClip; each triangle's corners as
//   nodes into the record.
// The CPU's lookups become chains here (nodes per vertex, edge uses per
// lower vertex, edges per region and per node), which keep the CPU's order
// wherever it decides something (the first use of an edge, the first of
// equally clockwise edges). Where the CPU throws (a loop that does not
// close, cannot be bridged or triangulated, coplanar overlapping quads) the
// tet is refused (kRefused); past a capacity here it is flagged
// (kFailRegions); the CPU takes either.

// ---- the layout of the regions' part of the scratch slice (kOffRegions*)
const uint kOffRC = kOffKept + ARR_MAX_PIECES, // 0 nodes, 1 regions, 2 loops, 3 loop corners, 4 triangles, 5 node heads set
    kOffNodeVert = kOffRC + 8u, kOffNodeTagCount = kOffNodeVert + ARR_MAX_NODES,
           kOffNodeNext = kOffNodeTagCount + ARR_MAX_NODES, kOffNodeCorner = kOffNodeNext + ARR_MAX_NODES,
           kOffNodeAux = kOffNodeCorner + ARR_MAX_NODES, // per node: a chain head while tracing a region
    kOffNodeHead = kOffNodeAux + ARR_MAX_NODES, kOffRegionCap = kOffNodeHead + ARR_MAX_VERTS,
           kOffRegionSide = kOffRegionCap + ARR_MAX_REGIONS, kOffRegionLoop = kOffRegionSide + ARR_MAX_REGIONS,
           kOffRegionLoops = kOffRegionLoop + ARR_MAX_REGIONS, kOffRegionSurface = kOffRegionLoops + ARR_MAX_REGIONS,
           kOffLoopStart = kOffRegionSurface + ARR_MAX_REGIONS, kOffLoopLen = kOffLoopStart + ARR_MAX_LOOPS,
           kOffLoopNode = kOffLoopLen + ARR_MAX_LOOPS, kOffParent = kOffLoopNode + ARR_MAX_LOOP_CORNERS,
           kOffRootHead = kOffParent + ARR_MAX_PIECES, kOffRootTail = kOffRootHead + ARR_MAX_PIECES,
           // per edge use or directed edge (at most the pool's corners)
    kOffUseB = kOffRootTail + ARR_MAX_PIECES, kOffUsePiece = kOffUseB + ARR_MAX_POOL,
           kOffUseNext = kOffUsePiece + ARR_MAX_POOL, kOffDirFrom = kOffUseNext + ARR_MAX_POOL,
           kOffDirTo = kOffDirFrom + ARR_MAX_POOL, kOffDirNext = kOffDirTo + ARR_MAX_POOL,
           kOffOutNext = kOffDirNext + ARR_MAX_POOL, kOffBnd = kOffOutNext + ARR_MAX_POOL,
           kOffBndNext = kOffBnd + ARR_MAX_POOL, kOffBndUsed = kOffBndNext + ARR_MAX_POOL,
           kOffPieceNode = kOffBndUsed + ARR_MAX_POOL, kOffUseHead = kOffPieceNode + ARR_MAX_POOL,
           kEndRegionsI = kOffUseHead + ARR_MAX_VERTS;
const uint kOffNodeTags = kOffRegionsL, kOffLoopLabel = kOffNodeTags + 4 * ARR_MAX_NODES,
           kOffDirLabel = kOffLoopLabel + ARR_MAX_LOOP_CORNERS, kEndRegionsL = kOffDirLabel + ARR_MAX_POOL;
const uint kOffRegionNormal = kOffRegionsD, kEndRegionsD = kOffRegionNormal + 3 * ARR_MAX_REGIONS;
// cut_arrange.glsl's kScratchI/L/D (and the host's) must end where this
// layout does: an array of size -1 does not compile.
int gRegionsLayoutCheck[kEndRegionsI == kScratchI && kEndRegionsL == kScratchL && kEndRegionsD == kScratchD ? 1 : -1];

// gRC: 0 nodes, 1 regions, 2 loops, 3 loop corners, 4 triangles, 5 node
// heads set, 6 the record's word of the first triangle
#define gRC(i) sI[gBaseI + kOffRC + uint(i)]
#define gNodeVert(i) sI[gBaseI + kOffNodeVert + uint(i)]
#define gNodeTagCount(i) sI[gBaseI + kOffNodeTagCount + uint(i)]
#define gNodeNext(i) sI[gBaseI + kOffNodeNext + uint(i)]
#define gNodeCorner(i) sI[gBaseI + kOffNodeCorner + uint(i)]
#define gNodeAux(i) sI[gBaseI + kOffNodeAux + uint(i)]
#define gNodeHead(v) sI[gBaseI + kOffNodeHead + uint(v)]
#define gNodeTag(i, k) sL[gBaseL + kOffNodeTags + 4u * uint(i) + uint(k)]
#define gRegionCap(r) sI[gBaseI + kOffRegionCap + uint(r)]
#define gRegionSide(r) sI[gBaseI + kOffRegionSide + uint(r)]
#define gRegionLoop(r) sI[gBaseI + kOffRegionLoop + uint(r)]
#define gRegionLoops(r) sI[gBaseI + kOffRegionLoops + uint(r)]
#define gRegionSurface(r) sI[gBaseI + kOffRegionSurface + uint(r)]
#define gLoopStart(l) sI[gBaseI + kOffLoopStart + uint(l)]
#define gLoopLen(l) sI[gBaseI + kOffLoopLen + uint(l)]
#define gLoopNode(i) sI[gBaseI + kOffLoopNode + uint(i)]
#define gLoopLabel(i) sL[gBaseL + kOffLoopLabel + uint(i)]
#define gParent(i) sI[gBaseI + kOffParent + uint(i)]
#define gRootHead(i) sI[gBaseI + kOffRootHead + uint(i)]
#define gRootTail(i) sI[gBaseI + kOffRootTail + uint(i)]
#define gUseB(i) sI[gBaseI + kOffUseB + uint(i)]
#define gUsePiece(i) sI[gBaseI + kOffUsePiece + uint(i)]
#define gUseNext(i) sI[gBaseI + kOffUseNext + uint(i)]
#define gUseHead(v) sI[gBaseI + kOffUseHead + uint(v)]
#define gDirFrom(i) sI[gBaseI + kOffDirFrom + uint(i)]
#define gDirTo(i) sI[gBaseI + kOffDirTo + uint(i)]
#define gDirNext(i) sI[gBaseI + kOffDirNext + uint(i)]
#define gDirLabel(i) sL[gBaseL + kOffDirLabel + uint(i)]
#define gOutNext(i) sI[gBaseI + kOffOutNext + uint(i)]
#define gBnd(i) sI[gBaseI + kOffBnd + uint(i)]
#define gBndNext(i) sI[gBaseI + kOffBndNext + uint(i)]
#define gBndUsed(i) sI[gBaseI + kOffBndUsed + uint(i)]
#define gPieceNode(i) sI[gBaseI + kOffPieceNode + uint(i)]
#define gRegionNormal(r) \
    dvec3(sD[gBaseD + kOffRegionNormal + 3u * uint(r)], sD[gBaseD + kOffRegionNormal + 3u * uint(r) + 1u], \
          sD[gBaseD + kOffRegionNormal + 3u * uint(r) + 2u])

/// Before a tet's first surface is traced: no nodes, regions or triangles.
void regionsReset()
{
    for (int i = 0; i < 8; ++i) gRC(i) = 0;
}

/// The side tag of quad q's side `side` (Node::tags, CutVertexId::tags).
uint64_t sideTag(int q, int side) { return kQuads[q].id << 1 | (side < 0 ? 1ul : 0ul); }

/// RemeshKernel::nodeOf: the node of vertex `vert` with tags t0..t3 (n of
/// them, at most 4; sorted here), made when new. -1 when full.
int nodeOf(int vert, uint64_t t0, uint64_t t1, uint64_t t2, uint64_t t3, int n)
{
    // Sorted by a network of compare-swaps; the unused ones (~0) go last.
    uint64_t a = n > 0 ? t0 : ~0ul, b = n > 1 ? t1 : ~0ul, c = n > 2 ? t2 : ~0ul, d = n > 3 ? t3 : ~0ul, x;
    if (b < a) { x = a; a = b; b = x; }
    if (d < c) { x = c; c = d; d = x; }
    if (c < a) { x = a; a = c; c = x; }
    if (d < b) { x = b; b = d; d = x; }
    if (c < b) { x = b; b = c; c = x; }
    while (gRC(5) <= vert) {
        gNodeHead(gRC(5)) = -1;
        gRC(5) = gRC(5) + 1;
    }
    int last = -1;
    for (int i = gNodeHead(vert); i >= 0; i = gNodeNext(i)) {
        if (gNodeTagCount(i) == n && (n < 1 || gNodeTag(i, 0) == a) && (n < 2 || gNodeTag(i, 1) == b) &&
            (n < 3 || gNodeTag(i, 2) == c) && (n < 4 || gNodeTag(i, 3) == d))
            return i;
        last = i;
    }
    if (gRC(0) == ARR_MAX_NODES) {
        gFail |= kFailRegions;
        return -1;
    }
    const int id = gRC(0);
    gRC(0) = id + 1;
    gNodeVert(id) = vert;
    gNodeTagCount(id) = n;
    gNodeTag(id, 0) = a;
    gNodeTag(id, 1) = b;
    gNodeTag(id, 2) = c;
    gNodeTag(id, 3) = d;
    gNodeNext(id) = -1;
    gNodeCorner(id) = 0;
    if (last < 0) gNodeHead(vert) = id;
    else gNodeNext(last) = id;
    return id;
}

bool nodeHasTag(int node, uint64_t tag)
{
    for (int k = 0; k < gNodeTagCount(node); ++k)
        if (gNodeTag(node, k) == tag) return true;
    return false;
}

/// traceRegions' isSlit: edge (a, b) on another quad's plane inside that quad.
bool isSlit(int a, int b, int s)
{
    if (uPrism) return false;
    for (int j = 0; j < gReachCount; ++j) {
        const int r = gReachQuad[j];
        if (r == gSQuad[s]) continue;
        const uint64_t id = kQuads[r].id;
        if (signOf(a, id) == 0 && signOf(b, id) == 0 && inExtentClosed(a, r) && inExtentClosed(b, r)) return true;
    }
    return false;
}

/// traceRegions' stripSide: the side of quad r's slit that piece i (region
/// 0) lies on at vertex v, for surface s traced on `side`. 0: refused.
int stripSide(int i, int r, int v, int s, int side)
{
    if (r == gSQuad[s]) return side;
    for (uint sd = kQuads[r].firstSide; sd < kQuads[r].firstSide + kQuads[r].sideCount; ++sd) {
        if (kSides[sd].partnerId == 0ul || signOf(v, kSides[sd].id) != 0) continue;
        const int o = reachingQuadById(kSides[sd].partnerId);
        if (o < 0) continue;
        if (kSides[sd].orient * double(pieceSign(0, i, kSides[sd].id)) < 0.0lf) { // on the partner's half
            const int flip = kSides[sd].fold != 0 ? -1 : 1; // a fold: the partner's side there is r's other side
            if (o == gSQuad[s]) return flip * side;
            const int sg = pieceSign(0, i, kQuads[o].id);
            if (sg == 0) gFail |= kRefused; // coplanar overlapping quads
            return flip * sg;
        }
    }
    const int sg = pieceSign(0, i, kQuads[r].id);
    if (sg == 0) gFail |= kRefused;
    return sg;
}

/// RemeshKernel::tJunctionSide: v on quad r's rim, on a rim line that lies
/// in the open slit of quad o: the side of o where r lies (o set), else 0.
int tJunctionSide(int v, int r, out int o)
{
    o = -1;
    if (uPrism || signOf(v, kQuads[r].id) != 0 || !inExtentClosed(v, r) || (inSlitOpen(v, r) && !onStripRim(v, r)))
        return 0;
    // r's rim sides through v, as bits from its first side.
    const uint first = kQuads[r].firstSide, end = first + kQuads[r].sideCount;
    uint rims = 0u;
    for (uint s = first; s < end; ++s)
        if (kSides[s].partner < 0 && signOf(v, kSides[s].id) == 0) rims |= 1u << (s - first);
    for (uint sd = first; sd < end; ++sd) {
        if (((rims >> (sd - first)) & 1u) == 0u) continue;
        for (int j = 0; j < gReachCount; ++j) {
            const int q = gReachQuad[j];
            if (q == r || signOf(v, kQuads[q].id) != 0 || !inSlitOpen(v, q) || onStripRim(v, q)) continue;
            if (!rimLineIn(r, sd, q)) continue;
            // RemeshKernel::cornerOffPlane (from the bits: no signOf, whose
            // loops llvmpipe would charge here for every j).
            bool corner = false;
            for (uint s2 = first; s2 < end; ++s2)
                corner = corner || (s2 != sd && ((rims >> (s2 - first)) & 1u) != 0u && !rimLineIn(r, s2, q));
            if (corner) return 0;
            const dvec3 n = kQuads[r].plane.xyz, sn = kSides[sd].plane.xyz;
            precise dvec3 inward = kSides[sd].orient * (sn - n * dot3(sn, n)); // precise: no fused multiply-add
            const double h = dot3(kQuads[q].plane.xyz, inward);
            if (h == 0.0lf) continue;
            o = q;
            return h > 0.0lf ? 1 : -1;
        }
    }
    return 0;
}

/// The node of corner k of piece i (region 0) traced on `side`: its vertex
/// and the tags of the slits it lies inside (and, at a T-junction, of the
/// slit that ends there: tJunctionSide).
int pieceCornerNode(int i, int k, int s, int side)
{
    const int v = pieceV(0, i, k);
    uvec2 t[4] = uvec2[4](uvec2(0u), uvec2(0u), uvec2(0u), uvec2(0u));
    int n = 0;
    for (int j = 0; j < gReachCount && !uPrism; ++j) {
        const int r = gReachQuad[j];
        if (signOf(v, kQuads[r].id) != 0 || !inSlitOpen(v, r) || onStripRim(v, r)) {
            int o;
            const int rSide = tJunctionSide(v, r, o);
            if (rSide == 0) continue;
            const int oSide = stripSide(i, o, v, s, side);
            if (gFail != 0u) return -1;
            if (oSide != rSide) continue;
        }
        const int sg = stripSide(i, r, v, s, side);
        if (gFail != 0u) return -1;
        if (n == 4) { // more than Node's 4 tags: the CPU would refuse if it made a triangle of it
            gFail |= kFailRegions;
            return -1;
        }
        t[n++] = b64(sideTag(r, sg));
    }
    return nodeOf(v, u64(t[0]), u64(t[1]), u64(t[2]), u64(t[3]), n);
}

/// Union-find's root of piece x (path compression, as the CPU).
int findRoot(int x)
{
    int r = x;
    while (gParent(r) != r) r = gParent(r);
    while (gParent(x) != r) {
        const int next = gParent(x);
        gParent(x) = r;
        x = next;
    }
    return r;
}

/// The projection of node `node`'s vertex on (e1, e2).
dvec2 project(int node, dvec3 e1, dvec3 e2)
{
    const dvec3 x = gVPos(gNodeVert(node));
    return dvec2(dot3(x, e1), dot3(x, e2));
}

/// The in-plane axes of normal n: e1 = normalize(x or y axis less its part along n), e2 = n x e1.
void planeAxes(dvec3 n, out dvec3 e1, out dvec3 e2)
{
    const dvec3 a = abs(n.x) < 0.9lf ? dvec3(1.0lf, 0.0lf, 0.0lf) : dvec3(0.0lf, 1.0lf, 0.0lf);
    const double d = dot3(n, a);
    precise dvec3 u = dvec3(a.x - n.x * d, a.y - n.y * d, a.z - n.z * d);
    const double inv = 1.0lf / dSqrt(dot3(u, u)); // glm::normalize
    e1 = u * inv;
    e2 = cross3(n, e1);
}

/// poly2::clockwiseLess: d1 reached before d2 turning clockwise from `back`.
int clockwiseHalf(dvec2 back, dvec2 d)
{
    precise double c = back.x * d.y - back.y * d.x, dt = back.x * d.x + back.y * d.y;
    return c < 0.0lf ? 0 : c == 0.0lf && dt < 0.0lf ? 1 : c > 0.0lf ? 2 : 3;
}
bool clockwiseLess(dvec2 back, dvec2 d1, dvec2 d2)
{
    const int h1 = clockwiseHalf(back, d1), h2 = clockwiseHalf(back, d2);
    if (h1 != h2) return h1 < h2;
    precise double c = d1.x * d2.y - d1.y * d2.x;
    return c < 0.0lf;
}

/// Regions of the root piece `root`'s directed edges (gRootHead chain), of
/// surface s traced on `side`, with outward normal `normal`: its boundary
/// edges walked into loops, a region appended when it has any.
void traceRoot(int root, int s, int side, dvec3 normal)
{
    // Boundary edges (those whose reverse the region lacks), in the
    // region's order; its edges chained per from-node first.
    for (int e = gRootHead(root); e >= 0; e = gDirNext(e)) {
        gNodeAux(gDirFrom(e)) = -1;
        gNodeAux(gDirTo(e)) = -1;
    }
    for (int e = gRootHead(root); e >= 0; e = gDirNext(e)) {
        gOutNext(e) = gNodeAux(gDirFrom(e));
        gNodeAux(gDirFrom(e)) = e;
    }
    int nb = 0;
    for (int e = gRootHead(root); e >= 0; e = gDirNext(e)) {
        const int from = gDirFrom(e), to = gDirTo(e);
        bool back = false;
        for (int f = gNodeAux(to); f >= 0 && !back; f = gOutNext(f)) back = gDirTo(f) == from;
        if (!back) gBnd(nb++) = e;
    }
    if (nb == 0) return;
    // The boundary edges per from-node, in boundary order (built backwards).
    for (int k = 0; k < nb; ++k) {
        gNodeAux(gDirFrom(gBnd(k))) = -1;
        gNodeAux(gDirTo(gBnd(k))) = -1;
    }
    for (int k = nb - 1; k >= 0; --k) {
        const int from = gDirFrom(gBnd(k));
        gBndNext(k) = gNodeAux(from);
        gNodeAux(from) = k;
        gBndUsed(k) = 0;
    }
    dvec3 e1, e2;
    planeAxes(normal, e1, e2);
    if (gRC(1) == ARR_MAX_REGIONS) {
        gFail |= kFailRegions;
        return;
    }
    const int region = gRC(1);
    gRC(1) = region + 1;
    gRegionCap(region) = gSQuad[s];
    gRegionSide(region) = side;
    gRegionSurface(region) = s;
    gRegionLoop(region) = gRC(2);
    gRegionLoops(region) = 0;
    const uint nb3 = gBaseD + kOffRegionNormal + 3u * uint(region);
    sD[nb3] = normal.x;
    sD[nb3 + 1u] = normal.y;
    sD[nb3 + 2u] = normal.z;
    for (int start = 0; start < nb; ++start) {
        if (gBndUsed(start) != 0) continue;
        if (gRC(2) == ARR_MAX_LOOPS) {
            gFail |= kFailRegions;
            return;
        }
        const int loop = gRC(2);
        gRC(2) = loop + 1;
        gRegionLoops(region) = gRegionLoops(region) + 1;
        gLoopStart(loop) = gRC(3);
        gLoopLen(loop) = 0;
        const int first = gDirFrom(gBnd(start));
        int cur = start;
        for (int guard = 0; guard <= nb; ++guard) {
            gBndUsed(cur) = 1;
            const int e = gBnd(cur);
            if (gRC(3) == ARR_MAX_LOOP_CORNERS) {
                gFail |= kFailRegions;
                return;
            }
            gLoopNode(gRC(3)) = gDirFrom(e);
            gLoopLabel(gRC(3)) = gDirLabel(e);
            gRC(3) = gRC(3) + 1;
            gLoopLen(loop) = gLoopLen(loop) + 1;
            const int at = gDirTo(e);
            if (at == first) break;
            // Next: the unused edge from `at` most clockwise from the way back.
            int best = -1;
            dvec2 bestDir = dvec2(0.0lf);
            const dvec2 pa = project(at, e1, e2), pb = project(gDirFrom(e), e1, e2);
            precise dvec2 back = dvec2(pb.x - pa.x, pb.y - pa.y);
            for (int k = gNodeAux(at); k >= 0; k = gBndNext(k)) {
                if (gBndUsed(k) != 0) continue;
                const dvec2 pc = project(gDirTo(gBnd(k)), e1, e2);
                precise dvec2 dir = dvec2(pc.x - pa.x, pc.y - pa.y);
                if (best < 0 || clockwiseLess(back, dir, bestDir)) {
                    bestDir = dir;
                    best = k;
                }
            }
            if (best < 0) { // an open boundary loop: the CPU refuses the cell
                gFail |= kRefused;
                return;
            }
            cur = best;
        }
    }
}

/// RemeshKernel::traceRegions for both sides of surface s (region 0 of the
/// pool holds its finished pieces, gKept which are kept): the regions and
/// their loops appended.
void traceSurface(int s)
{
    const int pieces = gPieceCount[0];
    // Union-find over the kept pieces across non-slit shared edges, in the
    // order of the edge uses; a use's edge is found among the earlier ones
    // through the chain of its lower vertex, which keeps each edge's first
    // piece.
    for (int i = 0; i < pieces; ++i) gParent(i) = i;
    for (int v = 0; v < gVertCount; ++v) gUseHead(v) = -1;
    int uses = 0;
    for (int i = 0; i < pieces && gFail == 0u; ++i) {
        if (!gKept[i]) continue;
        const int n = pieceLen(0, i);
        for (int k = 0; k < n; ++k) {
            int a = pieceV(0, i, k), b = pieceV(0, i, (k + 1) % n);
            if (a > b) {
                const int x = a;
                a = b;
                b = x;
            }
            int first = -1;
            for (int u = gUseHead(a); u >= 0 && first < 0; u = gUseNext(u))
                if (gUseB(u) == b) first = gUsePiece(u);
            if (first < 0) {
                gUseB(uses) = b;
                gUsePiece(uses) = i;
                gUseNext(uses) = gUseHead(a);
                gUseHead(a) = uses;
                ++uses;
            } else if (!isSlit(a, b, s)) {
                gParent(findRoot(i)) = findRoot(first);
            }
        }
    }
    const bool cap = gSQuad[s] >= 0 && !uPrism;
    for (int side = 1; side >= -1 && gFail == 0u; side -= 2) {
        if (cap ? (gSSides[s] & (side > 0 ? 1 : 2)) == 0 : side < 0) continue;
        const bool reverse = cap && side > 0;
        // Directed edges per root piece, in piece order.
        for (int i = 0; i < pieces; ++i) gRootHead(i) = -1;
        int edges = 0;
        for (int i = 0; i < pieces && gFail == 0u; ++i) {
            if (!gKept[i]) continue;
            const int n = pieceLen(0, i);
            for (int k = 0; k < n && gFail == 0u; ++k) gPieceNode(k) = pieceCornerNode(i, k, s, side);
            if (gFail != 0u) return;
            const int root = findRoot(i);
            for (int k = 0; k < n; ++k) {
                const int a = gPieceNode(k), b = gPieceNode((k + 1) % n);
                gDirFrom(edges) = reverse ? b : a;
                gDirTo(edges) = reverse ? a : b;
                gDirLabel(edges) = pieceL(0, i, k);
                gDirNext(edges) = -1;
                if (gRootHead(root) < 0) gRootHead(root) = edges;
                else gDirNext(gRootTail(root)) = edges;
                gRootTail(root) = edges;
                ++edges;
            }
        }
        const dvec3 normal = reverse ? -D3GET(gSNormalBits, s) : D3GET(gSNormalBits, s);
        for (int root = 0; root < pieces && gFail == 0u; ++root)
            if (gRootHead(root) >= 0) traceRoot(root, s, side, normal);
    }
}

/// RemeshKernel::markCorners' onOwnRim: a point of a quad's rim (kerf 0).
bool onOwnRim(int v)
{
    if (uPrism || vDim(v) == 3u) return false;
    const int pc = vPlaneCount(v);
    for (int i = 0; i < pc; ++i) {
        const uint64_t p = gVPlanes(8 * v + i), kind = p & 15ul;
        if (p < (1ul << 36) || kind < 1ul || kind > 4ul) continue;
        const uint64_t quad = p & ~15ul;
        for (int j = 0; j < pc; ++j)
            if (gVPlanes(8 * v + j) == quad) return true;
    }
    return false;
}

/// RemeshKernel::joinedSurfaceId: the id of the surface that face `id` of
/// another id is joined to (capFace: a face of one of its joined prisms that
/// coincides with its plane, facing the same way), else `id`.
uint64_t joinedSurfaceId(uint64_t id)
{
    for (int s = 0; s < gSurfaceCount; ++s) {
        const uint64_t own = u64(gSPlane[s]);
        if (gSAlsoCount[s] == 0 || own == id) continue;
        const dvec4 plane = capPlane(s);
        const dvec3 normal = D3GET(gSNormalBits, s);
        for (int k = 0; k < gSAlsoCount[s]; ++k) {
            const int q = gSAlso[4 * s + k];
            for (uint x = kQuads[q].firstSide; x < kQuads[q].firstSide + kQuads[q].sideCount; ++x) {
                if (kSides[x].id != id) continue;
                precise dvec3 n = kSides[x].orient * kSides[x].plane.xyz;
                if (dot3(n, normal) > 0.0lf && coincidentPlanes(plane, kSides[x].plane)) return own;
            }
        }
    }
    return id;
}

/// RemeshKernel::markCorners: gNodeCorner of every node of every loop.
void markCorners()
{
    for (int i = 0; i < gRC(0); ++i) gNodeCorner(i) = 0;
    for (int l = 0; l < gRC(2); ++l) {
        const int start = gLoopStart(l), n = gLoopLen(l);
        for (int i = 0; i < n; ++i) {
            const int prev = start + (i + n - 1) % n, at = start + i, next = start + (i + 1) % n;
            bool c = gLoopLabel(prev) != gLoopLabel(at);
            if (c && uPrism) c = joinedSurfaceId(gLoopLabel(prev)) != joinedSurfaceId(gLoopLabel(at));
            if (!c) {
                const dvec3 a = gVPos(gNodeVert(gLoopNode(prev))), b = gVPos(gNodeVert(gLoopNode(at))),
                            d = gVPos(gNodeVert(gLoopNode(next)));
                c = dot3(b - a, d - b) < 0.0lf;
            }
            const int v = gNodeVert(gLoopNode(at));
            if (c || vSteiner(v) || onOwnRim(v)) gNodeCorner(gLoopNode(at)) = 1;
        }
    }
}

// ---- triangulateRegions: per region, its loops' corners as poly2 points
int gPtNode[POLY2_MAX_POINTS]; // the node of each poly2 point
int gLoopPt[ARR_MAX_LOOPS];    // per loop of the region: its first point (its points are consecutive)
int gLoopPts[ARR_MAX_LOOPS];   // and how many
bool gLoopOuter[ARR_MAX_LOOPS];
int gHoleOf[ARR_MAX_LOOPS];    // per hole: the outer loop it is bridged into

/// Sets poly2Poly to loop l's points.
void polyOfLoop(int l)
{
    poly2PolyCount = 0;
    for (int i = 0; i < gLoopPts[l]; ++i) poly2AddCorner(gLoopPt[l] + i);
}

/// Appends the triangles of poly2Tri (point indices) to the record as nodes
/// (21 bits each), bit 63 set on a cap region's (CutCellGeometry::cap).
void putTriangles(bool cap)
{
    for (int t = 0; t + 2 < poly2TriCount; t += 3) {
        put(uint64_t(gPtNode[poly2Tri[t]]) | uint64_t(gPtNode[poly2Tri[t + 1]]) << 21 |
            uint64_t(gPtNode[poly2Tri[t + 2]]) << 42 | (cap ? 1ul << 63 : 0ul));
        gRC(4) = gRC(4) + 1;
    }
}

/// The mean of poly2Poly's n corners' positions (RemeshKernel's cornerMean).
dvec3 cornerMean(int n)
{
    precise dvec3 centre = dvec3(0.0lf);
    for (int i = 0; i < n; ++i) centre += gVPos(gNodeVert(gPtNode[poly2Poly[i]])) / double(n);
    return centre;
}

/// triangulateRegions' centreFan: cap region r of quad q (its n corners in
/// poly2Poly) as a fan from `centre`, a Steiner vertex tagged with the
/// region's side. False when a table is full (gFail set).
bool centreFan(int r, int q, int n, dvec3 e1, dvec3 e2, dvec3 centre)
{
    const uvec2 o = uvec2(0u);
    uvec2 planes[8] = uvec2[8](b64(kCentroid), b64(kQuads[q].id), b64(uint64_t(r) + 8ul), o, o, o, o, o);
    const int cv = makeSteiner(15u, planes, 3, centre);
    if (cv < 0) return false;
    const int cn = nodeOf(cv, sideTag(q, gRegionSide(r)), 0ul, 0ul, 0ul, 1);
    if (cn < 0) return false;
    const int ci = poly2AddPoint(dvec2(dot3(centre, e1), dot3(centre, e2)));
    if (ci < 0) {
        gFail |= kFailRegions;
        return false;
    }
    gPtNode[ci] = cn;
    for (int i = 0; i < n; ++i) poly2AddTri(ci, poly2Poly[i], poly2Poly[(i + 1) % n]);
    return true;
}

/// triangulateRegions' rimDiagonal: the ears' edge between poly2 points a
/// and b joins two corners neither of which has the side's tag `own`, and
/// is no edge of the region's n corners (poly2Poly).
bool rimDiagonal(int a, int b, int n, uint64_t own)
{
    if (nodeHasTag(gPtNode[a], own) || nodeHasTag(gPtNode[b], own)) return false;
    for (int i = 0; i < n; ++i) {
        const int p = poly2Poly[i], c = poly2Poly[(i + 1) % n];
        if ((p == a && c == b) || (p == b && c == a)) return false;
    }
    return true;
}

/// triangulateRegions' splitRimDiagonals: each such diagonal of the ears of
/// cap region r of quad q gets a midpoint tagged with the region's side
/// (named as a slit chord's midpoint), the two ears on it split in two
/// each. False when a table is full (gFail set).
bool splitRimDiagonals(int r, int q, int n, dvec3 e1, dvec3 e2)
{
    const uint64_t own = sideTag(q, gRegionSide(r));
    for (int t = 0; t + 2 < poly2TriCount; t += 3)
        for (int c = 0; c < 3; ++c) {
            const int a = poly2Tri[t + c], b = poly2Tri[t + (c + 1) % 3];
            if (!rimDiagonal(a, b, n, own)) continue;
            const int va = gNodeVert(gPtNode[a]), vb = gNodeVert(gPtNode[b]);
            const uint64_t ha = midpointWord(va), hb = midpointWord(vb);
            const uvec2 o = uvec2(0u);
            uvec2 planes[8] = uvec2[8](b64(kMid), b64(kQuads[q].id), b64(min(ha, hb)), b64(max(ha, hb)), o, o, o, o);
            precise dvec3 mid = 0.5lf * (gVPos(va) + gVPos(vb));
            const int mv = makeSteiner(vSupport(va) | vSupport(vb), planes, 4, mid);
            if (mv < 0) return false;
            const int mn = nodeOf(mv, own, 0ul, 0ul, 0ul, 1);
            if (mn < 0) return false;
            const int m = poly2AddPoint(dvec2(dot3(mid, e1), dot3(mid, e2)));
            if (m < 0) {
                gFail |= kFailRegions;
                return false;
            }
            gPtNode[m] = mn;
            for (int u = 0; u + 2 < poly2TriCount; u += 3)
                for (int k = 0; k < 3; ++k) {
                    const int x = poly2Tri[u + k], y = poly2Tri[u + (k + 1) % 3], z = poly2Tri[u + (k + 2) % 3];
                    if (!((x == a && y == b) || (x == b && y == a))) continue;
                    poly2Tri[u] = x;
                    poly2Tri[u + 1] = m;
                    poly2Tri[u + 2] = z;
                    poly2AddTri(m, y, z);
                    break;
                }
        }
    if (poly2Overflow) gFail |= kFailRegions;
    return !poly2Overflow;
}

/// RemeshKernel::triangulateRegions for region r.
void triangulateRegion(int r)
{
    const dvec3 nrm = gRegionNormal(r);
    dvec3 e1, e2;
    planeAxes(nrm, e1, e2);
    poly2Reset();
    const int loops = gRegionLoops(r);
    int outers = 0, holes = 0, lastHole = -1;
    for (int j = 0; j < loops; ++j) {
        const int l = gRegionLoop(r) + j;
        gLoopPt[j] = poly2PtCount;
        gLoopPts[j] = 0;
        for (int i = 0; i < gLoopLen(l); ++i) {
            const int nd = gLoopNode(gLoopStart(l) + i);
            if (gNodeCorner(nd) == 0) continue;
            const int p = poly2AddPoint(project(nd, e1, e2));
            if (p < 0) {
                gFail |= kFailRegions;
                return;
            }
            gPtNode[p] = nd;
            ++gLoopPts[j];
        }
        gLoopOuter[j] = false;
        if (gLoopPts[j] < 3) {
            if (gLoopPts[j] == 0) continue;
            gFail |= kRefused; // a degenerate boundary loop
            return;
        }
        // A loop of (nearly) zero area is a slit inside the region: a hole.
        precise double perim = 0.0lf;
        for (int i = 0; i < gLoopPts[j]; ++i) {
            const dvec2 a = poly2Pt(gLoopPt[j] + i), b = poly2Pt(gLoopPt[j] + (i + 1) % gLoopPts[j]);
            precise double dx = a.x - b.x, dy = a.y - b.y;
            perim += poly2Length(dx, dy);
        }
        polyOfLoop(j);
        precise double bound = 1e-9lf * perim * perim;
        gLoopOuter[j] = poly2SignedArea() > bound;
        if (gLoopOuter[j]) ++outers;
        else {
            ++holes;
            lastHole = j;
        }
    }
    // One loop too thin to span an area (a triangle a few nm across, a strip
    // 1e-10 voxel wide): a fan from its first corner.
    bool lone = false;
    if (outers == 0) {
        if (holes == 0) return;
        if (holes != 1) {
            gFail |= kRefused; // a region without an outer loop
            return;
        }
        gLoopOuter[lastHole] = true;
        outers = 1;
        holes = 0;
        lone = true;
    }
    // Each hole into the last outer loop that holds its centroid (the first
    // outer loop when there is one).
    int firstOuter = 0;
    while (!gLoopOuter[firstOuter] || gLoopPts[firstOuter] == 0) ++firstOuter;
    for (int h = 0; h < loops; ++h) {
        if (gLoopOuter[h] || gLoopPts[h] == 0) continue;
        int best = firstOuter;
        if (outers > 1) {
            precise dvec2 c = dvec2(0.0lf);
            const double hn = double(gLoopPts[h]);
            for (int i = 0; i < gLoopPts[h]; ++i) {
                c.x += poly2Pt(gLoopPt[h] + i).x / hn;
                c.y += poly2Pt(gLoopPt[h] + i).y / hn;
            }
            for (int o = 0; o < loops; ++o) {
                if (!gLoopOuter[o] || gLoopPts[o] == 0) continue;
                bool inside = false;
                const int L = gLoopPt[o], Ln = gLoopPts[o];
                for (int i = 0, j = Ln - 1; i < Ln; j = i++) {
                    const dvec2 a = poly2Pt(L + i), b = poly2Pt(L + j);
                    precise double x = (b.x - a.x) * (c.y - a.y) / (b.y - a.y) + a.x;
                    if ((a.y > c.y) != (b.y > c.y) && c.x < x) inside = !inside;
                }
                if (inside) best = o;
            }
        }
        gHoleOf[h] = best;
    }
    const int q = gRegionCap(r);
    for (int o = 0; o < loops && gFail == 0u; ++o) {
        if (!gLoopOuter[o] || gLoopPts[o] == 0) continue;
        polyOfLoop(o);
        poly2HoleCount = 0;
        poly2HoleStart[0] = 0;
        poly2TriCount = 0;
        bool hasHoles = false;
        for (int h = 0; h < loops; ++h) {
            if (gLoopOuter[h] || gLoopPts[h] == 0 || gHoleOf[h] != o) continue;
            hasHoles = true;
            poly2BeginHole();
            for (int i = 0; i < gLoopPts[h]; ++i) poly2AddHoleCorner(gLoopPt[h] + i);
        }
        if (poly2Overflow) {
            gFail |= kFailRegions;
            return;
        }
        if (hasHoles && !poly2BridgeHoles()) {
            gFail |= poly2Overflow ? kFailRegions : kRefused; // cannot bridge a hole
            return;
        }
        const int n = poly2PolyCount;
        const bool plainCap = q >= 0 && !uPrism && outers == 1 && !hasHoles;
        bool convex = plainCap;
        for (int i = 0; i < n && convex; ++i) {
            const dvec2 a = poly2Pt(poly2Poly[(i + n - 1) % n]), b = poly2Pt(poly2Poly[i]),
                        c = poly2Pt(poly2Poly[(i + 1) % n]);
            precise double bx = b.x - a.x, by = b.y - a.y, cx = c.x - b.x, cy = c.y - b.y;
            precise double tol = -1e-9lf * poly2Length(bx, by) * poly2Length(cx, cy);
            convex = poly2Cross(a, b, c) >= tol;
        }
        // A triangle with a corner only this side has needs no centre.
        bool ownCorner = false;
        for (int i = 0; i < n && convex && n == 3; ++i)
            ownCorner = ownCorner || nodeHasTag(gPtNode[poly2Poly[i]], sideTag(q, gRegionSide(r)));
        if (ownCorner) {
            poly2AddTri(poly2Poly[0], poly2Poly[1], poly2Poly[2]); // (n is 3 here)
        } else if (lone) {
            for (int i = 1; i + 1 < n; ++i) poly2AddTri(poly2Poly[0], poly2Poly[i], poly2Poly[i + 1]);
        } else if (convex) {
            // A cap region: a fan from a tagged centre.
            if (!centreFan(r, q, n, e1, e2, cornerMean(n))) return;
        } else {
            bool done = uPrism && poly2BestTriangulation();
            if (!done) {
                poly2TriCount = 0;
                done = poly2EarClip();
            }
            if (!done) {
                gFail |= poly2Overflow ? kFailRegions : kRefused; // triangulation failed
                return;
            }
            if (plainCap) {
                // A reflex cap region at zero kerf: an ear with no corner of
                // its own side, or a diagonal between two such corners, may be
                // the other side's too; then a fan from the tagged centre
                // where the region is star-shaped from it, else each such
                // diagonal split at a midpoint of the side's own.
                const uint64_t own = sideTag(q, gRegionSide(r));
                bool sharedEar = false;
                for (int t = 0; t + 2 < poly2TriCount && !sharedEar; t += 3)
                    sharedEar = !nodeHasTag(gPtNode[poly2Tri[t]], own) && !nodeHasTag(gPtNode[poly2Tri[t + 1]], own) &&
                             !nodeHasTag(gPtNode[poly2Tri[t + 2]], own);
                for (int t = 0; t + 2 < poly2TriCount && !sharedEar; t += 3)
                    for (int c = 0; c < 3 && !sharedEar; ++c)
                        sharedEar = rimDiagonal(poly2Tri[t + c], poly2Tri[t + (c + 1) % 3], n, own);
                if (sharedEar) {
                    const dvec3 centre = cornerMean(n);
                    const dvec2 c = dvec2(dot3(centre, e1), dot3(centre, e2));
                    bool star = true;
                    for (int i = 0; i < n && star; ++i) {
                        const dvec2 a = poly2Pt(poly2Poly[i]), b = poly2Pt(poly2Poly[(i + 1) % n]);
                        precise double bound = 1e-9lf * poly2Dist(a, c) * poly2Dist(b, c);
                        star = poly2Cross(c, a, b) > bound;
                    }
                    if (star) {
                        poly2TriCount = 0;
                        if (!centreFan(r, q, n, e1, e2, centre)) return;
                    } else if (!splitRimDiagonals(r, q, n, e1, e2)) {
                        return;
                    }
                }
            }
        }
        if (poly2Overflow) {
            gFail |= kFailRegions;
            return;
        }
        putTriangles(q >= 0);
    }
}

/// triangulateRegions for the regions of surface s (they are consecutive).
void triangulateSurface(int s)
{
    for (int r = 0; r < gRC(1) && gFail == 0u; ++r)
        if (gRegionSurface(r) == s) triangulateRegion(r);
}

/// The node table into the record: per node its vertex | tag count << 32,
/// then its tags.
void putNodes()
{
    for (int i = 0; i < gRC(0); ++i) {
        put(uint64_t(gNodeVert(i)) | uint64_t(gNodeTagCount(i)) << 32);
        for (int k = 0; k < gNodeTagCount(i); ++k) put(gNodeTag(i, k));
    }
}

// ---- pass 3's draw: the tet's triangles into the draw buffers
// (render/CutKernelGpu.h GpuCutDraw), drawn with glDrawArraysIndirect:
// three vertices per triangle in surface.vert's layout (world mm, unit
// normal), its TriangleInfo (surface.frag) and its key, at a slot taken
// with an atomic counter; past the capacity a triangle is only counted.
// Normals as render/CutGeometry.cpp's CutNormals::Shading: on the
// isosurface the volume's gradient (extractIsosurface's at a marching-
// tetrahedra vertex, else the trilinear interpolation of the cell corners'
// central differences), on caps the triangle's plane.
layout(std430, binding = 10) readonly buffer KernelBlocks { float kBlock[]; }; // per cell: 4^3 values round it
layout(std430, binding = 11) writeonly buffer DrawVertices { float dVertex[]; }; // 6 floats per vertex
layout(std430, binding = 12) writeonly buffer DrawTriangles { ivec4 dTriangle[]; }; // cell xyz, info
layout(std430, binding = 13) writeonly buffer DrawKeys { uvec2 dKey[]; };           // (tet, triangle of the tet)
layout(std430, binding = 14) buffer DrawCommand
{
    uint dCount, dInstances, dFirst, dBaseInstance; // DrawArraysIndirectCommand
    uint dWanted;                                   // triangles made, also those past the capacity
};
uniform dvec3 uOrigin, uSpacing; // index space to world mm
uniform uint uDrawCapacity;      // triangles the draw buffers hold

/// The value at grid point g of the block of the cell at `cell` (g within cell - 1 .. cell + 2).
float blockValue(ivec3 cell, ivec3 g)
{
    const ivec3 d = g - cell + ivec3(1);
    return kBlock[64u * gCell + uint(d.x + 4 * d.y + 16 * d.z)];
}

ivec3 gridVertexCoord(uint64_t id)
{
    const int64_t off = 1l << 20, mask = (1l << 21) - 1l;
    const int64_t i = int64_t(id) & mask, j = (int64_t(id) >> 21) & mask, k = (int64_t(id) >> 42) & mask;
    return ivec3(int(i - off), int(j - off), int(k - off));
}

ivec3 unitAxis(int a) { return ivec3(a == 0 ? 1 : 0, a == 1 ? 1 : 0, a == 2 ? 1 : 0); }

/// CutGeometry.cpp gradientNormal: at the marching-tetrahedra vertex on
/// grid edge (p0, p1), p0 the lower-keyed end.
vec3 edgeGradientNormal(ivec3 cell, ivec3 p0, ivec3 p1)
{
    const float v0 = blockValue(cell, p0), v1 = blockValue(cell, p1);
    const double t = edgeCrossing(v0, v1, uIsovalue);
    float ga[3]; // g's components (no vector is written at a run-time index: cut_kernel.glsl)
    for (int a = 0; a < 3; ++a) {
        const ivec3 e = unitAxis(a);
        precise float g0 = 0.5 * (blockValue(cell, p0 + e) - blockValue(cell, p0 - e));
        precise float g1 = 0.5 * (blockValue(cell, p1 + e) - blockValue(cell, p1 - e));
        precise float d = g1 - g0;
        precise double x = -(double(g0) + t * double(d)) * (1.0lf / uSpacing[a]);
        ga[a] = float(x);
    }
    vec3 g = vec3(ga[0], ga[1], ga[2]);
    precise float len = sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
    if (len > 0.0 && !isinf(len) && !isnan(len)) return g / len;
    const KernelCell c = kCells[gCell];
    const ivec3 lo = p0 - ivec3(c.x, c.y, c.z);
    const bool in0 = ((c.insideMask >> uint(lo.x + 2 * lo.y + 4 * lo.z)) & 1u) != 0u;
    const float s = in0 ? 1.0 : -1.0;
    for (int a = 0; a < 3; ++a) ga[a] = s * float(double(p1[a] - p0[a]) * uSpacing[a]);
    g = vec3(ga[0], ga[1], ga[2]);
    return g / sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
}

/// CutGeometry.cpp trilinearGradientNormal at index point p; zero when flat.
vec3 trilinearGradientNormal(ivec3 cell, dvec3 p)
{
    precise double gx = 0.0lf, gy = 0.0lf, gz = 0.0lf; // g's components (see above)
    const dvec3 f = clamp(p - dvec3(cell), dvec3(0.0lf), dvec3(1.0lf));
    for (int c = 0; c < 8; ++c) {
        const ivec3 q = cell + ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        precise double w = ((c & 1) != 0 ? f.x : 1.0lf - f.x) * (((c >> 1) & 1) != 0 ? f.y : 1.0lf - f.y) *
                           (((c >> 2) & 1) != 0 ? f.z : 1.0lf - f.z);
        const ivec3 ex = ivec3(1, 0, 0), ey = ivec3(0, 1, 0), ez = ivec3(0, 0, 1);
        gx -= w * 0.5lf * (double(blockValue(cell, q + ex)) - double(blockValue(cell, q - ex))) / uSpacing[0];
        gy -= w * 0.5lf * (double(blockValue(cell, q + ey)) - double(blockValue(cell, q - ey))) / uSpacing[1];
        gz -= w * 0.5lf * (double(blockValue(cell, q + ez)) - double(blockValue(cell, q - ez))) / uSpacing[2];
    }
    const dvec3 g = dvec3(gx, gy, gz);
    const double len = length3(g);
    return len > 0.0lf && !isinf(len) && !isnan(len) ? vec3(g / len) : vec3(0.0);
}

vec3 worldPosition(dvec3 p)
{
    precise dvec3 w = uOrigin + uSpacing * p;
    return vec3(w);
}

/// Whether no tet of the cell of `tet` (in slot `slot`) was flagged: the
/// draw's slots hold whole cells (the host's batches are whole cells).
bool cellComplete(uint slot, uint tet)
{
    const uint first = slot - tet % 5u;
    for (uint s = first; s < first + 5u; ++s)
        if (sI[s * kScratchI + kOffStateI + 1u] != 0) return false;
    return true;
}

/// The tet's triangles (gRC(4) of them, in the record from gRC(6)) into the draw buffers.
void emitTriangles(uint tet)
{
    const KernelCell kc = kCells[gCell];
    const ivec3 cell = ivec3(kc.x, kc.y, kc.z);
    for (int t = 0; t < gRC(4); ++t) {
        const uint64_t w = outRecord[uint(gRC(6) + t)];
        const int n[3] = int[3](int(w & 0x1ffffful), int((w >> 21) & 0x1ffffful), int((w >> 42) & 0x1ffffful));
        const int v[3] = int[3](gNodeVert(n[0]), gNodeVert(n[1]), gNodeVert(n[2]));
        vec3 pos[3];
        for (int k = 0; k < 3; ++k) pos[k] = worldPosition(gVPos(v[k]));
        const bool cap = (w >> 63) != 0ul;
        const vec3 c = cross(pos[1] - pos[0], pos[2] - pos[0]);
        const float cl = length(c);
        const vec3 faceNormal = cl > 0.0 ? c / cl : vec3(0.0, 0.0, 1.0);
        const uint slot = atomicAdd(dWanted, 1u);
        if (slot >= uDrawCapacity) continue;
        for (int k = 0; k < 3; ++k) {
            vec3 nrm = vec3(0.0);
            const int x = v[k];
            if (!cap && vDim(x) == 1u && vPlaneCount(x) == 1 && gVPlanes(8 * x) == kIso && gNodeTagCount(n[k]) == 0)
                nrm = edgeGradientNormal(cell, gridVertexCoord(gVFeature(3 * x)), gridVertexCoord(gVFeature(3 * x + 1)));
            else if (!cap)
                nrm = trilinearGradientNormal(cell, gVPos(x));
            if (nrm == vec3(0.0)) nrm = faceNormal; // (the CPU: area-weighted, the same plane)
            const uint b = 18u * slot + 6u * uint(k);
            dVertex[b] = pos[k].x;
            dVertex[b + 1u] = pos[k].y;
            dVertex[b + 2u] = pos[k].z;
            dVertex[b + 3u] = nrm.x;
            dVertex[b + 4u] = nrm.y;
            dVertex[b + 5u] = nrm.z;
        }
        // TriangleInfo: fragment id 1 (the host sets the fragments' once
        // recovered), cap bit 30, cut-geometry bit 31.
        dTriangle[slot] = ivec4(cell, int(1u | (cap ? 0x40000000u : 0u) | 0x80000000u));
        dKey[slot] = uvec2(tet, uint(t));
        atomicAdd(dCount, 3u);
    }
}
