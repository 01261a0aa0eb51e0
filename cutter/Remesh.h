// Re-meshing of the cut cells (MTCut paper sections 3.2 and 4, DESIGN.md
// invariants 2 and 5-10): the cells a blade touches are split into the same 5
// tetrahedra as the isosurface (cellTets), and each tetrahedron's solid piece
// P = T ∩ {V >= iso} is cut by the blade's swept surface.
//
// Method (per tetrahedron, index space, double precision). Every output
// polygon lies on a supporting plane: the marching-tetrahedra triangle(s) of
// the tet (the iso surface, exactly the uncut triangles' geometry) or a quad's
// plane (the caps). On each supporting plane the polygon is split by the lines
// of every other plane that crosses the tet (a full 2-D line arrangement, so the
// pieces meet edge to edge), the pieces are classified (iso pieces are kept;
// cap pieces are kept inside P and inside the quad), merged back into regions
// (not across the slit: with zero kerf the two sides of a quad are different
// surfaces), the region loops lose every vertex that is not a corner of some
// loop of the tet (so the extended split lines leave no vertex on a tet face
// that the neighbouring tet does not make too), and the loops are
// triangulated by ear clipping.
//
// Vertex identity (invariant 2): a vertex is named by the smallest simplex of
// the grid that holds it (grid vertex, edge, face by their grid vertices; or
// cell + tet for the inside) plus the set of planes it lies on that are active
// there (the iso surface; a quad's plane or side where the point lies in the
// closed quad; junction planes between consecutive quads of a stroke force
// both quads; a fold triangle's plane is the iso surface only on the tet faces
// and edges that hold that triangle's MT geometry, elsewhere a tet-local
// plane), plus, for zero kerf, a side tag (quad, +/-) for every quad
// whose open slit holds the point. The position is a function of that name
// alone (canonical order, double), and every side test is evaluated on it
// with one tie rule (|h| <= 1e-13 (1 + |x|) voxel counts as on the plane), so
// neighbouring tets decide identically. A vertex on a grid edge on the iso
// surface and on no blade plane is the marching-tetrahedra vertex itself; the
// fusion welds it to the uncut mesh's vertex.
//
// Kerf 0 is the paper's behaviour: both sides are produced, touching along
// the cut with coincident caps of opposite orientation and distinct vertices,
// joined at the rim where the blade stops inside the bone. Consecutive quads
// of a stroke meet on a junction plane through their shared stick that parts
// them, and each side of one quad's slit goes on as a side of the next: the
// same side where the plane bisects the two quads' planes, the other side
// where that plane does not part them (the stroke doubles back with both
// normals agreeing, both quads on one side of the stick, or goes straight on
// with them opposite) and the plane bisects the angle between the quads
// (QuadGeom::Side::fold). Any number of quads per cell.
//
// Kerf w > 0 (DESIGN invariant 7 and its sketch): each quad's removed region
// is a closed convex prism, the slab |h| <= w/2 around the quad's plane
// bounded by planes through the hull edges perpendicular to it in world mm
// (with anisotropic voxels not in index space); consecutive
// quads of a stroke that bend by less than kKerfMitreMaxBend share a mitre
// plane instead of their two end planes (so the strip has no micro-notches;
// the mask voxelises cutRegion(), which covers the mitre joints, and a
// corner of the joint too sharp for the mitre's reach gets a cap, the plane
// through it at right angles to the stick). The
// surface is (iso pieces outside every closed prism) + (prism face pieces
// inside the solid and outside every other closed prism; of two coincident
// faces facing the same way, the lower quad's), through the same arrangement,
// naming and triangulation as above, with no slits, tags or Steiner points.
// A rim continuing the previous quad's rim (within 1e-4 voxel), across a
// mitre or an unmitred turn, shares its plane object, so straight strokes
// meet the mitre in one rim line, and the prisms' faces on that one plane
// are one surface (kept where any of the prisms keeps it): no vertex where
// one prism's face ends on the other's, which the neighbouring cell may not
// see (a blade whose edge runs in a grid plane through a 90 degree turn).
// Where a blade pivots on a corner, the union of the prisms (or the solid
// left between them) can touch itself at one point inside a tet: the
// boundary there has several fans, and each fan but the first gets its own
// copy of the vertex (same name plus a pinch tag, same position), so the
// surface is a 2-manifold that touches itself at that point, as the exact
// shape does. What the kernel still cannot mesh (1 of 104 random head
// strokes: an open edge where a curved stroke's rims cross a mitre in
// slightly different lines) is refused by the local check, never written.
//
// Snap rounding (fusedMesh): new vertices joined by an edge that round to
// the same float position are one vertex of the written mesh, and so are
// the ends of an edge from an isosurface vertex along its grid edge that
// four triangles use, a float step long (remesh_detail::joinsAlongGridEdge),
// and of an edge from a point inside a tet face to another of the closed
// face that four triangles use, a few float
// steps long (remesh_detail::joinsPinchInFace);
// the triangles that collapse are dropped, and so are the pairs it folds
// back onto each other (remesh_detail::markCancellingPairs); the local
// check judges the mesh after that step.
#pragma once

