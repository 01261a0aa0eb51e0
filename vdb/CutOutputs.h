// Write-back of a cut into one OpenVDB file (DESIGN.md, "Outputs"): each
// fragment as a narrow-band level set, the cut mask with stroke ids, and the
// carved CT volume. Fragments come in as plain arrays (world positions and
// triangle indices), as OpenVDB's own meshToVolume takes them, so this folder
// never depends on cutter/.
//
// cut.vdb layout (grids in file order; `mtcut info cut.vdb` without --grid
// reads `carved`, the first float grid):
//
//   grid           type       class            transform
//   carved         FloatGrid  GRID_UNKNOWN     the volume's (spacing, origin)
//   cut_mask       Int32Grid  GRID_UNKNOWN     the volume's
//   fragment_000   FloatGrid  GRID_LEVEL_SET   uniform voxel (CutVdbOptions), origin at the
//   fragment_001   ...                         volume's voxel (0,0,0) centre
//
// Metadata:
//   file         mtcut:version    string  kMtcutVersion
//                mtcut:isovalue   float   isovalue of the cut isosurface (volume units)
//                mtcut:kerf_mm    float   kerf (blade width), mm
//                mtcut:path_file  string  the blade path file ("" when none)
//                mtcut:fragments  int32   number of fragment grids
//   carved       mtcut:dims, mtcut:units, mtcut:air_threshold, mtcut:min, mtcut:max,
//                mtcut:source     as writeVolume(.vdb) writes them, so readVolume(...,
//                                 gridName "carved") and `mtcut info --grid carved` read it
//   fragment_NNN mtcut:volume_mm3 double  enclosed volume of the mesh (signed; > 0 when
//                                         the winding is CCW outward), mm^3
//                mtcut:area_mm2   double  surface area of the mesh, mm^2
//                mtcut:triangles  int64   triangle count of the mesh
//                (plus OpenVDB's own: class level set, name)
// The fragment figures come from the triangles, exactly, not from the level set.
#pragma once

#include "vdb/Progress.h"
#include "vdb/Volume.h"

#include <openvdb/openvdb.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mtcut::vdb {

/// The producing version written into every output file (PROJECT_VERSION).
extern const char* const kMtcutVersion;

/// Names of the grids in cut.vdb.
inline constexpr const char* kCarvedGridName = "carved";
inline constexpr const char* kCutMaskGridName = "cut_mask";
/// "fragment_000", "fragment_001", ... (FragmentMesh::index, or the
/// position in the order given).
std::string fragmentGridName(size_t index);

/// A closed triangle mesh as caller-owned flat arrays (not copied).
struct FragmentMesh
{
    const float* worldPositions = nullptr;  ///< x,y,z per vertex, world mm (LPS)
    size_t vertexCount = 0;
    const uint32_t* triangleIndices = nullptr; ///< 3 vertex indices per triangle, CCW seen from outside
    size_t triangleCount = 0;
    /// Its number in the grid name (fragmentGridName) and in messages: the
    /// fragment's file number when only some fragments are written (the
    /// viewer's "save selected", `mtcut cut --min-volume`); kByPosition: its
    /// position in the list given to writeCutVdb.
    static constexpr size_t kByPosition = size_t(-1);
    size_t index = kByPosition;
};

/// What produced the cut; goes into the file metadata.
struct CutInfo
{
    float isovalue = 0.0f; ///< volume units (HU for CT)
    float kerfMm = 0.0f;
    std::string pathFile;  ///< blade path file, as the user named it
};

struct CutVdbOptions
{
    /// Voxel size of the fragment level sets, mm. Level sets need cubic voxels;
    /// 0 picks the volume's smallest spacing (so an anisotropic 0.5,0.5,2 mm
    /// scan gives 0.5 mm level sets). Must be finite and >= 0.
    double levelSetVoxelMm = 0.0;
    /// Narrow-band half-width in voxels of the level sets (>= 1). Values inside
    /// the band are signed distances in mm (< 0 inside); beyond it +-halfWidth*voxel.
    float halfWidthVoxels = 3.0f;
    /// The level sets' voxel size for `volume`: levelSetVoxelMm, or the
    /// volume's smallest spacing when that is 0.
    double voxelMmFor(const Volume& volume) const;
};

