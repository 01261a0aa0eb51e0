#include "vdb/HeaderParsers.h"

#include "vdb/Error.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace mtcut::vdb {

namespace {

// Same limits as Volume.h (kMaxDim, kMaxVoxels), which this file may not include.
constexpr int64_t kHeaderMaxDim = int64_t(1) << 16;
constexpr uint64_t kHeaderMaxVoxels = uint64_t(1) << 32;

constexpr bool kHostBigEndian = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;

std::string lower(std::string_view s)
{
    std::string out(s);
    for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

std::string_view trim(std::string_view s)
{
    const char* ws = " \t\r\n\v\f";
    const size_t b = s.find_first_not_of(ws);
    if (b == std::string_view::npos) return {};
    const size_t e = s.find_last_not_of(ws);
    return s.substr(b, e - b + 1);
}

/// Splits on any of seps, dropping empty pieces.
std::vector<std::string_view> split(std::string_view s, const char* seps)
{
    std::vector<std::string_view> out;
    size_t i = 0;
    while (i < s.size()) {
        const size_t b = s.find_first_not_of(seps, i);
        if (b == std::string_view::npos) break;
        size_t e = s.find_first_of(seps, b);
        if (e == std::string_view::npos) e = s.size();
        out.push_back(s.substr(b, e - b));
        i = e;
    }
    return out;
}

/// Whole-token parses (locale-free); false on junk, overflow or empty input.
bool parseInt64(std::string_view s, int64_t& v)
{
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    if (s.empty()) return false;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parseUInt64(std::string_view s, uint64_t& v)
{
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    if (s.empty() || s.front() == '-') return false;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parseFinite(std::string_view s, double& v)
{
    if (!s.empty() && s.front() == '+') s.remove_prefix(1);
    if (s.empty()) return false;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(v);
}

template <typename T>
void decodeAs(const unsigned char* bytes, size_t count, bool swap, float* out)
{
    for (size_t n = 0; n < count; ++n) {
        unsigned char b[sizeof(T)];
        std::memcpy(b, bytes + n * sizeof(T), sizeof(T));
        if (swap) {
            for (size_t k = 0; k < sizeof(T) / 2; ++k) std::swap(b[k], b[sizeof(T) - 1 - k]);
        }
        T v;
        std::memcpy(&v, b, sizeof(T));
        out[n] = static_cast<float>(v);
    }
}

} // namespace

size_t scalarSize(ScalarType type)
{
    switch (type) {
    case ScalarType::Int8:
    case ScalarType::UInt8: return 1;
    case ScalarType::Int16:
    case ScalarType::UInt16: return 2;
    case ScalarType::Int32:
    case ScalarType::UInt32:
    case ScalarType::Float32: return 4;
    case ScalarType::Float64: return 8;
    }
    return 1;
}

const char* scalarTypeName(ScalarType type)
{
    switch (type) {
    case ScalarType::Int8: return "int8";
    case ScalarType::UInt8: return "uint8";
    case ScalarType::Int16: return "int16";
    case ScalarType::UInt16: return "uint16";
    case ScalarType::Int32: return "int32";
    case ScalarType::UInt32: return "uint32";
    case ScalarType::Float32: return "float32";
    case ScalarType::Float64: return "float64";
    }
    return "?";
}

std::optional<ScalarType> scalarTypeFromName(std::string_view name)
{
    static const std::pair<const char*, ScalarType> kNames[] = {
        {"int8", ScalarType::Int8},       {"char", ScalarType::Int8},
        {"uint8", ScalarType::UInt8},     {"uchar", ScalarType::UInt8},
        {"int16", ScalarType::Int16},     {"short", ScalarType::Int16},
        {"uint16", ScalarType::UInt16},   {"ushort", ScalarType::UInt16},
        {"int32", ScalarType::Int32},     {"int", ScalarType::Int32},
        {"uint32", ScalarType::UInt32},   {"uint", ScalarType::UInt32},
        {"float32", ScalarType::Float32}, {"float", ScalarType::Float32},
        {"float64", ScalarType::Float64}, {"double", ScalarType::Float64},
    };
    const std::string key = lower(name);
    for (const auto& [n, t] : kNames) {
        if (key == n) return t;
    }
    return std::nullopt;
}

void decodeSamples(const unsigned char* bytes, size_t count, ScalarType type, bool bigEndian,
                   float* out)
{
    const bool swap = bigEndian != kHostBigEndian;
    switch (type) {
    case ScalarType::Int8: return decodeAs<int8_t>(bytes, count, false, out);
    case ScalarType::UInt8: return decodeAs<uint8_t>(bytes, count, false, out);
    case ScalarType::Int16: return decodeAs<int16_t>(bytes, count, swap, out);
    case ScalarType::UInt16: return decodeAs<uint16_t>(bytes, count, swap, out);
    case ScalarType::Int32: return decodeAs<int32_t>(bytes, count, swap, out);
    case ScalarType::UInt32: return decodeAs<uint32_t>(bytes, count, swap, out);
    case ScalarType::Float32: return decodeAs<float>(bytes, count, swap, out);
    case ScalarType::Float64: return decodeAs<double>(bytes, count, swap, out);
    }
}

// ---------------------------------------------------------------- raw options

RawOptions parseRawOptions(std::string_view spec)
{
    RawOptions o;
    bool seen[6] = {false, false, false, false, false, false};
    static const char* kKeys[6] = {"dims", "type", "endian", "spacing", "origin", "offset"};
    for (std::string_view token : split(spec, " \t\r\n")) {
        const size_t eq = token.find('=');
        const std::string key(token.substr(0, eq));
        const std::string_view value = eq == std::string_view::npos ? std::string_view() : token.substr(eq + 1);
        const std::string where = "raw option " + std::string(token);
        int k = 0;
        while (k < 6 && key != kKeys[k]) ++k;
        if (k == 6) {
            throw InputError(where + ": unknown key '" + key +
                             "' (expected dims, type, endian, spacing, origin, offset)");
        }
        if (eq == std::string_view::npos || value.empty()) throw InputError(where + ": missing value");
        if (seen[k]) throw InputError(where + ": " + key + " is given twice");
        seen[k] = true;
        const std::vector<std::string_view> parts = split(value, ",");
        const size_t commas = size_t(std::count(value.begin(), value.end(), ','));
        if (key == "dims") {
            if (parts.size() != 3 || commas != 2) throw InputError(where + ": expected three sizes X,Y,Z");
            for (int a = 0; a < 3; ++a) {
                int64_t v = 0;
                if (!parseInt64(parts[a], v)) {
                    throw InputError(where + ": '" + std::string(parts[a]) + "' is not an integer (or overflows)");
                }
                if (v <= 0) throw InputError(where + ": sizes must be positive");
                if (v > kHeaderMaxDim) {
                    throw InputError(where + ": size " + std::to_string(v) + " is more than the limit " +
                                     std::to_string(kHeaderMaxDim));
                }
                o.dims[a] = int(v);
            }
        } else if (key == "type") {
            const auto t = scalarTypeFromName(value);
            if (!t) {
                throw InputError(where + ": unsupported type (expected int8, uint8, int16, uint16, int32, "
                                         "uint32, float32 or float64)");
            }
            o.type = scalarTypeName(*t);
        } else if (key == "endian") {
            const std::string v = lower(value);
            if (v == "little") o.bigEndian = false;
            else if (v == "big") o.bigEndian = true;
            else throw InputError(where + ": expected little or big");
        } else if (key == "spacing") {
            if (!((parts.size() == 3 && commas == 2) || (parts.size() == 1 && commas == 0))) {
                throw InputError(where + ": expected one spacing or three X,Y,Z (mm)");
            }
            for (size_t a = 0; a < parts.size(); ++a) {
                double v = 0.0;
                if (!parseFinite(parts[a], v)) {
                    throw InputError(where + ": '" + std::string(parts[a]) + "' is not a finite number");
                }
                if (v <= 0.0) throw InputError(where + ": spacing must be positive");
                o.spacing[a] = v;
            }
            if (parts.size() == 1) o.spacing = {o.spacing[0], o.spacing[0], o.spacing[0]};
        } else if (key == "origin") {
            if (parts.size() != 3 || commas != 2) throw InputError(where + ": expected three coordinates X,Y,Z (mm)");
            for (int a = 0; a < 3; ++a) {
                if (!parseFinite(parts[a], o.origin[a])) {
                    throw InputError(where + ": '" + std::string(parts[a]) + "' is not a finite number");
                }
            }
        } else { // offset
            if (!parseUInt64(value, o.headerBytes)) {
                throw InputError(where + ": expected a non-negative byte count");
            }
        }
    }
    if (!seen[0]) throw InputError("raw options: dims=X,Y,Z is missing");
    if (!seen[1]) throw InputError("raw options: type=T is missing (int8, uint8, int16, uint16, int32, uint32, float32, float64)");
    return o;
}

// ---------------------------------------------------------------- MetaImage

MetaImageHeader parseMetaImageHeader(std::string_view text, const std::string& source)
{
    MetaImageHeader h;
    size_t pos = 0;
    int lineNo = 0;
    while (pos < text.size()) {
        size_t end = text.find('\n', pos);
        const size_t next = end == std::string_view::npos ? text.size() : end + 1;
        if (end == std::string_view::npos) end = text.size();
        const std::string_view line = text.substr(pos, end - pos);
        ++lineNo;
        const std::string where = source + ": MetaImage header line " + std::to_string(lineNo);
        for (const char c : line) {
            const unsigned char u = static_cast<unsigned char>(c);
            if (u < 32 && c != '\t' && c != '\r') {
                throw InputError(where + ": binary data before the ElementDataFile line");
            }
        }
        const std::string_view content = trim(line);
        pos = next;
        if (content.empty()) continue;
        const size_t eq = content.find('=');
        if (eq == std::string_view::npos) {
            throw InputError(where + ": expected 'Key = Value'");
        }
        const std::string key(trim(content.substr(0, eq)));
        if (key.empty()) throw InputError(where + ": empty key");
        h.fields[key] = std::string(trim(content.substr(eq + 1)));
        if (lower(key) == "elementdatafile") {
            h.headerBytes = next;
            return h;
        }
    }
    throw InputError(source + ": not a MetaImage header (no ElementDataFile line)");
}

namespace {

class Fields
{
public:
    Fields(const MetaImageHeader& h, const std::string& source) : mHeader(h), mSource(source) {}

    /// The value of the first of keys present (case-insensitive), or nullptr.
    const std::string* find(std::initializer_list<const char*> keys, std::string* foundKey = nullptr) const
    {
        for (const char* k : keys) {
            const std::string lk = lower(k);
            for (const auto& [key, value] : mHeader.fields) {
                if (lower(key) == lk) {
                    if (foundKey) *foundKey = key;
                    return &value;
                }
            }
        }
        return nullptr;
    }

    std::string error(const std::string& key, const std::string& what) const
    {
        const std::string* v = find({key.c_str()});
        return mSource + ": MetaImage " + key + " = " + (v ? *v : std::string()) + ": " + what;
    }

    /// n finite numbers under one of keys; false when absent.
    bool numbers(std::initializer_list<const char*> keys, size_t n, double* out) const
    {
        std::string key;
        const std::string* v = find(keys, &key);
        if (!v) return false;
        const auto parts = split(*v, " \t");
        if (parts.size() != n) {
            throw InputError(error(key, "expected " + std::to_string(n) + " numbers"));
        }
        for (size_t a = 0; a < n; ++a) {
            if (!parseFinite(parts[a], out[a])) {
                throw InputError(error(key, "'" + std::string(parts[a]) + "' is not a finite number"));
            }
        }
        return true;
    }

    std::optional<bool> flag(std::initializer_list<const char*> keys) const
    {
        std::string key;
        const std::string* v = find(keys, &key);
        if (!v) return std::nullopt;
        const std::string l = lower(*v);
        if (l == "true" || l == "1") return true;
        if (l == "false" || l == "0") return false;
        throw InputError(error(key, "expected True or False"));
    }

private:
    const MetaImageHeader& mHeader;
    const std::string& mSource;
};

} // namespace

MetaImageInfo interpretMetaImageHeader(const MetaImageHeader& header, const std::string& source)
{
    const Fields f(header, source);
    MetaImageInfo info;

    if (const std::string* t = f.find({"ObjectType"}); t && lower(*t) != "image") {
        throw InputError(f.error("ObjectType", "only Image objects are supported"));
    }
    const std::string* ndims = f.find({"NDims"});
    if (!ndims) throw InputError(source + ": MetaImage header has no NDims");
    int64_t nd = 0;
    if (!parseInt64(*ndims, nd)) throw InputError(f.error("NDims", "not an integer"));
    if (nd != 3) throw InputError(f.error("NDims", "only 3-D images are supported"));

    const std::string* dimSize = f.find({"DimSize"});
    if (!dimSize) throw InputError(source + ": MetaImage header has no DimSize");
    {
        const auto parts = split(*dimSize, " \t");
        if (parts.size() != 3) throw InputError(f.error("DimSize", "expected 3 sizes"));
        uint64_t total = 1;
        for (int a = 0; a < 3; ++a) {
            int64_t v = 0;
            if (!parseInt64(parts[a], v)) {
                throw InputError(f.error("DimSize", "'" + std::string(parts[a]) + "' is not an integer (or overflows)"));
            }
            if (v <= 0) throw InputError(f.error("DimSize", "sizes must be positive"));
            if (v > kHeaderMaxDim) {
                throw InputError(f.error("DimSize", "size " + std::to_string(v) + " is more than the limit " +
                                                        std::to_string(kHeaderMaxDim)));
            }
            info.dims[a] = int(v);
            total *= uint64_t(v);
        }
        if (total > kHeaderMaxVoxels) {
            throw InputError(f.error("DimSize", std::to_string(total) + " voxels is more than the limit " +
                                                    std::to_string(kHeaderMaxVoxels)));
        }
    }

    const std::string* et = f.find({"ElementType"});
    if (!et) throw InputError(source + ": MetaImage header has no ElementType");
    {
        static const std::pair<const char*, ScalarType> kTypes[] = {
            {"MET_CHAR", ScalarType::Int8},     {"MET_UCHAR", ScalarType::UInt8},
            {"MET_SHORT", ScalarType::Int16},   {"MET_USHORT", ScalarType::UInt16},
            {"MET_INT", ScalarType::Int32},     {"MET_UINT", ScalarType::UInt32},
            {"MET_FLOAT", ScalarType::Float32}, {"MET_DOUBLE", ScalarType::Float64},
        };
        bool found = false;
        for (const auto& [name, type] : kTypes) {
            if (*et == name) {
                info.type = type;
                found = true;
            }
        }
        if (!found) {
            throw InputError(f.error("ElementType", "unsupported (expected MET_CHAR, MET_UCHAR, MET_SHORT, "
                                                    "MET_USHORT, MET_INT, MET_UINT, MET_FLOAT or MET_DOUBLE)"));
        }
    }
    if (const std::string* ch = f.find({"ElementNumberOfChannels"})) {
        int64_t n = 0;
        if (!parseInt64(*ch, n) || n != 1) {
            throw InputError(f.error("ElementNumberOfChannels", "only single-channel images are supported"));
        }
    }

    if (!f.numbers({"ElementSpacing"}, 3, info.spacing.data())) {
        f.numbers({"ElementSize"}, 3, info.spacing.data());
    }
    for (double s : info.spacing) {
        if (!(s > 0.0)) throw InputError(source + ": MetaImage ElementSpacing must be positive");
    }
    f.numbers({"Offset", "Position", "Origin"}, 3, info.origin.data());
    f.numbers({"TransformMatrix", "Rotation", "Orientation"}, 9, info.matrix.data());

    info.bigEndian = f.flag({"ElementByteOrderMSB", "BinaryDataByteOrderMSB"}).value_or(false);
    if (f.flag({"BinaryData"}).value_or(true) == false) {
        throw InputError(f.error("BinaryData", "ASCII data is not supported"));
    }
    info.compressed = f.flag({"CompressedData"}).value_or(false);
    if (const std::string* cs = f.find({"CompressedDataSize"})) {
        if (!parseUInt64(*cs, info.compressedBytes)) {
            throw InputError(f.error("CompressedDataSize", "expected a non-negative byte count"));
        }
    }
    if (const std::string* hs = f.find({"HeaderSize"})) {
        if (!parseInt64(*hs, info.headerSize) || info.headerSize < -1) {
            throw InputError(f.error("HeaderSize", "expected a byte count or -1"));
        }
    }

    std::string dfKey;
    const std::string* df = f.find({"ElementDataFile"}, &dfKey);
    if (!df || df->empty()) throw InputError(source + ": MetaImage header has no ElementDataFile");
    if (lower(*df) == "local") {
        info.local = true;
    } else if (lower(*df).rfind("list", 0) == 0) {
        throw InputError(f.error(dfKey, "lists of data files are not supported"));
    } else if (df->find('%') != std::string::npos) {
        throw InputError(f.error(dfKey, "numbered data file patterns are not supported"));
    } else {
        info.local = false;
        info.dataFile = *df;
    }
    return info;
}

} // namespace mtcut::vdb