#include "cutter/CutMask.h"
#include "cutter/Mesh.h"
#include "vdb/Progress.h"
#include "vdb/Volume.h"

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <unordered_map>
#include <vector>

namespace mtcut::cutter {

/// Identity of an output vertex of the cut (see the file comment). Plain data,
/// compared and hashed by value.
struct CutVertexId
{
    /// 0: grid vertex, 1: grid edge, 2: tet face, 3: inside a tet.
    uint8_t dim = 0;
    uint8_t planeCount = 0;
    uint8_t tagCount = 0;
    /// dim 0..2: sorted grid vertex ids (gridVertexId); dim 3: cell id, tet index.
    std::array<uint64_t, 3> feature{};
    std::array<uint64_t, 8> planes{}; ///< sorted plane ids (1 = iso surface)
    /// Sorted side tags (quad plane id << 1 | minus); kerf > 0: 2^63 | k for
    /// the k-th copy of a vertex where the removed region pinches (inside a
    /// tet, or an isosurface vertex on a grid edge that touches one of its
    /// planes there).
    std::array<uint64_t, 4> tags{};

    bool operator==(const CutVertexId& o) const;
    bool operator<(const CutVertexId& o) const;
    /// True for a plain marching-tetrahedra vertex (grid edge, iso only, no tag).
    bool isIsoEdgeVertex() const { return dim == 1 && planeCount == 1 && planes[0] == 1 && tagCount == 0; }
};

struct CutVertexIdHash
{
    size_t operator()(const CutVertexId& v) const;
};

/// Packs grid vertex (i,j,k), -2^20 <= i,j,k < 2^20, into an id ordered like
/// the isosurface's "lower-keyed end": by (k, j, i).
uint64_t gridVertexId(int i, int j, int k);
/// The grid vertex (i,j,k) of a gridVertexId.
openvdb::Coord gridVertexCoord(uint64_t id);

/// The new geometry of one cut cell: triangles over cell-local vertices.
struct CutCellGeometry
{
    std::vector<CutVertexId> vertexIds;
    std::vector<glm::dvec3> indexPositions; ///< index space (voxels), one per vertex
    std::vector<uint32_t> indices;          ///< 3 per triangle, CCW seen from outside the solid
    /// One per triangle: 1 when it is a piece of the blade's cut face (a
    /// cap region of the kernel), 0 a piece of the isosurface. Carried, not
    /// found from the names: a cap triangle's three vertices need not share
    /// a blade plane (4 mm head sawing at kerf 0: 8 of 2.66 M triangles),
    /// nor do those of a cap region joined across two coplanar quads'
    /// coincident faces (kerf > 0, RemeshKernel's capSurfaces).
    std::vector<uint8_t> cap;
    /// The triangles (ascending) that the float repair's face rule moved
    /// into a cell face (repairFloatFolds): the cell across that face may
    /// make the same one facing the other way, a pair that bounds nothing
    /// and goes in fusion and the local check (markCancellingPairs).
    std::vector<uint32_t> intoFace;
    /// kerf > 0: the float repair's last look found no two of these
    /// triangles crossing or touching once written (trianglesCross, as the
    /// local check judges them), so the local check asks a pair of them
    /// again only where snap rounding moved or joined a vertex of the cell.
    bool crossFree = false;
    void clear()
    {
        vertexIds.clear();
        indexPositions.clear();
        indices.clear();
        cap.clear();
        intoFace.clear();
        crossFree = false;
    }
};

struct KernelPool; // one re-meshing kernel per thread (Remesh.cpp; the kernel: RemeshKernel.cpp)
struct PrismCache; // kerf > 0: rim planes per quad (Remesh.cpp)
struct QuadGeomCache; // zero kerf: each quad's index-space geometry, built once per quad (Remesh.cpp)

/// Keeps the re-meshed geometry of every cut cell of a CutMask and fuses it
/// with the uncut isosurface.
///
/// Incremental: update() re-meshes only the cells whose (stroke, quad) list
/// or quads changed since the last update (new cells, cells of a new or undone
/// quad, and those cells of a quad whose stroke neighbour came or went that its
/// changed junction side reaches: elsewhere the kernel's input is unchanged
/// and the cell is kept) and forgets cells that are no longer cut, so after undo the fused
/// mesh equals the earlier one exactly (same vertices, same triangles, same
/// order). Cost per update: O(quads of the mask) to find the changed quads
/// (each compared with what the last update saw), O(cells of the changed
/// quads and their stroke neighbours) to find the changed cells, plus the
/// kernel per re-meshed cell, which update() runs over the cells in parallel
/// (TBB; the result does not depend on the number of threads). The class is
/// not thread-safe.
class CutRemesher
{
public:
    /// Reads the volume's tree: one per loop over cells (its cached nodes
    /// make the neighbours' reads cheap), unregistered (nothing writes the
    /// tree while the remesher reads it).
    using VolumeAccessor = openvdb::tree::ValueAccessor<const openvdb::FloatTree, /*IsSafe=*/false>;

