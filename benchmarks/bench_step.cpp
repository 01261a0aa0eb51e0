// bench_step: the haptic step of bench_cut's cut on the 1 mm VHM head, alone
// and repeated, for profiling and for before/after comparisons of the
// re-mesher (the step figures of benchmarks/RESULTS.md from the
// forty-eighth session on, first made with a scratch copy of this).
//
// The cut is bench_cut's (bench::chooseCut on the head at 0.32 of the box
// height, the stroke sized to about --target cut cells). Each repeat undoes
// its last --steps quads (CutMask::undoToQuad, then an update) and adds them
// back one by one, timing each CutRemesher::update: a quad's new cells
// re-meshed, fused and checked, as a live stroke does. Prints the median,
// quartiles and extremes of the timed steps and the cells re-meshed a step;
// then the baseline, in the same run: the whole volume carved by the cut and
// its isosurface extracted again (bench_cut's baseline (a), two threads,
// median of 3), and the ratio of its median to the step's. (bench_cut has
// the OpenVDB level-set route too.)
//
// Usage: bench_step [--kerf MM] [--target CELLS] [--threads N] [--reps N]
//                   [--steps N] [--first-variant N] [--volume PATH]
// --first-variant N: the first stroke variant tried, as bench_cut's (0: a
// level stroke along the grid; 1-3 pitched and yawed by a degree or two).
// The isovalue is 400, bone on the VHM head (also for --volume).
// Defaults: kerf 0.5, target 419 (bench_cut's smallest cut: 425 cells),
// one thread, 40 repeats of 8 steps (all but the first quad of a shorter
// cut), ../shared/data/vhm-head-dicom. Exits 0
// with a note when the volume is absent, 2 on a bad argument, 1 when the
// volume cannot be read or no cut is accepted.
#include "benchmarks/BenchCuts.h"
#include "benchmarks/BenchUtil.h"
#include "cutter/Isosurface.h"
#include "vdb/CutOutputs.h"
#include "vdb/VolumeIO.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

using namespace mtcut;
using namespace mtcut::cutter;

