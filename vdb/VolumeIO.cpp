#include "vdb/VolumeIO.h"

#include "vdb/Formats.h"

#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace mtcut::vdb {

namespace fs = std::filesystem;

const char* formatName(Format format)
{
    switch (format) {
    case Format::Dicom: return "DICOM";
    case Format::Nrrd: return "NRRD";
    case Format::Nifti: return "NIfTI";
    case Format::MetaImage: return "MetaImage";
    case Format::Raw: return "raw";
    case Format::Vdb: return "OpenVDB";
    case Format::Unknown: break;
    }
    return "unknown";
}

namespace {

std::string lowerExtension(const std::string& path)
{
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    return ext;
}

/// The first bytes of a file, decompressed when it is gzip.
std::string peek(const std::string& path, size_t count)
{
    gzFile f = gzopen(path.c_str(), "rb");
    if (!f) return {};
    std::string bytes(count, '\0');
    const int got = gzread(f, bytes.data(), unsigned(count));
    gzclose(f);
    bytes.resize(got > 0 ? size_t(got) : 0);
    return bytes;
}

bool isNiftiHeader(const std::string& b)
{
    if (b.size() < 348) return false;
    int32_t sizeofHdr = 0;
    std::memcpy(&sizeofHdr, b.data(), 4);
    const int32_t swapped = int32_t(__builtin_bswap32(uint32_t(sizeofHdr)));
    if (sizeofHdr == 348 || swapped == 348) {
        return b.compare(344, 3, "n+1") == 0 || b.compare(344, 3, "ni1") == 0;
    }
    if ((sizeofHdr == 540 || swapped == 540) && b.size() >= 8) {
        return b.compare(4, 3, "n+2") == 0 || b.compare(4, 3, "ni2") == 0;
    }
    return false;
}

bool isMetaImageHeader(const std::string& b)
{
    // MetaImage: text lines "Key = Value"; the first key is usually ObjectType or NDims.
    size_t i = b.find_first_not_of(" \t\r\n");
    if (i == std::string::npos) return false;
    for (const char* key : {"ObjectType", "NDims", "ObjectSubType", "Comment"}) {
        const size_t n = std::strlen(key);
        if (b.compare(i, n, key) == 0) {
            const size_t eq = b.find_first_not_of(" \t", i + n);
            return eq != std::string::npos && b[eq] == '=';
        }
    }
    return false;
}

} // namespace

Format detectFormat(const std::string& path, const ReadOptions& options)
{
    std::error_code ec;
    const auto status = fs::status(path, ec);
    if (ec || !fs::exists(status)) throw InputError(path + ": no such file or folder");
    if (fs::is_directory(status)) return Format::Dicom;

    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path + ": cannot open for reading");
    std::string head(1024, '\0');
    in.read(head.data(), std::streamsize(head.size()));
    head.resize(size_t(in.gcount()));

    if (head.size() >= 132 && head.compare(128, 4, "DICM") == 0) return Format::Dicom;
    if (head.compare(0, 7, "NRRD000") == 0) return Format::Nrrd;
    if (head.size() >= 4 && head.compare(0, 4, " BDV") == 0) return Format::Vdb;
    if (isNiftiHeader(head)) return Format::Nifti;
    if (head.size() >= 2 && uint8_t(head[0]) == 0x1f && uint8_t(head[1]) == 0x8b) {
        if (isNiftiHeader(peek(path, 540))) return Format::Nifti;
    }
    if (isMetaImageHeader(head)) return Format::MetaImage;
    if (options.raw.valid()) return Format::Raw;
    const std::string ext = lowerExtension(path);
    if (ext == ".raw" || ext == ".bin" || ext == ".dat") return Format::Raw;
    return Format::Unknown;
}

Volume readVolume(const std::string& path, const ReadOptions& options, Interrupter* interrupter)
{
    const Format format = detectFormat(path, options);
    switch (format) {
    case Format::Dicom:
        return makeVolume(readDicomSeries(path, options, interrupter), path, options.sparse, interrupter);
    case Format::Nrrd:
        return makeVolume(readNrrd(path, interrupter), path, options.sparse, interrupter);
    case Format::Nifti:
        return makeVolume(readNifti(path, interrupter), path, options.sparse, interrupter);
    case Format::MetaImage:
        return makeVolume(readMetaImage(path, interrupter), path, options.sparse, interrupter);
    case Format::Raw:
        if (!options.raw.valid()) {
            throw InputError(path + ": raw data needs its layout (--dims X,Y,Z --type T, "
                                    "optionally --endian, --spacing, --offset)");
        }
        return makeVolume(readRaw(path, options.raw, interrupter), path, options.sparse, interrupter);
    case Format::Vdb:
        return readVdb(path, options);
    case Format::Unknown: break;
    }
    throw InputError(path + ": unknown format (expected a DICOM folder, NRRD, NIfTI, MetaImage, "
                            "OpenVDB, or raw data with --dims and --type)");
}

void writeVolume(const Volume& volume, const std::string& path)
{
    const std::string ext = lowerExtension(path);
    if (ext == ".vdb") return writeVdb(volume, path);
    if (ext == ".nrrd" || ext == ".nhdr") return writeNrrd(toDense(volume), path);
    if (ext == ".mha" || ext == ".mhd") return writeMetaImage(toDense(volume), path);
    if (ext == ".raw") return writeRaw(toDense(volume), path);
    throw InputError(path + ": unknown output format '" + ext +
                     "' (use .vdb, .nrrd, .nhdr, .mha, .mhd or .raw)");
}

} // namespace mtcut::vdb
