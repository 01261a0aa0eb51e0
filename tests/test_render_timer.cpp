// render/GpuTimer: per-pass times from GL_TIMESTAMP query pairs, read a frame
// or more later without waiting, nested passes, and the CPU fallback. On
// llvmpipe the timestamps are real (the counter has 64 bits), so the GPU path
// is what runs here; on NVIDIA the same test runs unchanged.
#include "cutter/Isosurface.h"
#include "render/Camera.h"
#include "render/GpuTimer.h"
#include "render/SurfaceRenderer.h"
#include "tests/TestVolumes.h"
#include "tests/test_render_util.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>

using namespace mtcut;
using namespace mtcut::render;
using openvdb::Coord;
using openvdb::Vec3d;

namespace {

struct Scene
{
    cutter::Mesh mesh;
    std::unique_ptr<SurfaceRenderer> renderer;
    Camera camera;
};

Scene sphereScene(int size)
{
    Scene s;
    const vdb::Volume vol =
        test::fieldVolume(Coord(48), Vec3d(1.0), Vec3d(-23.5), [](const Vec3d& p) { return 18.0 - p.length(); });
    s.mesh = cutter::extractIsosurface(vol, 0.0f);
    s.renderer = std::make_unique<SurfaceRenderer>(size, size);
    s.renderer->setSurface(s.mesh);
    s.camera = cameraFor("iso", s.renderer->bounds(), 1.0);
    return s;
}

/// One frame: "frame" { "draw" { render }, "read" { readFrame } }.
void timedFrame(GpuTimer& timer, Scene& s)
{
    timer.beginFrame();
    {
        auto frame = timer.scope("frame");
        {
            auto draw = timer.scope("draw");
            s.renderer->render(s.camera, RenderStyle{});
        }
        {
            auto read = timer.scope("read");
            (void)s.renderer->readFrame();
        }
    }
    timer.endFrame();
}

void expectFrameShape(const FrameTimes& f)
{
    ASSERT_EQ(f.passes.size(), 3u);
    EXPECT_EQ(f.passes[0].name, "frame");
    EXPECT_EQ(f.passes[1].name, "draw");
    EXPECT_EQ(f.passes[2].name, "read");
    EXPECT_EQ(f.passes[0].depth, 0);
    EXPECT_EQ(f.passes[0].parent, -1);
    for (int i : {1, 2}) {
        EXPECT_EQ(f.passes[size_t(i)].depth, 1);
        EXPECT_EQ(f.passes[size_t(i)].parent, 0);
    }
    for (const PassTime& p : f.passes) {
        EXPECT_GE(p.gpuMs, 0.0) << p.name;
        EXPECT_GE(p.cpuMs, 0.0) << p.name;
    }
    // The frame's interval holds both children's (one timeline): the parent
    // is at least their sum, and not absurdly more.
    const double children = f.passes[1].gpuMs + f.passes[2].gpuMs;
    EXPECT_GE(f.passes[0].gpuMs + 1e-6, children);
    EXPECT_EQ(f.topLevelGpuMs(), f.passes[0].gpuMs);
    EXPECT_EQ(f.find("read"), &f.passes[2]);
    EXPECT_EQ(f.find("nothing"), nullptr);
}

} // namespace

