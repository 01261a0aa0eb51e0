// A procedural CT-head phantom in HU: the built-in default input and the large
// benchmark volume.
#pragma once

#include "vdb/Volume.h"

#include <cstdint>

namespace mtcut::vdb {

struct PhantomOptions
{
    openvdb::Coord dims{512, 512, 256}; ///< grid size; the head's size in mm is fixed
    uint32_t seed = 1;                  ///< noise seed; same seed, same volume
};

/// The phantom as a dense scan (HU). Deterministic from (dims, seed),
/// whatever the thread count. Parallel; polls interrupter.
DenseScan makePhantomScan(const PhantomOptions& options, Interrupter* interrupter = nullptr);

/// makePhantomScan, made sparse; source "phantom".
Volume makePhantom(const PhantomOptions& options, Interrupter* interrupter = nullptr);

} // namespace mtcut::vdb
