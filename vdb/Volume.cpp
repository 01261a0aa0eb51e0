#include "vdb/Volume.h"

#include <openvdb/math/Maps.h>
#include <openvdb/tools/Dense.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <sstream>

namespace mtcut::vdb {

using openvdb::Coord;
using openvdb::Vec3d;

namespace {

std::string str(const Vec3d& v)
{
    std::ostringstream os;
    os << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
    return os.str();
}

/// Canonical index c (world axis order) -> file linear index:
/// base + c.x*step[0] + c.y*step[1] + c.z*step[2].
struct Orientation
{
    Coord dims;         ///< canonical dims
    Vec3d spacing;      ///< canonical spacing
    Vec3d origin;       ///< world of canonical voxel (0,0,0)
    int64_t base = 0;
    int64_t step[3] = {0, 0, 0};
};

Orientation canonicalOrientation(const VolumeGeometry& g, const std::string& source)
{
    constexpr double kTol = 1e-3;
    const int64_t stride[3] = {1, int64_t(g.dims[0]), int64_t(g.dims[0]) * g.dims[1]};
    Orientation o;
    o.origin = g.origin;
    bool used[3] = {false, false, false};
    for (int a = 0; a < 3; ++a) {
        Vec3d col(g.direction(0, a), g.direction(1, a), g.direction(2, a));
        const double len = col.length();
        col /= len;
        int w = 0;
        for (int c = 1; c < 3; ++c) if (std::abs(col[c]) > std::abs(col[w])) w = c;
        for (int c = 0; c < 3; ++c) {
            if (c != w && std::abs(col[c]) > kTol) {
                throw InputError(source + ": oblique orientation is not supported (file axis " +
                                 std::string(1, "ijk"[a]) + " points along " + str(col) +
                                 "); resample it to an axis-aligned grid first");
            }
        }
        if (used[w]) {
            throw InputError(source + ": degenerate orientation (two file axes point along world " +
                             std::string(1, "xyz"[w]) + ")");
        }
        used[w] = true;
        const bool flip = col[w] < 0.0;
        o.dims[w] = g.dims[a];
        o.spacing[w] = g.spacing[a];
        if (flip) {
            o.base += int64_t(g.dims[a] - 1) * stride[a];
            o.step[w] = -stride[a];
            // Canonical voxel 0 along w is the file's last voxel along a.
            o.origin[w] -= g.spacing[a] * double(g.dims[a] - 1);
        } else {
            o.step[w] = stride[a];
        }
    }
    return o;
}

} // namespace

void checkDims(const Coord& dims, const std::string& source)
{
    for (int a = 0; a < 3; ++a) {
        if (dims[a] <= 0) {
            throw InputError(source + ": size along " + std::string(1, "xyz"[a]) + " is " +
                             std::to_string(dims[a]) + " voxels, must be positive");
        }
        if (dims[a] > kMaxDim) {
            throw InputError(source + ": size along " + std::string(1, "xyz"[a]) + " is " +
                             std::to_string(dims[a]) + " voxels, more than the limit " +
                             std::to_string(kMaxDim));
        }
    }
    const uint64_t n = uint64_t(dims[0]) * uint64_t(dims[1]) * uint64_t(dims[2]);
    if (n > kMaxVoxels) {
        throw InputError(source + ": " + std::to_string(dims[0]) + " x " + std::to_string(dims[1]) +
                         " x " + std::to_string(dims[2]) + " = " + std::to_string(n) +
                         " voxels is more than the limit " + std::to_string(kMaxVoxels));
    }
}

void checkGeometry(const VolumeGeometry& g, const std::string& source)
{
    checkDims(g.dims, source);
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(g.spacing[a]) || g.spacing[a] <= 0.0) {
            throw InputError(source + ": spacing " + str(g.spacing) + " mm must be finite and positive");
        }
        if (!std::isfinite(g.origin[a])) {
            throw InputError(source + ": origin " + str(g.origin) + " is not finite");
        }
        const Vec3d col(g.direction(0, a), g.direction(1, a), g.direction(2, a));
        if (!std::isfinite(col.x()) || !std::isfinite(col.y()) || !std::isfinite(col.z()) ||
            col.length() < 1e-6) {
            throw InputError(source + ": direction of axis " + std::string(1, "ijk"[a]) + " " +
                             str(col) + " is not a valid direction");
        }
    }
}

