// Hand-written parsers of untrusted text: raw-data options and MetaImage
// headers, and the decoding of binary samples they describe. Kept free of
// OpenVDB so the libFuzzer targets build in seconds (tests/fuzz). Every
// failure is an InputError naming the key or line.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace mtcut::vdb {

/// Scalar sample types the readers decode (64-bit integers, complex and
/// multi-channel data are not supported).
enum class ScalarType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

/// Bytes per sample: 1, 2, 4 or 8.
size_t scalarSize(ScalarType type);
/// "int8" "uint8" "int16" "uint16" "int32" "uint32" "float32" "float64".
const char* scalarTypeName(ScalarType type);
/// The type named by scalarTypeName(), or the C-like aliases char, uchar,
/// short, ushort, int, uint, float, double; nullopt otherwise.
std::optional<ScalarType> scalarTypeFromName(std::string_view name);

/// Converts count samples of type from bytes (unaligned, byte-swapped when
/// bigEndian differs from the host) to float. Exact for integers up to 2^24;
/// NaN and Inf pass through (makeVolume rejects them). Cost: one pass.
void decodeSamples(const unsigned char* bytes, size_t count, ScalarType type, bool bigEndian,
                   float* out);

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
/// dims (three positive integers) and type (a scalarTypeFromName() name,
/// stored canonical) are required; spacing (one or three positive numbers),
/// origin (three finite numbers), endian (little|big) and offset (bytes, a
/// non-negative integer) are optional. Throws InputError naming the key and
/// value on an unknown or repeated key, a malformed, overflowing, negative or
/// non-finite number, or trailing junk.
RawOptions parseRawOptions(std::string_view spec);

/// MetaImage header keys (key -> value, keys as written).
struct MetaImageHeader
{
    std::map<std::string, std::string> fields;
    uint64_t headerBytes = 0; ///< bytes up to and including the ElementDataFile line
};

/// Parses a MetaImage header (.mha / .mhd text up to ElementDataFile): lines
/// "Key = Value", blank lines skipped, the last ElementDataFile line ends it.
/// text may run on into binary data (an attached .mha); only the header part
/// is read. Throws InputError naming source and line on a line without '=',
/// an empty key, a control byte in the header, or no ElementDataFile line.
MetaImageHeader parseMetaImageHeader(std::string_view text, const std::string& source);

/// What a MetaImage header says, checked (see interpretMetaImageHeader).
struct MetaImageInfo
{
    std::array<int, 3> dims{0, 0, 0};             ///< DimSize, each in [1, 2^16]
    ScalarType type = ScalarType::UInt8;          ///< ElementType
    std::array<double, 3> spacing{1.0, 1.0, 1.0}; ///< ElementSpacing (or ElementSize), mm
    std::array<double, 3> origin{0.0, 0.0, 0.0};  ///< Offset / Position / Origin, LPS mm
    /// TransformMatrix / Rotation / Orientation as written: direction of file
    /// axis a (LPS) = (matrix[3a], matrix[3a+1], matrix[3a+2]).
    std::array<double, 9> matrix{1, 0, 0, 0, 1, 0, 0, 0, 1};
    bool bigEndian = false;            ///< ElementByteOrderMSB / BinaryDataByteOrderMSB
    bool compressed = false;           ///< CompressedData (zlib or gzip stream)
    uint64_t compressedBytes = 0;      ///< CompressedDataSize; 0 when not given
    int64_t headerSize = 0;            ///< HeaderSize: bytes to skip in the data file; -1 = data at the end
    bool local = true;                 ///< ElementDataFile = LOCAL (data follows the header)
    std::string dataFile;              ///< the data file as written, when not LOCAL
    uint64_t voxelCount() const { return uint64_t(dims[0]) * uint64_t(dims[1]) * uint64_t(dims[2]); }
    uint64_t dataBytes() const { return voxelCount() * scalarSize(type); }
};

/// Interprets and checks the fields: NDims 3, DimSize positive and within
/// 2^16 per axis and 2^32 voxels, a supported ElementType, one channel,
/// finite positive spacing, finite origin and matrix, a single data file
/// (LIST and numbered file patterns are not supported). Throws InputError
/// naming source and the key. No I/O.
MetaImageInfo interpretMetaImageHeader(const MetaImageHeader& header, const std::string& source);

} // namespace mtcut::vdb
