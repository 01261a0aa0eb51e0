// MetaImage (.mha attached, .mhd + data file): the header text goes through
// parseMetaImageHeader/interpretMetaImageHeader (HeaderParsers.cpp, fuzzed);
// uncompressed data through readRaw, compressed data through zlib.
#include "vdb/Formats.h"

#include "vdb/AtomicFile.h"

#include <zlib.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

namespace mtcut::vdb {

namespace fs = std::filesystem;

namespace {

constexpr size_t kMaxHeaderBytes = size_t(1) << 20;
constexpr size_t kChunkBytes = size_t(1) << 24;
/// zlib's deflate cannot do better than about 1032:1.
constexpr uint64_t kMaxDeflateRatio = 1032;

struct FileCloser
{
    void operator()(FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<FILE, FileCloser>;

std::string num(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.17g", v);
    return buf;
}

/// Inflates the zlib or gzip stream at offset..offset+compressed (or to the
/// end of the file when compressed is 0) into exactly info.dataBytes() and
/// decodes it into values.
void readCompressed(const std::string& dataPath, uint64_t offset, const MetaImageInfo& info,
                    std::vector<float>& values, Interrupter* interrupter)
{
    std::error_code ec;
    const uint64_t fileBytes = fs::file_size(dataPath, ec);
    if (ec) throw InputError(dataPath + ": cannot read (" + ec.message() + ")");
    if (offset > fileBytes) {
        throw InputError(dataPath + ": file has " + std::to_string(fileBytes) + " bytes, data should start at byte " +
                         std::to_string(offset));
    }
    uint64_t compressed = fileBytes - offset;
    if (info.compressedBytes > 0) {
        if (info.compressedBytes > compressed) {
            throw InputError(dataPath + ": CompressedDataSize " + std::to_string(info.compressedBytes) +
                             " is more than the " + std::to_string(compressed) + " bytes left in the file");
        }
        compressed = info.compressedBytes;
    }
    const uint64_t expected = info.dataBytes();
    if (compressed * kMaxDeflateRatio + 64 < expected) {
        throw InputError(dataPath + ": " + std::to_string(compressed) + " compressed bytes cannot hold the " +
                         std::to_string(expected) + " bytes the header describes (data truncated?)");
    }
    FilePtr file(std::fopen(dataPath.c_str(), "rb"));
    if (!file) throw InputError(dataPath + ": cannot open for reading (" + std::strerror(errno) + ")");
    if (fseeko(file.get(), off_t(offset), SEEK_SET) != 0) {
        throw InputError(dataPath + ": cannot seek to byte " + std::to_string(offset));
    }

    z_stream zs{};
    if (inflateInit2(&zs, 15 + 32) != Z_OK) throw std::bad_alloc();
    std::unique_ptr<z_stream, int (*)(z_stream*)> guard(&zs, inflateEnd);
    const size_t bpv = scalarSize(info.type);
    std::vector<unsigned char> in(std::min<uint64_t>(compressed, kChunkBytes));
    std::vector<unsigned char> out(std::min<uint64_t>(expected, kChunkBytes / bpv * bpv));
    values.resize(info.voxelCount());
    uint64_t readIn = 0, decoded = 0;
    size_t outFill = 0;
    int rc = Z_OK;
    while (decoded < expected) {
        pollInterrupter(interrupter, int(100 * decoded / expected));
        if (zs.avail_in == 0 && readIn < compressed) {
            const size_t n = size_t(std::min<uint64_t>(compressed - readIn, in.size()));
            if (std::fread(in.data(), 1, n, file.get()) != n) {
                throw InputError(dataPath + ": cannot read compressed data");
            }
            readIn += n;
            zs.next_in = in.data();
            zs.avail_in = unsigned(n);
        }
        const size_t want = size_t(std::min<uint64_t>(out.size(), expected - decoded));
        zs.next_out = out.data() + outFill;
        zs.avail_out = unsigned(want - outFill);
        rc = inflate(&zs, Z_NO_FLUSH);
        if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
            throw InputError(dataPath + ": corrupt compressed data (" + (zs.msg ? zs.msg : "zlib error") + ")");
        }
        outFill = want - zs.avail_out;
        if (outFill == want) { // whole samples: want is a multiple of bpv
            decodeSamples(out.data(), want / bpv, info.type, info.bigEndian, values.data() + decoded / bpv);
            decoded += want;
            outFill = 0;
        }
        if (rc == Z_STREAM_END) break;
        if (rc == Z_BUF_ERROR && zs.avail_in == 0 && readIn == compressed) break; // input used up
    }
    if (decoded + outFill < expected) {
        throw InputError(dataPath + ": compressed data holds " + std::to_string(decoded + outFill) +
                         " bytes, the header describes " + std::to_string(expected) + " (truncated?)");
    }
}

std::string headerText(const DenseScan& scan, const std::string& dataFile)
{
    const VolumeGeometry& g = scan.geometry;
    std::string h;
    h += "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n";
    h += "CompressedData = False\nTransformMatrix =";
    for (int a = 0; a < 3; ++a) {
        for (int r = 0; r < 3; ++r) h += " " + num(g.direction(r, a));
    }
    h += "\nOffset = " + num(g.origin[0]) + " " + num(g.origin[1]) + " " + num(g.origin[2]) + "\n";
    h += "CenterOfRotation = 0 0 0\n";
    h += "ElementSpacing = " + num(g.spacing[0]) + " " + num(g.spacing[1]) + " " + num(g.spacing[2]) + "\n";
    h += "DimSize = " + std::to_string(g.dims[0]) + " " + std::to_string(g.dims[1]) + " " +
         std::to_string(g.dims[2]) + "\n";
    h += "ElementType = MET_FLOAT\n";
    h += "ElementDataFile = " + dataFile + "\n";
    return h;
}

void writeText(const std::string& tmp, const std::string& path, const std::string& text, bool close,
               FilePtr& file)
{
    file.reset(std::fopen(tmp.c_str(), "wb"));
    if (!file) throw InputError(path + ": cannot open for writing (" + std::strerror(errno) + ")");
    if (std::fwrite(text.data(), 1, text.size(), file.get()) != text.size()) {
        throw InputError(path + ": cannot write (" + std::strerror(errno) + ")");
    }
    if (close && std::fclose(file.release()) != 0) {
        throw InputError(path + ": cannot write (" + std::strerror(errno) + ")");
    }
}

} // namespace

DenseScan readMetaImage(const std::string& path, Interrupter* interrupter)
{
    InterrupterScope scope(interrupter, "reading MetaImage");
    std::string head(kMaxHeaderBytes, '\0');
    {
        FilePtr file(std::fopen(path.c_str(), "rb"));
        if (!file) throw InputError(path + ": cannot open for reading (" + std::strerror(errno) + ")");
        head.resize(std::fread(head.data(), 1, head.size(), file.get()));
    }
    const MetaImageHeader header = parseMetaImageHeader(head, path);
    const MetaImageInfo info = interpretMetaImageHeader(header, path);

    DenseScan scan;
    VolumeGeometry& g = scan.geometry;
    g.dims = openvdb::Coord(info.dims[0], info.dims[1], info.dims[2]);
    checkDims(g.dims, path);
    for (int a = 0; a < 3; ++a) {
        g.spacing[a] = info.spacing[size_t(a)];
        g.origin[a] = info.origin[size_t(a)];
        for (int r = 0; r < 3; ++r) g.direction(r, a) = info.matrix[size_t(3 * a + r)];
    }

    std::string dataPath = path;
    uint64_t offset = header.headerBytes;
    if (!info.local) {
        fs::path file(info.dataFile);
        if (file.is_relative()) file = fs::path(path).parent_path() / file;
        dataPath = file.lexically_normal().string();
        std::error_code ec;
        if (!fs::is_regular_file(dataPath, ec)) {
            throw InputError(path + ": data file " + dataPath + " (ElementDataFile) not found");
        }
        offset = info.headerSize > 0 ? uint64_t(info.headerSize) : 0;
        if (info.headerSize == -1 && !info.compressed) {
            const uint64_t bytes = fs::file_size(dataPath, ec);
            if (ec || bytes < info.dataBytes()) {
                throw InputError(dataPath + ": file has " + std::to_string(ec ? 0 : bytes) + " bytes, the header " +
                                 path + " describes " + std::to_string(info.dataBytes()));
            }
            offset = bytes - info.dataBytes();
        }
    }

    if (info.compressed) {
        readCompressed(dataPath, offset, info, scan.values, interrupter);
    } else {
        RawOptions raw;
        raw.dims = info.dims;
        raw.type = scalarTypeName(info.type);
        raw.bigEndian = info.bigEndian;
        raw.headerBytes = offset;
        DenseScan data = readRaw(dataPath, raw, interrupter);
        scan.values = std::move(data.values);
    }
    return scan;
}

void writeMetaImage(const DenseScan& scan, const std::string& path)
{
    const fs::path p(path);
    std::string ext = p.extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".mhd") {
        const fs::path rawPath = fs::path(path).replace_extension(".raw");
        writeRaw(scan, rawPath.string());
        writeFileAtomically(path, [&](const std::string& tmp) {
            FilePtr file;
            writeText(tmp, path, headerText(scan, rawPath.filename().string()), true, file);
        });
        return;
    }
    // .mha: header, then float32 little-endian data in the same file.
    writeFileAtomically(path, [&](const std::string& tmp) {
        FilePtr file;
        writeText(tmp, path, headerText(scan, "LOCAL"), false, file);
        writeFloat32LE(file.get(), scan.values, path);
        if (std::fclose(file.release()) != 0) throw InputError(path + ": cannot write (" + std::strerror(errno) + ")");
    });
}

} // namespace mtcut::vdb
