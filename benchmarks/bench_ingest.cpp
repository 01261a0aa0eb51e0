// Ingest: getting a CT head into a sparse grid.
//
// Cases (one parseable line each; times are medians of --runs, default 5):
//   phantom-512x512x256: makePhantomScan (make_s), then the dense -> sparse step.
//   dicom-vhm-head-512x512x245: readVolume of the 245-slice DICOM series
//     (read_s: decode + sparse), then the dense -> sparse step on its array.
// The dense -> sparse step, ours: makeVolume (air pruning, exact values within
// a block of tissue). Baseline: OpenVDB's own route, tools::copyFromDense with
// tolerance 0 into a FloatGrid with the same background (the minimum), on the
// same dense array. speedup = baseline_s / ours_s. Sizes: active voxels, grid
// memUsage (vdb_bytes, baseline_bytes), our grid written to .vdb (file_bytes),
// the dense float array (dense_bytes). Peak memory (peak_mib: the whole ingest,
// ours; baseline_peak_mib: dense array + copyFromDense) is VmHWM of a forked
// child that does only that case, measured before this process starts threads.
//
// Usage: bench_ingest [--runs N] [--skip-dicom]
#include "vdb/Phantom.h"
#include "vdb/VolumeIO.h"

#include <openvdb/tools/Dense.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

using namespace mtcut;
using namespace mtcut::vdb;
using Clock = std::chrono::steady_clock;

namespace {

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Peak resident memory of this process so far (VmHWM), MiB.
double peakMib()
{
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("VmHWM:", 0) == 0) return std::strtod(line.c_str() + 6, nullptr) / 1024.0;
    }
    return -1.0;
}

/// Runs work in a forked child and returns the child's peak memory (MiB), or
/// -1 if it failed. Call before this process starts TBB threads.
double peakInChild(const std::function<void()>& work)
{
    int fd[2];
    if (::pipe(fd) != 0) return -1.0;
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::close(fd[0]);
        double peak = -1.0;
        try {
            work();
            peak = peakMib();
        } catch (const std::exception& e) {
            std::fprintf(stderr, "child: %s\n", e.what());
        }
        [[maybe_unused]] const ssize_t w = ::write(fd[1], &peak, sizeof(peak));
        ::_exit(0);
    }
    ::close(fd[1]);
    double peak = -1.0;
    if (pid < 0 || ::read(fd[0], &peak, sizeof(peak)) != ssize_t(sizeof(peak))) peak = -1.0;
    ::close(fd[0]);
    if (pid > 0) ::waitpid(pid, nullptr, 0);
    return peak;
}

/// OpenVDB's dense -> sparse route on a canonical dense scan (i fastest).
openvdb::FloatGrid::Ptr baselineGrid(const DenseScan& scan, float background)
{
    const openvdb::Coord& d = scan.geometry.dims;
    // LayoutZYX: z slowest, x fastest - the DenseScan order.
    openvdb::tools::Dense<const float, openvdb::tools::LayoutZYX> dense(
        openvdb::CoordBBox(openvdb::Coord(0), d - openvdb::Coord(1)), scan.values.data());
    auto grid = openvdb::FloatGrid::create(background);
    openvdb::tools::copyFromDense(dense, *grid, /*tolerance=*/0.0f);
    return grid;
}

float minimum(const std::vector<float>& v) { return *std::min_element(v.begin(), v.end()); }

uint64_t fileBytes(const Volume& vol)
{
    const std::string path =
        (std::filesystem::temp_directory_path() / ("bench_ingest_" + std::to_string(::getpid()) + ".vdb")).string();
    writeVolume(vol, path);
    const uint64_t n = std::filesystem::file_size(path);
    std::filesystem::remove(path);
    return n;
}

struct Peaks
{
    double ours = -1.0, baseline = -1.0;
};

