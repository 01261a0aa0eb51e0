// mtcut cut: one batch cut of a scan along a blade path (or the built-in
// LeFort I-like stroke): the isosurface, the cut mask, the re-meshed cut
// cells fused with the uncut surface, and the outputs - one mesh per fragment,
// cut.vdb, slices.exr and summary.json - in an output folder.
#include "cutter/CutMask.h"
#include "cutter/Fusion.h"
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/PathFile.h"
#include "cutter/Remesh.h"
#include "tools/Cli.h"
#include "tools/CutOutputs.h"
#include "vdb/CutOutputs.h"
#include "vdb/Phantom.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

namespace mtcut::cli {

namespace {

using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

double secondsSince(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

// -- the stroke ---------------------------------------------------------------

/// Is this the procedural phantom's grid (any size)? Its field of view is
/// fixed and centred on the world origin (vdb/Phantom.h).
bool looksLikePhantom(const vdb::Volume& vol)
{
    if (vol.source == "phantom") return true;
    const openvdb::Vec3d fov = vdb::phantomFieldOfView();
    const openvdb::Vec3d s = vol.spacing(), o = vol.origin();
    for (int a = 0; a < 3; ++a) {
        const double extent = s[a] * double(vol.dims[a]);
        if (std::abs(extent - fov[a]) > 1e-6 * fov[a]) return false;
        if (std::abs(o[a] - (-0.5 * fov[a] + 0.5 * s[a])) > 1e-6 * fov[a]) return false;
    }
    return true;
}

/// The built-in stroke: makeLeFortStroke on the volume's frame; on the
/// phantom, at the height of its LeFort I plane; on other inputs, fitted to
/// the isosurface's bounding box (cutter::leFortOptionsFittedTo).
std::vector<cutter::Pose> builtinStroke(const vdb::Volume& vol, const cutter::IndexFrame& frame,
                                        const cutter::Mesh& surface, bool* onPhantom)
{
    *onPhantom = looksLikePhantom(vol);
    cutter::LeFortOptions options = *onPhantom ? cutter::LeFortOptions{} : cutter::leFortOptionsFittedTo(surface.positions);
    if (*onPhantom) {
        const double lo = frame.toWorld(glm::dvec3(0.0)).z;
        const double hi = frame.toWorld(glm::dvec3(0.0, 0.0, double(std::max(frame.dims.z - 1, 0)))).z;
        if (hi > lo) options.zFraction = (vdb::phantomLandmarks().leFortZ - lo) / (hi - lo);
    }
    return cutter::makeLeFortStroke(frame, options);
}

/// A volume (mm^3) or area (mm^2) for the fragment list, 10 wide: one
/// decimal, or two significant digits for a crumb that would print as 0.0
/// (a closed piece where the surface just reaches the blade).
std::string amountText(double v)
{
    char text[32];
    if (std::abs(v) < 0.05) std::snprintf(text, sizeof text, "%10.2g", v);
    else std::snprintf(text, sizeof text, "%10.1f", v);
    return text;
}

int runCut(const Args& args)
{
    // -- arguments: everything checked before the long work --------------------
    const float iso = args.isoValue("cut");
    if (!args.has("output")) throw InputError("mtcut cut needs -o OUTDIR");
    const double kerf = args.kerfMm();
    const cutter::PathFilterOptions filterOptions = args.pathFilterOptions();
    const std::string ext = args.get("format", "stl");
    checkMeshFormat(ext);
    const std::string outDir = args.get("output");
    if (outDir.empty()) throw InputError("-o: empty output folder name");
    {
        std::error_code ec;
        if (fs::exists(outDir, ec) && !fs::is_directory(outDir, ec)) {
            throw InputError(outDir + ": exists and is not a folder");
        }
    }
    const double minVolume = args.getDouble("min-volume", 0.0);
    if (!(std::isfinite(minVolume) && minVolume >= 0.0))
        throw InputError("--min-volume " + args.get("min-volume") + ": expected a volume in mm^3, 0 or more");
    // --level-set-voxel: cut.vdb's level sets' voxel size (default: the
    // scan's smallest spacing). Checked against that spacing once the scan
    // is read: finer than a quarter of it adds nothing the scan holds and
    // grows the level sets as the square of the ratio.
    const double levelSetVoxel = args.getDouble("level-set-voxel", 0.0);
    const std::string levelSetVoxelText = "--level-set-voxel " + args.get("level-set-voxel");
    if (args.has("level-set-voxel") && !(std::isfinite(levelSetVoxel) && levelSetVoxel > 0.0 && levelSetVoxel <= 100.0))
        throw InputError(levelSetVoxelText + ": expected a voxel size in mm, above 0 and at most 100");
    const std::string pathFile = args.get("path");
    std::vector<std::vector<cutter::Pose>> strokes;
    if (!pathFile.empty()) strokes = readStrokes(pathFile);

    CutTimings t;
    auto t0 = Clock::now();
    const vdb::Volume vol = readInput(args.positional[0], args);
    t.read = secondsSince(t0);
    if (args.has("level-set-voxel")) {
        const double finest = vdb::CutVdbOptions{}.voxelMmFor(vol); // the default: the smallest spacing
        if (levelSetVoxel < 0.25 * finest) {
            char text[96];
            std::snprintf(text, sizeof text, ": expected at least a quarter of the scan's smallest spacing (%g mm)",
                          0.25 * finest);
            throw InputError(levelSetVoxelText + text);
        }
    }

    // -- isosurface -------------------------------------------------------------
    t0 = Clock::now();
    cutter::Mesh uncut = extractSurface(vol, iso);
    t.extract = secondsSince(t0);
    if (uncut.empty()) throw InputError("no surface at iso " + args.get("iso") + ": nothing to cut");

    // -- cut mask ---------------------------------------------------------------
    t0 = Clock::now();
    const cutter::IndexFrame frame = cutter::frameOf(vol);
    bool onPhantom = false;
    if (strokes.empty()) strokes.push_back(builtinStroke(vol, frame, uncut, &onPhantom));
    cutter::CutMask mask(frame, kerf);
    size_t quadCount = addStrokes(mask, strokes, filterOptions);
    t.mask = secondsSince(t0);

    // -- re-mesh and fuse ---------------------------------------------------------
    t0 = Clock::now();
    cutter::Mesh fused;
    std::vector<uint8_t> onBlade; // per fused triangle: a cut face
    std::vector<cutter::Fragment> fragments;
    size_t surfaceCells = 0; // cut cells with new geometry: the blade meets the solid there
    size_t mostQuads = 0;    // the most quads crossing one of them (manyQuadsNote)
    const bool keepGoing = args.has("keep-going");
    std::vector<RefusedStroke> refused;
    std::vector<size_t> stepped; // strokes whose live cut stepped round a refusal
    try {
        cutter::CutRemesher remesher(vol, iso, uncut);
        bool whole = true;
        try {
            ProgressBar progress;
            remesher.update(mask, &progress);
        } catch (const InputError&) {
            throw;
        } catch (const Cancelled&) {
            throw;
        } catch (const std::runtime_error&) {
            if (!keepGoing) throw;
            whole = false;
        }
        if (!whole) {
            std::fprintf(stderr, "mtcut: the re-mesher refused the cut; --keep-going: cutting stroke by stroke\n");
            mask = cutter::CutMask(frame, kerf);
            quadCount = cutStrokeByStroke(remesher, mask, strokes, filterOptions, refused, &stepped);
        }
        std::vector<openvdb::Coord> withSurface;
        for (const auto& [cell, geometry] : remesher.cells())
            if (!geometry.indices.empty()) withSurface.push_back(cell);
        surfaceCells = withSurface.size();
        mostQuads = mostQuadsInACell(mask, withSurface);
        std::vector<uint32_t> source;
        fused = remesher.fusedMesh(&source);
        onBlade = remesher.bladeTriangles(source);
    } catch (const InputError&) {
        throw;
    } catch (const Cancelled&) {
        throw;
    } catch (const std::runtime_error& e) {
        throw InputError(describeRefusalWithHint(e.what(), frame, kerf, keepGoing)); // a configuration the kernel refuses
    }
    const size_t uncutTriangles = uncut.triangleCount();
    uncut = cutter::Mesh(); // free it
    fragments = cutter::fragmentsOf(fused, onBlade);
    onBlade = {};
    t.remesh = secondsSince(t0);

    t0 = Clock::now();
    const cutter::MeshCheck check = cutter::checkMesh(fused);
    t.check = secondsSince(t0);
    if (fragments.empty()) throw InputError("the cut left no surface");
    // --min-volume: the fragments below it get no file and no level set
    // (a scan's loose specks: the 1 mm head at 400 HU has hundreds under
    // 1 mm^3); summary.json counts them. They are the last ones (largest first).
    std::vector<bool> selected;
    size_t leftOut = 0, leftOutCut = 0;
    double leftOutVolume = 0.0;
    if (minVolume > 0.0) {
        selected.resize(fragments.size());
        for (size_t i = 0; i < fragments.size(); ++i) {
            selected[i] = fragments[i].volume >= minVolume;
            if (selected[i]) continue;
            ++leftOut;
            leftOutCut += fragments[i].cutArea > 0.0;
            leftOutVolume += fragments[i].volume;
        }
        if (leftOut == fragments.size()) {
            char largest[32];
            std::snprintf(largest, sizeof largest, "%.3g", fragments.front().volume);
            throw InputError("--min-volume " + args.get("min-volume") + ": every fragment is smaller (the largest is " +
                             largest + " mm^3): nothing to write");
        }
    }

    // -- outputs (each file atomic; summary.json last) ------------------------
    CutOutputRequest request;
    request.outDir = outDir;
    request.format = ext;
    request.input = args.positional[0];
    request.pathFile = pathFile;
    request.isovalue = iso;
    request.kerfMm = kerf;
    request.retraceVoxels = filterOptions.retraceTolerance;
    request.slideVoxels = filterOptions.slideTolerance;
    request.refused = refused;
    request.steppedRound = stepped;
    request.selected = selected;
    request.minVolumeMm3 = minVolume;
    request.levelSetVoxelMm = levelSetVoxel;
    if (pathFile.empty()) request.strokesWithoutFile = strokes;
    std::vector<FragmentRecord> records;
    {
        ProgressBar progress;
        records = writeCutOutputs(request, vol, mask, fragments, check, t, &progress);
    }

    // -- report -------------------------------------------------------------------
    std::printf("stroke:     %s, %zu stroke(s), %zu quads, kerf %g mm%s, retrace %g voxels, slide %g voxels\n",
                pathFile.empty() ? (onPhantom ? "built-in LeFort I (phantom's LeFort plane)" : "built-in LeFort I")
                                 : pathFile.c_str(),
                strokes.size(), quadCount, kerf, kerf == 0.0 ? " (zero width: nothing carved)" : "",
                filterOptions.retraceTolerance, filterOptions.slideTolerance);
    printStrokeByStroke(refused, stepped);
    std::printf("cut cells:  %zu (%zu meet the solid)\n", mask.cutCellCount(), surfaceCells);
    std::printf("surface:    %zu triangles uncut -> %zu fused, %zu fragment(s)\n",
                uncutTriangles, fused.triangleCount(),
                fragments.size());
    if (leftOut > 0)
        std::printf("left out:   %zu fragment(s) under %g mm^3 (--min-volume), %s mm^3 in all, %zu with cut faces: no "
                    "file, no level set\n",
                    leftOut, minVolume, amountText(leftOutVolume).c_str(), leftOutCut);
    // Which fragments the blade touched: a cut that separates a piece leaves
    // cut faces on both sides; the other fragments were apart before (a
    // noisy scan has hundreds of loose specks).
    size_t touched = 0;
    double cutArea = 0.0;
    for (const FragmentRecord& r : records) {
        touched += r.cutArea > 0.0;
        cutArea += r.cutArea;
    }
    std::printf("cut faces:  %s mm^2 on %zu fragment(s)%s%s\n", amountText(cutArea).c_str(), touched,
                leftOut > 0 ? " written" : "", touched == 1 && leftOutCut == 0 ? " (all on one: the cut separates no piece)" : "");
    // The largest fragments, then any other the blade touched; summary.json lists them all.
    constexpr size_t kListed = 12;
    size_t listed = 0;
    for (size_t i = 0; i < records.size(); ++i) {
        const FragmentRecord& r = records[i];
        if (i >= kListed && (!(r.cutArea > 0.0) || listed >= 2 * kListed)) continue;
        std::printf("  %-18s %s mm^3 %s mm^2 %9zu triangles", r.file.c_str(), amountText(r.volume).c_str(),
                    amountText(r.area).c_str(), r.triangles);
        if (r.cutArea > 0.0) std::printf(", %s mm^2 cut", amountText(r.cutArea).c_str());
        std::printf("\n");
        ++listed;
    }
    if (records.size() > listed)
        std::printf("  ... and %zu smaller fragment(s), listed in summary.json\n", records.size() - listed);
    std::printf("time:       read %.2f s, extract %.2f s, mask %.2f s, remesh %.2f s, check %.2f s, write %.2f s\n"
                "            (write, the parts at once: fragment files %.2f s, cut.vdb with the level sets %.2f s,\n"
                "            slices.exr %.2f s)\n",
                t.read, t.extract, t.mask, t.remesh, t.check, t.write, t.writeMeshes, t.writeVdb, t.writeSlices);
    std::printf("wrote:      %s/{fragment_000..%03zu.%s, cut.vdb, slices.exr, %ssummary.json}\n", outDir.c_str(),
                records.size() - 1, ext.c_str(), pathFile.empty() ? "stroke.csv, " : "");

    std::fflush(stdout); // warnings after the report, also when both go to one pipe
    if (const std::string note = manyQuadsNote(mostQuads, filterOptions.retraceTolerance, "--retrace 1"); !note.empty())
        std::fprintf(stderr, "mtcut: note: %s\n", note.c_str());
    if (const std::string note = touchingStlNote(records, ext); !note.empty())
        std::fprintf(stderr, "mtcut: warning: %s\n", note.c_str());
    if (!refused.empty())
        std::fprintf(stderr, "mtcut: warning: %zu stroke(s) cut only in part (--keep-going; summary.json \"refused\")\n",
                     refused.size());
    if (surfaceCells == 0) {
        // Not an error (the files are a faithful, uncut copy), but almost
        // certainly not what was meant: say so rather than look like a cut.
        if (mask.cutCellCount() == 0)
            std::fprintf(stderr, "mtcut: warning: the blade never enters the scan's box, so nothing was cut (the "
                                 "path is in world mm: check its position against the scan's origin)\n");
        else
            std::fprintf(stderr,
                         "mtcut: warning: the blade meets no solid at iso %g: none of its %zu cut cells holds part of "
                         "the surface, so nothing was cut (check --iso and the path's position in world mm)\n",
                         double(iso), mask.cutCellCount());
    }
    if (!check.ok()) {
        if (args.has("check")) {
            std::printf("%s", check.report().c_str());
            return 1;
        }
        std::fprintf(stderr, "mtcut: warning: the cut mesh has %zu defects (run with --check for the report)\n",
                     check.defects());
    } else if (args.has("check")) {
        std::printf("%s", check.report().c_str());
    }
    return 0;
}

std::vector<std::string> cutOptions()
{
    std::vector<std::string> o = kInputOptions;
    for (const char* name : {"iso", "path", "kerf", "retrace", "slide", "output", "format", "min-volume", "level-set-voxel"}) o.push_back(name);
    return o;
}

const CommandRegistrar cut({"cut", "cut INPUT --iso V [--path PATH.csv] [--kerf MM] [--retrace VOXELS] [--slide VOXELS] -o OUTDIR [--format stl|obj|ply|off] [--min-volume MM3] [--level-set-voxel MM] [--check] [--keep-going]",
                            "cut the isosurface along a blade path (default: a built-in LeFort I stroke); writes "
                            "fragment_NNN meshes (largest first), cut.vdb, slices.exr, summary.json into OUTDIR. --path: "
                            "poses t,x,y,z,dx,dy,dz,length (cutter/PATH_FORMAT.md), a blank line between strokes; a stroke "
                            "going back into the cut adds nothing there. --kerf: saw width in mm, 0 to 20 (0: a zero-width blade, the "
                            "carved volume equals the input); --retrace: a pose within this many voxels of the cut so far is "
                            "dropped as going back over it (the path filter's tolerance, 0 to 4, default 0.25; 1 makes a "
                            "saw worked back and forth many times faster to cut, and the cut may stop short of where the "
                            "blade went by up to that much); --slide: a pose whose blade lies within this many voxels of the "
                            "line of the last kept one is held back as sliding along itself (it sweeps no area) until the "
                            "blade leaves that line (0 to 4, default 0.25); --min-volume: write no file or level set for a fragment "
                            "smaller than MM3 (loose specks; summary.json counts them; default 0: every fragment); --level-set-voxel: the "
                            "voxel size in mm of cut.vdb's level sets (default: the scan's smallest spacing; at least a "
                            "quarter of it); --check: "
                            "exit 1 on any mesh defect; --keep-going: when the re-mesher refuses a "
                            "stroke, cut it up to where it is refused, drop the rest, say so and go on (default: exit 1, "
                            "nothing written)",
                            cutOptions(), {"check", "keep-going"}, 1, 1, runCut});

} // namespace

} // namespace mtcut::cli
