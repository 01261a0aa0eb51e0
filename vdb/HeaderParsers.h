// Hand-written parsers of untrusted text: raw-data options and MetaImage
// headers. Kept free of OpenVDB so the libFuzzer targets build in seconds
// (tests/fuzz). Every failure is an InputError naming the key or line.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>

namespace mtcut::vdb {

/// Layout of a headerless raw file (all but dims and type have defaults).
struct RawOptions
{
    std::array<int, 3> dims{0, 0, 0};
    /// int8 uint8 int16 uint16 int32 uint32 float32 float64
    std::string type;
    bool bigEndian = false;
    std::array<double, 3> spacing{1.0, 1.0, 1.0}; ///< mm
    std::array<double, 3> origin{0.0, 0.0, 0.0};  ///< mm, centre of voxel (0,0,0)
    uint64_t headerBytes = 0;                     ///< bytes to skip at the start of the file
    bool valid() const { return dims[0] > 0 && !type.empty(); }
};

/// Parses raw options written as whitespace-separated key=value pairs:
/// "dims=512,512,245 type=int16 endian=little spacing=1,1,1 origin=0,0,0 offset=0".
/// dims and type are required. Throws InputError naming the key and value.
RawOptions parseRawOptions(std::string_view spec);

/// MetaImage header keys (key -> value, keys as written).
struct MetaImageHeader
{
    std::map<std::string, std::string> fields;
    uint64_t headerBytes = 0; ///< bytes up to and including the ElementDataFile line
};

/// Parses a MetaImage header (.mha / .mhd text up to ElementDataFile).
/// Throws InputError naming source and line on malformed input.
MetaImageHeader parseMetaImageHeader(std::string_view text, const std::string& source);

} // namespace mtcut::vdb
