// bench_strokes: seeded random strokes cut on a CT volume the way a live
// stroke cuts them, to count what the re-mesher refuses. Not a test (it
// asserts nothing and takes minutes); the sweeps in benchmarks/RESULTS.md
// ("Updates after every quad", "Where a step's instructions go") were made
// with it or its scratch forerunners.
//
// Each seed: `--strokes` strokes of cutter::makeRandomStrokes with the
// parameters tests/test_cut_props.cpp varies by seed (150 + 50 (seed % 5)
// poses, 0.4 + 0.2 (seed % 4) mm a pose, blade 20 + 10 (seed % 4) mm; the
// path turning by --turn a pose, 0.05 as there, about 1 for sharp turns and
// strokes doubling back), one after another on one mask, then checkMesh of
// the fused mesh. How a stroke
// is updated (--mode):
//   live    a cutter::LiveStroke updated after every quad (the viewer's and
//           `mtcut cut --keep-going`'s policy: a refused update is waited out,
//           8 in a row or a refused last one stop the stroke); the default;
//   quad    update() after every quad, every refused update counted; the
//           quads stay in the mask, so a refusal that stays repeats;
//   stroke  one update() per stroke; a refused stroke is undone
//           (CutMask::undoStroke), as a user would.
// Prints a line per seed (`seed=...`: strokes stopped, updates deferred or
// refused, checkMesh defects of the fused mesh, the live updates and the
// slowest one's time, the fused mesh's hash (`mesh=`, bench::meshHash: the
// same bits before and after a change that should not alter the cut), and
// each stroke's first refusal), then a summary line (`summary ...`). Exit
// status 1 when a fused mesh has a defect (a refusal is not one: the
// re-mesher refuses rather than write a broken surface).
//
// Usage: bench_strokes VOLUME [--iso V] [--kerf MM] [--seeds A-B] [--strokes N]
//                      [--turn W] [--saw across|slide|both] [--tremor MM]
//                      [--retrace VOXELS] [--slide VOXELS] [--turn-crossing-sticks on|off]
//                      [--mode live|quad|stroke] [--threads N]
// VOLUME is anything `mtcut` reads (a DICOM folder, .nhdr, .nii.gz, ...).
// Defaults: iso 400, kerf 0.5, seeds 8000-8009, 4 strokes, turn 0.05, live,
// one thread.
//
// --saw: instead of random walks, each stroke is a saw worked back and
// forth through a random vertex of the uncut isosurface
// (cutter::makeSawingStroke, 400 poses): `across` swings the blade across
// itself while pushing it deeper, `slide` slides it along its own line while
// it advances, `both` alternates them stroke by stroke. By seed: amplitude
// 2, 4 or 6 mm, feed 0.01, 0.03 or 0.05 mm a pose, 16, 24 or 32 poses a
// cycle, blade 10 or 20 mm. --tremor (default 0.05 mm; 0: a scripted saw,
// every pose in one plane) sets the hand's tremor, and 0.08 rad a mm of it
// the blade's. Each line then also gives the slowest update (worst_ms).
//
// --retrace: the path filter's retrace tolerance in voxels
// (PathFilterOptions::retraceTolerance, default 0.25; `mtcut cut --retrace`).
//
// --slide: the path filter's slide tolerance in voxels (rule 2c,
// PathFilterOptions::slideTolerance, default 0.25; negative: off).
//
// --turn-crossing-sticks: the path filter's rule 3 (a')
// (PathFilterOptions::turnCrossingSticks; default off, as there).
#include "benchmarks/BenchUtil.h"
#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/LiveStroke.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"
#include "vdb/VolumeIO.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <optional>
#include <string>
#include <vector>

using namespace mtcut;
using namespace mtcut::cutter;

namespace {

enum class Mode { Live, Quad, Stroke };

struct Totals
{
    size_t seeds = 0, strokes = 0, stopped = 0, stepped = 0, deferred = 0, refused = 0, defects = 0, dirtySeeds = 0;
    size_t updates = 0;   // live updates
    double worstMs = 0.0; // the slowest of them
};

[[noreturn]] void usage(const char* why)
{
    std::fprintf(stderr,
                 "bench_strokes: %s\nusage: bench_strokes VOLUME [--iso V] [--kerf MM] [--seeds A-B] [--strokes N] "
                 "[--turn W] [--saw across|slide|both] [--tremor MM] [--retrace VOXELS] [--slide VOXELS] [--turn-crossing-sticks on|off] "
                 "[--mode live|quad|stroke] [--threads N]\n",
                 why);
    std::exit(2);
}

} // namespace

