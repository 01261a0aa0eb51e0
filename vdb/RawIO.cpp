// Headerless raw volumes: read any scalar type described by RawOptions,
// write float32 little-endian.
#include "vdb/Formats.h"

#include "vdb/AtomicFile.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>

namespace mtcut::vdb {

namespace {

constexpr size_t kChunkVoxels = size_t(1) << 22; // per read and progress poll

struct FileCloser
{
    void operator()(FILE* f) const { std::fclose(f); }
};
using FilePtr = std::unique_ptr<FILE, FileCloser>;

} // namespace

DenseScan readRaw(const std::string& path, const RawOptions& options, Interrupter* interrupter)
{
    InterrupterScope scope(interrupter, "reading raw data");
    const auto type = scalarTypeFromName(options.type);
    if (!type) throw InputError(path + ": unsupported raw type '" + options.type + "'");
    DenseScan scan;
    VolumeGeometry& g = scan.geometry;
    g.dims = openvdb::Coord(options.dims[0], options.dims[1], options.dims[2]);
    g.spacing = openvdb::Vec3d(options.spacing[0], options.spacing[1], options.spacing[2]);
    g.origin = openvdb::Vec3d(options.origin[0], options.origin[1], options.origin[2]);
    checkDims(g.dims, path);

    std::error_code ec;
    const uint64_t fileBytes = std::filesystem::file_size(path, ec);
    if (ec) throw InputError(path + ": cannot read (" + ec.message() + ")");
    const uint64_t voxels = uint64_t(g.dims[0]) * uint64_t(g.dims[1]) * uint64_t(g.dims[2]);
    const size_t bpv = scalarSize(*type);
    const uint64_t dataBytes = voxels * bpv; // <= 2^35: checkDims bounds voxels
    if (options.headerBytes > fileBytes || fileBytes - options.headerBytes < dataBytes) {
        throw InputError(path + ": file has " + std::to_string(fileBytes) + " bytes, but offset " +
                         std::to_string(options.headerBytes) + " + " + std::to_string(g.dims[0]) + " x " +
                         std::to_string(g.dims[1]) + " x " + std::to_string(g.dims[2]) + " " +
                         scalarTypeName(*type) + " voxels need " +
                         std::to_string(options.headerBytes + dataBytes) + " bytes");
    }

    FilePtr file(std::fopen(path.c_str(), "rb"));
    if (!file) throw InputError(path + ": cannot open for reading (" + std::strerror(errno) + ")");
    if (options.headerBytes > 0 && fseeko(file.get(), off_t(options.headerBytes), SEEK_SET) != 0) {
        throw InputError(path + ": cannot seek to byte " + std::to_string(options.headerBytes));
    }
    scan.values.resize(voxels);
    std::vector<unsigned char> buffer(std::min<uint64_t>(voxels, kChunkVoxels) * bpv);
    for (uint64_t done = 0; done < voxels;) {
        pollInterrupter(interrupter, int(100 * done / voxels));
        const size_t n = size_t(std::min<uint64_t>(voxels - done, kChunkVoxels));
        if (std::fread(buffer.data(), bpv, n, file.get()) != n) {
            throw InputError(path + ": data ends early at voxel " + std::to_string(done) + " of " +
                             std::to_string(voxels));
        }
        decodeSamples(buffer.data(), n, *type, options.bigEndian, scan.values.data() + done);
        done += n;
    }
    return scan;
}

void writeFloat32LE(std::FILE* file, const std::vector<float>& values, const std::string& path)
{
    std::vector<unsigned char> buffer;
    const size_t count = values.size();
    for (size_t done = 0; done < count;) {
        const size_t n = std::min(count - done, kChunkVoxels);
        buffer.resize(n * 4);
        for (size_t v = 0; v < n; ++v) {
            uint32_t bits;
            std::memcpy(&bits, &values[done + v], 4);
            for (int b = 0; b < 4; ++b) buffer[4 * v + size_t(b)] = static_cast<unsigned char>(bits >> (8 * b));
        }
        if (std::fwrite(buffer.data(), 1, buffer.size(), file) != buffer.size()) {
            throw InputError(path + ": cannot write (" + std::strerror(errno) + ")");
        }
        done += n;
    }
}

void writeRaw(const DenseScan& scan, const std::string& path)
{
    writeFileAtomically(path, [&](const std::string& tmp) {
        FilePtr file(std::fopen(tmp.c_str(), "wb"));
        if (!file) throw InputError(path + ": cannot open for writing (" + std::strerror(errno) + ")");
        writeFloat32LE(file.get(), scan.values, path);
        if (std::fclose(file.release()) != 0) {
            throw InputError(path + ": cannot write (" + std::strerror(errno) + ")");
        }
    });
}

} // namespace mtcut::vdb
