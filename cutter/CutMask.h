// The sparse cut mask (DESIGN invariant 5): which cells the blade's swept
// region touches, which stroke cut each first, and every (stroke, quad) that
// touches it, in stroke order - with undo/redo per stroke and back to any
// earlier stick of the current stroke. No depth limit: the mask is an OpenVDB
// grid over the whole index space.
#pragma once

#include "cutter/BladePath.h"
#include "cutter/PoseStream.h"
#include "vdb/Volume.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

namespace mtcut::cutter {

/// The index frame (scale + translation, dims) of a canonical volume.
IndexFrame frameOf(const vdb::Volume& volume);

/// One quad of one stroke. Stroke ids are 1-based positions in the stroke
/// list (so after undo a new stroke reuses the id, and a mask rebuilt from
/// the same path has the same ids); quad ids are 0-based within the stroke.
struct QuadRef
{
    uint32_t stroke = 0;
    uint32_t quad = 0;
    bool operator==(const QuadRef& o) const { return stroke == o.stroke && quad == o.quad; }
};

/// The widest saw a CutMask takes, mm: surgical saws and burrs are 0.1-6 mm
/// wide; a kerf near the scan's size would make every cell a cut cell.
constexpr double kMaxKerfMm = 20.0;

/// Cut cells of a volume.
///
/// Cells are index-space marching-tetrahedra cells (see BladePath.h): cell
/// (i,j,k) spans index [i,i+1]x[j,j+1]x[k,k+1]; only cells inside the volume
/// (0 <= c < dims - 1) are ever cut. A cell is cut by quad q when its closed
/// box touches the region cutRegion(q, kerf) (K_q; for kerf > 0 grown to
/// cover the re-mesher's mitre joints, capped ones included, see BladePath.h).
///
/// Storage: grid() is an Int32Grid (background 0) whose ACTIVE voxels are
/// exactly the cut cells, valued with the id of the first stroke that cut them
/// (OpenVDB's usual tree: any size, memory ~ cut cells). quadsAt() gives each
/// cut cell's (stroke, quad) list in the order the quads were added (stroke
/// order, then quad order). The history keeps every quad's cell list so undo
/// is exact: after any sequence of add/undo/redo the mask (grid active set and
/// values, and every list) equals the mask built from scratch from the strokes
/// and quads that remain.
///
/// Not thread-safe: one geometry thread owns it (PoseStream hands it the
/// cutting information).
class CutMask
{
public:
    /// kerfMm in [0, kMaxKerfMm]: full saw width, world mm (0 = the paper's
    /// zero-width blade). Throws InputError otherwise.
    explicit CutMask(const IndexFrame& frame, double kerfMm = 0.0);

    const IndexFrame& frame() const { return mFrame; }
    double kerf() const { return mKerf; }

    // -- building ------------------------------------------------------------
    /// Starts a new stroke (and drops the redo history). Returns its id.
    uint32_t beginStroke();
    /// Adds the next quad of the current stroke (a stroke is begun if none
    /// is open), voxelising it. Returns its QuadRef. Cost: voxelisation
    /// (cutRegion) + O(cells) hash updates.
    QuadRef addQuad(const Quad& quad);
    /// Same, with cells already computed by voxelizeCut(quad, kerf(), frame())
    /// on another thread (the input thread). Cells outside the volume are ignored.
    QuadRef addQuad(const Quad& quad, const std::vector<glm::ivec3>& cells);

    // -- undo / redo -----------------------------------------------------------
    /// Removes the last stroke (or what is left of it). False when empty.
    bool undoStroke();
    /// Re-applies the last undone stroke or stroke part. False when none.
    bool redoStroke();
    /// Cuts the current (last) stroke back to its first `quadCount` quads,
    /// i.e. back to stick `quadCount` of a quad strip. The removed quads can
    /// be redone (redoStroke) until a new stroke or quad is added.
    void undoToQuad(uint32_t quadCount);

