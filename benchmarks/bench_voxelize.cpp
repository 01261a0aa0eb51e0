// Blade voxelisation throughput and the input thread's rate.
//
// Cases (one parseable line each, best of 5):
//   voxelize: filter + exact conservative voxelisation of a stroke's quads
//     (ours, one thread) vs the OpenVDB route: meshToUnsignedDistanceField of
//     the same quads with a 1-voxel band (multi-threaded TBB), the usual way
//     to rasterise a surface into a sparse grid. Quality: cut cells (ours) and
//     active voxels (baseline).
//   mask: inserting the cells into a CutMask (grid + per-cell lists).
//   input: the input thread's achieved pose rate (parse + filter + voxelise +
//     push) with the geometry thread busy (16 ms "frames" between drains),
//     against parsing alone on one thread as the baseline.
// Volume: the 512x512x245 head box (0.5 x 0.5 x 1.0 mm).
#include "cutter/CutMask.h"
#include "cutter/PathFile.h"
#include "vdb/VolumeIO.h"

#include <openvdb/tools/MeshToVolume.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>

using namespace mtcut::cutter;
namespace vdb = mtcut::vdb;
using Clock = std::chrono::steady_clock;

namespace {

template <class F>
double bestMs(int runs, F&& f)
{
    double best = 1e300;
    for (int i = 0; i < runs; ++i) {
        const auto t0 = Clock::now();
        f();
        best = std::min(best, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    }
    return best;
}

void voxelizeCase(const char* name, const IndexFrame& f, const std::vector<std::vector<Pose>>& strokes,
                  double kerf)
{
    std::vector<Quad> quads;
    for (const auto& s : strokes) {
        auto q = filterStroke(s, f);
        quads.insert(quads.end(), q.begin(), q.end());
    }
    size_t cells = 0;
    std::vector<glm::ivec3> buf;
    const double ours = bestMs(5, [&] {
        cells = 0;
        for (const Quad& q : quads) {
            buf.clear();
            voxelizeQuad(q, kerf, f, buf);
            cells += buf.size();
        }
    });
    // Baseline: OpenVDB unsigned distance field of the same quads, 1-voxel band.
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quadIdx;
    auto xform = openvdb::math::Transform::createLinearTransform(1.0);
    xform->preScale(openvdb::Vec3d(f.spacing.x, f.spacing.y, f.spacing.z));
    xform->postTranslate(openvdb::Vec3d(f.origin.x, f.origin.y, f.origin.z));
    for (const Quad& q : quads) {
        const uint32_t b = uint32_t(points.size());
        for (uint32_t i = 0; i < q.cornerCount; ++i)
            points.emplace_back(float(q.corners[i].x), float(q.corners[i].y), float(q.corners[i].z));
        if (q.cornerCount == 4) quadIdx.emplace_back(b, b + 1, b + 2, b + 3);
        else tris.emplace_back(b, b + 1, b + 2);
    }
    size_t baseVoxels = 0;
    const double base = bestMs(5, [&] {
        auto grid = openvdb::tools::meshToUnsignedDistanceField<openvdb::FloatGrid>(*xform, points, tris,
                                                                                   quadIdx, 1.0f);
        baseVoxels = grid->activeVoxelCount();
    });
    CutMask mask(f, kerf);
    std::vector<std::vector<glm::ivec3>> cellLists;
    for (const Quad& q : quads) {
        cellLists.emplace_back();
        voxelizeQuad(q, kerf, f, cellLists.back());
    }
    const double maskMs = bestMs(5, [&] {
        mask = CutMask(f, kerf);
        for (size_t i = 0; i < quads.size(); ++i) mask.addQuad(quads[i], cellLists[i]);
    });
    std::printf("case=voxelize path=%s kerf=%.1f quads=%zu cells=%zu ours_ms=%.2f baseline_ms=%.2f "
                "ratio=%.2f quads_per_s=%.3g cells_per_s=%.3g baseline_voxels=%zu\n",
                name, kerf, quads.size(), cells, ours, base, base / ours, quads.size() / (ours * 1e-3),
                cells / (ours * 1e-3), baseVoxels);
    std::printf("case=mask path=%s kerf=%.1f quads=%zu cut_cells=%zu insert_ms=%.2f cells_per_s=%.3g "
                "memory_MB=%.1f\n",
                name, kerf, quads.size(), mask.cutCellCount(), maskMs, cells / (maskMs * 1e-3),
                mask.memoryBytes() / 1048576.0);
}

void inputCase(const IndexFrame& f, const std::vector<Pose>& stroke)
{
    std::vector<std::string> lines;
    for (int rep = 0; rep < 10; ++rep) { // 10 LeFort strokes in a row
        for (const Pose& p : stroke) lines.push_back(formatPoseLine(p));
        lines.push_back("stroke");
    }
    // Baseline: parsing alone, one thread.
    const double parseMs = bestMs(3, [&] {
        size_t n = 0;
        for (size_t i = 0; i < lines.size(); ++i)
            n += parsePathLine(lines[i], i + 1, "bench").kind == PathLine::Kind::Pose;
        if (n == 0) std::printf("?\n");
    });
    double best = 1e300;
    size_t poses = 0, quads = 0;
    for (int run = 0; run < 3; ++run) {
        InputThreadOptions opt;
        opt.kerfMm = 1.0;
        InputThread input(std::make_unique<MemoryLineSource>(lines), f, opt);
        CutMask mask(f, 1.0);
        std::thread geometry([&] {
            while (true) {
                const bool closed = input.queue().closed();
                drainCutInfo(input.queue(), mask);
                if (closed) break;
                std::this_thread::sleep_for(std::chrono::milliseconds(16)); // busy rendering a frame
            }
        });
        const auto t0 = Clock::now();
        input.start();
        input.join();
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        geometry.join();
        best = std::min(best, ms);
        poses = input.posesRead();
        quads = input.quadsMade();
    }
    std::printf("case=input poses=%zu quads=%zu ours_ms=%.1f baseline_parse_ms=%.1f ratio=%.2f "
                "poses_per_s=%.3g\n",
                poses, quads, best, parseMs, parseMs / best, poses / (best * 1e-3));
}

} // namespace

int main()
{
    openvdb::initialize();
    // The geometry of the 245-slice Visible Human head (512 x 512 x 245 at 1 mm, origin 0,0,1000);
    // read from the DICOM series when it is there, so the frame is the real one.
    IndexFrame head;
    head.dims = glm::ivec3(512, 512, 245);
    head.spacing = glm::dvec3(1.0, 1.0, 1.0);
    head.origin = glm::dvec3(0.0, 0.0, 1000.0);
    const std::string dicom = std::string(MTCUT_SHARED_DATA) + "/vhm-head-dicom";
    if (std::filesystem::is_directory(dicom)) head = frameOf(vdb::readVolume(dicom));
    const std::vector<Pose> lefort = makeLeFortStroke(head);
    for (double kerf : {0.0, 1.0}) voxelizeCase("lefort", head, {lefort}, kerf);
    // Long random strokes across the head: 20 strokes of 4000 poses, 60 mm blade.
    const auto random = makeRandomStrokes(head, 3, 20, 4000, 0.3, 60.0);
    voxelizeCase("random60mm", head, random, 1.0);
    inputCase(head, lefort);
    return 0;
}
