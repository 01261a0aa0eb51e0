// The CT volume: a sparse OpenVDB float grid in the file's units, with a
// transform from index space to world millimetres.
#pragma once

#include "vdb/Progress.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace mtcut::vdb {

/// Geometry of a scan as its file states it (before canonicalisation).
/// Index (i,j,k) is the file's own order, i fastest.
struct VolumeGeometry
{
    openvdb::Coord dims{0, 0, 0};          ///< voxels along i, j, k; all > 0
    openvdb::Vec3d spacing{1.0, 1.0, 1.0}; ///< mm between voxel centres along i, j, k; all > 0
    openvdb::Vec3d origin{0.0, 0.0, 0.0};  ///< world mm (LPS) of the centre of voxel (0,0,0)
    /// Column a is the unit world direction (LPS) of file axis a.
    openvdb::Mat3d direction = openvdb::Mat3d::identity();
};

/// A scan as decoded by a reader: dense values in the file's index order.
struct DenseScan
{
    VolumeGeometry geometry;
    std::vector<float> values; ///< size dims.x*dims.y*dims.z, i fastest, then j, then k
    std::string units;         ///< "HU" when the file says so (CT rescale); "" when unknown
};

/// How a dense scan becomes sparse.
struct SparseOptions
{
    /// Voxels <= airThreshold are air (inactive). Default: -500 for HU data,
    /// otherwise min + 2% of the value range.
    std::optional<float> airThreshold;
};

/// A scan held sparsely.
///
/// Index space: voxel (i,j,k), 0 <= i < dims.x etc., with the index axes
/// canonicalised on load to point along world +x, +y, +z (a file's flips and
/// axis permutations are applied to the data), so grid->transform() is a pure
/// scale (spacing, mm) and translation (origin). World space is the DICOM
/// patient frame, LPS: +x to the patient's left, +y posterior, +z superior,
/// in millimetres (NIfTI's RAS is converted).
///
/// Sparsity: voxels above airThreshold are active. An 8^3 block that neither
/// holds an active voxel nor touches a block that does is an inactive tile at
/// the background value (= minValue). So every voxel within 8 voxels of an
/// active one keeps its exact value, and any isovalue above airThreshold sees
/// exactly the file's data. Memory follows the non-air part of the scan.
struct Volume
{
    openvdb::FloatGrid::Ptr grid; ///< values in file units; background = minValue
    openvdb::Coord dims{0, 0, 0}; ///< size of the scan in voxels (index box [0, dims-1])
    float airThreshold = 0.0f;
    float minValue = 0.0f; ///< over the whole scan
    float maxValue = 0.0f;
    std::string units;  ///< "HU" for CT in Hounsfield units, "" when unknown
    std::string source; ///< the file or folder it came from, or "phantom"

    openvdb::CoordBBox indexBox() const
    {
        return openvdb::CoordBBox(openvdb::Coord(0), dims - openvdb::Coord(1));
    }
    /// Voxel spacing in mm along x, y, z.
    openvdb::Vec3d spacing() const { return grid->voxelSize(); }
    /// World mm (LPS) of the centre of voxel (0,0,0).
    openvdb::Vec3d origin() const { return grid->indexToWorld(openvdb::Vec3d(0.0)); }
    uint64_t voxelCount() const
    {
        return uint64_t(dims.x()) * uint64_t(dims.y()) * uint64_t(dims.z());
    }
};

/// Largest scan accepted (voxels); checked on headers before any allocation.
constexpr uint64_t kMaxVoxels = uint64_t(1) << 32;
/// Largest extent along one axis.
constexpr int kMaxDim = 1 << 16;

/// Throws InputError ("<source>: ...") unless 0 < dims <= kMaxDim on every axis
/// and the product is <= kMaxVoxels. Call on a header before allocating.
void checkDims(const openvdb::Coord& dims, const std::string& source);

/// Throws InputError unless spacing is finite and > 0, origin finite and the
/// direction columns finite and non-zero.
void checkGeometry(const VolumeGeometry& geometry, const std::string& source);

/// Builds the sparse Volume: checks the geometry, rejects NaN/Inf values
/// (naming the first voxel), canonicalises the orientation (axis-aligned
/// directions with flips and permutations; oblique directions, more than
/// 1e-3 off an axis, are rejected), guesses HU units when the file gave none
/// and the minimum lies in [-3100, -900], then prunes air (see Volume).
/// Consumes scan.values. Parallel (TBB); polls interrupter per slab of blocks.
Volume makeVolume(DenseScan&& scan, const std::string& source,
                  const SparseOptions& options = {}, Interrupter* interrupter = nullptr);

/// The volume as a dense array in canonical index order (i fastest), with
/// inactive tiles at the background value, plus its canonical geometry.
DenseScan toDense(const Volume& volume);

/// What `mtcut info` prints.
struct VolumeStats
{
    uint64_t activeVoxels = 0;
    uint64_t memoryBytes = 0; ///< the sparse grid in memory
    uint64_t denseBytes = 0;  ///< the same scan as a dense float array
    float suggestedBoneIso = 0.0f;
};

/// Counts and a suggested bone isovalue: Otsu's threshold over the active
/// (non-air) voxels' histogram, which splits soft tissue from bone; for HU
/// data clamped to [150, 700] HU. Cost: one pass over the active voxels.
VolumeStats computeStats(const Volume& volume);

} // namespace mtcut::vdb
