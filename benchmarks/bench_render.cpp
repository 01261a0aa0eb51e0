// GPU passes: per-pass GPU times (render/GpuTimer: GL_TIMESTAMP query pairs)
// and frames per second for the MTCut paper's Table 1 cases, against
// re-uploading the whole fused mesh every frame, in the same run.
//
// Volumes (the paper's sizes): crops of the CT-head phantom of 64x64x22,
// 256x256x40, 512x512x40, 512x512x100 and 256x256x196 voxels, and the real
// 512x512x245 VHM head (../shared/data/vhm-head-dicom, iso 400 HU; skipped
// when absent). A crop keeps the phantom's voxel size (512 in-plane: the
// 512x512x256 phantom, 0.47 x 0.47 x 1 mm; 256 and 64: the 256x256x256
// phantom, 0.94 x 0.94 x 1 mm), its slices centred on the LeFort I plane; the
// 64x64 crop is centred on the maxilla. Each volume uncut, then with cuts of
// about 419 / 3,638 / 11,716 cut cells (benchmarks/BenchCuts.h: the strokes of
// bench_cut, at the LeFort plane; on the head at 0.32 of its height; zero kerf).
//
// Per frame (1024x768 default, camera "iso" framing the surface; every frame
// ends with glFinish, so frame times are wall times of finished frames):
//   ours:     "mask"    GPU mask coding: MaskAtlas built for the cut cells
//                       and one point per cell drawn into it (OR logic-op);
//             "upload"  the cut geometry uploaded (setCutGeometry);
//             "draw"    the uncut isosurface (uploaded once) with the discard
//                       pass, then the cut geometry.
//             In these rows the cut geometry comes from the CPU re-mesher
//             (the GPU cut pass is timed apart, --gpu-cut), so the paper's step 3
//             is "CPU remesh + upload" here: remesh_ms (CutRemesher::update
//             of the whole cut from scratch, one thread) + cutgeom_ms
//             (cutGeometryOf) + the upload pass. frame_ms excludes the CPU
//             remesh (an interactive cut re-meshes only the changed cells,
//             see bench_cut); fps_remesh includes it (the paper re-generates
//             every cut voxel each frame).
//   split:    the same draw with the cut geometry emptied: "discard" (steps 1
//             and 2 of the paper: isosurface with the cut cells discarded);
//             cutdraw_ms = draw - discard.
//   baseline: the fused mesh (CutRemesher::fusedMesh, built once outside the
//             timing: fused_ms) uploaded whole ("upload": setSurface) and
//             drawn without discard ("draw"), every frame.
//   uncut:    the surface alone ("draw"), the paper's "fps original"; its
//             baseline re-uploads the uncut mesh every frame.
// Times are medians over --frames frames (after one warm-up frame). With no
// timer queries (GL_TIMESTAMP with 0 bits) the pass times are CPU times and
// the line says gpu_timed=0.
//
// Usage: bench_render [--quick] [--frames N] [--size WxH] [--egl-device]
//                     [--cpu-passes] [--targets N,N,...] [--gpu-cut [LANES]]
//                     [--volumes a,b,...] [--head PATH]
//   --quick: the 64x64x22 and 256x256x40 crops, uncut and the 419-cell cut,
//            3 frames (about 40 s on llvmpipe on a loaded 2-core machine).
//   --egl-device: EGL_PLATFORM=device (the NVIDIA EGL device platform); the
//            default already prefers a hardware EGL device, then Mesa's
//            surfaceless platform.
//   --cpu-passes: pass times are CPU wall times with glFinish before and
//            after each pass (GpuTimer::Mode::CpuFinish; gpu_timed=0), for
//            comparing with the timestamps (on llvmpipe a timestamp is taken
//            when a rasterizer thread reaches it in its tile, so they are
//            rough there).
//   --gpu-cut [LANES]: also the GPU cut pass (render/CutKernelGpu.h) per
//            cut: gen_ms, the whole cut made by it (its staged draws and the
//            records read back), recover_ms, that and pass 4 (each cell
//            finished on the CPU, the flagged ones re-meshed there), and
//            frames that draw its own output (glDrawArraysIndirect):
//            "case=gpucut" lines. One tet per LANES vertex-shader
//            invocations (default 8 on llvmpipe, its SIMD width, 1 else).
//   --volumes: names among 64x64x22, 256x256x40, 512x512x40, 512x512x100,
//            256x256x196, head.
//   --head PATH: read the VHM head from PATH (any format readVolume takes,
//            e.g. a .vdb written by `mtcut convert` from the DICOM series)
//            instead of ../shared/data/vhm-head-dicom.
// One parseable line per case ("case=render ..."), then a Markdown table.
#include "benchmarks/BenchCuts.h"
#include "benchmarks/BenchUtil.h"
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/KernelInput.h"
#include "cutter/Remesh.h"
#include "render/Camera.h"
#include "render/Context.h"
#include "render/CutGeometry.h"
#include "render/CutKernelGpu.h"
#include "render/GpuTimer.h"
#include "render/MaskTiling.h"
#include "render/SurfaceRenderer.h"
#include "vdb/Phantom.h"
#include "vdb/VolumeIO.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

