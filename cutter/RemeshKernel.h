// Internal to cutter/: what the re-meshing front end (Remesh.cpp: quad
// geometry, caches, CutRemesher) and the per-cell kernel (RemeshKernel.cpp:
// the arrangement of each tet's isosurface pieces and blade planes) share.
// Not part of the library's interface; no GL.
#pragma once

#include "cutter/Isosurface.h"
#include "cutter/Remesh.h"
#include "vdb/Volume.h"

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include <openvdb/math/Coord.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace mtcut::cutter::remesh_detail {

using glm::dvec3;
using openvdb::Coord;

constexpr uint64_t kBoundaryLabel = uint64_t(1) << 63; ///< | mask of tet-local vertices of the tet face/edge
constexpr uint64_t kIso = 1; ///< the isosurface in a vertex name (CutVertexId::planes, sorted first)
constexpr int kJunctionKind = 7;
constexpr int kPlusKind = 8, kMinusKind = 9; ///< kerf > 0: the prism's offset planes
/// Kerf > 0: the caps at the sharp corners of a mitred joint (makePrismGeom,
/// Remesh.cpp), named by the joint's lower quad: the stick's
/// lexicographically first corner, then its second. Every kind up to
/// kMinusKind is a blade plane (isBladePlaneId).
constexpr int kCapKinds[2] = {5, 6};
/// Kerf > 0: the tag (CutVertexId::tags) of the k-th copy (k >= 1) of a
/// vertex inside a tet where the removed region's boundary pinches; k = 1
/// also for the cap's copy of a marching-tetrahedra vertex exactly on a
/// plane of the removed region that the isosurface only touches there.
constexpr uint64_t kPinchTag = uint64_t(1) << 63;

/// splitmix64's finaliser: a bijection of 64-bit words in which each input
/// bit flips about half of the output bits (the input digests of cells, the
/// words of a Steiner midpoint's name; mixWord in cut_arrange.glsl).
inline uint64_t mixBits(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

inline uint64_t planeIdOf(uint32_t stroke, uint32_t quad, int kind)
{
    return (uint64_t(stroke) << 36) | (uint64_t(quad) << 4) | uint64_t(kind);
}

struct Plane
{
    dvec3 n{0.0};
    double d = 0.0;
    double h(const dvec3& x) const { return glm::dot(n, x) - d; }
};

/// World mm of index-space point p in double, before the rounding to float
/// that CutRemesher::fusedMesh applies (worldPosition).
inline dvec3 exactWorldPosition(const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing, const dvec3& p)
{
    return dvec3(origin[0] + spacing[0] * p.x, origin[1] + spacing[1] * p.y, origin[2] + spacing[2] * p.z);
}

/// "(x, y, z)", for refusal messages.
std::string cellText(const Coord& c);

/// A quad's zero-kerf removed region in index space: its plane and its sides
/// (each a plane through a hull edge; the junction with the previous/next
/// quad of the stroke is one shared mitre plane, so the strip is one surface).
struct QuadGeom
{
    uint64_t id = 0; ///< plane id of the quad's plane (kind 0)
    Plane pi;
    struct Side
    {
        uint64_t id = 0;
        Plane plane;
        double orient = 1.0; ///< inside the quad: orient * h >= 0
        int partner = -1;    ///< junction: the other quad's index in the cell's quad list (-1: rim)
        uint64_t partnerId = 0;
        /// Junction: at each end of the shared edge, this quad's rim side there and
        /// the partner's (0 when none); a point on both is one corner of the strip.
        std::array<std::pair<uint64_t, uint64_t>, 2> cornerSides{};
        /// Zero kerf, a junction where the plane that bisects the two quads'
        /// planes does not part them: the stroke doubles back with both
        /// normals agreeing (both quads on one side of the shared edge), or
        /// goes straight on with them opposite. The plane bisects the angle
        /// between the two quads instead, and each side of this quad's slit
        /// goes on as the partner's other side (a fold's wedge lies above one
        /// quad and below the other).
        bool fold = false;
    };
    std::vector<Side> sides;
};

class RemeshKernel; // RemeshKernel.cpp

/// A vertex the kernel made in a tet: its name (no tags), the tet-local
/// vertices of the smallest simplex holding it, and its position (index
/// space). For the tests of the GPU port's vertex positions.
struct VertexProbe
{
    CutVertexId key;
    uint8_t support = 0;
    dvec3 pos{0.0};
    bool steiner = false; ///< a Steiner point (slit midpoint, cap centre)
};

/// The arrangement of one tet as the GPU port computes it
/// (shaders/cut_arrange.glsl, cut_regions.glsl): per surface (iso
/// polygons, then caps) its pieces once split by the tet's planes, made
/// conforming, classified (kept) and given their slit midpoints; the
/// triangles of its regions; and its vertex table at the end (the regions'
/// Steiner centres included). For the tests that hold the two equal.
struct ArrangementProbe
{
    struct Piece
    {
        std::vector<int> v;           ///< vertex indices into `verts`
        std::vector<uint64_t> lab;    ///< lab[i]: the label of edge v[i] -> v[i + 1]
        bool kept = true;
    };
    struct Surface
    {
        uint64_t plane = 0;
        std::vector<Piece> pieces;
    };
    /// A corner of a triangle: the vertex and its side tags (Node).
    struct Corner
    {
        int vert = 0;
        std::vector<uint64_t> tags;
        bool operator==(const Corner& o) const { return vert == o.vert && tags == o.tags; }
    };
    bool solid = false;
    std::vector<VertexProbe> verts; ///< the regions' Steiner centres last
    std::vector<Surface> surfaces;
    std::vector<std::array<Corner, 3>> triangles; ///< as triangulateRegions emits them
    std::vector<uint8_t> triangleCap;             ///< per triangle: 1 on a cap region (CutCellGeometry::cap)
};

/// A name the kernel gave a point in a tet (makeVertex, before it looks
/// for a vertex of that name): the call's simplex, the planes that made the
/// point and where, and the planes of the name (empty with `refused` when
/// more than a name holds). For the tests of the GPU port's naming.
struct NameProbe
{
    int tet = 0;
    uint8_t support = 0;
    std::vector<uint64_t> defining;
    dvec3 pos0{0.0};
    std::vector<uint64_t> planes;
    bool refused = false;
};

/// The kernel's first phase in one tet of a cell, as the GPU cut pass's
/// port computes it too (shaders/cut_kernel.glsl), for the tests that hold
/// the two equal: which of the cell's quads can reach the tet (gatherQuads),
/// and the tet's marching-tetrahedra polygons with their planes
/// (isoTriangles). Nothing but `solid` is set when no corner is inside.
struct TetPhaseOne
{
    bool solid = false;
    std::vector<uint32_t> quads; ///< indices into the cell's quad list, ascending
    int triCount = 0;            ///< marching-tetrahedra polygons: 0, 1 (a triangle or a flat quad) or 2
    std::array<std::vector<std::array<int, 2>>, 2> triEdges; ///< each corner's tet edge (tet-local vertices)
    std::array<std::vector<dvec3>, 2> triPts;                ///< each corner, index space
    std::array<Plane, 2> triPlane;                           ///< ISO_A, ISO_B
};

/// The re-meshing kernel of one thread (its scratch is reused from cell to
/// cell). remesh() re-meshes one cut cell of `volume` at `iso` from the
/// geometry of the quads that cut it (zero kerf: quads, each with its sides
/// and junction partners; kerf > 0, prism: closed prisms), in the cell's
/// quad order, into `out` (cleared first); it throws std::runtime_error
/// ("remesh: ... in cell (i, j, k)") for a configuration it refuses. The
/// output depends only on the cell, its corner values and `quads`.
///
/// The output is then made to hold up once written in float world mm
/// (cutter/FloatRepair.h): the exact geometry can have features far below a
/// float step (at the VHM head's z of 1100 mm a float step is 0.12 um), and
/// a sliver whose apex rounds across its base folds over its neighbours.
class CellKernel
{
public:
    CellKernel(const vdb::Volume& volume, float iso);
    ~CellKernel();
    CellKernel(const CellKernel&) = delete;
    CellKernel& operator=(const CellKernel&) = delete;

    void remesh(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out);
    /// What remesh() does to a cell's geometry after its tets: `out` holds
    /// the triangles of the cell's five tets as remesh() makes them, from
    /// elsewhere (the GPU cut pass: render/CutKernelGpu.h); the pinches split
    /// (kerf > 0) and the float repairs made, so that `out` is then what
    /// remesh() gives. Throws std::runtime_error as remesh() does.
    void finish(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out);
    /// For tests of the GPU port: the first phase of each of the cell's tets.
    std::array<TetPhaseOne, kTetsPerCell> phaseOneForTesting(const Coord& cell, const std::vector<QuadGeom>& quads,
                                                             bool prism);
    /// For tests of the GPU port: the vertices the kernel makes in each of
    /// the cell's tets (none in a tet without solid), in order of making.
    std::array<std::vector<VertexProbe>, kTetsPerCell> verticesForTesting(const Coord& cell,
                                                                          const std::vector<QuadGeom>& quads, bool prism);
    /// For tests of the GPU port: every name the kernel computes in the cell
    /// (all tets, in order; stops at a refusal, which it records).
    std::vector<NameProbe> namesForTesting(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism);
    /// For tests of the GPU port: each tet's arrangement (ArrangementProbe).
    /// Throws as remesh() does for a cell it refuses.
    std::array<ArrangementProbe, kTetsPerCell> arrangementForTesting(const Coord& cell,
                                                                     const std::vector<QuadGeom>& quads, bool prism);
    /// For tests: whether the kernel leaves out the caps of a tet that can
    /// keep no piece (a cap whose section of the tet holds no point of its
    /// own quad, kerf > 0 closed prism, in the solid; on by default). The
    /// output is the same either way but for the last bits of a vertex
    /// inside a tet on four or more planes, whose position is its first
    /// maker's.
    void skipOutsideCapsForTesting(bool skip);
    /// For tests: whether the kernel leaves out a tet's mitres (kerf > 0)
    /// that the partner prism holds whole (capOutside; on by default). The
    /// output is then as with skipOutsideCapsForTesting. The GPU cut pass's
    /// port (shaders/cut_arrange.glsl) does not yet: its arrangement tests
    /// compare it with this off.
    void skipHeldMitresForTesting(bool skip);
    /// For tests: whether the kernel answers a repeated naming (the same
    /// simplex and planes again in one tet; a tet face or edge point with the
    /// same defining planes again in one cell) from its memos (on by
    /// default). The output is the same either way.
    void useNameMemoForTesting(bool use);
    /// For tests: how many namings the memo has answered.
    size_t nameMemoHitsForTesting() const;
    /// Of the namings, those the per-cell memo answered (a tet face or edge point an earlier tet named).
    size_t cellNameMemoHitsForTesting() const;
    /// For tests: whether the kernel passes over what lies off a plane by
    /// far without asking signs (on by default): a piece whose every corner
    /// lies strictly on one side of a splitting plane stays whole, and
    /// making pieces conform, an edge looks only at the vertices within its
    /// reach. The output is the same either way; in a cell where many
    /// prisms cross, the kernel takes a third less time.
    void skipFarForTesting(bool skip);
    /// For tests: how many pieces and vertices it passed over so.
    size_t farSkipsForTesting() const;
    /// For tests: whether making pieces conform looks only at the pieces a
    /// crossing plane left whole outside its junction zone (on by default):
    /// every other piece was split at the points its neighbours were, so no
    /// vertex of another lies inside its edges. The output is the same
    /// either way; at kerf 0.5 a haptic step on the 1 mm head takes 5 % less.
    void conformOpenOnlyForTesting(bool only);
    /// For tests: how many pieces conformity passed over so.
    size_t conformPassedForTesting() const;
    /// For tests: whether, with kerf, a prism face that coincides over a tet
    /// with another quad's facing the same way (coplanar consecutive quads'
    /// offset faces) is joined to it, one surface (on by default). The cut
    /// is the same region either way, triangulated without the mitre
    /// between them: fewer triangles, the same area and volume per cell; a
    /// level stroke's step takes about a seventh less time.
    void joinCoincidentFacesForTesting(bool join);
    /// For tests: how many faces were joined so.
    size_t coincidentJoinsForTesting() const;

private:
    std::unique_ptr<RemeshKernel> mKernel;
    openvdb::Vec3d mOrigin, mSpacing;
    /// remesh()'s geometry as it grows, kept between cells for its
    /// capacity; the caller's `out` gets it at its final size.
    CutCellGeometry mScratch;
};

/// The quads of `cell` of `mask` as update() hands them to the kernel that
/// cuts `volume` at `iso` (in the cell's order, degenerate ones left out,
/// with kerf > 0 the prisms the others cover there left out (PrismCover.h;
/// where the cell has air, they need cover only where they meet its
/// solid), partners resolved), built without update()'s caches; empty when
/// the cell is not cut. For the GPU cut pass's input (cutter/KernelInput.h)
/// and tests. Without `volume`, a prism is left out only where the others
/// cover all of its part of the cell (what removedVoxels takes).
std::vector<QuadGeom> kernelQuadsOf(const CutMask& mask, const Coord& cell, const vdb::Volume* volume = nullptr,
                                    float iso = 0.0f);

struct CellSolidReader; // Remesh.cpp

/// kernelQuadsOf(mask, cell, &volume, iso) for many cells of one mask: each
/// quad's geometry is built once and shared by the cells it cuts.
/// kernelQuadsOf alone starts from nothing for every cell, and with kerf > 0
/// a prism is built from its stroke's rim planes, so it builds every prism
/// of the stroke up to the cell's quads: packing the GPU cut pass's input
/// for the 1 mm head's 11,748-cell cut at kerf 0.5 that way took 2.1 s, ten
/// times the CPU's whole update(). The mask and volume must not change while
/// this is used.
class KernelQuads
{
public:
    KernelQuads(const CutMask& mask, const vdb::Volume& volume, float iso);
    ~KernelQuads();
    KernelQuads(const KernelQuads&) = delete;
    KernelQuads& operator=(const KernelQuads&) = delete;
    /// kernelQuadsOf(mask, cell, &volume, iso).
    std::vector<QuadGeom> of(const Coord& cell);

private:
    const CutMask& mMask;
    std::unique_ptr<PrismCache> mPrisms;
    std::unique_ptr<QuadGeomCache> mQuadGeoms;
    std::unique_ptr<CellSolidReader> mSolid;
};

/// Sorts `cells` and drops repeats, in Coord's order (its operator<), by a
/// packed 64-bit key when every coordinate fits 21 bits biased (any cell a
/// cut can reach: -1 to dims), else by Coord itself. `runs`, ascending
/// offsets (may be empty), splits `cells` into lists each of which may
/// already be in order (a quad's cells mostly are): those are merged, not
/// sorted again. CutRemesher::update's dirty cells.
void sortUniqueCells(std::vector<Coord>& cells, const std::vector<size_t>& runs = {});

/// The fans of a vertex from its link (the edge b -> c opposite it in each
/// of its triangles, in triangle order): when every link vertex starts
/// exactly one link edge and ends exactly one, the link is a union of
/// disjoint closed cycles, one per fan (a disc of triangles round the
/// vertex); returns their number and, in `fanOf`, each edge's fan (numbered
/// in order of first edge). Returns 0 (fanOf unspecified) for any other
/// link: an open or doubly used edge round the vertex, or a cycle of two
/// edges (two triangles back to back). A vertex with two or
/// more fans is where the surface touches itself at one point (a pinch);
/// with kerf > 0, where the removed region's boundary meets the isosurface
/// in a saddle across cells (CutRemesher::fusedMesh), each fan but the first
/// gets its own copy of the vertex. Cost O(link log link).
int linkFans(const std::vector<std::pair<uint32_t, uint32_t>>& link, std::vector<int>& fanOf);

/// Cancelling pairs once written: two triangles on one vertex set facing
/// opposite ways (`tris`, snapped) that
/// - snap rounding made so, not being on one vertex set before (`before`,
///   the same triangles unsnapped): a cap region a float step across,
///   fanned from its centre, whose corners joined (4 mm head, kerf 0,
///   random strokes seed 8043: three quads' planes through one point 4e-5 mm
///   from a cell face); or
/// - of which one at least the float repair's face rule put into a cell
///   face (`intoFace`, one flag per triangle, or empty for none;
///   CutCellGeometry::intoFace): a solid sliver thinner than a float step
///   round a grid edge, flattened into the face between two cells by both
///   (2 mm head, kerf 0, random strokes seed 8023: the blade 8e-5 mm from
///   the isosurface's vertex on the edge).
/// They coincide and bound nothing, and they use each of their edges once
/// each way, so both go (fusedMesh and the local check alike). A pair the
/// kernel made as it is (two cells' triangles back to back in their common
/// face) is neither and stays, for the check to refuse. Marks them in
/// `drop` (one entry per triangle); pairs are taken in triangle order, so a
/// third triangle on the set stays. Cost O(n log n).
void markCancellingPairs(const std::vector<std::array<uint32_t, 3>>& tris,
                         const std::vector<std::array<uint32_t, 3>>& before, const std::vector<char>& intoFace,
                         std::vector<char>& drop);

} // namespace mtcut::cutter::remesh_detail
