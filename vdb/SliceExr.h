// Write-back of a cut as an OpenEXR slice stack for image tools (DESIGN.md,
// "Outputs"): the carved volume and the cut mask, one image per z slice.
//
// slices.exr layout: ONE multi-part OpenEXR 2 file, one scan-line part per
// z slice k = 0 .. dims.z-1, in order.
//   part name       sliceName(k): "slice_0000", "slice_0001", ... (%04d; wider past 9999)
//   data window     (0,0) - (dims.x-1, dims.y-1) = display window; pixel (x,y) is
//                   voxel (i=x, j=y, k). With the canonical LPS axes (vdb/Volume.h)
//                   that is the usual radiological axial view: anterior at the top,
//                   the patient's left on the image's right.
//   channels        density  FLOAT  the volume's value at the voxel (HU for CT),
//                                   inactive voxels included (carved = background)
//                   mask     UINT   stroke id of the cut voxel, 0 = not cut
//                                   (active voxels of the cut mask; ids are 1-based)
//   compression     ZIP (16 scan lines per block, zlib level 1), increasing y
//   pixelAspectRatio spacing.x / spacing.y (EXR's width/height of a pixel)
//   attributes, on every part:
//     mtcut:spacing_mm  v3d     voxel spacing x, y, z, mm
//     mtcut:origin_mm   v3d     world (LPS, mm) centre of voxel (0,0,0)
//     mtcut:slice_index int     k
//     mtcut:slice_z_mm  double  world z (mm) of the slice's voxel centres
//     mtcut:isovalue    float   isovalue of the cut isosurface (volume units)
//     mtcut:units       string  the volume's units ("HU", or "" when unknown)
//     mtcut:version     string  kMtcutVersion (vdb/CutOutputs.h)
#pragma once

#include "vdb/Progress.h"
#include "vdb/Volume.h"

#include <openvdb/openvdb.h>

#include <string>

namespace mtcut::vdb {

/// Part name of slice k: "slice_0000" ...
std::string sliceName(int k);

/// Writes slices.exr (layout above) for volume (pass the carved volume:
/// volume.grid = carveVolume(...); dims, spacing, origin and units are read
/// from it) and cutMask (voxel coordinates in the volume's index space; its
/// transform is ignored; voxels outside the index box are ignored).
/// Atomic: a failed or cancelled write leaves no file and no temporary behind.
/// Throws InputError when an active cut-mask voxel inside the box has a stroke
/// id < 1 (naming the voxel) or the path cannot be written ("<path>: cannot
/// write EXR (...)"); Cancelled when the interrupter asks (polled per slice).
/// Cost: one pass over the dense volume (copyToDense, 8 slices at a time,
/// parallel) plus ZIP compression, which runs on OpenEXR's global thread pool
/// (Imf::setGlobalThreadCount; 0 threads = compress on the calling thread).
/// Memory: 8 slices of float + uint32 (16 MB for 512 x 512).
void writeSliceStack(const std::string& path, const Volume& volume, const openvdb::Int32Grid& cutMask,
                     float isovalue, Interrupter* interrupter = nullptr);

/// Sizes OpenEXR's global thread pool, which compresses the blocks of every
/// EXR this process writes (slice stacks, rendered frames): `threads` = 0
/// compresses on the calling thread (OpenEXR's default at start-up); the
/// front ends (mtcut, mtcut-view) call it once with the number of hardware
/// threads. Not thread-safe: call it before writing starts.
void setExrThreadCount(unsigned threads);

} // namespace mtcut::vdb
