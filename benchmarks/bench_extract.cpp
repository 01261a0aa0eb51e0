// Isosurface extraction: our Marching Tetrahedra (cutter::extractIsosurface)
// against openvdb::tools::volumeToMesh (adaptivity 0) on the same grid and
// isovalue, both on the same TBB thread count (default 2). Per case one line:
//   case=... iso=... threads=N ours_s=.. vdb_s=.. ratio=vdb/ours ours_tris=..
//   vdb_tris=.. ours_tris_per_s=.. vdb_tris_per_s=.. ours_peak_mib=..
//   vdb_peak_mib=.. ours_defects=.. vdb_defects=..
// Times are medians of 5 runs. Peak memory is the rise of the process's
// resident high-water mark (VmHWM, reset through /proc/self/clear_refs)
// during the first run, output included (malloc_trim before, fixed mmap
// threshold, so freed buffers do not hide it). volumeToMesh's quads are split into two
// triangles and its winding reversed (it treats values below the isovalue as
// inside; bone is above) before checkMesh counts its defects.
//
// Usage: bench_extract [--threads N] [--runs N] [--quick] [--hash]
//   --quick: 256x256x128 phantom, 4 mm head. --hash: no timing; one line per
//   case (isovalues 400 and -300) with an FNV-1a hash of every output array,
//   to check that an optimisation leaves the mesh bit for bit unchanged.
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "vdb/Phantom.h"
#include "vdb/VolumeIO.h"

#include <openvdb/tools/VolumeToMesh.h>
#include <malloc.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

using namespace mtcut;

namespace {

long statusKiB(const char* key)
{
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line)) {
        if (line.compare(0, std::strlen(key), key) == 0) return std::stol(line.substr(std::strlen(key) + 1));
    }
    return 0;
}

/// Seconds (median of runs) and peak resident rise (MiB, first run) of f.
std::pair<double, double> measure(int runs, const std::function<void()>& f)
{
    std::vector<double> seconds;
    double peakMiB = 0.0;
    for (int r = 0; r < runs; ++r) {
        malloc_trim(0); // give freed pages back, so the high-water mark measures this run
        std::ofstream("/proc/self/clear_refs") << "5";
        const long before = statusKiB("VmRSS:");
        const auto t0 = std::chrono::steady_clock::now();
        f();
        seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        if (r == 0) peakMiB = double(statusKiB("VmHWM:") - before) / 1024.0;
    }
    std::sort(seconds.begin(), seconds.end());
    return {seconds[seconds.size() / 2], peakMiB};
}