using namespace mtcut;
using bench::Clock;
using bench::median;
using bench::msSince;
using openvdb::Coord;

namespace {

struct Options
{
    int frames = 7;
    /// --cpu-passes: pass times from glFinish-bracketed CPU wall time
    /// (GpuTimer::Mode::CpuFinish) instead of timestamps.
    bool cpuPasses = false;
    int width = 1024, height = 768;
    std::vector<size_t> targets{419, 3638, 11716};
    /// --gpu-cut: the GPU cut pass (pass 3) too, one tet per `lanes`
    /// vertex-shader invocations.
    const render::GpuCutKernel* gpuCut = nullptr;
    size_t lanes = 1;
};

/// Per-pass medians over the frames of one loop, and the frame wall time.
struct LoopTimes
{
    std::map<std::string, double> passMs; ///< median per pass name
    double frameMs = 0.0;                 ///< median wall time of a finished frame
    bool gpuTimed = true;
    double pass(const std::string& name) const
    {
        auto it = passMs.find(name);
        return it == passMs.end() ? 0.0 : it->second;
    }
};

/// Runs `frame` (which opens its passes on the timer) frames + 1 times, the
/// first as warm-up; glFinish ends each frame.
template <typename F>
LoopTimes timeLoop(const Options& o, F&& frame)
{
    const int frames = o.frames;
    render::GpuTimer timer(4, o.cpuPasses ? render::GpuTimer::Mode::CpuFinish : render::GpuTimer::Mode::Auto);
    std::vector<double> wall;
    std::map<std::string, std::vector<double>> passes;
    for (int i = 0; i <= frames; ++i) {
        const auto t0 = Clock::now();
        timer.beginFrame();
        frame(timer);
        timer.endFrame();
        glFinish();
        if (i > 0) wall.push_back(msSince(t0));
    }
    timer.finish();
    LoopTimes out;
    out.gpuTimed = timer.gpuTimed();
    for (const render::FrameTimes& f : timer.takeResults()) {
        if (f.frame == 0) continue; // warm-up
        for (const render::PassTime& p : f.passes) passes[p.name].push_back(p.gpuMs);
    }
    for (auto& [name, v] : passes) out.passMs[name] = median(v);
    out.frameMs = median(wall);
    return out;
}

struct Row
{
    std::string volume;
    std::string dims;
    size_t uncutTris = 0;
    size_t target = 0, cells = 0, cutTris = 0, capTris = 0, fusedTris = 0;
    int variant = -1, refused = 0;
    double remeshMs = 0, cutgeomMs = 0, tilingMs = 0, fusedMs = 0;
    double maskMs = 0, uploadMs = 0, drawMs = 0, discardMs = 0, frameMs = 0;
    double baseUploadMs = 0, baseDrawMs = 0, baseFrameMs = 0;
    // --gpu-cut: the whole cut made by the GPU cut pass (its staged draws,
    // records read back), then recovered (+ the CPU's finish, flagged
    // cells by the CPU kernel); frames drawing its own output.
    double gpuGenMs = -1, gpuRecoverMs = 0, gpuDrawMs = 0, gpuFrameMs = 0;
    size_t gpuTris = 0, gpuCpuCells = 0;
    bool gpuTimed = true, ok = true;
    std::string note;
    double fps() const { return 1e3 / frameMs; }
    double fpsRemesh() const { return 1e3 / (frameMs + remeshMs + cutgeomMs); }
    double baseFps() const { return 1e3 / baseFrameMs; }
};

void printRow(const Row& r, const Options& o)
{
    if (!r.ok) {
        std::printf("case=render volume=%s dims=%s target=%zu refused=%d note=\"%s\"\n", r.volume.c_str(), r.dims.c_str(),
                    r.target, r.refused, r.note.c_str());
        std::fflush(stdout);
        return;
    }
    std::printf("case=render volume=%s dims=%s size=%dx%d uncut_tris=%zu target=%zu cut_cells=%zu cut_tris=%zu cap_tris=%zu "
                "fused_tris=%zu variant=%d refused=%d remesh_ms=%.2f cutgeom_ms=%.2f tiling_ms=%.2f fused_ms=%.1f "
                "mask_ms=%.3f upload_ms=%.3f draw_ms=%.2f discard_ms=%.2f cutdraw_ms=%.2f frame_ms=%.2f fps=%.2f "
                "fps_remesh=%.2f base_upload_ms=%.2f base_draw_ms=%.2f base_frame_ms=%.2f base_fps=%.2f speedup=%.2f "
                "gpu_timed=%d frames=%d\n",
                r.volume.c_str(), r.dims.c_str(), o.width, o.height, r.uncutTris, r.target, r.cells, r.cutTris, r.capTris,
                r.fusedTris, r.variant, r.refused, r.remeshMs, r.cutgeomMs, r.tilingMs, r.fusedMs, r.maskMs, r.uploadMs,
                r.drawMs, r.discardMs, r.drawMs - r.discardMs, r.frameMs, r.fps(), r.fpsRemesh(), r.baseUploadMs,
                r.baseDrawMs, r.baseFrameMs, r.baseFps(), r.baseFrameMs / r.frameMs, r.gpuTimed ? 1 : 0, o.frames);
    if (r.gpuGenMs >= 0)
        std::printf("case=gpucut volume=%s dims=%s target=%zu cut_cells=%zu lanes=%zu gen_ms=%.1f recover_ms=%.1f "
                    "gpu_tris=%zu cpu_tris=%zu cells_by_cpu=%zu draw_ms=%.2f frame_ms=%.2f fps=%.2f\n",
                    r.volume.c_str(), r.dims.c_str(), r.target, r.cells, o.lanes, r.gpuGenMs, r.gpuRecoverMs, r.gpuTris,
                    r.cutTris, r.gpuCpuCells, r.gpuDrawMs, r.gpuFrameMs, 1e3 / r.gpuFrameMs);
    std::fflush(stdout);
}

struct VolumeSpec
{
    std::string name;          ///< "512x512x40", "head"
    Coord dims;                ///< crop size (head: whole)
    int sourceXY = 512;        ///< in-plane size of the phantom it is cropped from
    bool head = false;
};

/// `dims` voxels of the phantom `src` (dense, canonical order): slices centred
/// on slice `zc`, columns centred on (xc, yc); clamped into the source.
vdb::Volume cropOf(const vdb::DenseScan& src, const Coord& dims, int xc, int yc, int zc, const std::string& name)
{
    const Coord sd = src.geometry.dims;
    const Coord lo(std::clamp(xc - dims.x() / 2, 0, sd.x() - dims.x()), std::clamp(yc - dims.y() / 2, 0, sd.y() - dims.y()),
                   std::clamp(zc - dims.z() / 2, 0, sd.z() - dims.z()));
    vdb::DenseScan crop;
    crop.geometry = src.geometry;
    crop.geometry.dims = dims;
    for (int a = 0; a < 3; ++a) crop.geometry.origin[a] = src.geometry.origin[a] + src.geometry.spacing[a] * lo[a];
    crop.units = src.units;
    crop.values.resize(size_t(dims.x()) * size_t(dims.y()) * size_t(dims.z()));
    size_t n = 0;
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j) {
            const size_t row = (size_t(lo.z() + k) * size_t(sd.y()) + size_t(lo.y() + j)) * size_t(sd.x()) + size_t(lo.x());
            std::copy_n(src.values.begin() + long(row), size_t(dims.x()), crop.values.begin() + long(n));
            n += size_t(dims.x());
        }
    return vdb::makeVolume(std::move(crop), name);
}

