// mtcut info | convert | phantom: the volume commands.
#include "tools/Cli.h"
#include "vdb/Phantom.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace mtcut::cli {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string num(double v)
{
    std::ostringstream os;
    os << v;
    return os.str();
}

void printInfo(const vdb::Volume& vol, const std::string& format, double seconds)
{
    const vdb::VolumeStats stats = vdb::computeStats(vol);
    const auto s = vol.spacing();
    const auto o = vol.origin();
    const std::string u = vol.units.empty() ? "" : " " + vol.units;
    std::printf("input:     %s (%s)\n", vol.source.c_str(), format.c_str());
    std::printf("grid:      %d x %d x %d voxels\n", vol.dims.x(), vol.dims.y(), vol.dims.z());
    if (s.x() == s.y() && s.y() == s.z()) {
        std::printf("spacing:   %s mm\n", num(s.x()).c_str());
    } else {
        std::printf("spacing:   %s x %s x %s mm\n", num(s.x()).c_str(), num(s.y()).c_str(), num(s.z()).c_str());
    }
    std::printf("origin:    (%s, %s, %s) mm, LPS, centre of voxel (0,0,0)\n", num(o.x()).c_str(),
                num(o.y()).c_str(), num(o.z()).c_str());
    std::printf("extent:    %s x %s x %s mm\n", num(s.x() * vol.dims.x()).c_str(),
                num(s.y() * vol.dims.y()).c_str(), num(s.z() * vol.dims.z()).c_str());
    std::printf("values:    %s .. %s%s\n", num(vol.minValue).c_str(), num(vol.maxValue).c_str(), u.c_str());
    std::printf("air:       <= %s%s (inactive)\n", num(vol.airThreshold).c_str(), u.c_str());
    std::printf("active:    %llu voxels (%.1f%% of %llu)\n", (unsigned long long)stats.activeVoxels,
                100.0 * double(stats.activeVoxels) / double(vol.voxelCount()),
                (unsigned long long)vol.voxelCount());
    std::printf("memory:    %s sparse, %s as dense float (%.1f%%)\n", humanBytes(double(stats.memoryBytes)).c_str(),
                humanBytes(double(stats.denseBytes)).c_str(),
                100.0 * double(stats.memoryBytes) / double(stats.denseBytes));
    std::printf("bone iso:  %s%s (suggested)\n", num(std::round(stats.suggestedBoneIso)).c_str(), u.c_str());
    std::printf("read in:   %.2f s\n", seconds);
}

int runInfo(const Args& args)
{
    const std::string& path = args.positional[0];
    const auto t0 = Clock::now();
    const vdb::Volume vol = readInput(path, args);
    printInfo(vol, vdb::formatName(vdb::detectFormat(path, readOptions(args))), secondsSince(t0));
    return 0;
}

int runConvert(const Args& args)
{
    const auto t0 = Clock::now();
    const vdb::Volume vol = readInput(args.positional[0], args);
    vdb::writeVolume(vol, args.positional[1]);
    std::printf("wrote %s: %d x %d x %d voxels in %.2f s\n", args.positional[1].c_str(), vol.dims.x(),
                vol.dims.y(), vol.dims.z(), secondsSince(t0));
    return 0;
}

/// "X,Y,Z" of positive integers.
openvdb::Coord parseSize(const std::string& text)
{
    openvdb::Coord c;
    char extra = 0;
    if (std::sscanf(text.c_str(), "%d,%d,%d%c", &c[0], &c[1], &c[2], &extra) != 3 || c[0] <= 0 || c[1] <= 0 ||
        c[2] <= 0) {
        throw InputError("--size " + text + ": expected three positive integers X,Y,Z");
    }
    return c;
}

int runPhantom(const Args& args)
{
    vdb::PhantomOptions options;
    if (args.has("size")) options.dims = parseSize(args.get("size"));
    vdb::checkDims(options.dims, "--size " + args.get("size"));
    const long long seed = args.getInt("seed", options.seed);
    if (seed < 0 || seed > 0xffffffffLL) throw InputError("--seed " + args.get("seed") + ": expected 0..4294967295");
    options.seed = uint32_t(seed);
    const auto t0 = Clock::now();
    ProgressBar progress;
    const vdb::Volume vol = vdb::makePhantom(options, &progress);
    vdb::writeVolume(vol, args.positional[0]);
    std::printf("wrote %s: phantom %d x %d x %d voxels, seed %u, in %.2f s\n", args.positional[0].c_str(),
                vol.dims.x(), vol.dims.y(), vol.dims.z(), options.seed, secondsSince(t0));
    return 0;
}

const CommandRegistrar info({"info", "info INPUT", "grid size, spacing, values, memory, suggested bone isovalue",
                             kInputOptions, {}, 1, 1, runInfo});
const CommandRegistrar convert({"convert", "convert INPUT OUT.{vdb,nrrd,nhdr,mha,mhd,raw}",
                                "convert a scan to a sparse VDB (or another volume format)", kInputOptions, {}, 2, 2,
                                runConvert});
const CommandRegistrar phantom({"phantom", "phantom OUT.vdb [--size X,Y,Z] [--seed N]",
                                "write the procedural CT-head phantom (default 512,512,256)", {"size", "seed"}, {},
                                1, 1, runPhantom});

} // namespace

} // namespace mtcut::cli