    /// `uncut` must be extractIsosurface(volume, isovalue) (normals optional);
    /// it is copied. `volume` must outlive the remesher.
    CutRemesher(const vdb::Volume& volume, float isovalue, const Mesh& uncut);
    ~CutRemesher();
    CutRemesher(const CutRemesher&) = delete;
    CutRemesher& operator=(const CutRemesher&) = delete;

    /// Brings the cut geometry in line with `mask` (same volume frame). Returns
    /// the number of cells re-meshed. The cut cells are the mask's cut
    /// cells plus the cells just outside the scan box (index -1 or dims-1)
    /// that a quad of a border cell touches: the isosurface closes there and
    /// the mask holds only cells inside the box; cutCellCount() counts them
    /// all. An air cell (all eight corners outside the solid: most cells of a
    /// cut through a head) has no triangles, cut or not, whatever its quads:
    /// it is recorded as cut but never re-meshed, counted, checked or listed
    /// in cells(); every other cut cell is listed there.
    /// Throws std::runtime_error ("remesh: ... cell (i,j,k)") when a cell
    /// meets a configuration the kernel does not handle (two exactly coplanar,
    /// overlapping quads; see the file comment for kerf > 0), rather than
    /// produce a broken mesh.
    ///
    /// Never silent: after re-meshing, every edge of the re-meshed (and
    /// forgotten) cells' triangles, and of their neighbours' triangles inside
    /// those cells, must be used by exactly two triangles of the fused mesh,
    /// once each way; no triangle may repeat a vertex or have zero area in
    /// float world mm (as fusedMesh() writes it); and every vertex of the
    /// changed cells must have one fan (no pinch points; a new vertex whose
    /// fans are each a closed disc is a pinch, which
    /// fusedMesh() splits, and so is such an isosurface vertex whose
    /// triangles are all cut cells'); otherwise it throws
    /// std::runtime_error("remesh: open or inconsistent surface ... in cell
    /// (i, j, k)"). With kerf > 0, no triangle of the changed cells may
    /// cross or touch another in float world mm, decided exactly
    /// (TriangleIntersect.h, with CGAL's rules for triangles that share a
    /// vertex or an edge; the copies of a pinch vertex count as one vertex);
    /// otherwise it throws std::runtime_error("remesh: the surface crosses
    /// or touches itself ... in cell (i, j, k)"). Cost proportional to the
    /// changed cells. On any throw the
    /// remesher is left exactly as before the call (strong guarantee), so
    /// fusedMesh() still returns the last good mesh; the caller should undo
    /// the stroke in the mask (the next update then has nothing to do).
    /// With the environment variable MTCUT_REMESH_DEBUG set, an open edge is
    /// also described on stderr (both vertices' names and float positions,
    /// and the triangles around it), to find which rule of the kernel broke.
    ///
    /// `interrupter` (optional) is started as "re-meshing the cut cells" and
    /// polled from the worker threads as cells are done, with the percentage
    /// of the cells to re-mesh; when it asks to stop, update() throws
    /// Cancelled and, as on any throw, leaves the remesher as it was.
    size_t update(const CutMask& mask, Interrupter* interrupter = nullptr);