namespace {

[[noreturn]] void usage(const std::string& why)
{
    std::fprintf(stderr,
                 "bench_step: %s\nusage: bench_step [--kerf MM] [--target CELLS] [--threads N] [--reps N] [--steps N] "
                 "[--first-variant N] [--volume PATH]\n",
                 why.c_str());
    std::exit(2);
}

long positive(const std::string& flag, const char* v)
{
    char* end = nullptr;
    const long n = std::strtol(v, &end, 10);
    if (end == v || *end != '\0' || n < 1) usage(flag + " wants a positive count");
    return n;
}

/// The cut, its steps timed and the baseline; throws what reading or cutting throws.
int run(const std::string& path, double kerf, size_t target, int threads, int reps, int steps, int firstVariant)
{
    const vdb::Volume vol = vdb::readVolume(path);
    const Mesh uncut = extractIsosurface(vol, 400.0f);
    bench::CutScene sc;
    sc.name = std::filesystem::path(path).filename().string();
    sc.vol = &vol;
    sc.uncut = &uncut;
    bench::locateCutPlane(sc, 0.32 * double(vol.dims.z() - 1));
    // (The smallest limit alive wins: this one ends before the baseline's.)
    std::optional<tbb::global_control> limit;
    limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(threads));
    bench::SizedCut cut = bench::chooseCut(sc, target, kerf, {}, firstVariant);
    if (!cut.ok) {
        std::fprintf(stderr, "bench_step: no cut of about %zu cells accepted: %s\n", target, cut.note.c_str());
        return 1;
    }
    if (cut.quads.size() < 2) {
        std::fprintf(stderr, "bench_step: the cut is one quad; no step to time\n");
        return 1;
    }
    if (size_t(steps) >= cut.quads.size()) { // (as bench_cut: an air variant's stroke can be short)
        std::fprintf(stderr, "bench_step: the cut has %zu quads; timing its last %zu\n", cut.quads.size(), cut.quads.size() - 1);
        steps = int(cut.quads.size() - 1);
    }
    const uint32_t first = uint32_t(cut.quads.size() - size_t(steps));
    std::vector<double> ms;
    std::vector<glm::ivec3> cellBuf;
    size_t remeshed = 0;
    for (int r = 0; r < reps; ++r) {
        cut.mask->undoToQuad(first);
        cut.remesher->update(*cut.mask);
        for (uint32_t i = first; i < cut.quads.size(); ++i) {
            cellBuf.clear();
            voxelizeCut(cut.quads[i], cut.mask->kerf(), cut.mask->frame(), cellBuf);
            cut.mask->addQuad(cut.quads[i], cellBuf);
            const auto t0 = bench::Clock::now();
            remeshed += cut.remesher->update(*cut.mask);
            ms.push_back(bench::msSince(t0));
        }
    }
    std::vector<double> sorted = ms;
    std::sort(sorted.begin(), sorted.end());
    auto at = [&](double q) { return 1e3 * sorted[size_t(q * double(sorted.size() - 1) + 0.5)]; };
    std::printf("volume=%s kerf=%g target=%zu variant=%d cells=%zu threads=%d steps=%zu median_us=%.1f q1_us=%.1f "
                "q3_us=%.1f min_us=%.1f max_us=%.1f remeshed_per_step=%.2f\n",
                sc.name.c_str(), kerf, target, cut.variant, cut.cells, threads, ms.size(), 1e3 * bench::median(ms), at(0.25), at(0.75),
                at(0.0), at(1.0), double(remeshed) / double(ms.size()));
    // Baseline: carve the whole volume and extract again, two threads.
    limit.reset();
    tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    openvdb::MaskGrid removed;
    removed.topologyUnion(*cut.mask->grid());
    std::vector<double> again;
    size_t triangles = 0;
    for (int r = 0; r < 3; ++r) {
        const auto t0 = bench::Clock::now();
        vdb::Volume carved = vol;
        carved.grid = vdb::carveVolume(vol, removed);
        triangles = extractIsosurface(carved, 400.0f).triangleCount();
        again.push_back(bench::msSince(t0));
    }
    std::printf("baseline=carve+extract threads=2 median_ms=%.1f triangles=%zu ratio=%.0f\n", bench::median(again),
                triangles, bench::median(again) / bench::median(ms));
    return 0;
}

} // namespace

int main(int argc, char** argv)
{
    double kerf = 0.5;
    size_t target = 419;
    int threads = 1, reps = 40, steps = 8, firstVariant = 0;
    std::string path = std::string(MTCUT_SHARED_DATA) + "/vhm-head-dicom";
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (i + 1 >= argc) usage("missing value after " + a);
        const char* v = argv[++i];
        if (a == "--kerf") {
            char* end = nullptr;
            kerf = std::strtod(v, &end);
            if (end == v || *end != '\0' || !(kerf >= 0.0 && kerf <= 10.0)) usage("--kerf wants a width from 0 to 10 mm");
        } else if (a == "--target") {
            target = size_t(positive(a, v));
        } else if (a == "--threads") {
            threads = int(positive(a, v));
        } else if (a == "--reps") {
            reps = int(positive(a, v));
        } else if (a == "--steps") {
            steps = int(positive(a, v));
        } else if (a == "--first-variant") {
            char* end = nullptr;
            const long n = std::strtol(v, &end, 10);
            if (end == v || *end != '\0' || n < 0 || n >= bench::kStrokeVariants)
                usage("--first-variant wants 0 to " + std::to_string(bench::kStrokeVariants - 1));
            firstVariant = int(n);
        } else if (a == "--volume") {
            path = v;
        } else {
            usage("unknown option " + a);
        }
    }
    if (!std::filesystem::exists(path)) {
        std::printf("bench_step: %s is absent; nothing to time\n", path.c_str());
        return 0;
    }
    try {
        return run(path, kerf, target, threads, reps, steps, firstVariant);
    } catch (const std::exception& e) { // an unreadable volume, no bone in the cut's plane
        std::fprintf(stderr, "bench_step: %s\n", e.what());
        return 1;
    }
}
