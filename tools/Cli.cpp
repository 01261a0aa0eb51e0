#include "tools/Cli.h"

#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/LiveStroke.h"
#include "cutter/PathFile.h"
#include "cutter/Remesh.h"
#include "vdb/Error.h"

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <regex>
#include <unistd.h>

namespace mtcut::cli {

namespace {
std::map<std::string, Command>& registry()
{
    static std::map<std::string, Command> r;
    return r;
}
std::atomic<bool> gInterrupted{false};
extern "C" void onSigint(int) { gInterrupted = true; }
} // namespace

CommandRegistrar::CommandRegistrar(Command command)
{
    registry().emplace(command.name, std::move(command));
}
const std::map<std::string, Command>& commands() { return registry(); }

std::string Args::get(const std::string& name, const std::string& fallback) const
{
    auto it = options.find(name);
    return it == options.end() ? fallback : it->second;
}

double Args::getDouble(const std::string& name, double fallback) const
{
    auto it = options.find(name);
    if (it == options.end()) return fallback;
    char* end = nullptr;
    const double v = std::strtod(it->second.c_str(), &end);
    if (it->second.empty() || *end != '\0') {
        throw InputError("--" + name + " " + it->second + ": expected a number");
    }
    return v;
}

double Args::kerfMm() const
{
    const double kerf = getDouble("kerf", 0.0);
    if (!(kerf >= 0.0 && kerf <= cutter::kMaxKerfMm))
        throw InputError("--kerf " + get("kerf") + ": expected a saw width from 0 to " +
                         std::to_string(int(cutter::kMaxKerfMm)) + " mm");
    return kerf;
}

cutter::PathFilterOptions Args::pathFilterOptions() const
{
    cutter::PathFilterOptions o;
    o.retraceTolerance = filterToleranceWith(getDouble("retrace", o.retraceTolerance), "--retrace " + get("retrace"),
                                             o.retraceTolerance);
    o.slideTolerance =
        filterToleranceWith(getDouble("slide", o.slideTolerance), "--slide " + get("slide"), o.slideTolerance);
    return o;
}

double filterToleranceWith(double voxels, const std::string& what, double fallback)
{
    if (!(voxels >= 0.0 && voxels <= cutter::kMaxRetraceTolerance)) {
        char text[128];
        std::snprintf(text, sizeof text, ": expected a tolerance from 0 to %g voxels (default %g)",
                      cutter::kMaxRetraceTolerance, fallback);
        throw InputError(what + text);
    }
    return voxels;
}

float Args::isoValue(const std::string& command) const
{
    if (!has("iso"))
        throw InputError("mtcut " + command +
                         " needs --iso V (the isovalue, in the scan's units; `mtcut info INPUT` suggests one for bone)");
    const double iso = getDouble("iso", 0.0);
    if (!std::isfinite(iso)) throw InputError("--iso " + get("iso") + ": expected a finite number");
    return float(iso);
}

long long Args::getInt(const std::string& name, long long fallback) const
{
    auto it = options.find(name);
    if (it == options.end()) return fallback;
    char* end = nullptr;
    const long long v = std::strtoll(it->second.c_str(), &end, 10);
    if (it->second.empty() || *end != '\0') {
        throw InputError("--" + name + " " + it->second + ": expected an integer");
    }
    return v;
}

const std::vector<std::string> kInputOptions = {"series", "grid", "air", "dims", "type",
                                                "endian", "spacing", "origin", "offset"};

vdb::ReadOptions readOptions(const Args& args)
{
    vdb::ReadOptions options;
    options.seriesUid = args.get("series");
    options.gridName = args.get("grid");
    if (args.has("air")) options.sparse.airThreshold = float(args.getDouble("air", 0.0));
    std::string spec;
    for (const char* key : {"dims", "type", "endian", "spacing", "origin", "offset"}) {
        if (args.has(key)) spec += std::string(key) + "=" + args.get(key) + " ";
    }
    if (!spec.empty()) options.raw = vdb::parseRawOptions(spec);
    return options;
}

vdb::Volume readInput(const std::string& path, const Args& args)
{
    ProgressBar progress;
    return vdb::readVolume(path, readOptions(args), &progress);
}

cutter::Mesh extractSurface(const vdb::Volume& vol, float iso)
{
    const std::string warning = cutter::isosurfaceWarning(vol, iso);
    if (!warning.empty()) std::fprintf(stderr, "mtcut: warning: %s\n", warning.c_str());
    ProgressBar progress;
    cutter::IsosurfaceOptions options;
    options.interrupter = &progress;
    return cutter::extractIsosurface(vol, iso, options);
}

std::vector<std::vector<cutter::Pose>> readStrokes(const std::string& pathFile)
{
    std::vector<std::vector<cutter::Pose>> strokes = cutter::readPathFile(pathFile);
    if (strokes.empty()) throw InputError(pathFile + ": no poses (an empty path cuts nothing)");
    return strokes;
}

size_t addStrokes(cutter::CutMask& mask, const std::vector<std::vector<cutter::Pose>>& strokes,
                  const cutter::PathFilterOptions& filterOptions)
{
    size_t count = 0;
    // One filter for all strokes, knowing the cut so far: a stroke that goes
    // back into the cut adds nothing there (rule 2b).
    cutter::PathFilter filter(mask.frame(), filterOptions);
    cutter::setEarlierQuads(mask, filter);
    for (const std::vector<cutter::Pose>& stroke : strokes) {
        const std::vector<cutter::Quad> quads = filter.pushStroke(stroke);
        if (quads.empty()) continue;
        mask.beginStroke();
        for (const cutter::Quad& q : quads) {
            mask.addQuad(q);
            filter.addEarlierQuad(q);
        }
        count += quads.size();
    }
    return count;
}

size_t cutStrokeByStroke(cutter::CutRemesher& remesher, cutter::CutMask& mask,
                         const std::vector<std::vector<cutter::Pose>>& strokes,
                         const cutter::PathFilterOptions& filterOptions, std::vector<RefusedStroke>& refused,
                         std::vector<size_t>* steppedRound, std::vector<uint32_t>* maskStrokes)
{
    size_t count = 0;
    if (maskStrokes) maskStrokes->assign(strokes.size(), 0);
    cutter::PathFilter filter(mask.frame(), filterOptions);
    cutter::setEarlierQuads(mask, filter); // a stroke going back into the cut so far adds nothing there
    for (size_t i = 0; i < strokes.size(); ++i) {
        // As filter.pushStroke, knowing which pose made each quad.
        std::vector<cutter::Quad> quads;
        std::vector<double> times; // per quad: the time of the pose that made it
        for (const cutter::Pose& pose : strokes[i]) {
            filter.push(pose, quads);
            times.resize(quads.size(), pose.time);
        }
        for (const cutter::Quad& q : filter.endStroke()) quads.push_back(q);
        times.resize(quads.size(), strokes[i].empty() ? 0.0 : strokes[i].back().time);
        if (quads.empty()) continue;
        mask.beginStroke();
        for (const cutter::Quad& q : quads) mask.addQuad(q);
        std::string why = refusalOf(remesher, mask);
        size_t kept = quads.size();
        if (!why.empty()) {
            // Again quad by quad, as the viewer cuts a live stroke: a refusal
            // of where the blade stops at one quad waits for the next.
            mask.undoStroke(); // as the remesher holds it
            cutter::LiveStroke live(mask, remesher);
            cutter::LiveStroke::Result r;
            for (size_t q = 0; q < quads.size() && !live.stopped(); ++q) {
                live.add(quads[q]);
                r = live.update();
            }
            if (!live.stopped()) r = live.finish();
            why = r.refusal;
            kept = live.acceptedQuads();
            if (steppedRound && live.steppedRound() > 0) steppedRound->push_back(i + 1);
            if (kept < quads.size())
                refused.push_back({i + 1, kept, quads.size(), times[kept], describeRefusal(why, mask.frame(), mask.kerf())});
        }
        for (size_t k = 0; k < kept; ++k) filter.addEarlierQuad(quads[k]);
        if (maskStrokes && kept > 0) (*maskStrokes)[i] = mask.strokeCount();
        count += kept;
    }
    return count;
}

std::string describeRefusal(const std::string& what, const cutter::IndexFrame& frame, double kerf)
{
    if (what.rfind("remesh: ", 0) != 0) return what; // not a refusal
    std::string out = what;
    std::smatch m;
    static const std::regex cell(R"(cell \((-?[0-9]+), (-?[0-9]+), (-?[0-9]+)\))");
    if (std::regex_search(what, m, cell)) {
        const glm::dvec3 c = frame.toWorld(glm::dvec3(std::stod(m[1]) + 0.5, std::stod(m[2]) + 0.5, std::stod(m[3]) + 0.5));
        char buf[128];
        std::snprintf(buf, sizeof buf, ", centred at (%.2f, %.2f, %.2f) mm", c.x, c.y, c.z);
        out += buf;
    }
    out += "; the re-mesher refuses rather than write a broken surface";
    if (kerf == 0.0) out += " (a stroke that crosses or pivots through itself may go through with a saw width: kerf > 0, e.g. --kerf 0.5)";
    return out;
}

void printStrokeByStroke(const std::vector<RefusedStroke>& refused, const std::vector<size_t>& steppedRound)
{
    for (const RefusedStroke& r : refused)
        std::printf("refused:    stroke %zu at quad %zu of %zu (made by the pose at t = %g s): cut to quad %zu, the "
                    "rest dropped: %s\n",
                    r.stroke, r.quadsKept + 1, r.quads, r.time, r.quadsKept, r.message.c_str());
    for (const size_t s : steppedRound)
        std::printf("stepped:    stroke %zu stepped round a refusal below a float step (its blade moved by at most "
                    "%g voxel there)\n",
                    s, cutter::LiveStroke::kStepRoundMostVoxels);
}

size_t mostQuadsInACell(const cutter::CutMask& mask, const std::vector<openvdb::Coord>& cells)
{
    size_t most = 0;
    for (const openvdb::Coord& c : cells)
        if (const std::vector<cutter::QuadRef>* list = mask.quadsAt(c)) most = std::max(most, list->size());
    return most;
}

std::string manyQuadsNote(size_t most, double retraceVoxels, const std::string& how)
{
    if (most < kManyQuadsPerCell || retraceVoxels >= 1.0) return {};
    char text[512];
    std::snprintf(text, sizeof text,
                  "up to %zu quads cross one cut cell (a saw worked back and forth over its cut lays one over the "
                  "whole blade each time it goes %g voxel deeper), and each that the others do not cover makes the "
                  "cell slower to re-mesh; %s lays one only once it goes a voxel deeper (the cut may then lag the "
                  "blade by up to a voxel)",
                  most, retraceVoxels, how.c_str());
    return text;
}

std::string describeRefusalWithHint(const std::string& what, const cutter::IndexFrame& frame, double kerf,
                                    bool keepGoing)
{
    std::string why = describeRefusal(what, frame, kerf);
    if (!keepGoing && cutter::LiveStroke::belowAFloatStep(what))
        why += "; --keep-going cuts the strokes one by one as live strokes, which step round a refusal below a "
               "float step like this one (moving the blade by a hundredth of a voxel at most)";
    return why;
}

ProgressBar::ProgressBar() : mTty(::isatty(2) != 0)
{
    gInterrupted = false;
    std::signal(SIGINT, onSigint);
}

ProgressBar::~ProgressBar() { std::signal(SIGINT, SIG_DFL); }

void ProgressBar::start(const char* name)
{
    std::lock_guard<std::mutex> lock(mMutex);
    mName = name ? name : "";
    mLast = -1;
}

void ProgressBar::end()
{
    std::lock_guard<std::mutex> lock(mMutex);
    if (mTty && mLast >= 0) std::fprintf(stderr, "\r\033[K");
    mLast = -1;
}

bool ProgressBar::wasInterrupted(int percent)
{
    if (mTty && percent >= 0 && percent != mLast.load()) {
        std::unique_lock<std::mutex> lock(mMutex, std::try_to_lock);
        if (lock.owns_lock() && percent > mLast) {
            mLast = percent;
            constexpr int kWidth = 30;
            const int filled = percent * kWidth / 100;
            std::fprintf(stderr, "\r%-28.28s [%s%s] %3d%%", mName.c_str(), std::string(size_t(filled), '#').c_str(),
                         std::string(size_t(kWidth - filled), ' ').c_str(), percent);
            std::fflush(stderr);
        }
    }
    return gInterrupted.load();
}

std::string humanBytes(double bytes)
{
    const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
    int u = 0;
    while (bytes >= 1024.0 && u < 4) {
        bytes /= 1024.0;
        ++u;
    }
    char buf[64];
    std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", bytes, units[u]);
    return buf;
}

} // namespace mtcut::cli