void runVolume(const std::string& name, const vdb::Volume& vol, double planeIndexZ, const Options& o,
               std::vector<Row>& rows)
{
    const float iso = 400.0f;
    const auto d = vol.dims;
    const std::string dims = std::to_string(d.x()) + "x" + std::to_string(d.y()) + "x" + std::to_string(d.z());
    cutter::Mesh uncut;
    {
        tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
        const auto t0 = Clock::now();
        uncut = cutter::extractIsosurface(vol, iso);
        std::printf("volume=%s dims=%s spacing=%.4g,%.4g,%.4g iso=%g uncut_tris=%zu extract_ms=%.0f\n", name.c_str(),
                    dims.c_str(), vol.spacing()[0], vol.spacing()[1], vol.spacing()[2], double(iso), uncut.triangleCount(),
                    msSince(t0));
        std::fflush(stdout);
    }
    if (uncut.empty()) return;
    const cutter::Mesh empty;
    render::SurfaceRenderer ours(o.width, o.height), base(o.width, o.height);
    ours.setSurface(uncut);
    const render::Camera camera = render::cameraFor("iso", ours.bounds(), double(o.width) / o.height);
    const render::RenderStyle style;
    // The baseline: upload the whole (fused) mesh every frame, then draw it.
    auto timeBaseline = [&](const cutter::Mesh& mesh, Row& r) {
        const LoopTimes b = timeLoop(o, [&](render::GpuTimer& timer) {
            {
                auto s = timer.scope("upload");
                base.setSurface(mesh);
            }
            auto s = timer.scope("draw");
            base.render(camera, style);
        });
        r.baseUploadMs = b.pass("upload");
        r.baseDrawMs = b.pass("draw");
        r.baseFrameMs = b.frameMs;
    };

    // -- uncut ------------------------------------------------------------------
    {
        Row r;
        r.volume = name;
        r.dims = dims;
        r.uncutTris = r.fusedTris = uncut.triangleCount();
        const LoopTimes t = timeLoop(o, [&](render::GpuTimer& timer) {
            auto s = timer.scope("draw");
            ours.render(camera, style);
        });
        r.drawMs = r.discardMs = t.pass("draw");
        r.frameMs = t.frameMs;
        r.gpuTimed = t.gpuTimed;
        timeBaseline(uncut, r);
        printRow(r, o);
        rows.push_back(r);
    }

    // -- cuts -------------------------------------------------------------------
    bench::CutScene scene;
    scene.name = name;
    scene.vol = &vol;
    scene.iso = iso;
    scene.uncut = &uncut;
    try {
        bench::locateCutPlane(scene, planeIndexZ);
    } catch (const std::exception& e) {
        std::printf("volume=%s: %s; no cuts\n", name.c_str(), e.what());
        return;
    }
    for (size_t target : o.targets) {
        Row r;
        r.volume = name;
        r.dims = dims;
        r.uncutTris = uncut.triangleCount();
        r.target = target;
        bench::SizedCut cut;
        {
            tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
            cut = bench::chooseCut(scene, target, 0.0, [&](int variant, const std::string& why) {
                std::printf("  %s target %zu: stroke variant %d (%s) refused: %s\n", name.c_str(), target, variant,
                            bench::strokeKindName(variant), why.c_str());
            });
        }
        r.refused = cut.refused;
        if (!cut.ok) {
            r.ok = false;
            r.note = cut.note;
            printRow(r, o);
            rows.push_back(r);
            continue;
        }
        r.variant = cut.variant;
        r.cells = cut.cells;
        r.remeshMs = cut.remeshMs;
        auto t0 = Clock::now();
        const render::CutGeometry geometry = render::cutGeometryOf(*cut.remesher, vol, iso);
        r.cutgeomMs = msSince(t0);
        r.cutTris = geometry.mesh.triangleCount();
        for (uint8_t c : geometry.triangleIsCap) r.capTris += c;
        t0 = Clock::now();
        const render::MaskTiling tiling = render::tileMask(render::remeshedCellGrid(*cut.remesher)->tree());
        r.tilingMs = msSince(t0);
        t0 = Clock::now();
        const cutter::Mesh fused = cut.remesher->fusedMesh();
        r.fusedMs = msSince(t0);
        r.fusedTris = fused.triangleCount();

        const LoopTimes t = timeLoop(o, [&](render::GpuTimer& timer) {
            {
                auto s = timer.scope("mask");
                ours.setCutCells(tiling, true);
            }
            {
                auto s = timer.scope("upload");
                ours.setCutGeometry(geometry.mesh, {}, geometry.triangleIsCap);
            }
            auto s = timer.scope("draw");
            ours.render(camera, style);
        });
        r.maskMs = t.pass("mask");
        r.uploadMs = t.pass("upload");
        r.drawMs = t.pass("draw");
        r.frameMs = t.frameMs;
        r.gpuTimed = t.gpuTimed;
        ours.setCutGeometry(empty);
        const LoopTimes split = timeLoop(o, [&](render::GpuTimer& timer) {
            auto s = timer.scope("discard");
            ours.render(camera, style);
        });
        r.discardMs = split.pass("discard");
        if (o.gpuCut) {
            std::vector<Coord> cells;
            for (const auto& entry : cut.remesher->cells()) cells.push_back(entry.first);
            auto draw = std::make_shared<render::GpuCutDraw>(2 * r.cutTris + 4096);
            const cutter::PackedKernelInput input = cutter::packKernelInput(vol, iso, *cut.mask, cells);
            glFinish();
            t0 = Clock::now();
            o.gpuCut->cutCells(input, o.lanes, draw.get());
            glFinish();
            r.gpuGenMs = msSince(t0);
            t0 = Clock::now();
            const render::RecoveredCells rec = render::recoverCutCells(*o.gpuCut, vol, iso, *cut.mask, cells, o.lanes, draw.get());
            glFinish();
            r.gpuRecoverMs = msSince(t0);
            r.gpuTris = draw->triangleCount();
            r.gpuCpuCells = rec.byCpu;
            ours.setCutCells(tiling, true);
            ours.setGpuCutGeometry(draw);
            const LoopTimes g = timeLoop(o, [&](render::GpuTimer& timer) {
                auto s = timer.scope("draw");
                ours.render(camera, style);
            });
            r.gpuDrawMs = g.pass("draw");
            r.gpuFrameMs = g.frameMs;
        }
        ours.clearCut();
        timeBaseline(fused, r);
        printRow(r, o);
        rows.push_back(r);
    }
}