Volume makeVolume(DenseScan&& scan, const std::string& source, const SparseOptions& options,
                  Interrupter* interrupter)
{
    InterrupterScope scope(interrupter, "building sparse grid");
    const VolumeGeometry& g = scan.geometry;
    checkGeometry(g, source);
    const uint64_t n = uint64_t(g.dims[0]) * uint64_t(g.dims[1]) * uint64_t(g.dims[2]);
    if (scan.values.size() != n) {
        throw InputError(source + ": holds " + std::to_string(scan.values.size()) +
                         " values, expected " + std::to_string(n));
    }
    const float* data = scan.values.data();

    // Range and the first non-finite value, in one parallel pass.
    struct Range
    {
        float lo = std::numeric_limits<float>::max();
        float hi = std::numeric_limits<float>::lowest();
        uint64_t firstBad = std::numeric_limits<uint64_t>::max();
    };
    const Range range = tbb::parallel_reduce(
        tbb::blocked_range<uint64_t>(0, n, 1 << 16), Range(),
        [&](const tbb::blocked_range<uint64_t>& r, Range acc) {
            for (uint64_t i = r.begin(); i != r.end(); ++i) {
                const float v = data[i];
                if (!std::isfinite(v)) {
                    acc.firstBad = std::min(acc.firstBad, i);
                    continue;
                }
                acc.lo = std::min(acc.lo, v);
                acc.hi = std::max(acc.hi, v);
            }
            return acc;
        },
        [](Range a, const Range& b) {
            a.lo = std::min(a.lo, b.lo);
            a.hi = std::max(a.hi, b.hi);
            a.firstBad = std::min(a.firstBad, b.firstBad);
            return a;
        });
    if (range.firstBad != std::numeric_limits<uint64_t>::max()) {
        const uint64_t i = range.firstBad % g.dims[0];
        const uint64_t j = (range.firstBad / g.dims[0]) % g.dims[1];
        const uint64_t k = range.firstBad / (uint64_t(g.dims[0]) * g.dims[1]);
        throw InputError(source + ": voxel (" + std::to_string(i) + ", " + std::to_string(j) + ", " +
                         std::to_string(k) + ") is " +
                         (std::isnan(data[range.firstBad]) ? "NaN" : "infinite") +
                         "; the volume must hold finite values");
    }
    pollInterrupter(interrupter, 5);

    Volume vol;
    vol.source = source;
    vol.minValue = range.lo;
    vol.maxValue = range.hi;
    vol.units = scan.units;
    if (vol.units.empty() && range.lo >= -3100.0f && range.lo <= -900.0f) vol.units = "HU";
    if (options.airThreshold) {
        vol.airThreshold = *options.airThreshold;
    } else if (vol.units == "HU") {
        vol.airThreshold = std::max(-500.0f, range.lo);
    } else {
        vol.airThreshold = range.lo + 0.02f * (range.hi - range.lo);
    }

    const Orientation o = canonicalOrientation(g, source);
    vol.dims = o.dims;

    using LeafT = openvdb::FloatTree::LeafNodeType;
    const float background = range.lo;
    const float air = vol.airThreshold;
    const Coord nb((o.dims[0] + 7) / 8, (o.dims[1] + 7) / 8, (o.dims[2] + 7) / 8);
    const auto blockIndex = [&](int bx, int by, int bz) {
        return (size_t(bz) * nb[1] + by) * nb[0] + bx;
    };
    const auto fileIndex = [&](int x, int y, int z) {
        return o.base + x * o.step[0] + y * o.step[1] + z * o.step[2];
    };

    // Pass 1: which 8^3 blocks hold tissue (a value above the air threshold).
    std::vector<uint8_t> tissue(size_t(nb[0]) * nb[1] * nb[2], 0);
    std::atomic<bool> cancelled{false};
    tbb::parallel_for(tbb::blocked_range<int>(0, nb[2]), [&](const tbb::blocked_range<int>& r) {
        for (int bz = r.begin(); bz != r.end(); ++bz) {
            if (cancelled || (interrupter && interrupter->wasInterrupted(5 + 45 * bz / nb[2]))) {
                cancelled = true;
                return;
            }
            for (int by = 0; by < nb[1]; ++by) {
                for (int bx = 0; bx < nb[0]; ++bx) {
                    bool found = false;
                    for (int z = bz * 8; z < std::min(bz * 8 + 8, o.dims[2]) && !found; ++z)
                        for (int y = by * 8; y < std::min(by * 8 + 8, o.dims[1]) && !found; ++y)
                            for (int x = bx * 8; x < std::min(bx * 8 + 8, o.dims[0]); ++x)
                                if (data[fileIndex(x, y, z)] > air) { found = true; break; }
                    tissue[blockIndex(bx, by, bz)] = found;
                }
            }
        }
    });
    if (cancelled) throw Cancelled();

    // Pass 2: a leaf for every block that holds or touches tissue, exact values.
    tbb::enumerable_thread_specific<std::vector<LeafT*>> leavesPerThread;
    tbb::parallel_for(tbb::blocked_range<int>(0, nb[2]), [&](const tbb::blocked_range<int>& r) {
        auto& leaves = leavesPerThread.local();
        for (int bz = r.begin(); bz != r.end(); ++bz) {
            if (cancelled || (interrupter && interrupter->wasInterrupted(50 + 45 * bz / nb[2]))) {
                cancelled = true;
                return;
            }
            for (int by = 0; by < nb[1]; ++by) {
                for (int bx = 0; bx < nb[0]; ++bx) {
                    bool keep = false;
                    for (int dz = -1; dz <= 1 && !keep; ++dz)
                        for (int dy = -1; dy <= 1 && !keep; ++dy)
                            for (int dx = -1; dx <= 1 && !keep; ++dx) {
                                const int x = bx + dx, y = by + dy, z = bz + dz;
                                if (x < 0 || y < 0 || z < 0 || x >= nb[0] || y >= nb[1] || z >= nb[2]) continue;
                                keep = tissue[blockIndex(x, y, z)];
                            }
                    if (!keep) continue;
                    auto* leaf = new LeafT(Coord(bx * 8, by * 8, bz * 8), background, false);
                    for (int z = bz * 8; z < std::min(bz * 8 + 8, o.dims[2]); ++z)
                        for (int y = by * 8; y < std::min(by * 8 + 8, o.dims[1]); ++y)
                            for (int x = bx * 8; x < std::min(bx * 8 + 8, o.dims[0]); ++x) {
                                const float v = data[fileIndex(x, y, z)];
                                const auto offset = LeafT::coordToOffset(Coord(x, y, z));
                                if (v > air) leaf->setValueOn(offset, v);
                                else leaf->setValueOff(offset, v);
                            }
                    leaves.push_back(leaf);
                }
            }
        }
    });
    if (cancelled) {
        for (auto& leaves : leavesPerThread)
            for (LeafT* leaf : leaves) delete leaf;
        throw Cancelled();
    }

    vol.grid = openvdb::FloatGrid::create(background);
    for (auto& leaves : leavesPerThread)
        for (LeafT* leaf : leaves) vol.grid->tree().addLeaf(leaf);
    scan.values = std::vector<float>(); // release the dense copy early

    vol.grid->setTransform(openvdb::math::Transform::Ptr(new openvdb::math::Transform(
        std::make_shared<openvdb::math::ScaleTranslateMap>(o.spacing, o.origin))));
    vol.grid->setName("density");
    pollInterrupter(interrupter, 100);
    return vol;
}

