// Live pose sources and the input -> geometry thread hand-off (MTCut paper,
// section 3 and Figure 1: the haptic thread builds the "cutting information",
// the geometry thread consumes it).
//
//   LineSource (stdin, UDP on 127.0.0.1, memory)
//     -> InputThread: parsePathLine -> PathFilter -> voxelizeCut   (GLM + std)
//     -> SpscQueue<CutInfo>  (lock-free, unbounded: the producer never blocks)
//     -> geometry thread: drainCutInfo(queue, CutMask) (CutMask.h)
//
// No OpenVDB here, so tests/tsan builds this with -fsanitize=thread quickly.
//
// Ordering and loss: every quad the filter makes reaches the consumer, in
// order, exactly once; nothing is coalesced by the queue. The only poses that
// make no quad are those the path filter drops by its documented rule (same
// cell as the previous stick, BladePath.h) and malformed lines, which become
// CutInfo::Kind::Error items (the stream goes on: a live device must not stop
// the session for one bad datagram).
#pragma once

#include "cutter/BladePath.h"

#include <atomic>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace mtcut::cutter {

/// Single-producer single-consumer FIFO, unbounded and lock-free.
///
/// A linked list of fixed blocks of BlockSize slots. push() never waits:
/// when its block is full it allocates the next one (so the producer's cost
/// is O(1) amortised, plus one allocation per BlockSize items); the consumer
/// frees blocks it has emptied. Memory grows only while the consumer lags.
/// Exactly one thread may call push() and exactly one (other) thread
/// tryPop()/empty(); close()/closed() may be called from either.
template <class T, size_t BlockSize = 1024>
class SpscQueue
{
public:
    SpscQueue() : mHead(new Block), mTail(mHead) {}
    ~SpscQueue()
    {
        Block* b = mHead;
        while (b) {
            Block* n = b->next.load(std::memory_order_relaxed);
            delete b;
            b = n;
        }
    }
    SpscQueue(const SpscQueue&) = delete;
    SpscQueue& operator=(const SpscQueue&) = delete;

    /// Producer: appends v. Never blocks.
    void push(T v)
    {
        if (mWrite == BlockSize) {
            Block* b = new Block;
            mTail->next.store(b, std::memory_order_release);
            mTail = b;
            mWrite = 0;
        }
        mTail->slots[mWrite] = std::move(v);
        ++mWrite;
        mTail->written.store(mWrite, std::memory_order_release);
        mPushed.fetch_add(1, std::memory_order_relaxed);
    }

    /// Consumer: takes the oldest item into v; false when none is ready.
    bool tryPop(T& v)
    {
        while (true) {
            if (mRead < mHead->written.load(std::memory_order_acquire)) {
                v = std::move(mHead->slots[mRead]);
                ++mRead;
                return true;
            }
            if (mRead < BlockSize) return false;
            Block* n = mHead->next.load(std::memory_order_acquire);
            if (!n) return false;
            delete mHead;
            mHead = n;
            mRead = 0;
        }
    }

    /// Producer: no more items will come.
    void close() { mClosed.store(true, std::memory_order_release); }
    /// True once close() was called (items may still be queued: pop until
    /// tryPop fails after seeing closed()).
    bool closed() const { return mClosed.load(std::memory_order_acquire); }
    /// Items pushed so far (any thread; a snapshot).
    uint64_t pushedCount() const { return mPushed.load(std::memory_order_relaxed); }

private:
    struct Block
    {
        T slots[BlockSize];
        std::atomic<size_t> written{0};
        std::atomic<Block*> next{nullptr};
    };
    // Consumer side.
    Block* mHead;
    size_t mRead = 0;
    // Producer side (own cache line).
    alignas(64) Block* mTail;
    size_t mWrite = 0;
    alignas(64) std::atomic<bool> mClosed{false};
    std::atomic<uint64_t> mPushed{0};
};

/// One unit of cutting information, input thread -> geometry thread.
struct CutInfo
{
    enum class Kind : uint8_t
    {
        Quad,      ///< a new quad (and its cells, when the input thread voxelises)
        StrokeEnd, ///< the input's stroke ended (blank line / `stroke`)
        Error,     ///< a bad line or pose; `message` says which; the stream goes on
    };
    Kind kind = Kind::Quad;
    uint32_t stroke = 0;    ///< input stroke number, 0-based
    uint32_t quadIndex = 0; ///< quad number within the stroke, 0-based
    uint64_t line = 0;      ///< input line that produced it (1-based)
    double time = 0.0;      ///< pose time, s
    Quad quad;
    std::vector<glm::ivec3> cells; ///< index-space cut cells (voxelizeCut), if computed
    std::string message;
};

