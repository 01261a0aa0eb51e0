#include "vdb/Phantom.h"

#include <cmath>
namespace mtcut::vdb {
DenseScan makePhantomScan(const PhantomOptions& options, Interrupter*)
{
    // Placeholder: a sphere of bone in soft tissue in air.
    DenseScan scan;
    scan.geometry.dims = options.dims;
    scan.units = "HU";
    const auto& d = options.dims;
    scan.values.resize(size_t(d[0]) * d[1] * d[2]);
    for (int k = 0; k < d[2]; ++k)
        for (int j = 0; j < d[1]; ++j)
            for (int i = 0; i < d[0]; ++i) {
                const double x = (i + 0.5) / d[0] - 0.5, y = (j + 0.5) / d[1] - 0.5, z = (k + 0.5) / d[2] - 0.5;
                const double r = std::sqrt(x * x + y * y + z * z);
                scan.values[(size_t(k) * d[1] + j) * d[0] + i] = r < 0.3 ? (r > 0.25 ? 1200.f : 40.f) : (r < 0.4 ? 40.f : -1000.f);
            }
    return scan;
}
Volume makePhantom(const PhantomOptions& options, Interrupter* interrupter)
{
    return makeVolume(makePhantomScan(options, interrupter), "phantom", {}, interrupter);
}
} // namespace mtcut::vdb