cutter::Mesh fromVdb(const std::vector<openvdb::Vec3s>& points, const std::vector<openvdb::Vec3I>& tris,
                     const std::vector<openvdb::Vec4I>& quads)
{
    cutter::Mesh m;
    for (const auto& p : points) m.positions.emplace_back(p.x(), p.y(), p.z());
    for (const auto& t : tris) m.indices.insert(m.indices.end(), {t[0], t[2], t[1]});
    for (const auto& q : quads) m.indices.insert(m.indices.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
    return m;
}

/// FNV-1a 64 over the bytes of the mesh's arrays (sizes included).
uint64_t meshHash(const cutter::Mesh& m)
{
    uint64_t h = 1469598103934665603ull;
    auto add = [&](const void* data, size_t bytes) {
        const unsigned char* p = static_cast<const unsigned char*>(data);
        for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
    };
    const size_t sizes[4] = {m.positions.size(), m.normals.size(), m.indices.size(), m.triangleVoxels.size()};
    add(sizes, sizeof(sizes));
    add(m.positions.data(), m.positions.size() * sizeof(glm::vec3));
    add(m.normals.data(), m.normals.size() * sizeof(glm::vec3));
    add(m.indices.data(), m.indices.size() * sizeof(uint32_t));
    add(m.triangleVoxels.data(), m.triangleVoxels.size() * sizeof(glm::ivec3));
    return h;
}

void hashCase(const std::string& name, const vdb::Volume& vol, float iso, int threads)
{
    const cutter::Mesh mesh = cutter::extractIsosurface(vol, iso);
    std::printf("case=%s iso=%g threads=%d tris=%zu verts=%zu hash=%016llx\n", name.c_str(), double(iso), threads,
                mesh.triangleCount(), mesh.vertexCount(), static_cast<unsigned long long>(meshHash(mesh)));
    std::fflush(stdout);
}

void runCase(const std::string& name, const vdb::Volume& vol, float iso, int threads, int runs)
{
    cutter::Mesh ours;
    const auto [oursS, oursPeak] = measure(runs, [&] {
        ours = cutter::Mesh();
        ours = cutter::extractIsosurface(vol, iso);
    });
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    const auto [vdbS, vdbPeak] = measure(runs, [&] {
        points.clear();
        tris.clear();
        quads.clear();
        openvdb::tools::volumeToMesh(*vol.grid, points, tris, quads, double(iso), 0.0);
    });
    const size_t vdbTris = tris.size() + 2 * quads.size();
    const cutter::MeshCheck oursCheck = cutter::checkMesh(ours);
    const cutter::MeshCheck vdbCheck = cutter::checkMesh(fromVdb(points, tris, quads));
    std::printf("case=%s iso=%g threads=%d ours_s=%.4f vdb_s=%.4f ratio=%.2f ours_tris=%zu vdb_tris=%zu "
                "ours_tris_per_s=%.3g vdb_tris_per_s=%.3g ours_peak_mib=%.1f vdb_peak_mib=%.1f ours_defects=%zu "
                "vdb_defects=%zu\n",
                name.c_str(), double(iso), threads, oursS, vdbS, vdbS / oursS, ours.triangleCount(), vdbTris,
                double(ours.triangleCount()) / oursS, double(vdbTris) / vdbS, oursPeak, vdbPeak, oursCheck.defects(),
                vdbCheck.defects());
    if (!vdbCheck.ok()) {
        std::printf("  volumeToMesh defects: boundary %zu, non-manifold edges %zu, inconsistent %zu, "
                    "non-manifold vertices %zu, degenerate %zu, wrong-way shells %zu\n",
                    vdbCheck.boundaryEdges, vdbCheck.nonManifoldEdges, vdbCheck.inconsistentEdges,
                    vdbCheck.nonManifoldVertices, vdbCheck.degenerateTriangles, vdbCheck.negativeVolumeShells);
    }
    std::fflush(stdout);
}

} // namespace

int main(int argc, char** argv)
{
    int threads = 2, runs = 5;
    bool quick = false, hash = false;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) threads = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--runs") && i + 1 < argc) runs = std::max(1, std::atoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--quick")) quick = true;
        else if (!std::strcmp(argv[i], "--hash")) hash = true;
    }
    openvdb::initialize();
    mallopt(M_MMAP_THRESHOLD, 1 << 20); // fixed: big buffers are mmapped and returned when freed
    tbb::global_control control(tbb::global_control::max_allowed_parallelism, size_t(threads));
    try {
        {
            vdb::PhantomOptions options;
            options.dims = quick ? openvdb::Coord(256, 256, 128) : openvdb::Coord(512, 512, 256);
            const vdb::Volume phantom = vdb::makePhantom(options);
            const std::string name = "phantom-" + std::to_string(options.dims.x()) + "x" +
                                     std::to_string(options.dims.y()) + "x" + std::to_string(options.dims.z());
            if (hash) {
                hashCase(name, phantom, 400.0f, threads);
                hashCase(name, phantom, -300.0f, threads);
            } else {
                runCase(name, phantom, 400.0f, threads, runs);
            }
        }
        const std::string data = MTCUT_SHARED_DATA;
        const std::string head = data + (quick ? "/vhm_head_4mm.nhdr" : "/vhm-head-dicom");
        if (std::filesystem::exists(head)) {
            const vdb::Volume vol = vdb::readVolume(head);
            const std::string name = quick ? "vhm-head-4mm" : "vhm-head-dicom-512x512x245";
            for (float iso : {400.0f, -300.0f}) {
                if (hash) hashCase(name, vol, iso, threads);
                else runCase(name, vol, iso, threads, runs);
            }
        } else {
            std::printf("case=vhm-head skipped: %s not found\n", head.c_str());
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_extract: %s\n", e.what());
        return 1;
    }
    return 0;
}