/// A source of text lines in the path format (PathFile.h).
class LineSource
{
public:
    virtual ~LineSource() = default;
    /// Next line into `line`; false at the end of the stream. May block
    /// (for at most about 100 ms at a time for UDP, to notice stop()).
    virtual bool next(std::string& line) = 0;
    /// Asks a blocked next() to return false soon. Any thread.
    virtual void stop() {}
    /// Name for messages ("stdin", "udp:127.0.0.1:5000", ...).
    virtual std::string name() const = 0;
};

/// Lines from a std::istream (e.g. std::cin, a pipe from a device driver).
class StreamLineSource : public LineSource
{
public:
    StreamLineSource(std::istream& in, std::string name) : mIn(in), mName(std::move(name)) {}
    bool next(std::string& line) override;
    std::string name() const override { return mName; }

private:
    std::istream& mIn;
    std::string mName;
};

/// Lines from memory (tests, benchmarks).
class MemoryLineSource : public LineSource
{
public:
    explicit MemoryLineSource(std::vector<std::string> lines) : mLines(std::move(lines)) {}
    bool next(std::string& line) override;
    std::string name() const override { return "memory"; }

private:
    std::vector<std::string> mLines;
    size_t mNext = 0;
};

/// Lines from UDP datagrams on 127.0.0.1 only (never another interface).
/// A datagram holds one or more '\n'-separated lines (at most 64 KiB); a line
/// does not span datagrams. The stream ends at a line `end` or on stop().
/// UDP may drop datagrams under load; on loopback the kernel buffer (enlarged
/// to 4 MiB where allowed) absorbs bursts far beyond 1 kHz.
class UdpLineSource : public LineSource
{
public:
    /// Binds 127.0.0.1:port (0 = any free port, see port()). Throws
    /// InputError when the port cannot be bound.
    explicit UdpLineSource(uint16_t port = 0);
    ~UdpLineSource() override;
    bool next(std::string& line) override;
    void stop() override { mStop.store(true); }
    std::string name() const override;
    uint16_t port() const { return mPort; }

private:
    int mSocket = -1;
    uint16_t mPort = 0;
    std::atomic<bool> mStop{false};
    std::vector<std::string> mPending;
    size_t mPendingNext = 0;
    std::vector<char> mBuffer;
    bool mEnded = false;
};

/// Sends `text` as one datagram to 127.0.0.1:port (tests, and a template for
/// a device driver). Throws InputError on failure.
void sendUdpLoopback(uint16_t port, const std::string& text);

/// Options of the input thread.
struct InputThreadOptions
{
    PathFilterOptions filter;
    double kerfMm = 0.0;   ///< for the voxelisation
    bool voxelize = true;  ///< compute CutInfo::cells on the input thread
};

/// The paper's haptic thread: reads lines, parses and filters poses, builds
/// quads and (optionally) their cut cells, and pushes CutInfo into queue().
/// It never waits for the consumer. Bad lines/poses become Kind::Error items.
class InputThread
{
public:
    InputThread(std::unique_ptr<LineSource> source, const IndexFrame& frame,
                const InputThreadOptions& options = {});
    /// Stops the source and joins.
    ~InputThread();
    InputThread(const InputThread&) = delete;
    InputThread& operator=(const InputThread&) = delete;

    /// Starts reading on a new thread.
    void start();
    /// Asks the source to stop; join() then returns soon.
    void stop();
    /// Waits until the source ended; the queue is closed by then.
    void join();

    SpscQueue<CutInfo>& queue() { return mQueue; }
    /// Counters, readable from any thread while running.
    uint64_t posesRead() const { return mPoses.load(std::memory_order_relaxed); }
    uint64_t sticksKept() const { return mSticks.load(std::memory_order_relaxed); }
    uint64_t quadsMade() const { return mQuads.load(std::memory_order_relaxed); }
    uint64_t errors() const { return mErrors.load(std::memory_order_relaxed); }

private:
    void run();

    std::unique_ptr<LineSource> mSource;
    IndexFrame mFrame;
    InputThreadOptions mOptions;
    SpscQueue<CutInfo> mQueue;
    std::thread mThread;
    std::atomic<uint64_t> mPoses{0}, mSticks{0}, mQuads{0}, mErrors{0};
};

} // namespace mtcut::cutter
