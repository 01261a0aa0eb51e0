// Shader build times: how long the driver takes to compile and link each
// program of the GPU passes, built exactly as the renderer builds them
// (render/CutKernelGpu's cutPassLibrary for the cut pass). The GPU cut pass's
// programs are large (the exact arrangement kernel on doubles); a driver may
// take far longer on them than on the drawing shaders, and this says which.
//
// Usage: bench_render_shaders [--egl-device] [--fill-cache] [PROGRAM ...]
//   PROGRAM: cut_phase_one.comp, cut_vertex_positions.comp, cut_names.comp,
//            cut_arrange.vert, cut_regions.vert, poly2_test.comp,
//            mask_query.comp, surface (surface.vert + surface.frag);
//            default: all, the small ones first.
//   MTCUT_SHADER_PREAMBLE in the environment goes in front of every shader
//   (render/Shaders.h), to try a driver's pragmas.
//   --fill-cache: use buildProgram's program cache (render/Shaders.h,
//   ProgramCache) as the renderer does: a program found there is loaded
//   (the line says cached=1), one built slowly is stored (stored=1). Without
//   it every program is built, the cache neither read nor written. Several
//   processes side by side fill the cache for a later run in parallel.
// Mesa (llvmpipe) defers most of its compiling to the first draw or
// dispatch, so its build_ms are small and say little; on NVIDIA the build is
// done at link. One line per program: "case=shader program=NAME source_kb=N
// build_ms=T", or "... failed_ms=T warnings=N error=..." (the whole log less
// its warnings) when it does not build. Run one program per process (under
// `timeout`) where a driver may not finish.
#include "benchmarks/BenchUtil.h"
#include "render/Context.h"
#include "render/CutKernelGpu.h"
#include "render/Shaders.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <sstream>
#include <string>
#include <vector>

using namespace mtcut;
using bench::Clock;
using bench::msSince;

namespace {

struct Build
{
    std::vector<std::string> files;
    std::string defines;
};

Build buildOf(const std::string& name)
{
    if (name == "surface") return {{"surface.vert", "surface.frag"}, {}};
    if (name.rfind("cut_", 0) == 0) return {{name}, render::cutPassLibrary(name)};
    if (name == "poly2_test.comp") return {{name}, render::poly2Library()};
    if (name == "mask_query.comp") return {{name}, render::shaderSource("mask.glsl")};
    throw std::runtime_error("unknown program " + name);
}

} // namespace

int main(int argc, char** argv)
{
    std::vector<std::string> names;
    bool fillCache = false;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--egl-device")) {
            setenv("EGL_PLATFORM", "device", 1);
        } else if (!std::strcmp(argv[i], "--fill-cache")) {
            fillCache = true;
        } else if (argv[i][0] == '-') {
            std::fprintf(stderr, "usage: bench_render_shaders [--egl-device] [--fill-cache] [PROGRAM ...]\n");
            return 2;
        } else {
            names.push_back(argv[i]);
        }
    }
    if (names.empty())
        names = {"surface", "mask_query.comp", "poly2_test.comp", "cut_phase_one.comp", "cut_vertex_positions.comp",
                 "cut_names.comp", "cut_arrange.vert", "cut_regions.vert"};
    if (!fillCache) render::setProgramCache({});
    try {
        auto ctx = render::createHeadlessContext();
        const char* preamble = std::getenv("MTCUT_SHADER_PREAMBLE");
        std::printf("device=\"%s\" preamble=\"%s\"\n", ctx->description().c_str(), preamble ? preamble : "");
        std::fflush(stdout);
        for (const std::string& name : names) {
            size_t bytes = 0;
            Build b;
            const Clock::time_point t0 = Clock::now();
            try {
                b = buildOf(name);
                for (const std::string& f : b.files) bytes += render::shaderSource(f).size();
                bytes += b.defines.size();
                const render::ProgramCacheCounts before = render::programCacheCounts();
                const render::Program program = render::buildProgram(b.files, b.defines);
                const double ms = msSince(t0);
                const render::ProgramCacheCounts after = render::programCacheCounts();
                std::printf("case=shader program=%s source_kb=%.0f build_ms=%.0f", name.c_str(), bytes / 1024.0, ms);
                if (fillCache)
                    std::printf(" cached=%d stored=%d", int(after.loaded > before.loaded), int(after.stored > before.stored));
                std::printf("\n");
            } catch (const std::exception& e) {
                // The whole log but its warnings (NVIDIA's runs to hundreds of
                // "might be used before being initialized" lines before the error).
                std::istringstream log(e.what());
                std::string line, kept;
                int warnings = 0;
                while (std::getline(log, line)) {
                    if (line.find(": warning ") != std::string::npos) {
                        ++warnings;
                    } else if (!line.empty()) {
                        kept += (kept.empty() ? "" : " | ") + line;
                    }
                }
                std::printf("case=shader program=%s source_kb=%.0f failed_ms=%.0f warnings=%d error=\"%s\"\n", name.c_str(),
                            bytes / 1024.0, msSince(t0), warnings, kept.c_str());
            }
            std::fflush(stdout);
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_render_shaders: %s\n", e.what());
        return 1;
    }
    return 0;
}