    // -- queries ---------------------------------------------------------------
    /// Active voxels = cut cells; value = first stroke id.
    openvdb::Int32Grid::ConstPtr grid() const { return mGrid; }
    bool isCut(const openvdb::Coord& cell) const { return mCells.count(cell) != 0; }
    /// The (stroke, quad) list of a cell in order; nullptr when not cut.
    const std::vector<QuadRef>* quadsAt(const openvdb::Coord& cell) const;
    /// The quad itself (world mm), for its plane / region.
    const Quad& quad(const QuadRef& ref) const;
    uint32_t strokeCount() const { return uint32_t(mStrokes.size()); }
    uint32_t quadCount(uint32_t stroke) const;
    size_t cutCellCount() const { return mCells.size(); }
    /// Calls f(cell, list) for every cut cell, in unspecified order.
    void forEachCutCell(
        const std::function<void(const openvdb::Coord&, const std::vector<QuadRef>&)>& f) const;
    /// Cells that the last addQuad made newly cut (for incremental
    /// re-meshing); cleared by the next change. All cells the last quad
    /// touches, new or not: cellsOf(ref).
    const std::vector<openvdb::Coord>& lastNewCells() const { return mLastNew; }
    const std::vector<openvdb::Coord>& cellsOf(const QuadRef& ref) const;
    /// A number that only this quad (as added, with its cells) carries in the
    /// process, kept through undo/redo and shared by copies of the mask: two
    /// equal serials are the same quad and cells, so a consumer can tell an
    /// unchanged quad in O(1) (CutRemesher::update). Unequal serials say
    /// nothing (the same quad may have been added again).
    uint64_t quadSerial(const QuadRef& ref) const;
    /// Memory of the grid and lists, bytes (approximate).
    size_t memoryBytes() const;

private:
    struct QuadRecord
    {
        Quad quad;
        std::vector<openvdb::Coord> cells;
        uint64_t serial = 0; ///< quadSerial()
    };
    struct StrokeRecord
    {
        std::vector<QuadRecord> quads;
    };
    struct CoordHash
    {
        size_t operator()(const openvdb::Coord& c) const
        {
            return size_t(uint32_t(c.x()) * 73856093u ^ uint32_t(c.y()) * 19349663u ^
                          uint32_t(c.z()) * 83492791u);
        }
    };
    void apply(uint32_t stroke, uint32_t quadIndex, const std::vector<openvdb::Coord>& cells);
    void unapply(uint32_t stroke, uint32_t quadIndex, const std::vector<openvdb::Coord>& cells);
    QuadRef push(QuadRecord&& rec);

    IndexFrame mFrame;
    double mKerf;
    openvdb::Int32Grid::Ptr mGrid;
    std::unordered_map<openvdb::Coord, std::vector<QuadRef>, CoordHash> mCells;
    std::vector<StrokeRecord> mStrokes;
    bool mStrokeOpen = false;
    /// Undone work, last undone at the back: (stroke id, first quad index, quads).
    struct RedoEntry
    {
        uint32_t stroke;
        std::vector<QuadRecord> quads;
    };
    std::vector<RedoEntry> mRedo;
    std::vector<openvdb::Coord> mLastNew;
};

/// Hands every quad of `mask`'s strokes to filter.addEarlierQuad (after
/// filter.clearEarlierQuads()), so the next stroke through `filter` drops
/// the poses that retrace the cut so far (PathFilter rule 2b). Between strokes only.
void setEarlierQuads(const CutMask& mask, PathFilter& filter);

/// Geometry thread: applies every CutInfo ready in `queue` to `mask`, in
/// order, without waiting (returns when the queue is momentarily empty). A
/// quad with quadIndex 0 begins a new mask stroke; quads without cells
/// (InputThreadOptions::voxelize off) are voxelised here. Error items are
/// appended to `errors` when given. Returns the number of quads applied.
size_t drainCutInfo(SpscQueue<CutInfo>& queue, CutMask& mask,
                    std::vector<std::string>* errors = nullptr);

} // namespace mtcut::cutter
