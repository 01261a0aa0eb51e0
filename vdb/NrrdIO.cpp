// NRRD through teem: the header is read first (skipData) so sizes are checked
// before teem allocates; then teem reads the data (raw, gzip, ascii, hex;
// either endianness; attached or detached) and we convert it to float.
#include "vdb/Formats.h"

#include "vdb/AtomicFile.h"

#include <teem/nrrd.h>

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>

namespace mtcut::vdb {

namespace fs = std::filesystem;

namespace {

constexpr uint64_t kMaxDeflateRatio = 1032; // zlib cannot compress better

struct NrrdDeleter
{
    void operator()(Nrrd* n) const { nrrdNuke(n); }
};
struct NioDeleter
{
    void operator()(NrrdIoState* n) const { nrrdIoStateNix(n); }
};
using NrrdPtr = std::unique_ptr<Nrrd, NrrdDeleter>;
using NioPtr = std::unique_ptr<NrrdIoState, NioDeleter>;

/// teem's biff message as one line: the innermost (most specific) complaint.
std::string biffMessage()
{
    char* err = biffGetDone(NRRD);
    std::string text = err ? err : "";
    std::free(err);
    std::string best;
    size_t pos = 0;
    while (pos < text.size()) {
        size_t end = text.find('\n', pos);
        if (end == std::string::npos) end = text.size();
        std::string line = text.substr(pos, end - pos);
        pos = end + 1;
        // "[nrrd] _nrrdFunc: what" -> "what"
        if (line.rfind("[nrrd] ", 0) == 0) line.erase(0, 7);
        const size_t colon = line.find(": ");
        if (colon != std::string::npos && line.find(' ') > colon) line.erase(0, colon + 2);
        while (!line.empty() && (line.back() == ' ' || line.back() == '\r')) line.pop_back();
        if (!line.empty()) best = line;
    }
    return best.empty() ? "cannot read as NRRD" : best;
}

std::optional<ScalarType> scalarType(int nrrdType)
{
    switch (nrrdType) {
    case nrrdTypeChar: return ScalarType::Int8;
    case nrrdTypeUChar: return ScalarType::UInt8;
    case nrrdTypeShort: return ScalarType::Int16;
    case nrrdTypeUShort: return ScalarType::UInt16;
    case nrrdTypeInt: return ScalarType::Int32;
    case nrrdTypeUInt: return ScalarType::UInt32;
    case nrrdTypeFloat: return ScalarType::Float32;
    case nrrdTypeDouble: return ScalarType::Float64;
    default: return std::nullopt;
    }
}

uint64_t fileSize(const std::string& p)
{
    std::error_code ec;
    const uint64_t s = fs::file_size(p, ec);
    return ec ? 0 : s;
}

/// Cheap check that the data files can hold what the header claims, so a
/// lying header fails here instead of in a huge allocation.
void checkDataSize(const std::string& path, const NrrdIoState& nio, uint64_t dataBytes, uint64_t values)
{
    if (nio.dataFNFormat) return; // numbered file sequence: teem checks each file
    std::vector<std::string> files;
    for (unsigned i = 0; i < nio.dataFNArr->len; ++i) {
        std::string name = nio.dataFN[i];
        if (name.empty() || name == "-") return;
        if (!fs::path(name).is_absolute() && nio.path) name = std::string(nio.path) + "/" + name;
        files.push_back(name);
    }
    if (files.empty()) files.push_back(path); // attached
    uint64_t available = 0;
    for (const std::string& f : files) available += fileSize(f);

    uint64_t needed = 0;
    if (nio.encoding == nrrdEncodingRaw) {
        needed = dataBytes;
    } else if (nio.encoding == nrrdEncodingGzip) {
        needed = dataBytes / kMaxDeflateRatio;
    } else if (nio.encoding == nrrdEncodingAscii) {
        needed = values; // at least a digit per value
    } else if (nio.encoding == nrrdEncodingHex) {
        needed = 2 * dataBytes;
    }
    if (available < needed) {
        throw InputError(path + ": header describes " + std::to_string(dataBytes) + " bytes of " +
                         nio.encoding->name + " data, but " + (nio.dataFNArr->len == 0 ? "the file holds " : files.size() > 1 ? "the data files hold " : "the data file holds ") +
                         std::to_string(available) + " bytes (truncated?)");
    }
}

/// World frame of the header's space, as factors on LPS x, y (z is always superior).
std::pair<double, double> lpsSigns(const std::string& path, const Nrrd& n)
{
    switch (n.space) {
    case nrrdSpaceUnknown:            // "space dimension: 3": assume LPS
    case nrrdSpaceLeftPosteriorSuperior:
    case nrrdSpaceScannerXYZ:
    case nrrdSpace3DRightHanded: return {1.0, 1.0};
    case nrrdSpaceRightAnteriorSuperior: return {-1.0, -1.0};
    case nrrdSpaceLeftAnteriorSuperior: return {1.0, -1.0};
    default: break;
    }
    throw InputError(path + ": NRRD space '" + airEnumStr(nrrdSpace, n.space) +
                     "' is not supported (use left-posterior-superior, right-anterior-superior, "
                     "left-anterior-superior or scanner-xyz)");
}

VolumeGeometry geometryOf(const std::string& path, const Nrrd& n)
{
    VolumeGeometry g;
    g.dims = openvdb::Coord(int(n.axis[0].size), int(n.axis[1].size), int(n.axis[2].size));
    g.origin = openvdb::Vec3d(0.0);
    if (n.spaceDim > 0) {
        if (n.spaceDim != 3) {
            throw InputError(path + ": NRRD space has " + std::to_string(n.spaceDim) +
                             " dimensions, expected 3");
        }
        const auto [sx, sy] = lpsSigns(path, n);
        const double sign[3] = {sx, sy, 1.0};
        for (int a = 0; a < 3; ++a) {
            const double* d = n.axis[a].spaceDirection;
            openvdb::Vec3d v(d[0] * sign[0], d[1] * sign[1], d[2] * sign[2]);
            if (!std::isfinite(v.x()) || !std::isfinite(v.y()) || !std::isfinite(v.z()) || v.length() <= 0.0) {
                throw InputError(path + ": axis " + std::to_string(a) +
                                 " has no usable space direction (every axis must be a spatial one)");
            }
            g.spacing[a] = v.length();
            v /= g.spacing[a];
            for (int r = 0; r < 3; ++r) g.direction(r, a) = v[r];
            if (std::isfinite(n.spaceOrigin[a])) g.origin[a] = n.spaceOrigin[a] * sign[a];
        }
        return g;
    }
    // No space: per-axis "spacings" (and "axis mins"), world = index axes.
    for (int a = 0; a < 3; ++a) {
        const double s = n.axis[a].spacing;
        if (std::isfinite(s) && s != 0.0) {
            g.spacing[a] = std::abs(s);
            if (s < 0.0) g.direction(a, a) = -1.0;
        }
        if (std::isfinite(n.axis[a].min)) {
            g.origin[a] = n.axis[a].min + (n.axis[a].center == nrrdCenterCell ? 0.5 * s : 0.0);
        }
    }
    return g;
}

template <typename T>
void convert(const void* data, size_t count, float* out)
{
    const T* in = static_cast<const T*>(data);
    for (size_t i = 0; i < count; ++i) out[i] = static_cast<float>(in[i]);
}

} // namespace

DenseScan readNrrd(const std::string& path, Interrupter* interrupter)
{
    InterrupterScope scope(interrupter, "reading NRRD");
    pollInterrupter(interrupter, 0);
    NrrdPtr nrrd(nrrdNew());
    NioPtr nio(nrrdIoStateNew());
    nio->skipData = AIR_TRUE;
    if (nrrdLoad(nrrd.get(), path.c_str(), nio.get()) != 0) {
        throw InputError(path + ": " + biffMessage());
    }
    if (nrrd->dim != 3) {
        throw InputError(path + ": NRRD has dimension " + std::to_string(nrrd->dim) +
                         ", only 3-D scalar volumes are supported");
    }
    const auto type = scalarType(nrrd->type);
    if (!type) {
        throw InputError(path + ": NRRD type '" + airEnumStr(nrrdType, nrrd->type) +
                         "' is not supported (8/16/32-bit integers, float, double)");
    }
    openvdb::Coord dims;
    for (int a = 0; a < 3; ++a) {
        const size_t s = nrrd->axis[a].size;
        dims[a] = s > size_t(INT32_MAX) ? INT32_MAX : int(s); // checkDims names the size
    }
    checkDims(dims, path);
    DenseScan scan;
    scan.geometry = geometryOf(path, *nrrd);
    const uint64_t voxels = uint64_t(dims[0]) * uint64_t(dims[1]) * uint64_t(dims[2]);
    checkDataSize(path, *nio, voxels * scalarSize(*type), voxels);
    if (nrrd->sampleUnits && std::string(nrrd->sampleUnits) == "HU") scan.units = "HU";
    if (char* units = nrrdKeyValueGet(nrrd.get(), "units")) {
        if (std::string(units) == "HU") scan.units = "HU";
        if (!nrrdStateKeyValueReturnInternalPointers) std::free(units);
    }

    const int headerType = nrrd->type;
    // Now the data (teem re-reads the header; it is small).
    nrrd.reset(nrrdNew());
    nio.reset(nrrdIoStateNew());
    if (nrrdLoad(nrrd.get(), path.c_str(), nio.get()) != 0) {
        throw InputError(path + ": " + biffMessage());
    }
    pollInterrupter(interrupter, 80);
    if (nrrd->type != headerType || nrrd->dim != 3 || nrrdElementNumber(nrrd.get()) != voxels || !nrrd->data) {
        throw InputError(path + ": NRRD header changed while reading");
    }
    scan.values.resize(voxels);
    float* out = scan.values.data();
    switch (nrrd->type) {
    case nrrdTypeChar: convert<int8_t>(nrrd->data, voxels, out); break;
    case nrrdTypeUChar: convert<uint8_t>(nrrd->data, voxels, out); break;
    case nrrdTypeShort: convert<int16_t>(nrrd->data, voxels, out); break;
    case nrrdTypeUShort: convert<uint16_t>(nrrd->data, voxels, out); break;
    case nrrdTypeInt: convert<int32_t>(nrrd->data, voxels, out); break;
    case nrrdTypeUInt: convert<uint32_t>(nrrd->data, voxels, out); break;
    case nrrdTypeFloat: convert<float>(nrrd->data, voxels, out); break;
    case nrrdTypeDouble: convert<double>(nrrd->data, voxels, out); break;
    }
    pollInterrupter(interrupter, 100);
    return scan;
}

void writeNrrd(const DenseScan& scan, const std::string& path)
{
    const VolumeGeometry& g = scan.geometry;
    std::string ext = fs::path(path).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    const bool detached = ext == ".nhdr";

    // A header around the caller's data (nrrdNix later leaves the data alone).
    struct NixDeleter
    {
        void operator()(Nrrd* n) const { nrrdNix(n); }
    };
    std::unique_ptr<Nrrd, NixDeleter> nrrd(nrrdNew());
    if (nrrdWrap_va(nrrd.get(), const_cast<float*>(scan.values.data()), nrrdTypeFloat, 3, size_t(g.dims[0]),
                    size_t(g.dims[1]), size_t(g.dims[2])) != 0 ||
        nrrdSpaceSet(nrrd.get(), nrrdSpaceLeftPosteriorSuperior) != 0) {
        throw InputError(path + ": " + biffMessage());
    }
    const double origin[3] = {g.origin[0], g.origin[1], g.origin[2]};
    double dirs[3][NRRD_SPACE_DIM_MAX];
    for (int a = 0; a < 3; ++a) {
        for (int r = 0; r < NRRD_SPACE_DIM_MAX; ++r) dirs[a][r] = r < 3 ? g.direction(r, a) * g.spacing[a] : NAN;
    }
    if (nrrdSpaceOriginSet(nrrd.get(), origin) != 0) throw InputError(path + ": " + biffMessage());
    nrrdAxisInfoSet_va(nrrd.get(), nrrdAxisInfoSpaceDirection, dirs[0], dirs[1], dirs[2]);
    nrrdAxisInfoSet_va(nrrd.get(), nrrdAxisInfoKind, nrrdKindDomain, nrrdKindDomain, nrrdKindDomain);
    // Units go in a key/value pair: teem 1.12 under-allocates its "sample units" line by the
    // quotes it adds (a heap overflow that AddressSanitizer reports). We read both.
    if (!scan.units.empty() && nrrdKeyValueAdd(nrrd.get(), "units", scan.units.c_str()) != 0) {
        throw InputError(path + ": " + biffMessage());
    }

    NioPtr nio(nrrdIoStateNew());
    nio->format = nrrdFormatNRRD;
    nio->skipFormatURL = AIR_TRUE;
    if (!detached) {
        nio->encoding = nrrdEncodingGzip;
        writeFileAtomically(path, [&](const std::string& tmp) {
            if (nrrdSave(tmp.c_str(), nrrd.get(), nio.get()) != 0) {
                throw InputError(path + ": " + biffMessage());
            }
        });
        return;
    }
    // Detached: the data file (raw, host byte order as the header says) first.
    const fs::path dataPath = fs::path(path).replace_extension(".raw");
    writeFileAtomically(dataPath.string(), [&](const std::string& tmp) {
        FILE* f = std::fopen(tmp.c_str(), "wb");
        if (!f) throw InputError(dataPath.string() + ": cannot open for writing (" + std::strerror(errno) + ")");
        const size_t n = std::fwrite(scan.values.data(), sizeof(float), scan.values.size(), f);
        if (std::fclose(f) != 0 || n != scan.values.size()) {
            throw InputError(dataPath.string() + ": cannot write (" + std::strerror(errno) + ")");
        }
    });
    // The header: teem writes every field but, with skipData, no "data file"
    // line, so that line is added here (header-relative name).
    nio->encoding = nrrdEncodingRaw;
    nio->detachedHeader = AIR_TRUE;
    nio->skipData = AIR_TRUE;
    writeFileAtomically(path, [&](const std::string& tmp) {
        if (nrrdSave(tmp.c_str(), nrrd.get(), nio.get()) != 0) {
            throw InputError(path + ": " + biffMessage());
        }
        std::string text;
        {
            std::ifstream in(tmp, std::ios::binary);
            text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
        }
        while (!text.empty() && text.back() == '\n') text.pop_back();
        text += "\ndata file: " + dataPath.filename().string() + "\n";
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        out << text;
        out.close();
        if (!out) throw InputError(path + ": cannot write header");
    });
}

} // namespace mtcut::vdb
