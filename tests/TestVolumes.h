// Volumes made from implicit fields, for tests that need analytic shapes.
#pragma once

#include "vdb/Volume.h"

#include <algorithm>
#include <utility>

namespace mtcut::test {

/// A volume sampling f (world mm -> value) at voxel centres origin + ijk * spacing,
/// nothing pruned (the air threshold is below every value).
template <typename F>
vdb::Volume fieldVolume(openvdb::Coord dims, openvdb::Vec3d spacing, openvdb::Vec3d origin, F f)
{
    vdb::DenseScan scan;
    scan.geometry.dims = dims;
    scan.geometry.spacing = spacing;
    scan.geometry.origin = origin;
    scan.values.resize(size_t(dims.x()) * dims.y() * dims.z());
    float lo = 1e30f;
    size_t n = 0;
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j)
            for (int i = 0; i < dims.x(); ++i) {
                const openvdb::Vec3d p = origin + openvdb::Vec3d(i, j, k) * spacing;
                scan.values[n] = float(f(p));
                lo = std::min(lo, scan.values[n++]);
            }
    scan.units = "mm";
    vdb::SparseOptions sparse;
    sparse.airThreshold = lo - 1.0f;
    return vdb::makeVolume(std::move(scan), "field", sparse);
}

} // namespace mtcut::test
