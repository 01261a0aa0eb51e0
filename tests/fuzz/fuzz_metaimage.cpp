// libFuzzer: MetaImage header text -> parseMetaImageHeader -> interpretMetaImageHeader,
// then the sample decoder on the bytes after the header. InputError is the
// expected answer to bad input; anything else (crash, UB, other exception) is a bug.
#include "vdb/Error.h"
#include "vdb/HeaderParsers.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    using namespace mtcut::vdb;
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    try {
        const MetaImageHeader header = parseMetaImageHeader(text, "fuzz.mha");
        if (header.headerBytes > size) __builtin_trap();
        const MetaImageInfo info = interpretMetaImageHeader(header, "fuzz.mha");
        if (info.voxelCount() == 0 || info.voxelCount() > (uint64_t(1) << 32)) __builtin_trap();
        // Decode what data follows (at most the voxels the header describes).
        const size_t bpv = scalarSize(info.type);
        const size_t available = (size - size_t(header.headerBytes)) / bpv;
        const size_t count = size_t(std::min<uint64_t>(available, info.voxelCount()));
        std::vector<float> out(count);
        decodeSamples(data + header.headerBytes, count, info.type, info.bigEndian, out.data());
    } catch (const mtcut::InputError&) {
    }
    return 0;
}