    /// The cells the last successful update() kept without re-meshing, the
    /// kernel's input there being unchanged: cells of a quad whose stroke
    /// neighbour came or went, where the neighbour's junction does not reach,
    /// and cells where a quad came or went that reaches none of their tets
    /// (the mask lists a quad wherever its cut region, grown round a mitre,
    /// touches; with kerf > 0 that is most of the cells a step re-meshed
    /// before on the phantom's solid bone). Not counted in update()'s result.
    size_t lastKeptCells() const { return mLastKept; }
    /// The chunks the last update's local check ran in parallel (0: one
    /// serial check; a whole cut of 2,048 cells or more on several threads
    /// is checked in chunks of 1,024).
    size_t lastCheckChunks() const { return mLastCheckChunks; }

    /// Where update() takes a cell's new geometry from before it runs the
    /// kernel: e.g. the GPU cut pass's recovered cells
    /// (render/CutKernelGpu.h recoverCutCells). Called from update()'s worker
    /// threads (so it must be safe to call concurrently) for each cell to
    /// re-mesh; returning true, `out` holds that cell's geometry as
    /// CellKernel::remesh makes it from the mask's quads, and the kernel is
    /// not run; false: the kernel makes it. The fusion and the local check
    /// are the same either way. Empty (the default): always the kernel.
    /// Geometry without one cap flag per triangle makes update() throw
    /// std::invalid_argument naming the cell (the re-mesher as before).
    using CellSource = std::function<bool(const openvdb::Coord&, CutCellGeometry&)>;
    void setCellSource(CellSource source) { mCellSource = std::move(source); }
    /// The cells of the last successful update() that the cell source gave.
    size_t lastSourcedCells() const { return mLastSourced; }

    /// For tests only: re-mesh every kept cell anyway and throw
    /// std::logic_error when the result differs from the kept geometry.
    void setVerifyKeptCellsForTesting(bool on) { mVerifyKept = on; }

    /// For tests only: called on each cell's new geometry right after the
    /// kernel made it (e.g. to corrupt it and see the check fire; the
    /// geometry's crossFree is cleared after it). Empty: none.
    void setCellHookForTesting(std::function<void(const openvdb::Coord&, CutCellGeometry&)> hook)
    {
        mCellHook = std::move(hook);
    }