/// Times the dense -> sparse step (ours and baseline) on `dense` and prints the case line.
void sparseCase(const std::string& name, const DenseScan& dense, const std::string& firstTimes, int runs,
                const Peaks& peaks)
{
    std::vector<double> ours, base;
    Volume vol;
    openvdb::FloatGrid::Ptr baseGrid;
    const float background = minimum(dense.values);
    for (int r = 0; r < runs; ++r) {
        DenseScan copy = dense; // makeVolume consumes its input; the copy is not timed
        auto t0 = Clock::now();
        vol = makeVolume(std::move(copy), name);
        ours.push_back(seconds(t0));
        baseGrid.reset();
        t0 = Clock::now();
        baseGrid = baselineGrid(dense, background);
        base.push_back(seconds(t0));
    }
    const VolumeStats stats = computeStats(vol);
    const double oursS = median(ours), baseS = median(base);
    std::printf("case=%s %s ours_s=%.3f baseline_s=%.3f speedup=%.2f active=%llu baseline_active=%llu "
                "vdb_bytes=%llu baseline_bytes=%llu file_bytes=%llu dense_bytes=%llu dense_over_vdb=%.2f "
                "peak_mib=%.0f baseline_peak_mib=%.0f runs=%d\n",
                name.c_str(), firstTimes.c_str(), oursS, baseS, baseS / oursS,
                (unsigned long long)stats.activeVoxels, (unsigned long long)baseGrid->activeVoxelCount(),
                (unsigned long long)stats.memoryBytes, (unsigned long long)baseGrid->memUsage(),
                (unsigned long long)fileBytes(vol), (unsigned long long)stats.denseBytes,
                double(stats.denseBytes) / double(stats.memoryBytes), peaks.ours, peaks.baseline, runs);
    std::fflush(stdout);
}

bool notImplemented(const std::exception& e) { return std::strstr(e.what(), "not implemented") != nullptr; }

} // namespace

int run(int argc, char** argv)
{
    int runs = 5;
    bool skipDicom = false;
    for (int a = 1; a < argc; ++a) {
        if (!std::strcmp(argv[a], "--runs") && a + 1 < argc) runs = std::max(1, std::atoi(argv[++a]));
        else if (!std::strcmp(argv[a], "--skip-dicom")) skipDicom = true;
        else {
            std::fprintf(stderr, "usage: %s [--runs N] [--skip-dicom]\n", argv[0]);
            return 2;
        }
    }
    openvdb::initialize();
    const char* env = std::getenv("MTCUT_DATA");
    const std::string dicom = std::string(env ? env : MTCUT_SHARED_DATA) + "/vhm-head-dicom";
    const bool haveDicom = !skipDicom && std::filesystem::is_directory(dicom);

    // Peaks first, each in its own child, before this process starts threads.
    const PhantomOptions phantom; // 512 x 512 x 256, seed 1
    Peaks phantomPeaks, dicomPeaks;
    phantomPeaks.ours = peakInChild([&] { makePhantom(phantom); });
    phantomPeaks.baseline = peakInChild([&] {
        const DenseScan s = makePhantomScan(phantom);
        baselineGrid(s, minimum(s.values));
    });
    if (haveDicom) {
        dicomPeaks.ours = peakInChild([&] { readVolume(dicom); });
        dicomPeaks.baseline = peakInChild([&] {
            const DenseScan s = toDense(readVolume(dicom));
            baselineGrid(s, minimum(s.values));
        });
    }

    // Phantom.
    {
        std::vector<double> make;
        DenseScan scan;
        for (int r = 0; r < std::max(3, runs); ++r) {
            const auto t0 = Clock::now();
            scan = makePhantomScan(phantom);
            make.push_back(seconds(t0));
        }
        char times[64];
        std::snprintf(times, sizeof(times), "make_s=%.3f", median(make));
        sparseCase("phantom-512x512x256", scan, times, runs, phantomPeaks);
    }

    // DICOM head.
    const std::string dicomCase = "dicom-vhm-head-512x512x245";
    if (skipDicom) {
        std::printf("case=%s skipped=\"--skip-dicom\"\n", dicomCase.c_str());
    } else if (!haveDicom) {
        std::printf("case=%s skipped=\"%s not found (set MTCUT_DATA)\"\n", dicomCase.c_str(), dicom.c_str());
    } else {
        try {
            std::vector<double> read;
            Volume vol;
            for (int r = 0; r < std::max(3, runs); ++r) {
                const auto t0 = Clock::now();
                vol = readVolume(dicom);
                read.push_back(seconds(t0));
            }
            char times[64];
            std::snprintf(times, sizeof(times), "read_s=%.3f", median(read));
            sparseCase(dicomCase, toDense(vol), times, runs, dicomPeaks);
        } catch (const std::exception& e) {
            if (!notImplemented(e)) throw;
            std::printf("case=%s skipped=\"%s\"\n", dicomCase.c_str(), e.what());
        }
    }
    return 0;
}

int main(int argc, char** argv)
{
    try {
        return run(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_ingest: %s\n", e.what());
        return 1;
    }
}
