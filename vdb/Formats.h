// Internal: one reader (and writer) per format, each with the library made
// for it. readVolume() dispatches here; tests and fuzzers call them directly.
// Readers name the file in every InputError. Writers take the final path and
// write atomically (writeFileAtomically), data file before header.
#pragma once

#include "vdb/VolumeIO.h"

#include <cstdio>
#include <map>
#include <string>
#include <string_view>

namespace mtcut::vdb {

/// DICOM series in a folder, through GDCM (any transfer syntax GDCM decodes,
/// JPEG 2000 included). Slices sorted along the slice normal, rescale applied.
DenseScan readDicomSeries(const std::string& folder, const ReadOptions& options, Interrupter* interrupter);

/// NRRD (attached or detached header, raw or gzip, either endianness) through teem.
DenseScan readNrrd(const std::string& path, Interrupter* interrupter);
/// Writes .nrrd (attached, gzip) or .nhdr + .raw (detached, raw) through teem.
void writeNrrd(const DenseScan& scan, const std::string& path);

/// NIfTI-1 or -2 (.nii, .nii.gz, .hdr/.img) through nifti_clib.
DenseScan readNifti(const std::string& path, Interrupter* interrupter);

DenseScan readMetaImage(const std::string& path, Interrupter* interrupter);
/// Writes .mha (attached) or .mhd + .raw (detached), float32 little-endian.
void writeMetaImage(const DenseScan& scan, const std::string& path);

/// Headerless raw data described by options.
DenseScan readRaw(const std::string& path, const RawOptions& options, Interrupter* interrupter);
/// Float32 little-endian, x fastest, no header.
void writeRaw(const DenseScan& scan, const std::string& path);

/// Appends values to an open file as float32 little-endian, in chunks.
/// Throws InputError naming path on a short write. Shared by raw, .mha, .mhd.
void writeFloat32LE(std::FILE* file, const std::vector<float>& values, const std::string& path);

/// Sets the Volume's fields on a grid as metadata: mtcut:dims (Vec3i),
/// mtcut:units, mtcut:air_threshold, mtcut:min, mtcut:max (float),
/// mtcut:source. readVdb() restores a Volume from them; cut.vdb's carved
/// grid carries them too.
void setVolumeMetadata(openvdb::GridBase& grid, const Volume& volume);

/// OpenVDB file: the named float grid, or the first float grid.
Volume readVdb(const std::string& path, const ReadOptions& options);
/// One float grid with the Volume's fields as metadata (mtcut:dims, ...).
void writeVdb(const Volume& volume, const std::string& path);

} // namespace mtcut::vdb