DenseScan toDense(const Volume& volume)
{
    DenseScan scan;
    scan.geometry.dims = volume.dims;
    scan.geometry.spacing = volume.spacing();
    scan.geometry.origin = volume.origin();
    scan.units = volume.units;
    scan.values.assign(volume.voxelCount(), volume.grid->background());
    // LayoutXYZ: x changes fastest, as in our scans.
    openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(volume.indexBox(),
                                                                   scan.values.data());
    openvdb::tools::copyToDense(*volume.grid, dense);
    return scan;
}

VolumeStats computeStats(const Volume& volume)
{
    VolumeStats stats;
    stats.activeVoxels = volume.grid->activeVoxelCount();
    stats.memoryBytes = volume.grid->memUsage();
    stats.denseBytes = volume.voxelCount() * sizeof(float);

    // Otsu's threshold over the active voxels' histogram.
    constexpr int kBins = 1024;
    const float lo = volume.airThreshold, hi = volume.maxValue;
    if (!(hi > lo)) {
        stats.suggestedBoneIso = hi;
        return stats;
    }
    const double scale = kBins / double(hi - lo);
    std::vector<double> hist(kBins, 0.0);
    for (auto it = volume.grid->cbeginValueOn(); it; ++it) {
        const int bin = std::clamp(int((double(*it) - lo) * scale), 0, kBins - 1);
        hist[bin] += double(it.getVoxelCount());
    }
    double total = 0.0, sumAll = 0.0;
    for (int b = 0; b < kBins; ++b) {
        total += hist[b];
        sumAll += b * hist[b];
    }
    double w0 = 0.0, sum0 = 0.0, bestVar = -1.0;
    int best = kBins / 2;
    for (int b = 0; b < kBins; ++b) {
        w0 += hist[b];
        sum0 += b * hist[b];
        const double w1 = total - w0;
        if (w0 <= 0.0 || w1 <= 0.0) continue;
        const double m0 = sum0 / w0, m1 = (sumAll - sum0) / w1;
        const double var = w0 * w1 * (m0 - m1) * (m0 - m1);
        if (var > bestVar) {
            bestVar = var;
            best = b;
        }
    }
    float iso = lo + float((best + 1) / scale);
    if (volume.units == "HU") iso = std::clamp(iso, 150.0f, 700.0f);
    stats.suggestedBoneIso = iso;
    return stats;
}

} // namespace mtcut::vdb