TEST(RenderTimer, NestedPassesFromTimestamps)
{
    MTCUT_REQUIRE_GL();
    Scene s = sphereScene(256);
    GpuTimer timer(3);
    std::printf("GL_TIMESTAMP counter bits: %d\n", timer.timestampBits());
    if (!timer.gpuTimed()) GTEST_SKIP() << "no timer queries on this context (the CPU fallback is tested below)";
    const int frames = 12;
    std::vector<FrameTimes> got;
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < frames; ++i) {
        timedFrame(timer, s);
        for (FrameTimes& f : timer.takeResults()) got.push_back(std::move(f));
    }
    timer.finish();
    const double wallMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    for (FrameTimes& f : timer.takeResults()) got.push_back(std::move(f));
    // readFrame() synchronises with the GPU, so no slot is ever pending for
    // long: every frame arrives, in order.
    EXPECT_EQ(timer.droppedFrames(), 0u);
    ASSERT_EQ(got.size(), size_t(frames));
    double drawSum = 0.0, frameSum = 0.0;
    for (size_t i = 0; i < got.size(); ++i) {
        EXPECT_EQ(got[i].frame, i);
        EXPECT_TRUE(got[i].gpuTimed);
        expectFrameShape(got[i]);
        drawSum += got[i].passes[1].gpuMs;
        frameSum += got[i].passes[0].gpuMs;
    }
    // The frames' GPU intervals follow one another in command order, all
    // between the first submission and finish(): they fit in the wall time.
    // (A single frame's GPU interval need not lie inside its CPU scope: its
    // end timestamp is written when the GPU reaches it, after the scope.)
    EXPECT_LE(frameSum, wallMs + 1.0);
    std::printf("means over %d frames: frame %.3f ms, draw %.3f ms (GPU timestamps)\n", frames,
                frameSum / frames, drawSum / frames);
    // A 256x256 frame of a 10k-triangle sphere takes measurable time.
    EXPECT_GT(drawSum, 0.0);
    EXPECT_EQ(timer.latest().frame, uint64_t(frames - 1));
}

// Frames issued without any read-back: the timer never waits. With a ring of
// 2 the frames whose slot is still pending are dropped; every other frame
// arrives (after finish()), in order.
TEST(RenderTimer, NeverWaitsAndDropsFramesWhoseSlotIsPending)
{
    MTCUT_REQUIRE_GL();
    Scene s = sphereScene(512);
    GpuTimer timer(2);
    if (!timer.gpuTimed()) GTEST_SKIP() << "no timer queries on this context";
    const int frames = 20;
    std::vector<FrameTimes> got;
    for (int i = 0; i < frames; ++i) {
        timer.beginFrame();
        {
            auto draw = timer.scope("draw");
            s.renderer->render(s.camera, RenderStyle{});
        }
        timer.endFrame();
        for (FrameTimes& f : timer.takeResults()) got.push_back(std::move(f));
    }
    timer.finish();
    for (FrameTimes& f : timer.takeResults()) got.push_back(std::move(f));
    std::printf("%d frames without read-back, ring of 2: %zu timed, %llu dropped\n", frames, got.size(),
                (unsigned long long)timer.droppedFrames());
    EXPECT_EQ(got.size() + timer.droppedFrames(), size_t(frames));
    EXPECT_GE(got.size(), 2u);
    for (size_t i = 1; i < got.size(); ++i) EXPECT_LT(got[i - 1].frame, got[i].frame);
    for (const FrameTimes& f : got) {
        ASSERT_EQ(f.passes.size(), 1u);
        EXPECT_GE(f.passes[0].gpuMs, 0.0);
    }
}

TEST(RenderTimer, CpuFallback)
{
    MTCUT_REQUIRE_GL();
    Scene s = sphereScene(256);
    for (GpuTimer::Mode mode : {GpuTimer::Mode::Cpu, GpuTimer::Mode::CpuFinish}) {
        GpuTimer timer(3, mode);
        EXPECT_FALSE(timer.gpuTimed());
        timedFrame(timer, s);
        // CPU times are final at endFrame: delivered at once, no finish().
        const std::vector<FrameTimes> got = timer.takeResults();
        ASSERT_EQ(got.size(), 1u);
        EXPECT_FALSE(got[0].gpuTimed);
        expectFrameShape(got[0]);
        for (const PassTime& p : got[0].passes) EXPECT_EQ(p.gpuMs, p.cpuMs);
    }
}

TEST(RenderTimer, PassesOutsideAFrameRecordNothing)
{
    MTCUT_REQUIRE_GL();
    GpuTimer timer;
    EXPECT_EQ(timer.begin("outside"), -1);
    timer.end(-1);
    timer.beginFrame();
    timer.endFrame(); // a frame without passes
    timer.finish();
    const std::vector<FrameTimes> got = timer.takeResults();
    ASSERT_EQ(got.size(), 1u);
    EXPECT_TRUE(got[0].passes.empty());
}
