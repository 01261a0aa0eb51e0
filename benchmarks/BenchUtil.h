// Small helpers shared by the benchmark programs: wall-clock milliseconds
// and the median of repeated timings.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

namespace mtcut::bench {

using Clock = std::chrono::steady_clock;

/// Wall milliseconds since t0.
inline double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

/// The median of `v` (the mean of the middle two for an even count); NaN when empty.
inline double median(std::vector<double> v)
{
    if (v.empty()) return std::nan("");
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

} // namespace mtcut::bench
