// Small helpers shared by the benchmark programs: wall-clock milliseconds,
// the median of repeated timings, and FNV-1a hashes of results.
#pragma once

#include "cutter/Mesh.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
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

/// FNV-1a over raw bytes, chained through `h`.
inline uint64_t fnv(uint64_t h, const void* data, size_t bytes)
{
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}
template <class T> inline uint64_t fnvVec(uint64_t h, const std::vector<T>& v)
{
    const uint64_t n = v.size();
    h = fnv(h, &n, sizeof n);
    return v.empty() ? h : fnv(h, v.data(), v.size() * sizeof(T));
}
inline constexpr uint64_t kFnvSeed = 1469598103934665603ull;
/// FNV-1a over the mesh's arrays, each with its size: positions, normals,
/// indices, triangle voxels (bench_cut --hash, bench_strokes' mesh=).
inline uint64_t meshHash(const cutter::Mesh& m, uint64_t h = kFnvSeed)
{
    h = fnvVec(h, m.positions);
    h = fnvVec(h, m.normals);
    h = fnvVec(h, m.indices);
    return fnvVec(h, m.triangleVoxels);
}
} // namespace mtcut::bench
