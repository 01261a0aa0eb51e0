// Per-pass GPU times of each frame from GL timer queries, without stalling
// (DESIGN "GPU passes"; used by the viewer's overlay and bench_render).
//
// Every pass is a pair of glQueryCounter(GL_TIMESTAMP) queries, so passes
// nest (GL_TIME_ELAPSED queries cannot: one may be active per target). Each
// frame's queries live in one slot of a ring of `ringFrames` slots; a frame's
// results are read when its last query is available, which the timer polls
// (GL_QUERY_RESULT_AVAILABLE, never GL_QUERY_RESULT on a pending query) at
// beginFrame / takeResults, typically a frame or more later. When the frame
// that would reuse a slot finds it still pending, that frame is not timed
// (droppedFrames() counts them) rather than waiting for the GPU.
//
// Fallback: a context whose GL_TIMESTAMP counter has 0 bits (no timer
// queries) times passes on the CPU instead; gpuTimed() and
// FrameTimes::gpuTimed say so. CPU times are command submission times unless
// Mode::CpuFinish, which brackets each pass with glFinish (stalls; then they
// include the GPU's execution).
//
//   GpuTimer timer;
//   for (;;) {
//       timer.beginFrame();
//       { auto s = timer.scope("surface"); drawSurface(); }
//       { auto s = timer.scope("cut"); drawCut(); }
//       timer.endFrame();
//       for (const FrameTimes& f : timer.takeResults()) show(f);
//   }
//
// Needs a current GL 4.5 context for its whole life (query objects); not
// thread-safe.
#pragma once

#include "render/GlObjects.h"

#include <chrono>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace mtcut::render {

/// One pass of one frame.
struct PassTime
{
    std::string name;
    int depth = 0;      ///< nesting level: 0 for a pass opened at the top of the frame
    int parent = -1;    ///< index of the enclosing pass in FrameTimes::passes; -1 at the top
    /// Milliseconds between the pass's begin and end timestamps on the GPU
    /// (>= 0; contains the times of its nested passes). With no timer
    /// queries (FrameTimes::gpuTimed false) it equals cpuMs.
    double gpuMs = 0.0;
    /// CPU wall milliseconds between begin and end (command submission, or
    /// submission + execution with Mode::CpuFinish).
    double cpuMs = 0.0;
};

/// The timed passes of one frame, in the order they began.
struct FrameTimes
{
    uint64_t frame = 0;   ///< index of the frame (0 for the first beginFrame)
    bool gpuTimed = true; ///< false: gpuMs are CPU fallback times
    std::vector<PassTime> passes;

    /// Sum of gpuMs of the top-level (depth 0) passes.
    double topLevelGpuMs() const;
    /// The first pass named `name`, or null.
    const PassTime* find(const std::string& name) const;
};

class GpuTimer
{
public:
    enum class Mode
    {
        Auto,      ///< timestamp queries when the context has them, else Cpu
        Cpu,       ///< CPU wall time of submission only (never stalls)
        CpuFinish, ///< CPU wall time with glFinish before and after each pass (stalls)
    };

    /// A ring of `ringFrames` (>= 1) frame slots. Results of frame f are
    /// available once the GPU has passed its end; with ringFrames = 1 every
    /// frame whose predecessor is still pending at beginFrame is dropped.
    explicit GpuTimer(int ringFrames = 4, Mode mode = Mode::Auto);
    GpuTimer(const GpuTimer&) = delete;
    GpuTimer& operator=(const GpuTimer&) = delete;

    /// True when passes are timed by GPU timestamps (Auto on a context whose
    /// GL_TIMESTAMP counter has > 0 bits).
    bool gpuTimed() const { return mGpu; }
    /// Bits of the context's GL_TIMESTAMP counter (0: no timer queries).
    int timestampBits() const { return mBits; }

    /// Starts a frame: collects the results that have arrived, then claims
    /// the next slot (or marks the frame untimed when the slot is pending).
    void beginFrame();
    /// Ends the frame begun last. Passes must all be closed.
    void endFrame();

    /// Opens pass `name` (nested in the innermost open pass); returns a
    /// handle for end(). Outside beginFrame/endFrame, or in a dropped frame,
    /// it records nothing and returns -1.
    int begin(const std::string& name);
    /// Closes the pass `handle` (must be the innermost open one; -1: no-op).
    void end(int handle);

    /// Closes its pass when it goes out of scope.
    class Scope
    {
    public:
        Scope(Scope&& o) noexcept : mTimer(o.mTimer), mHandle(o.mHandle) { o.mTimer = nullptr; }
        Scope(const Scope&) = delete;
        Scope& operator=(const Scope&) = delete;
        Scope& operator=(Scope&&) = delete;
        ~Scope()
        {
            if (mTimer) mTimer->end(mHandle);
        }

    private:
        friend class GpuTimer;
        Scope(GpuTimer* timer, int handle) : mTimer(timer), mHandle(handle) {}
        GpuTimer* mTimer;
        int mHandle;
    };
    /// begin(name) now, end() when the returned Scope dies.
    [[nodiscard]] Scope scope(const std::string& name) { return Scope(this, begin(name)); }

    /// The frames whose results arrived since the last call, oldest first
    /// (polls; never waits). At most 256 are kept between calls (the oldest
    /// go first).
    std::vector<FrameTimes> takeResults();
    /// The newest frame with results (no passes before the first).
    const FrameTimes& latest() const { return mLatest; }
    /// Waits for every ended frame's results (glFinish-like stall: for the
    /// end of a benchmark or a test, not per frame).
    void finish();

    /// Frames not timed because their slot was still pending.
    uint64_t droppedFrames() const { return mDropped; }
    /// Frames begun so far.
    uint64_t frameCount() const { return mFrame; }

private:
    using Clock = std::chrono::steady_clock;
    struct OpenPass
    {
        int index;
        Clock::time_point cpuBegin;
    };
    struct Slot
    {
        std::vector<Query> queries; ///< 2 per pass: begin, end (grown as needed)
        FrameTimes times;           ///< names, nesting and CPU times; gpuMs filled when read
        bool pending = false;       ///< ended, results not read yet
    };

    void poll(bool wait);
    bool readSlot(Slot& slot, bool wait);
    void deliver(FrameTimes&& times);

    Mode mMode;
    bool mGpu = false;
    int mBits = 0;
    std::vector<Slot> mSlots;
    Slot* mCurrent = nullptr; ///< the frame being recorded (null: none, or dropped)
    bool mInFrame = false;
    std::vector<OpenPass> mOpen;
    uint64_t mFrame = 0;
    uint64_t mDropped = 0;
    std::deque<FrameTimes> mArrived;
    FrameTimes mLatest;
};

} // namespace mtcut::render