    /// The fused mesh (DESIGN "Fusion"): the uncut triangles outside the cut
    /// cells in their original order, then the cut cells' triangles (cells in
    /// ascending (x,y,z)). Vertices: all uncut vertices (unused ones stay),
    /// then the new ones; marching-tetrahedra vertices of cut cells are the
    /// uncut mesh's own (welded by edge key). Normals when the uncut mesh has
    /// them (new vertices: area-weighted triangle normals). Snap rounding
    /// (file comment) can drop collapsed triangles. A new vertex whose
    /// triangles form several fans, each a closed disc (a pinch that spans
    /// cells: an offset plane through a saddle of the isosurface on a cell
    /// face; at kerf 0, three slits of a stroke with sharp turns meeting at a
    /// point), gets a copy per fan but the first, at its position,
    /// appended after the new vertices; so does such an isosurface vertex
    /// whose triangles are all cut cells' (every cell round its grid edge
    /// that has triangles is cut), after them. With `source`, for each
    /// fused triangle where it came from: an uncut triangle's index, or
    /// uncut().triangleCount() + j for the j-th triangle of cells() (cells
    /// ascending, each cell's triangles in order). Cost O(mesh).
    Mesh fusedMesh(std::vector<uint32_t>* source = nullptr) const;
    /// For each triangle of a fusedMesh() (its `source`): 1 when it lies on
    /// the blade (a cut face: CutCellGeometry::cap of the cell's triangle),
    /// else 0. Throws std::logic_error for a cell without one flag per
    /// triangle, std::invalid_argument for a source that is not this
    /// remesher's.
    std::vector<uint8_t> bladeTriangles(const std::vector<uint32_t>& source) const;

    /// The cut cells' new geometry only (no uncut triangles), cells ascending.
    /// Air cells (all eight corners outside the solid: no uncut triangle, and
    /// the kernel makes none whatever cuts them) are cut but not listed:
    /// cutCellCount() counts them.
    const std::map<openvdb::Coord, CutCellGeometry>& cells() const { return mCells; }
    /// The cells whose geometry the last successful update() re-made or
    /// forgot, air cells left out (ascending; empty when it changed nothing). For an interactive
    /// view: upload cells().at(c) for each of them that is still in cells(),
    /// drop the others, instead of building a whole fusedMesh() per step.
    const std::vector<openvdb::Coord>& lastChangedCells() const { return mLastChanged; }
    const Mesh& uncut() const { return mUncut; }
    /// The cells the last successful update() recorded as cut (the mask's
    /// cut cells and those just outside the scan box its quads reach), air
    /// cells included.
    size_t cutCellCount() const { return mRecords.size(); }

private:
    struct CellRecord
    {
        std::vector<QuadRef> quads;
        std::vector<std::array<double, 36>> quadCorners; ///< the quads' (and their stroke neighbours') corners now
        std::array<uint64_t, 2> input{}; ///< digest of the kernel's input when meshed (Remesh.cpp kernelInputDigest)
        bool air = false; ///< an air cell (update()): recorded as cut, never meshed; the rest is empty
    };
    /// A quad of the mask as the last successful update() saw it.
    struct SeenQuad
    {
        std::array<double, 12> corners{};
        glm::dvec3 normal{0.0};
        uint32_t cornerCount = 0;
        bool degenerate = false;
        std::vector<openvdb::Coord> cells;
        uint64_t serial = 0; ///< CutMask::quadSerial
    };
    std::unique_ptr<KernelPool> mKernels; ///< update()'s re-meshing, one kernel per thread
    std::unique_ptr<PrismCache> mPrismCache;
    std::unique_ptr<QuadGeomCache> mQuadCache;
    std::vector<std::vector<SeenQuad>> mSeen; ///< per stroke, per quad
    double mSeenKerf = -1.0;                  ///< the mask's kerf and frame at the last update (-1: none yet)
    IndexFrame mSeenFrame;
    std::vector<openvdb::Coord> mLastChanged;
    size_t mLastKept = 0;
    mutable size_t mLastCheckChunks = 0; ///< set by checkLocally
    bool mVerifyKept = false;
    const vdb::Volume* mVolume;
    float mIso;
    Mesh mUncut;
    std::map<openvdb::Coord, CutCellGeometry> mCells;
    std::map<openvdb::Coord, CellRecord> mRecords;
    /// Uncut triangles per cell: the first one's index (extractIsosurface
    /// writes a cell's triangles together), -1 where there is none. A tree,
    /// not a hash map: the checks look up the neighbours of the changed
    /// cells, so the lookups stay in one leaf (a hash map's were a third of a
    /// haptic step, cache misses).
    openvdb::Int32Tree mUncutFirst{-1};
    using UncutAccessor = openvdb::tree::ValueAccessor<const openvdb::Int32Tree, /*IsSafe=*/false>;
    /// The uncut triangles of `cell`: (first, count); count 0 when none.
    std::pair<uint32_t, uint32_t> uncutRun(UncutAccessor& acc, const openvdb::Coord& cell) const;
    /// Uncut triangles (ascending) that hold an end of an uncut edge whose two
    /// vertices have one float position: the only uncut triangles that
    /// fusedMesh()'s snap rounding can change, besides those next to cut cells.
    std::vector<uint32_t> mSnapTriangles;
    std::function<void(const openvdb::Coord&, CutCellGeometry&)> mCellHook;
    CellSource mCellSource;
    size_t mLastSourced = 0;