/// Mesh figures recorded per fragment. Cost: one pass over the triangles.
struct FragmentStats
{
    double volumeMm3 = 0.0; ///< signed (divergence theorem), > 0 for CCW-outward closed meshes
    double areaMm2 = 0.0;
    uint64_t triangles = 0;
};

/// Checks the mesh and computes its figures. Throws InputError
/// ("fragment 1: ...", index = position in the fragment list) when it has no
/// triangles, a vertex index >= vertexCount, a non-finite position, or zero
/// total area (all triangles degenerate). Degenerate triangles among others are fine.
FragmentStats checkFragmentMesh(const FragmentMesh& mesh, size_t index);

/// The fragment as a narrow-band signed distance level set (GRID_LEVEL_SET,
/// background halfWidthVoxels * voxelMm, values in mm, < 0 inside), through
/// openvdb::tools::meshToVolume reading the caller's arrays in place (a mesh
/// adapter; nothing copied). Transform: uniform scale voxelMm, translated so
/// index (0,0,0) is at worldOrigin. Sign comes from OpenVDB's inside test,
/// which needs a closed mesh; winding does not matter.
/// Checks the mesh as checkFragmentMesh (InputError). Throws Cancelled when
/// the interrupter asks. Cost: O(triangles + narrow-band voxels), parallel (TBB).
openvdb::FloatGrid::Ptr fragmentToLevelSet(const FragmentMesh& mesh, size_t index, double voxelMm,
                                           const openvdb::Vec3d& worldOrigin, float halfWidthVoxels = 3.0f,
                                           Interrupter* interrupter = nullptr);

/// Carves in place: every voxel (or tile) active in `removed` (index space of
/// grid) becomes grid.background() and inactive; values elsewhere are untouched
/// (bit-exact); nodes left constant are pruned (exactly, tolerance 0).
/// Cost: O(removed active voxels) plus one prune over the tree.
void carveGrid(openvdb::FloatGrid& grid, const openvdb::MaskGrid& removed);

/// The volume's grid with the removed voxels carved (carveGrid). `removed`
/// holds voxel coordinates in the volume's index space (its transform is
/// ignored); voxels outside volume.indexBox() are ignored. The tree is
/// deep-copied (the only copy: OpenVDB trees cannot share nodes); transform
/// and name are the volume's, metadata is not copied. Cost: one tree copy
/// (memory of the sparse grid) plus carveGrid.
openvdb::FloatGrid::Ptr carveVolume(const Volume& volume, const openvdb::MaskGrid& removed);

/// Writes cut.vdb as described at the top of this file, atomically (a failed
/// or cancelled write leaves no file and no temporary behind).
///   volume     the uncut scan: its transform and metadata go to `carved`/`cut_mask`
///   carved     carveVolume(volume, removed) (same index space as volume)
///   cutMask    active voxels = cut cells in the volume's index space, value =
///              stroke id (1-based); written with the volume's transform (the
///              grid's own transform is ignored), tree shared, not copied
///   fragments  written in the order given (the caller sorts, largest first)
/// Throws InputError for a bad fragment (checkFragmentMesh), a bad option, or
/// an unwritable path ("<path>: cannot write VDB (...)"); Cancelled when the
/// interrupter asks (polled per fragment and inside meshToLevelSet).
/// Cost: the level sets dominate (see fragmentToLevelSet), then file I/O.
void writeCutVdb(const std::string& path, const Volume& volume, const openvdb::FloatGrid& carved,
                 const openvdb::Int32Grid& cutMask, const std::vector<FragmentMesh>& fragments,
                 const CutInfo& info, const CutVdbOptions& options = {}, Interrupter* interrupter = nullptr);

} // namespace mtcut::vdb
