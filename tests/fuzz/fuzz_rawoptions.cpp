// libFuzzer: raw-data option strings -> parseRawOptions. InputError is the
// expected answer to bad input; the result of a successful parse must be valid.
#include "vdb/Error.h"
#include "vdb/HeaderParsers.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    using namespace mtcut::vdb;
    try {
        const RawOptions o = parseRawOptions(std::string_view(reinterpret_cast<const char*>(data), size));
        if (!o.valid() || !scalarTypeFromName(o.type)) __builtin_trap();
        for (int a = 0; a < 3; ++a) {
            if (o.dims[a] <= 0 || !(o.spacing[a] > 0.0) || !std::isfinite(o.spacing[a]) ||
                !std::isfinite(o.origin[a])) {
                __builtin_trap();
            }
        }
    } catch (const mtcut::InputError&) {
    }
    return 0;
}