    /// The grid edge (lower, higher gridVertexId) of each corner of the
    /// uncut triangles of `cell` (`run`: uncutRun's), 3 per triangle in mesh
    /// order; empty when the cell has none. `acc` reads the volume (one per
    /// loop over cells: a fresh one per cell walked the tree from its root
    /// each time, about 600 instructions a call).
    /// Throws std::logic_error when the uncut mesh does not match the volume there.
    void uncutCornerEdges(VolumeAccessor& acc, const openvdb::Coord& cell, std::pair<uint32_t, uint32_t> run,
                          std::vector<std::pair<uint64_t, uint64_t>>& out) const;
    /// The local check of update() over `changed` (sorted cells), in
    /// LocalCheck.cpp: closed, 2-manifold, no triangle of zero area in float,
    /// and with kerf (the cut has a width) no triangle crossing or touching
    /// another. Throws std::runtime_error ("remesh: ...") naming a cell.
    void checkLocally(const std::vector<openvdb::Coord>& changed, bool kerf) const;
    /// checkLocally over one set of changed cells, on the calling thread.
    void checkRegion(const std::vector<openvdb::Coord>& changed, bool kerf) const;
};

/// remesher.update(mask): "" when it went through, else the re-mesher's
/// refusal ("remesh: ..."; the re-mesher is then as before the call); what
/// else it throws (InputError, Cancelled, std::logic_error) goes on.
std::string refusalOf(CutRemesher& remesher, const CutMask& mask);

/// True when `planeId` (an entry of CutVertexId::planes) is a face of the
/// blade's removed region: the quad's plane (the caps of a zero-kerf cut),
/// or, with kerf > 0, a prism face (the offset planes at +-w/2, a side
/// through a hull edge, a mitre between consecutive quads). False for the
/// iso surface's planes, Steiner markers and tet-local planes.
bool isBladePlaneId(uint64_t planeId);

/// The blade plane (isBladePlaneId) that all three vertices lie on, i.e. the
/// supporting plane of a cap triangle; 0 for a piece of the isosurface, and
/// for a cap triangle whose vertices share none (a region joined across
/// coincident faces; CutCellGeometry::cap tells cut faces).
uint64_t capPlaneOf(const CutVertexId& a, const CutVertexId& b, const CutVertexId& c);

/// The float world position (mm) that fusedMesh() writes for an index-space
/// point of a cut cell: origin + spacing * p per axis, rounded to float.
glm::vec3 worldPosition(const vdb::Volume& volume, const glm::dvec3& indexPoint);

/// The voxels (grid points, index space) inside the removed region of a
/// kerf > 0 cut: the union of the quads' prisms as the re-mesher shapes them
/// (mitre joints included). Empty for kerf 0. For the carved volume.
openvdb::MaskGrid::Ptr removedVoxels(const CutMask& mask);

/// The cells within one cell (26-neighbourhood) of `cells` and `cells`
/// themselves, ascending, without repeats: the region CutRemesher's local
/// check reads around the changed cells. Cost O(27 n log n) at worst.
std::vector<openvdb::Coord> dilatedCells(const std::vector<openvdb::Coord>& cells);

/// Re-meshes one cell cut by the given quads of `mask` into `out` (cleared
/// first). For tests and tools; CutRemesher is the incremental front end.
void remeshCell(const vdb::Volume& volume, float isovalue, const CutMask& mask, const openvdb::Coord& cell,
                CutCellGeometry& out);

} // namespace mtcut::cutter