void printTable(const std::vector<Row>& rows)
{
    std::printf("\n| volume | uncut tris | cut cells (target) | cut tris | CPU remesh + cutGeometryOf ms | mask GPU ms | "
                "upload GPU ms | draw GPU ms (discard / cut) | frame ms | fps | fps incl. CPU remesh | re-upload: upload / draw GPU ms | "
                "re-upload frame ms | re-upload fps | speedup |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Row& r : rows) {
        if (!r.ok) {
            std::printf("| %s %s | %zu | (%zu) refused: %s | | | | | | | | | | | | |\n", r.volume.c_str(), r.dims.c_str(),
                        r.uncutTris, r.target, r.note.c_str());
            continue;
        }
        if (r.target == 0) {
            std::printf("| %s %s | %zu | uncut | | | | | %.2f | %.1f | %.1f | | %.2f / %.2f | %.1f | %.1f | %.2fx |\n",
                        r.volume.c_str(), r.dims.c_str(), r.uncutTris, r.drawMs, r.frameMs, r.fps(), r.baseUploadMs,
                        r.baseDrawMs, r.baseFrameMs, r.baseFps(), r.baseFrameMs / r.frameMs);
            continue;
        }
        std::printf("| %s %s | %zu | %zu (%zu) | %zu | %.1f + %.1f | %.3f | %.3f | %.2f (%.2f / %.2f) | %.1f | %.1f | %.1f | "
                    "%.2f / %.2f | %.1f | %.1f | %.2fx |\n",
                    r.volume.c_str(), r.dims.c_str(), r.uncutTris, r.cells, r.target, r.cutTris, r.remeshMs, r.cutgeomMs,
                    r.maskMs, r.uploadMs, r.drawMs, r.discardMs, r.drawMs - r.discardMs, r.frameMs, r.fps(), r.fpsRemesh(),
                    r.baseUploadMs, r.baseDrawMs, r.baseFrameMs, r.baseFps(), r.baseFrameMs / r.frameMs);
    }
}

