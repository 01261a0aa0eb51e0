// Reading any supported scan into a Volume, and writing one back out.
#pragma once

#include "vdb/HeaderParsers.h"
#include "vdb/Volume.h"

#include <string>
#include <string_view>

namespace mtcut::vdb {

enum class Format { Unknown, Dicom, Nrrd, Nifti, MetaImage, Raw, Vdb };

const char* formatName(Format format);

struct ReadOptions
{
    /// DICOM: the SeriesInstanceUID to read; empty picks the series with the most slices.
    std::string seriesUid;
    /// Raw files: how to read them. Ignored for other formats.
    RawOptions raw;
    /// .vdb: the float grid to read; empty picks the first float grid.
    std::string gridName;
    SparseOptions sparse;
};

/// The format of path, from its content (magic bytes, header keys), falling
/// back to the extension only where a format has no magic (raw). A folder is
/// DICOM. Unknown when nothing matches. Throws InputError if path does not exist.
Format detectFormat(const std::string& path, const ReadOptions& options = {});

/// Reads path (any supported format, detected from content) into a Volume.
/// Throws InputError with a one-line message naming the file on bad input.
/// Reports progress and honours cancellation through interrupter.
Volume readVolume(const std::string& path, const ReadOptions& options = {},
                  Interrupter* interrupter = nullptr);

/// Writes the volume; the format follows the extension: .vdb, .nrrd (gzip,
/// attached), .nhdr (+ .raw detached), .mha, .mhd (+ .raw), .raw (header-less,
/// float32 little-endian). Nothing half-written: temporary file, then rename.
void writeVolume(const Volume& volume, const std::string& path);

} // namespace mtcut::vdb
