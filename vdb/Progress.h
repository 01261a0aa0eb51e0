// Progress and cancellation for long work. We use OpenVDB's interrupter
// interface as it is, so the same object drives our readers, our meshing and
// OpenVDB's own tools (volumeToMesh, meshToVolume, ...).
#pragma once

#include "vdb/Error.h"

#include <openvdb/util/NullInterrupter.h>

namespace mtcut {

/// start(name) / wasInterrupted(percent) / end(). wasInterrupted must be
/// thread-safe: it is polled from worker threads, once per batch of work.
using Interrupter = openvdb::util::NullInterrupter;

/// Report progress (0..100, or -1 for "still alive") and throw Cancelled
/// when the interrupter asks to stop. Null interrupter: no-op.
inline void pollInterrupter(Interrupter* interrupter, int percent = -1)
{
    if (interrupter && interrupter->wasInterrupted(percent)) throw Cancelled();
}

/// Calls start() on construction and end() on destruction (also on throw).
class InterrupterScope
{
public:
    InterrupterScope(Interrupter* interrupter, const char* name) : mInterrupter(interrupter)
    {
        if (mInterrupter) mInterrupter->start(name);
    }
    ~InterrupterScope()
    {
        if (mInterrupter) mInterrupter->end();
    }
    InterrupterScope(const InterrupterScope&) = delete;
    InterrupterScope& operator=(const InterrupterScope&) = delete;

private:
    Interrupter* mInterrupter;
};

} // namespace mtcut