int main(int argc, char** argv)
{
    if (argc < 2 || argv[1][0] == '-') usage("no volume given");
    const std::string path = argv[1];
    float iso = 400.0f;
    double kerf = 0.5;
    long seedLo = 8000, seedHi = 8009;
    int strokes = 4, threads = 1;
    double turn = 0.05;
    Mode mode = Mode::Live;
    std::optional<SawMotion> saw; // none: random strokes
    double tremor = 0.05;
    PathFilterOptions filterOptions;
    for (int i = 2; i < argc; ++i) {
        const std::string a = argv[i];
        if (i + 1 >= argc) usage(("missing value after " + a).c_str());
        const char* v = argv[++i];
        char* end = nullptr;
        if (a == "--iso") {
            iso = std::strtof(v, &end);
            if (!std::isfinite(iso)) usage("--iso wants a finite value");
        } else if (a == "--kerf") {
            kerf = std::strtod(v, &end);
            if (!(kerf >= 0.0)) usage("--kerf wants a width >= 0 mm");
        } else if (a == "--seeds") {
            seedLo = std::strtol(v, &end, 10);
            seedHi = seedLo;
            if (*end == '-') seedHi = std::strtol(end + 1, &end, 10);
            if (seedLo < 0 || seedHi < seedLo || seedHi > long(UINT32_MAX))
                usage("--seeds wants A or A-B with 0 <= A <= B < 2^32");
        } else if (a == "--strokes") {
            strokes = int(std::strtol(v, &end, 10));
            if (strokes < 1) usage("--strokes wants a positive count");
        } else if (a == "--turn") {
            turn = std::strtod(v, &end);
            if (!(turn >= 0.0 && turn <= 100.0)) usage("--turn wants a weight from 0 to 100");
        } else if (a == "--threads") {
            threads = int(std::strtol(v, &end, 10));
            if (threads < 1) usage("--threads wants a positive count");
        } else if (a == "--saw") {
            const std::string m = v;
            if (m == "across") saw = SawMotion::Across;
            else if (m == "slide") saw = SawMotion::Slide;
            else if (m == "both") saw = SawMotion::Both;
            else usage("--saw wants across, slide or both");
            continue;
        } else if (a == "--tremor") {
            tremor = std::strtod(v, &end);
            if (!(tremor >= 0.0 && tremor <= 10.0)) usage("--tremor wants 0 to 10 mm");
        } else if (a == "--turn-crossing-sticks") {
            const std::string on(v);
            if (on != "on" && on != "off") usage("--turn-crossing-sticks wants on or off");
            filterOptions.turnCrossingSticks = on == "on";
            continue;
        } else if (a == "--retrace") {
            filterOptions.retraceTolerance = std::strtod(v, &end);
            if (!(filterOptions.retraceTolerance >= 0.0 && filterOptions.retraceTolerance <= kMaxRetraceTolerance))
                usage("--retrace wants 0 to 4 voxels");
        } else if (a == "--slide") {
            filterOptions.slideTolerance = std::strtod(v, &end);
            if (!(filterOptions.slideTolerance <= kMaxRetraceTolerance))
                usage("--slide wants at most 4 voxels (negative: off)");
        } else if (a == "--mode") {
            const std::string m = v;
            if (m == "live") mode = Mode::Live;
            else if (m == "quad") mode = Mode::Quad;
            else if (m == "stroke") mode = Mode::Stroke;
            else usage("--mode wants live, quad or stroke");
            continue;
        } else {
            usage(("unknown option " + a).c_str());
        }
        if (!end || *end != '\0') usage(("not a number: " + a + " " + v).c_str());
    }
    openvdb::initialize();
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    vdb::Volume vol;
    try {
        vol = vdb::readVolume(path);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_strokes: %s\n", e.what());
        return 1;
    }
    const Mesh uncut = extractIsosurface(vol, iso, IsosurfaceOptions{nullptr, false});
    const IndexFrame frame = frameOf(vol);
    const char* modeName = mode == Mode::Live ? "live" : mode == Mode::Quad ? "quad" : "stroke";
    std::printf("volume=%s iso=%g kerf=%g seeds=%ld-%ld strokes=%d turn=%g retrace=%g slide=%g turn_crossing_sticks=%s "
                "mode=%s threads=%d uncut_tris=%zu\n",
                path.c_str(), double(iso), kerf, seedLo, seedHi, strokes, turn, filterOptions.retraceTolerance,
                filterOptions.slideTolerance, filterOptions.turnCrossingSticks ? "on" : "off", modeName, threads, uncut.triangleCount());
    std::fflush(stdout);
    Totals total;
    const auto t0 = bench::Clock::now();
    for (long seed = seedLo; seed <= seedHi; ++seed) {
        const auto ts = bench::Clock::now();
        const uint32_t s32 = uint32_t(seed);
        CutMask mask(frame, kerf);
        CutRemesher remesher(vol, iso, uncut);
        std::vector<std::vector<Pose>> all;
        if (saw) {
            all = makeSawingStrokes(uncut.positions, s32, strokes, *saw, tremor);
        } else {
            all = makeRandomStrokes(frame, s32, strokes, 150 + 50 * int(s32 % 5), 0.4 + 0.2 * (s32 % 4),
                                    20.0 + 10.0 * (s32 % 4), turn);
        }
        size_t stopped = 0, deferred = 0, refused = 0, stepped = 0, updates = 0;
        double worstMs = 0.0; // the slowest live update
        std::string notes;
        for (size_t s = 0; s < all.size(); ++s) {
            const std::vector<Quad> quads = filterStroke(all[s], frame, filterOptions);
            if (quads.empty()) continue;
            if (mode == Mode::Live) {
                LiveStroke live(mask, remesher);
                LiveStroke::Result r;
                for (size_t q = 0; q < quads.size() && live.add(quads[q]); ++q) {
                    const auto tu = bench::Clock::now();
                    r = q + 1 < quads.size() ? live.update() : live.finish();
                    worstMs = std::max(worstMs, bench::msSince(tu));
                    ++updates;
                    deferred += r.outcome == LiveStroke::Outcome::Deferred;
                    if (r.steppedRound)
                        notes += " | stroke " + std::to_string(s) + " stepped round at quad " + std::to_string(q) + " of " +
                                 std::to_string(quads.size()) + ": " + r.refusal;
                    if (r.outcome == LiveStroke::Outcome::Stopped) break;
                }
                stepped += live.steppedRound();
                if (live.stopped()) {
                    ++stopped;
                    notes += " | stroke " + std::to_string(s) + " stopped, " + std::to_string(live.acceptedQuads()) + " of " +
                             std::to_string(quads.size()) + " quads kept: " + r.refusal;
                }
            } else {
                mask.beginStroke();
                size_t strokeRefused = 0;
                for (size_t q = 0; q < quads.size(); ++q) {
                    mask.addQuad(quads[q]);
                    if (mode == Mode::Stroke && q + 1 < quads.size()) continue;
                    try {
                        remesher.update(mask);
                    } catch (const std::exception& e) {
                        if (strokeRefused++ == 0) // the first refusal of the stroke, with its reason
                            notes += " | stroke " + std::to_string(s) + " quad " + std::to_string(q) + " of " +
                                     std::to_string(quads.size()) + ": " + e.what();
                        if (mode == Mode::Stroke) {
                            mask.undoStroke(); // the refused stroke goes, as a user would undo it
                            remesher.update(mask);
                        }
                    }
                }
                if (strokeRefused > 1) notes += " (" + std::to_string(strokeRefused) + " updates refused)";
                refused += strokeRefused;
            }
        }
        const Mesh fused = remesher.fusedMesh();
        const MeshCheck check = checkMesh(fused);
        total.seeds += 1;
        total.strokes += all.size();
        total.stopped += stopped;
        total.deferred += deferred;
        total.refused += refused;
        total.stepped += stepped;
        total.defects += check.defects();
        total.dirtySeeds += check.defects() != 0;
        total.updates += updates;
        total.worstMs = std::max(total.worstMs, worstMs);
        std::printf("seed=%ld stopped=%zu stepped=%zu deferred=%zu refused=%zu defects=%zu ms=%.0f updates=%zu worst_ms=%.1f "
                    "mesh=%016llx%s\n",
                    seed, stopped, stepped, deferred, refused, check.defects(), bench::msSince(ts), updates, worstMs,
                    static_cast<unsigned long long>(bench::meshHash(fused)), notes.c_str());
        if (check.defects() != 0) std::printf("%s\n", check.report().c_str());
        std::fflush(stdout);
    }
    std::printf("summary seeds=%zu strokes=%zu stopped=%zu stepped=%zu deferred=%zu refused=%zu defects=%zu "
                "seeds_with_defects=%zu s=%.1f updates=%zu worst_ms=%.1f\n",
                total.seeds, total.strokes, total.stopped, total.stepped, total.deferred, total.refused, total.defects,
                total.dirtySeeds, bench::msSince(t0) / 1e3, total.updates, total.worstMs);
    return total.defects != 0 ? 1 : 0;
}
