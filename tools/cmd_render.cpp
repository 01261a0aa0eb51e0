// mtcut render: a frame of a scan's isosurface, optionally cut along a blade
// path, drawn headless on the GPU (EGL; Mesa llvmpipe without one): the uncut
// surface with the cut cells discarded by the GPU-coded mask, plus the cut
// cells' geometry (the CPU re-mesher's; with --gpu-cut, the GPU cut pass's
// own output, recovered and checked against the CPU's).
// PNG for people; EXR with RGBA, Z, N.X/N.Y/N.Z and fragment channels.
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/PathFile.h"
#include "cutter/Remesh.h"
#include "render/Camera.h"
#include "render/Context.h"
#include "render/CutGeometry.h"
#include "render/CutKernelGpu.h"
#include "render/MaskTiling.h"
#include "render/Shaders.h"
#include "render/SurfaceRenderer.h"
#include "tools/Cli.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>

#include <unistd.h>

namespace mtcut::cli {

namespace {

using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

constexpr long long kMaxImageSide = 8192;

double secondsSince(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

int imageSide(const Args& args, const char* name, long long fallback)
{
    const long long v = args.getInt(name, fallback);
    if (v < 1 || v > kMaxImageSide) {
        throw InputError(std::string("--") + name + " " + args.get(name) + ": expected an integer in [1, " +
                         std::to_string(kMaxImageSide) + "]");
    }
    return int(v);
}

std::string lowerExtension(const std::string& path)
{
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

int runRender(const Args& args)
{
    // -- arguments: everything checked before the long work --------------------
    const float iso = args.isoValue("render");
    if (!args.has("output")) throw InputError("mtcut render needs -o OUT.png or -o OUT.exr");
    const std::string pathFile = args.get("path");
    const double kerf = args.kerfMm();
    if (args.has("kerf") && pathFile.empty()) throw InputError("--kerf needs --path (there is no cut without a path)");
    const cutter::PathFilterOptions filterOptions = args.pathFilterOptions();
    for (const char* option : {"retrace", "slide"})
        if (args.has(option) && pathFile.empty())
            throw InputError(std::string("--") + option + " needs --path (there is no cut without a path)");
    const int width = imageSide(args, "width", 1024);
    const int height = imageSide(args, "height", 1024);
    const std::string view = args.get("view", "front");
    // The view's syntax, checked now on a unit box (the real bounds come later).
    (void)render::cameraFor(view, render::Bounds{glm::dvec3(-1.0), glm::dvec3(1.0)}, double(width) / height);
    const std::string out = args.get("output");
    const std::string ext = lowerExtension(out);
    if (ext != ".png" && ext != ".exr") throw InputError("-o " + out + ": expected a .png or .exr file name");
    {
        const fs::path parent = fs::path(out).has_parent_path() ? fs::path(out).parent_path() : fs::path(".");
        std::error_code ec;
        if (!fs::is_directory(parent, ec)) throw InputError("-o " + out + ": folder " + parent.string() + " does not exist");
        if (::access(parent.c_str(), W_OK) != 0) throw InputError("-o " + out + ": folder " + parent.string() + " is not writable");
        if (fs::is_directory(out, ec)) throw InputError("-o " + out + ": is a folder");
    }
    std::vector<std::vector<cutter::Pose>> strokes;
    if (!pathFile.empty()) strokes = readStrokes(pathFile);

    // -- the GL context first: no point reading a scan we cannot draw -----------
    auto t0 = Clock::now();
    const std::unique_ptr<render::GlContext> context = render::createHeadlessContext();

    const vdb::Volume vol = readInput(args.positional[0], args);
    const double readSeconds = secondsSince(t0);

    t0 = Clock::now();
    const cutter::Mesh uncut = extractSurface(vol, iso);
    if (uncut.empty()) throw InputError("no surface at iso " + args.get("iso") + ": nothing to render");

    // -- the cut (CPU re-mesher) ---------------------------------------------------
    render::SurfaceRenderer renderer(width, height);
    size_t cutCells = 0, fragments = 0, cutTriangles = 0;
    std::vector<RefusedStroke> refused; // --keep-going
    std::vector<size_t> stepped;        // --keep-going: strokes that stepped round a refusal
    std::string gpuCutLine;             // --gpu-cut
    if (strokes.empty()) {
        if (args.has("gpu-cut"))
            std::fprintf(stderr, "mtcut: --gpu-cut: no cut (no --path given), nothing for the GPU cut pass to make\n");
        const std::vector<uint32_t> ids = render::fragmentIdsOf(uncut);
        fragments = ids.empty() ? 0 : *std::max_element(ids.begin(), ids.end());
        renderer.setSurface(uncut, ids);
    } else {
        const cutter::IndexFrame frame = cutter::frameOf(vol);
        cutter::CutMask mask(frame, kerf);
        addStrokes(mask, strokes, filterOptions);
        try {
            cutter::CutRemesher remesher(vol, iso, uncut);
            if (const std::string why = refusalOf(remesher, mask); !why.empty()) {
                if (!args.has("keep-going")) throw InputError(describeRefusalWithHint(why, frame, kerf, false));
                std::fprintf(stderr, "mtcut: the re-mesher refused the cut; --keep-going: cutting stroke by stroke\n");
                mask = cutter::CutMask(frame, kerf);
                cutStrokeByStroke(remesher, mask, strokes, filterOptions, refused, &stepped);
            }
            std::vector<uint32_t> source;
            const cutter::Mesh fused = remesher.fusedMesh(&source);
            const render::CutGeometry cut = render::cutGeometryOf(remesher, vol, iso);
            std::vector<uint32_t> uncutIds, cutIds;
            render::discardFragmentIds(remesher, fused, source, uncutIds, cutIds);
            for (uint32_t id : uncutIds) fragments = std::max<size_t>(fragments, id);
            for (uint32_t id : cutIds) fragments = std::max<size_t>(fragments, id);
            renderer.setSurface(uncut, uncutIds);
            renderer.setCutCells(render::tileMask(render::remeshedCellGrid(remesher)->tree()));
            renderer.setCutGeometry(cut.mesh, cutIds, cut.triangleIsCap);
            cutCells = mask.cutCellCount();
            cutTriangles = cut.mesh.triangleCount();
            if (args.has("gpu-cut")) {
                // The GPU cut pass makes the cut geometry again and draws its
                // own output; recovered, each cell is checked against the CPU's.
                std::vector<openvdb::Coord> cells;
                for (const auto& entry : remesher.cells()) cells.push_back(entry.first);
                const auto g0 = Clock::now();
                // Its programs are large (the exact kernel on doubles): quick
                // on Mesa, but an NVIDIA 580 driver took up to 3 minutes for
                // one (benchmarks/RESULTS.md) the first time, then they come
                // from the program cache; so say what is going on.
                std::fprintf(stderr, "mtcut: --gpu-cut: building the GPU cut pass's shaders\n");
                const size_t cachedBefore = render::programCacheCounts().loaded;
                const render::GpuCutKernel gpu;
                const size_t cached = render::programCacheCounts().loaded - cachedBefore;
                // The first draws of a process then take the driver's own
                // compile (RESULTS: NVIDIA 28-58 s, then kept in its shader
                // disk cache; llvmpipe minutes after a shader change, then
                // kept in Mesa's disk cache).
                std::fprintf(stderr,
                             "mtcut: --gpu-cut: shaders built in %.1f s (%zu of 5 from the program cache); "
                             "making the cut geometry of %zu cells (a driver compiles the programs' code at their "
                             "first draw: up to a minute, or minutes on Mesa after a change)\n",
                             secondsSince(g0), cached, cells.size());
                auto draw = std::make_shared<render::GpuCutDraw>(2 * cutTriangles + 4096);
                const render::RecoveredCells rec = render::recoverCutCells(gpu, vol, iso, mask, cells, 1, draw.get());
                size_t differ = 0;
                for (size_t i = 0; i < cells.size(); ++i) {
                    const cutter::CutCellGeometry& want = remesher.cells().at(cells[i]);
                    differ += rec.cells[i].vertexIds != want.vertexIds || rec.cells[i].indices != want.indices ||
                              rec.cells[i].indexPositions != want.indexPositions;
                }
                draw->setFragmentIds(render::gpuCutFragmentIds(*draw, rec, cells, remesher, cutIds));
                renderer.setGpuCutGeometry(draw);
                // Pass 4: the recovered cells fused as the CPU's are (the
                // re-mesher taking them instead of running its kernel).
                std::map<openvdb::Coord, const cutter::CutCellGeometry*> recovered;
                for (size_t i = 0; i < cells.size(); ++i) recovered[cells[i]] = &rec.cells[i];
                cutter::CutRemesher fromGpu(vol, iso, uncut);
                fromGpu.setCellSource([&](const openvdb::Coord& c, cutter::CutCellGeometry& geometry) {
                    const auto it = recovered.find(c);
                    if (it == recovered.end()) return false;
                    geometry = *it->second;
                    return true;
                });
                fromGpu.update(mask);
                const cutter::Mesh fusedGpu = fromGpu.fusedMesh();
                const bool sameFused = fusedGpu.positions == fused.positions && fusedGpu.indices == fused.indices;
                char line[384];
                std::snprintf(line, sizeof line,
                              "%zu triangles drawn from the GPU's output; %zu cells made by the GPU, %zu by the CPU; "
                              "recovered geometry %s; fused: %zu triangles, %s; %.2f s",
                              draw->triangleCount(), rec.byGpu, rec.byCpu,
                              differ ? ("differs from the CPU's in " + std::to_string(differ) + " cells").c_str()
                                     : "equal to the CPU's in every cell",
                              fusedGpu.triangleCount(), sameFused ? "the CPU's mesh" : "NOT the CPU's mesh",
                              secondsSince(g0));
                gpuCutLine = line;
                if (differ || !sameFused) throw std::logic_error("mtcut render --gpu-cut: " + gpuCutLine);
            }
        } catch (const InputError&) {
            throw;
        } catch (const Cancelled&) {
            throw;
        } catch (const std::runtime_error& e) {
            throw InputError(describeRefusal(e.what(), frame, kerf)); // a configuration the kernel refuses
        }
    }
    const double cutSeconds = secondsSince(t0);

    // -- draw and write ------------------------------------------------------------
    t0 = Clock::now();
    const render::Camera camera = render::cameraFor(view, renderer.bounds(), double(width) / height);
    render::RenderStyle style;
    style.highlight = args.has("highlight");
    renderer.render(camera, style);
    const render::Frame frame = renderer.readFrame();
    const double renderSeconds = secondsSince(t0);
    if (ext == ".png") {
        render::writePng(frame, out);
    } else {
        render::writeExr(frame, out);
    }

    std::printf("surface:    %zu triangles at iso %g, %zu fragment(s)\n", uncut.triangleCount(), double(iso), fragments);
    if (!strokes.empty()) {
        std::printf("cut:        %s, %zu cut cells, %zu cut-geometry triangles\n", pathFile.c_str(), cutCells,
                    cutTriangles);
        if (!gpuCutLine.empty()) std::printf("gpu cut:    %s\n", gpuCutLine.c_str());
        printStrokeByStroke(refused, stepped);
    }
    std::printf("view:       %s, eye (%.1f, %.1f, %.1f) mm, target (%.1f, %.1f, %.1f) mm\n", view.c_str(), camera.eye.x,
                camera.eye.y, camera.eye.z, camera.target.x, camera.target.y, camera.target.z);
    std::printf("gl:         %s\n", context->description().c_str());
    std::printf("time:       read %.2f s, surface and cut %.2f s, render %.2f s\n", readSeconds, cutSeconds,
                renderSeconds);
    std::printf("wrote:      %s (%dx%d)\n", out.c_str(), width, height);
    if (!refused.empty()) {
        std::fflush(stdout);
        std::fprintf(stderr, "mtcut: warning: %zu stroke(s) cut only in part (--keep-going)\n", refused.size());
    }
    return 0;
}

std::vector<std::string> renderOptions()
{
    std::vector<std::string> o = kInputOptions;
    for (const char* name : {"iso", "path", "kerf", "retrace", "slide", "output", "width", "height", "view"}) o.push_back(name);
    return o;
}

const CommandRegistrar renderCommand(
    {"render",
     "render INPUT --iso V [--path PATH.csv] [--kerf MM] [--retrace VOXELS] [--slide VOXELS] -o OUT.{png,exr} [--width W --height H] "
     "[--view front|side|top|iso|EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ[:FOV]]] [--highlight] [--keep-going] [--gpu-cut]",
     "draw the isosurface (cut along PATH.csv when given) headless on the GPU into a PNG, or an EXR with RGBA, Z "
     "(depth, mm), N.X/N.Y/N.Z (world normal) and fragment (uint id) channels; default 1024x1024, front view; "
     "--highlight colours the cut geometry; --kerf, --retrace and --slide as mtcut cut's; --keep-going: a stroke the re-mesher refuses is cut up to where it is "
     "refused, as mtcut cut --keep-going; --gpu-cut: the cut geometry is made again by the GPU cut pass and drawn from "
     "its own output, and the recovered geometry is checked against the CPU re-mesher's",
     renderOptions(), {"highlight", "keep-going", "gpu-cut"}, 1, 1, runRender});

} // namespace

} // namespace mtcut::cli
