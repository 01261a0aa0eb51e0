// 10^6 poses through the input thread -> geometry thread hand-off, under
// ThreadSanitizer (tests/tsan/run.sh). Checks order, no loss, and that the
// consumer sees exactly what a single-threaded run of the same filter makes.
// Exit 0 on success; TSan aborts with a report on any data race.
#include "cutter/PathFile.h"
#include "cutter/PoseStream.h"

#include <chrono>
#include <cstdio>
#include <thread>

using namespace mtcut::cutter;

namespace {

int failures = 0;
#define CHECK(cond)                                                                                \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            std::fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);          \
            ++failures;                                                                            \
        }                                                                                          \
    } while (0)

void rawQueue()
{
    SpscQueue<uint64_t, 256> q;
    constexpr uint64_t kCount = 1'000'000;
    std::thread producer([&] {
        for (uint64_t i = 0; i < kCount; ++i) q.push(i);
        q.close();
    });
    uint64_t next = 0;
    bool ordered = true;
    while (true) {
        const bool closed = q.closed();
        uint64_t v;
        while (q.tryPop(v)) ordered &= (v == next++);
        if (closed) break;
    }
    producer.join();
    CHECK(ordered);
    CHECK(next == kCount);
}

void inputToGeometry()
{
    IndexFrame f;
    f.dims = glm::ivec3(400, 400, 100);
    f.spacing = glm::dvec3(0.5, 0.5, 1.0);
    constexpr int kStrokes = 100, kSteps = 10'000; // 10^6 poses
    const auto strokes = makeRandomStrokes(f, 5, kStrokes, kSteps, 0.4, 2.0);
    std::vector<std::string> lines;
    lines.reserve(size_t(kStrokes) * kSteps + kStrokes);
    for (const auto& s : strokes) {
        for (const Pose& p : s) lines.push_back(formatPoseLine(p));
        lines.push_back("stroke");
    }
    // Reference: the same filter on one thread.
    size_t expectedQuads = 0;
    for (const auto& s : strokes) expectedQuads += filterStroke(s, f).size();

    InputThreadOptions opt;
    opt.kerfMm = 0.5;
    InputThread input(std::make_unique<MemoryLineSource>(std::move(lines)), f, opt);
    size_t quads = 0, cells = 0, strokeEnds = 0, errors = 0;
    bool ordered = true;
    std::thread geometry([&] {
        uint32_t stroke = 0, nextQuad = 0;
        uint64_t lastLine = 0;
        CutInfo info;
        int batches = 0;
        while (true) {
            const bool closed = input.queue().closed();
            while (input.queue().tryPop(info)) {
                ordered &= info.line >= lastLine;
                lastLine = info.line;
                if (info.kind == CutInfo::Kind::Quad) {
                    ordered &= info.stroke == stroke && info.quadIndex == nextQuad;
                    ++nextQuad;
                    ++quads;
                    cells += info.cells.size();
                } else if (info.kind == CutInfo::Kind::StrokeEnd) {
                    ordered &= info.stroke == stroke;
                    ++stroke;
                    nextQuad = 0;
                    ++strokeEnds;
                } else {
                    ++errors;
                }
            }
            if (closed) break;
            // A busy geometry thread: a "frame" of work now and then.
            if (++batches % 16 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
    });
    const auto t0 = std::chrono::steady_clock::now();
    input.start();
    // Read the counters from a third thread while it runs (they are atomics).
    uint64_t seen = 0;
    while (seen < uint64_t(kStrokes) * kSteps && input.quadsMade() <= expectedQuads) {
        seen = input.posesRead();
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    input.join();
    geometry.join();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    CHECK(ordered);
    CHECK(errors == 0);
    CHECK(strokeEnds == size_t(kStrokes));
    CHECK(input.posesRead() == uint64_t(kStrokes) * kSteps);
    CHECK(quads == expectedQuads);
    CHECK(quads == input.quadsMade());
    std::printf("tsan_handoff: %llu poses, %zu quads, %zu cells in %.1f s (%.0f poses/s under TSan)\n",
                (unsigned long long)input.posesRead(), quads, cells, s, input.posesRead() / s);
}

} // namespace

int main()
{
    rawQueue();
    inputToGeometry();
    if (failures) std::fprintf(stderr, "tsan_handoff: %d check(s) failed\n", failures);
    else std::printf("tsan_handoff: OK\n");
    return failures ? 1 : 0;
}