std::vector<std::string> split(const std::string& s)
{
    std::vector<std::string> out;
    std::stringstream ss(s);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(item);
    return out;
}

} // namespace

int main(int argc, char** argv)
{
    Options o;
    bool quick = false, framesGiven = false, targetsGiven = false, gpuCut = false;
    size_t lanes = 0; // --gpu-cut's: 8 on llvmpipe (its SIMD width; cut_arrange.vert), else 1
    std::vector<std::string> names;
    std::string headPath = std::string(MTCUT_SHARED_DATA) + "/vhm-head-dicom";
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--quick")) {
            quick = true;
        } else if (!std::strcmp(argv[i], "--frames") && i + 1 < argc) {
            o.frames = std::max(1, std::atoi(argv[++i]));
            framesGiven = true;
        } else if (!std::strcmp(argv[i], "--size") && i + 1 < argc) {
            if (std::sscanf(argv[++i], "%dx%d", &o.width, &o.height) != 2) {
                std::fprintf(stderr, "bench_render: --size WxH, e.g. 1024x768\n");
                return 2;
            }
        } else if (!std::strcmp(argv[i], "--gpu-cut")) {
            gpuCut = true;
            if (i + 1 < argc && std::isdigit(static_cast<unsigned char>(argv[i + 1][0])))
                lanes = size_t(std::max(1, std::atoi(argv[++i])));
        } else if (!std::strcmp(argv[i], "--cpu-passes")) {
            o.cpuPasses = true;
        } else if (!std::strcmp(argv[i], "--egl-device")) {
            setenv("EGL_PLATFORM", "device", 1);
        } else if (!std::strcmp(argv[i], "--targets") && i + 1 < argc) {
            o.targets.clear();
            for (const std::string& t : split(argv[++i])) o.targets.push_back(size_t(std::atol(t.c_str())));
            targetsGiven = true;
        } else if (!std::strcmp(argv[i], "--volumes") && i + 1 < argc) {
            names = split(argv[++i]);
        } else if (!std::strcmp(argv[i], "--head") && i + 1 < argc) {
            headPath = argv[++i];
        } else {
            std::fprintf(stderr, "usage: bench_render [--quick] [--frames N] [--size WxH] [--egl-device] [--cpu-passes] "
                                 "[--targets N,N,...] [--gpu-cut [LANES]] [--volumes 64x64x22,256x256x40,512x512x40,512x512x100,256x256x196,head] [--head PATH]\n");
            return 2;
        }
    }
    const std::vector<VolumeSpec> all = {
        {"64x64x22", Coord(64, 64, 22), 256, false},     {"256x256x40", Coord(256, 256, 40), 256, false},
        {"512x512x40", Coord(512, 512, 40), 512, false}, {"512x512x100", Coord(512, 512, 100), 512, false},
        {"256x256x196", Coord(256, 256, 196), 256, false}, {"head", Coord(512, 512, 245), 512, true}};
    if (names.empty()) {
        names = quick ? std::vector<std::string>{"64x64x22", "256x256x40"}
                      : std::vector<std::string>{"64x64x22", "256x256x40", "512x512x40", "512x512x100", "256x256x196", "head"};
    }
    if (quick && !framesGiven) o.frames = 3;
    if (quick && !targetsGiven) o.targets = {419};
    openvdb::initialize();
    std::vector<Row> rows;
    try {
        const std::unique_ptr<render::GlContext> context = render::createHeadlessContext();
        std::printf("device=\"%s\" size=%dx%d frames=%d\n", context->description().c_str(), o.width, o.height, o.frames);
        std::fflush(stdout);
        std::unique_ptr<render::GpuCutKernel> gpuKernel;
        if (gpuCut) {
            const auto t0 = Clock::now();
            gpuKernel = std::make_unique<render::GpuCutKernel>();
            const bool llvmpipe = context->description().find("llvmpipe") != std::string::npos;
            o.lanes = lanes ? lanes : llvmpipe ? 8 : 1;
            o.gpuCut = gpuKernel.get();
            std::printf("gpu_cut: shaders built in %.0f ms, one tet per %zu lanes\n", msSince(t0), o.lanes);
            std::fflush(stdout);
        }
        std::map<int, vdb::DenseScan> phantoms; // by in-plane size
        const vdb::PhantomLandmarks marks = vdb::phantomLandmarks();
        for (const std::string& name : names) {
            auto spec = std::find_if(all.begin(), all.end(), [&](const VolumeSpec& s) { return s.name == name; });
            if (spec == all.end()) throw std::runtime_error("unknown volume " + name);
            if (spec->head) {
                const std::string& path = headPath;
                if (!std::filesystem::exists(path)) {
                    std::printf("case=render volume=vhm-head skipped: %s not found\n", path.c_str());
                    continue;
                }
                const vdb::Volume vol = vdb::readVolume(path);
                runVolume("vhm-head", vol, 0.32 * double(vol.dims.z() - 1), o, rows);
                continue;
            }
            auto it = phantoms.find(spec->sourceXY);
            if (it == phantoms.end()) {
                phantoms.clear(); // one dense phantom at a time (268 MB at 512)
                vdb::PhantomOptions po;
                po.dims = Coord(spec->sourceXY, spec->sourceXY, 256);
                it = phantoms.emplace(spec->sourceXY, vdb::makePhantomScan(po)).first;
            }
            const vdb::DenseScan& src = it->second;
            auto toIndex = [&](int a, double w) { return int(std::lround((w - src.geometry.origin[a]) / src.geometry.spacing[a])); };
            const int zc = toIndex(2, marks.leFortZ);
            const bool small = spec->dims.x() < spec->sourceXY;
            const int xc = small ? toIndex(0, marks.maxillaBone[0]) : spec->sourceXY / 2;
            const int yc = small ? toIndex(1, marks.maxillaBone[1]) : spec->sourceXY / 2;
            const std::string vname = "phantom-" + spec->name;
            const vdb::Volume vol = cropOf(src, spec->dims, xc, yc, zc, vname);
            const double zLo = (vol.origin()[2] - src.geometry.origin[2]) / src.geometry.spacing[2];
            runVolume(vname, vol, double(zc) - zLo, o, rows);
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_render: %s\n", e.what());
        return 1;
    }
    printTable(rows);
    return 0;
}
