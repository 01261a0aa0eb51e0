// Cut-update latency: a new piece of stroke -> cut mask -> re-meshed and
// fused geometry (CutRemesher), for straight strokes (kerf 0, then 0.5 mm) through bone
// whose cut-cell counts are close to the paper's Table 1 (419, 3,638 and
// 11,716 cells), on the phantom (512x512x256) and on the real VHM head
// (512x512x245, 1 mm, iso 400 HU), against two baselines run in the same
// process:
//   (a) re-extract: carve the cut cells' voxels out of the volume
//       (vdb::carveVolume; cell (i,j,k) -> voxel (i,j,k), a 1-voxel slot) and
//       extractIsosurface of the whole volume (TBB, 2 threads), i.e. what a
//       tool without local re-meshing does per step;
//   (b) the OpenVDB route: the bone as a narrow-band level set (built once,
//       outside the timing: volumeToMesh of the CT grid at the isovalue ->
//       meshToLevelSet, uniform voxel = the scan's smallest spacing, half
//       width 3), and per step: the step's quad as a closed slab mesh of
//       thickness max(kerf, 1 level-set voxel) -> meshToLevelSet, a deep copy
//       of the bone level set, csgDifference, volumeToMesh (2 threads).
//
// Ours (one core: tbb::global_control max_allowed_parallelism 1):
//   step:  one new quad (QuadRegion voxelisation + CutMask::addQuad) to the
//          updated cut geometry (CutRemesher::update); fusedMesh() (an
//          O(whole mesh) copy the GPU path does not need) timed separately,
//          in a second pass over the same steps (between timed steps it
//          would leave the caches cold: 1.2 vs 0.55 ms per step, 11,748 cells, kerf 0).
//          The steps are the last `kSteps` quads of the cut, re-added after
//          CutMask::undoToQuad, so the mask holds the whole cut minus a few
//          quads when they run (the real haptic situation at that cut size).
//   view:  after a step, what an interactive view needs instead of a fused
//          mesh: the geometry of CutRemesher::lastChangedCells() gathered into
//          world-mm float positions and indices (what a renderer uploads).
//   whole: a fresh remesher's update() over the whole mask, and + fusedMesh().
//   "re-meshed" counts the cells the kernel ran on (update()'s result): air
//          cells (all eight corners outside the bone) are recorded without it,
//          so "us per cell" is a whole update's time per cell of bone.
//   noop:  update() when nothing changed (the per-update O(cut cells) scan).
//   kernel: one CellKernel over every cut cell, from outside, each quad's
//          geometry built once (remesh_detail::KernelQuads); no fusion, no
//          local check, one thread (until 2026-11-28 each cell's quads were
//          built anew, with kerf > 0 every prism of the stroke again per cell,
//          so this column could exceed the whole update()).
// Times are medians of --runs repeats (steps: runs x kSteps samples).
//
// The stroke (benchmarks/BenchCuts.h, shared with bench_render): in a
// horizontal plane at the LeFort I level (phantom: its leFortZ landmark;
// head: 0.32 of the box height), half a voxel off the grid planes, the base
// sweeping along +x in front of the face, the blade pointing posterior; its
// length binary-searched for each target cell count (cut cells = the mask's
// cells, air included; "surface cells" are those with new geometry). When
// the remesher refuses a stroke (it throws for some configurations) the other
// variants of BenchCuts.h are tried in order (see StrokeKind): shifted and
// turned ones, then ones whose tip line holds no bone surface ("air"), then
// through-cuts; the count of refused strokes is printed.
//
// Usage: bench_cut [--quick] [--runs N] [--phantom-only] [--head-only]
//                  [--targets N,N,...] [--no-baselines] [--dump DIR] [--hash] [--threads N]
//                  [--first-variant N]
//   --first-variant N: start at stroke variant N (BenchCuts.h, StrokeKind):
//          1..3 are the tip strokes pitched 2N and yawed 1.5N degrees, so
//          their kerf faces lie along no grid plane (variant 0's are level).
//   --threads N: run ours (the remesher) on N threads instead of one core
//          (CutRemesher::update re-meshes the cells in parallel; the goals
//          and the tables are one core; results are identical: --hash).
//   --quick: 256x256x128 phantom and the 4 mm head, targets 100,419,1000, 1 run.
//   --no-baselines: ours only (to profile the remesher, e.g. under perf).
//   --dump DIR: write every refused stroke to DIR as a path file (mtcut cut --path).
//   --hash: also print, per case, FNV-1a hashes of the results (the whole
//          cut's fusedMesh: positions, normals, indices, triangle voxels; its
//          cells(): ids, index positions, indices; and every haptic step's
//          fusedMesh, chained), so a speed-up can be checked bit-identical:
//          run before and after with the same arguments and diff the
//          "case=hash" lines.
#include "benchmarks/BenchCuts.h"
#include "benchmarks/BenchUtil.h"
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/PathFile.h"
#include "cutter/Remesh.h"
#include "cutter/RemeshKernel.h"
#include "vdb/CutOutputs.h"
#include "vdb/Phantom.h"
#include "vdb/VolumeIO.h"

#include <glm/geometric.hpp>

#include <openvdb/tools/Composite.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

using namespace mtcut;
using namespace mtcut::cutter;
using bench::Clock;
using bench::median;
using bench::msSince;
using bench::fnv;
using bench::fnvVec;
using bench::kFnvSeed;
using bench::meshHash;
using openvdb::Coord;

namespace {

constexpr int kSteps = 8;       // haptic steps per run
bool gBaselines = true;         // --no-baselines: ours only (for profiling)
std::string gDumpDir;           // --dump DIR: write refused strokes there as path files
bool gHash = false;             // --hash: print hashes of the results
int gOursThreads = 1;           // --threads N: ours on N threads (the goals are one core)
int gFirstVariant = 0;          // --first-variant N: the first stroke variant tried

uint64_t cellsHash(const CutRemesher& r)
{
    uint64_t h = kFnvSeed;
    for (const auto& [c, g] : r.cells()) {
        const int xyz[3] = {c.x(), c.y(), c.z()};
        h = fnv(h, xyz, sizeof xyz);
        for (const CutVertexId& id : g.vertexIds) {
            h = fnv(h, &id.dim, 3);
            h = fnv(h, id.feature.data(), sizeof id.feature);
            h = fnv(h, id.planes.data(), sizeof(uint64_t) * id.planeCount);
            h = fnv(h, id.tags.data(), sizeof(uint64_t) * id.tagCount);
        }
        h = fnvVec(h, g.indexPositions);
        h = fnvVec(h, g.indices);
    }
    return h;
}

/// A volume with its isosurface; `scene` (the strokes' plane, BenchCuts.h)
/// points at them, so a VolumeCase is not copied.
struct VolumeCase
{
    vdb::Volume vol;
    Mesh uncut;
    bench::CutScene scene; ///< name, iso, frame and cut plane
    // Baseline (b): the bone as a level set, built once.
    openvdb::FloatGrid::Ptr boneLs;
    double lsVoxel = 1.0;
    double lsBuildS = 0.0;
    size_t vdbBoneTris = 0;

    VolumeCase() = default;
    VolumeCase(const VolumeCase&) = delete;
    VolumeCase& operator=(const VolumeCase&) = delete;
};

// -- baseline (b) -------------------------------------------------------------

openvdb::math::Transform::Ptr lsTransform(const VolumeCase& vc)
{
    const IndexFrame& f = vc.scene.frame;
    auto xform = openvdb::math::Transform::createLinearTransform(vc.lsVoxel);
    xform->postTranslate(openvdb::Vec3d(f.origin.x, f.origin.y, f.origin.z));
    return xform;
}

void buildBoneLevelSet(VolumeCase& vc)
{
    const IndexFrame& f = vc.scene.frame;
    vc.lsVoxel = std::min({f.spacing.x, f.spacing.y, f.spacing.z});
    const auto t0 = Clock::now();
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(*vc.vol.grid, points, tris, quads, double(vc.scene.iso), 0.0);
    vc.boneLs = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*lsTransform(vc), points, tris, quads, 3.0f);
    vc.lsBuildS = msSince(t0) * 1e-3;
}

/// Closed slab meshes (world mm) of the quads, thickness t along each normal.
void slabMesh(const std::vector<Quad>& quads, double t, std::vector<openvdb::Vec3s>& points,
              std::vector<openvdb::Vec3I>& tris, std::vector<openvdb::Vec4I>& polys)
{
    for (const Quad& q : quads) {
        glm::dvec3 n = q.normal;
        if (q.degenerate) continue;
        const uint32_t b = uint32_t(points.size());
        const uint32_t k = q.cornerCount;
        for (int side : {-1, 1})
            for (uint32_t i = 0; i < k; ++i) {
                const glm::dvec3 p = q.corners[i] + (0.5 * t * side) * n;
                points.emplace_back(float(p.x), float(p.y), float(p.z));
            }
        if (k == 4) {
            polys.emplace_back(b, b + 3, b + 2, b + 1);
            polys.emplace_back(b + 4, b + 5, b + 6, b + 7);
        } else {
            tris.emplace_back(b, b + 2, b + 1);
            tris.emplace_back(b + 3, b + 4, b + 5);
        }
        for (uint32_t i = 0; i < k; ++i) {
            const uint32_t j = (i + 1) % k;
            polys.emplace_back(b + i, b + j, b + k + j, b + k + i);
        }
    }
}

struct VdbStep
{
    double bladeMs = 0, copyMs = 0, csgMs = 0, meshMs = 0;
    double total() const { return bladeMs + copyMs + csgMs + meshMs; }
    size_t tris = 0;
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
};

void vdbStep(const VolumeCase& vc, const std::vector<Quad>& blade, double kerf, VdbStep& s)
{
    std::vector<openvdb::Vec3s> bp;
    std::vector<openvdb::Vec3I> bt;
    std::vector<openvdb::Vec4I> bq;
    slabMesh(blade, std::max(kerf, vc.lsVoxel), bp, bt, bq);
    auto t0 = Clock::now();
    openvdb::FloatGrid::Ptr bladeLs = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*lsTransform(vc), bp, bt, bq, 3.0f);
    s.bladeMs = msSince(t0);
    t0 = Clock::now();
    openvdb::FloatGrid::Ptr bone = vc.boneLs->deepCopy();
    s.copyMs = msSince(t0);
    t0 = Clock::now();
    openvdb::tools::csgDifference(*bone, *bladeLs);
    s.csgMs = msSince(t0);
    t0 = Clock::now();
    s.points.clear();
    s.triangles.clear();
    s.quads.clear();
    openvdb::tools::volumeToMesh(*bone, s.points, s.triangles, s.quads, 0.0, 0.0);
    s.meshMs = msSince(t0);
    s.tris = s.triangles.size() + 2 * s.quads.size();
}

Mesh fromVdb(const VdbStep& s)
{
    Mesh m;
    for (const auto& p : s.points) m.positions.emplace_back(p.x(), p.y(), p.z());
    for (const auto& t : s.triangles) m.indices.insert(m.indices.end(), {t[0], t[1], t[2]});
    for (const auto& q : s.quads) m.indices.insert(m.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
    return m;
}

// -- one target ----------------------------------------------------------------

struct Row
{
    std::string volume;
    double kerf = 0.0;
    size_t target = 0, cells = 0, surfaceCells = 0, remeshedWhole = 0, quads = 0;
    double blade = 0, sweep = 0; // mm
    int refused = 0, variant = 0;
    glm::dvec3 from{0.0}, to{0.0}; // the stroke's first and last base, world mm
    std::string note;
    // ours, one core
    double stepVoxUs = 0, stepUpdateUs = 0, stepFusedMs = 0, stepNew = 0, stepRemeshed = 0, stepViewUs = 0;
    double setupMs = 0, wholeUpdateMs = 0, wholeFusedMs = 0, noopMs = 0, kernelMs = 0;
    size_t oursDefects = 0, oursTris = 0;
    // baselines
    double aMs = 0, bStepMs = 0, bBladeMs = 0, bCopyMs = 0, bCsgMs = 0, bMeshMs = 0, bWholeMs = 0;
    size_t bDefects = 0, bTris = 0;
    std::string bDefectText;
    bool ok = false;
    // --hash
    uint64_t wholeHash = 0, cellsHash = 0, stepsHash = kFnvSeed;
    size_t fusedVertices = 0;
};

Row runTarget(VolumeCase& vc, size_t target, int runs, double kerf)
{
    Row row;
    row.kerf = kerf;
    row.volume = vc.scene.name;
    row.target = target;
    std::vector<Quad> quads;
    std::unique_ptr<CutMask> mask;
    std::unique_ptr<CutRemesher> remesher;
    // -- choose the stroke, and the whole cut from scratch (one core) ----------
    std::vector<double> wholeUpdate, wholeFused, setup;
    Mesh fused;
    {
        tbb::global_control ours(tbb::global_control::max_allowed_parallelism, size_t(gOursThreads));
        std::vector<Pose> chosen;
        bench::forEachCutStroke(vc.scene, target, kerf, [&](bench::CandidateStroke& c) {
            row.blade = c.blade;
            row.sweep = c.sweep();
            row.variant = c.variant;
            row.from = c.poses.front().base;
            row.to = c.poses.back().base;
            try {
                wholeUpdate.clear();
                wholeFused.clear();
                setup.clear();
                for (int r = 0; r < runs; ++r) {
                    remesher.reset();
                    auto t0 = Clock::now();
                    remesher = std::make_unique<CutRemesher>(vc.vol, vc.scene.iso, vc.uncut);
                    setup.push_back(msSince(t0));
                    t0 = Clock::now();
                    row.remeshedWhole = remesher->update(*c.mask);
                    wholeUpdate.push_back(msSince(t0));
                    fused = remesher->fusedMesh();
                    wholeFused.push_back(msSince(t0));
                }
                row.ok = true;
                chosen = std::move(c.poses);
                quads = std::move(c.quads);
                mask = std::move(c.mask);
                return true;
            } catch (const InputError& e) { // kerf > 0 not implemented: no other stroke will do
                row.note = e.what();
                return true; // stop: row.ok stays false
            } catch (const std::exception& e) {
                ++row.refused;
                std::printf("  %s kerf %g target %zu: stroke variant %d (%s, blade %.3f mm, %zu cells, base (%.3f, %.3f, %.3f) "
                            "-> (%.3f, %.3f, %.3f)) refused: %s\n",
                            vc.scene.name.c_str(), kerf, target, c.variant, bench::strokeKindName(c.variant), row.blade,
                            c.mask->cutCellCount(), row.from.x, row.from.y, row.from.z, row.to.x, row.to.y, row.to.z, e.what());
                if (!gDumpDir.empty()) {
                    const std::string file = gDumpDir + "/refused_" + vc.scene.name + "_" + std::to_string(target) + "_v" +
                                             std::to_string(c.variant) + ".csv";
                    std::ofstream out(file);
                    out << "# bench_cut: stroke refused by the remesher on " << vc.scene.name << " at iso " << vc.scene.iso
                        << ": " << e.what() << "\nt,x,y,z,dx,dy,dz,length\n";
                    for (const Pose& p : c.poses) out << formatPoseLine(p) << "\n";
                    std::printf("    wrote %s\n", file.c_str());
                }
                std::fflush(stdout);
                return false;
            }
        }, gFirstVariant);
        if (!row.ok) {
            if (row.note.empty()) row.note = "every stroke refused";
            return row;
        }
        row.cells = mask->cutCellCount();
        row.quads = quads.size();
        if (gHash) {
            row.wholeHash = meshHash(fused);
            row.cellsHash = cellsHash(*remesher);
            row.fusedVertices = fused.vertexCount();
        }
        row.setupMs = median(setup);
        row.wholeUpdateMs = median(wholeUpdate);
        row.wholeFusedMs = median(wholeFused);
        for (const auto& [c, g] : remesher->cells()) row.surfaceCells += !g.indices.empty();
        // No-op update: the O(cut cells) scan every update pays.
        std::vector<double> noop;
        for (int r = 0; r < std::max(runs, 3); ++r) {
            const auto t0 = Clock::now();
            remesher->update(*mask);
            noop.push_back(msSince(t0));
        }
        row.noopMs = median(noop);
        // The kernel alone, from outside: one kernel over every cut cell, each
        // quad's geometry built once (remesh_detail::KernelQuads, as the GPU
        // pass's input takes it), on this thread.
        std::vector<Coord> cutCells;
        mask->forEachCutCell([&](const Coord& c, const std::vector<QuadRef>&) { cutCells.push_back(c); });
        std::sort(cutCells.begin(), cutCells.end());
        std::vector<double> kernel;
        CutCellGeometry scratch;
        for (int r = 0; r < runs; ++r) {
            const auto t0 = Clock::now();
            remesh_detail::CellKernel cellKernel(vc.vol, vc.scene.iso);
            remesh_detail::KernelQuads kernelQuads(*mask, vc.vol, vc.scene.iso);
            for (const Coord& c : cutCells) cellKernel.remesh(c, kernelQuads.of(c), mask->kerf() > 0, scratch);
            kernel.push_back(msSince(t0));
        }
        row.kernelMs = median(kernel);

        // -- haptic steps ---------------------------------------------------------
        const int steps = int(std::min<size_t>(kSteps, quads.size() - 1));
        std::vector<double> vox, upd, fus, added, remeshed, view;
        std::vector<glm::vec3> viewPositions;
        std::vector<uint32_t> viewIndices;
        std::vector<glm::ivec3> cellBuf;
        try {
            for (int r = 0; r < runs; ++r) {
                const uint32_t first = uint32_t(quads.size()) - uint32_t(steps);
                mask->undoToQuad(first);
                remesher->update(*mask);
                for (uint32_t i = first; i < quads.size(); ++i) {
                    auto t0 = Clock::now();
                    cellBuf.clear();
                    voxelizeCut(quads[i], mask->kerf(), mask->frame(), cellBuf);
                    mask->addQuad(quads[i], cellBuf);
                    vox.push_back(1e3 * msSince(t0));
                    added.push_back(double(mask->lastNewCells().size()));
                    t0 = Clock::now();
                    remeshed.push_back(double(remesher->update(*mask)));
                    upd.push_back(1e3 * msSince(t0));
                    // The interactive view: the changed cells' new geometry
                    // in world mm, as a renderer would upload it.
                    t0 = Clock::now();
                    viewPositions.clear();
                    viewIndices.clear();
                    for (const Coord& c : remesher->lastChangedCells()) {
                        auto it = remesher->cells().find(c);
                        if (it == remesher->cells().end()) continue;
                        const uint32_t base = uint32_t(viewPositions.size());
                        for (const glm::dvec3& p : it->second.indexPositions)
                            viewPositions.push_back(glm::vec3(vc.scene.frame.toWorld(p)));
                        for (uint32_t k : it->second.indices) viewIndices.push_back(base + k);
                    }
                    view.push_back(1e3 * msSince(t0));
                }
                // The whole fused mesh after each step, timed apart: a live
                // stroke does not build it (the viewer fuses when the stroke
                // ends), and its 100 MB of output would leave the next step's
                // caches cold.
                mask->undoToQuad(first);
                remesher->update(*mask);
                for (uint32_t i = first; i < quads.size(); ++i) {
                    cellBuf.clear();
                    voxelizeCut(quads[i], mask->kerf(), mask->frame(), cellBuf);
                    mask->addQuad(quads[i], cellBuf);
                    remesher->update(*mask);
                    auto t0 = Clock::now();
                    fused = remesher->fusedMesh();
                    fus.push_back(msSince(t0));
                    if (gHash && r == 0) row.stepsHash = meshHash(fused, row.stepsHash);
                }
            }
        } catch (const std::exception& e) {
            row.note = std::string("step refused: ") + e.what();
            std::printf("  %s target %zu: %s\n", vc.scene.name.c_str(), target, row.note.c_str());
            if (!gDumpDir.empty()) {
                const std::string file = gDumpDir + "/refused_step_" + vc.scene.name + "_" + std::to_string(target) + ".csv";
                std::ofstream out(file);
                out << "# bench_cut: this stroke re-meshes cleanly from scratch on " << vc.scene.name << " at iso " << vc.scene.iso
                    << ", but after CutMask::undoToQuad(quads - " << steps
                    << ") + update, re-adding the quads one by one with update() after each throws: " << e.what()
                    << "\nt,x,y,z,dx,dy,dz,length\n";
                for (const Pose& p : chosen) out << formatPoseLine(p) << "\n";
                std::printf("    wrote %s\n", file.c_str());
            }
        }
        row.stepVoxUs = median(vox);
        row.stepUpdateUs = median(upd);
        row.stepFusedMs = median(fus);
        row.stepViewUs = median(view);
        row.stepNew = median(added);
        row.stepRemeshed = median(remeshed);
    }
    const MeshCheck oursCheck = checkMesh(fused);
    row.oursDefects = oursCheck.defects();
    row.oursTris = fused.triangleCount();
    fused = Mesh();

    // -- baseline (a): carve + re-extract the whole volume, 2 threads ------------
    if (gBaselines) {
        tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
        openvdb::MaskGrid removed;
        removed.topologyUnion(*mask->grid());
        std::vector<double> a;
        for (int r = 0; r < runs; ++r) {
            const auto t0 = Clock::now();
            vdb::Volume carved = vc.vol;
            carved.grid = vdb::carveVolume(vc.vol, removed);
            const Mesh m = extractIsosurface(carved, vc.scene.iso);
            a.push_back(msSince(t0));
            if (m.empty()) std::printf("?\n");
        }
        row.aMs = median(a);

        // -- baseline (b): OpenVDB level sets, per step and for the whole cut --------
        std::vector<double> total, blade, copy, csg, mesh;
        VdbStep s;
        for (int r = 0; r < runs; ++r) {
            vdbStep(vc, {quads.back()}, mask->kerf(), s);
            total.push_back(s.total());
            blade.push_back(s.bladeMs);
            copy.push_back(s.copyMs);
            csg.push_back(s.csgMs);
            mesh.push_back(s.meshMs);
        }
        row.bStepMs = median(total);
        row.bBladeMs = median(blade);
        row.bCopyMs = median(copy);
        row.bCsgMs = median(csg);
        row.bMeshMs = median(mesh);
        std::vector<double> whole;
        for (int r = 0; r < runs; ++r) {
            vdbStep(vc, quads, mask->kerf(), s);
            whole.push_back(s.total());
        }
        row.bWholeMs = median(whole);
        row.bTris = s.tris;
        const MeshCheck c = checkMesh(fromVdb(s));
        row.bDefects = c.defects();
        std::ostringstream os;
        os << "boundary " << c.boundaryEdges << ", non-manifold edges " << c.nonManifoldEdges << ", inconsistent "
           << c.inconsistentEdges << ", non-manifold vertices " << c.nonManifoldVertices << ", degenerate "
           << c.degenerateTriangles << ", wrong-way shells " << c.negativeVolumeShells;
        row.bDefectText = os.str();
    }
    return row;
}

std::string label(const Row& r)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, ", kerf %g", r.kerf);
    return r.volume + buf;
}

void printRow(const Row& r)
{
    if (!r.ok) {
        std::printf("case=cut volume=%s kerf=%g target=%zu refused=%d note=\"%s\"\n", r.volume.c_str(), r.kerf,
                    r.target, r.refused, r.note.c_str());
        return;
    }
    const double stepUs = r.stepVoxUs + r.stepUpdateUs;
    std::printf("case=cut volume=%s kerf=%g target=%zu cut_cells=%zu surface_cells=%zu remeshed_whole=%zu quads=%zu "
                "blade_mm=%.2f sweep_mm=%.2f refused=%d step_new_cells=%.0f step_remeshed=%.0f step_vox_us=%.1f "
                "step_update_us=%.1f step_us=%.1f step_view_us=%.1f step_fused_ms=%.2f setup_ms=%.1f whole_update_ms=%.2f "
                "whole_fused_ms=%.2f noop_update_ms=%.3f kernel_ms=%.2f us_per_cell=%.1f a_ms=%.1f b_step_ms=%.1f "
                "b_blade_ms=%.2f b_copy_ms=%.1f b_csg_ms=%.2f b_mesh_ms=%.1f b_whole_ms=%.1f step_vs_a=%.0f "
                "step_vs_b=%.0f whole_vs_a=%.2f whole_fused_vs_a=%.2f whole_vs_b=%.2f ours_tris=%zu b_tris=%zu "
                "ours_defects=%zu b_defects=%zu variant=%d kind=%s from=%.3f,%.3f,%.3f to=%.3f,%.3f,%.3f%s%s\n",
                r.volume.c_str(), r.kerf, r.target, r.cells, r.surfaceCells, r.remeshedWhole, r.quads, r.blade, r.sweep, r.refused,
                r.stepNew, r.stepRemeshed, r.stepVoxUs, r.stepUpdateUs, stepUs, r.stepViewUs, r.stepFusedMs, r.setupMs,
                r.wholeUpdateMs, r.wholeFusedMs, r.noopMs, r.kernelMs, r.remeshedWhole ? 1e3 * r.wholeUpdateMs / double(r.remeshedWhole) : 0.0,
                r.aMs, r.bStepMs, r.bBladeMs, r.bCopyMs, r.bCsgMs, r.bMeshMs, r.bWholeMs, r.aMs / (stepUs * 1e-3),
                r.bStepMs / (stepUs * 1e-3), r.aMs / r.wholeUpdateMs, r.aMs / r.wholeFusedMs,
                r.bWholeMs / r.wholeUpdateMs, r.oursTris, r.bTris, r.oursDefects, r.bDefects, r.variant, bench::strokeKindName(r.variant), r.from.x,
                r.from.y, r.from.z, r.to.x, r.to.y, r.to.z, r.note.empty() ? "" : " note=", r.note.c_str());
    if (r.bDefects) std::printf("  OpenVDB route defects: %s\n", r.bDefectText.c_str());
    if (gHash)
        std::printf("case=hash volume=%s kerf=%g target=%zu cut_cells=%zu quads=%zu variant=%d fused_tris=%zu "
                    "fused_vertices=%zu whole=%016llx cells=%016llx steps=%016llx%s%s\n",
                    r.volume.c_str(), r.kerf, r.target, r.cells, r.quads, r.variant, r.oursTris, r.fusedVertices,
                    static_cast<unsigned long long>(r.wholeHash), static_cast<unsigned long long>(r.cellsHash),
                    static_cast<unsigned long long>(r.stepsHash), r.note.empty() ? "" : " note=", r.note.c_str());
    std::fflush(stdout);
}

void printTables(const std::vector<Row>& rows)
{
    std::printf("\nHaptic step (ours on %d thread(s); median of runs x %d steps) vs baselines per step\n\n", gOursThreads, kSteps);
    std::printf("| volume | cut cells (target) | surface cells | new cells / re-meshed per step | vox+mask us | "
                "update us | step us | + view us | fusedMesh ms | (a) re-extract ms | (b) OpenVDB ms (blade/copy/csg/mesh) | "
                "step vs (a) | step vs (b) |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Row& r : rows) {
        if (!r.ok) {
            std::printf("| %s | (%zu) | refused (%d strokes): %s | | | | | | | | | | |\n", label(r).c_str(), r.target,
                        r.refused, r.note.c_str());
            continue;
        }
        const double stepUs = r.stepVoxUs + r.stepUpdateUs;
        std::printf("| %s | %zu (%zu) | %zu | %.0f / %.0f | %.0f | %.0f | %.0f | %.1f | %.1f | %.0f | %.0f (%.1f/%.0f/%.1f/%.0f) | "
                    "%.0fx | %.0fx |\n",
                    label(r).c_str(), r.cells, r.target, r.surfaceCells, r.stepNew, r.stepRemeshed, r.stepVoxUs,
                    r.stepUpdateUs, stepUs, r.stepViewUs, r.stepFusedMs, r.aMs, r.bStepMs, r.bBladeMs, r.bCopyMs, r.bCsgMs,
                    r.bMeshMs, r.aMs / (stepUs * 1e-3), r.bStepMs / (stepUs * 1e-3));
    }
    std::printf("\nWhole cut from scratch (ours on %d thread(s); median of runs)\n\n", gOursThreads);
    std::printf("| volume | cut cells | re-meshed | stroke: blade x sweep mm, quads (variant) | update ms | + fusedMesh ms | us per cell | "
                "no-op update ms | kernel alone ms | remesher setup ms | (a) ms | (b) whole ms | update vs (a) | "
                "+fused vs (a) | update vs (b) | defects ours / (b) | refused strokes |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Row& r : rows) {
        if (!r.ok) continue;
        std::printf("| %s | %zu | %zu | %.1f x %.1f, %zu (%s %d) | %.1f | %.1f | %.0f | %.2f | %.1f | %.0f | %.0f | %.0f | %.2fx | "
                    "%.2fx | %.2fx | %zu / %zu | %d |\n",
                    label(r).c_str(), r.cells, r.remeshedWhole, r.blade, r.sweep, r.quads, bench::strokeKindName(r.variant), r.variant, r.wholeUpdateMs, r.wholeFusedMs,
                    r.remeshedWhole ? 1e3 * r.wholeUpdateMs / double(r.remeshedWhole) : 0.0, r.noopMs, r.kernelMs, r.setupMs, r.aMs, r.bWholeMs,
                    r.aMs / r.wholeUpdateMs, r.aMs / r.wholeFusedMs, r.bWholeMs / r.wholeUpdateMs, r.oursDefects,
                    r.bDefects, r.refused);
    }
}

void runVolume(VolumeCase& vc, double planeIndexZ, const std::vector<size_t>& targets, int runs,
               std::vector<Row>& rows)
{
    vc.scene.vol = &vc.vol;
    vc.scene.uncut = &vc.uncut;
    {
        tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
        const auto t0 = Clock::now();
        vc.uncut = extractIsosurface(vc.vol, vc.scene.iso);
        const double extractMs = msSince(t0);
        bench::locateCutPlane(vc.scene, planeIndexZ);
        if (gBaselines) buildBoneLevelSet(vc);
        else vc.boneLs = openvdb::FloatGrid::create();
        const bench::CutScene& sc = vc.scene;
        std::printf("volume=%s dims=%dx%dx%d spacing=%.4g,%.4g,%.4g iso=%g uncut_tris=%zu extract_ms=%.0f "
                    "plane_z_mm=%.2f x_centre_mm=%.1f y_front_mm=%.1f bone_ls_voxel_mm=%.4g bone_ls_build_s=%.2f "
                    "bone_ls_active=%llu\n",
                    sc.name.c_str(), sc.frame.dims.x, sc.frame.dims.y, sc.frame.dims.z, sc.frame.spacing.x,
                    sc.frame.spacing.y, sc.frame.spacing.z, double(sc.iso), vc.uncut.triangleCount(), extractMs, sc.planeZ,
                    sc.xCentre, sc.yFront, vc.lsVoxel, vc.lsBuildS,
                    static_cast<unsigned long long>(vc.boneLs->activeVoxelCount()));
        std::fflush(stdout);
    }
    for (size_t target : targets) {
        rows.push_back(runTarget(vc, target, runs, 0.0));
        printRow(rows.back());
    }
    // Kerf 0.5 mm: measured only once the remesher accepts kerf > 0.
    for (size_t target : targets) {
        Row row = runTarget(vc, target, runs, 0.5);
        printRow(row);
        const bool refused = !row.ok;
        rows.push_back(std::move(row));
        if (refused) break;
    }
}

} // namespace

int main(int argc, char** argv)
{
    int runs = 5;
    bool quick = false, phantom = true, head = true, runsGiven = false;
    std::vector<size_t> targets;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--runs") && i + 1 < argc) {
            runs = std::max(1, std::atoi(argv[++i]));
            runsGiven = true;
        } else if (!std::strcmp(argv[i], "--quick")) {
            quick = true;
        } else if (!std::strcmp(argv[i], "--phantom-only")) {
            head = false;
        } else if (!std::strcmp(argv[i], "--dump") && i + 1 < argc) {
            gDumpDir = argv[++i];
        } else if (!std::strcmp(argv[i], "--hash")) {
            gHash = true;
        } else if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) {
            gOursThreads = std::atoi(argv[++i]);
            if (gOursThreads < 1) {
                std::fprintf(stderr, "bench_cut: --threads wants a positive number, got '%s'\n", argv[i]);
                return 2;
            }
        } else if (!std::strcmp(argv[i], "--first-variant") && i + 1 < argc) {
            gFirstVariant = std::atoi(argv[++i]);
            if (gFirstVariant < 0 || gFirstVariant >= bench::kStrokeVariants) {
                std::fprintf(stderr, "bench_cut: --first-variant wants 0..%d, got '%s'\n", bench::kStrokeVariants - 1, argv[i]);
                return 2;
            }
        } else if (!std::strcmp(argv[i], "--no-baselines")) {
            gBaselines = false;
        } else if (!std::strcmp(argv[i], "--head-only")) {
            phantom = false;
        } else if (!std::strcmp(argv[i], "--targets") && i + 1 < argc) {
            std::stringstream ss(argv[++i]);
            std::string item;
            while (std::getline(ss, item, ',')) targets.push_back(size_t(std::atol(item.c_str())));
        } else {
            std::fprintf(stderr,
                         "usage: bench_cut [--quick] [--runs N] [--phantom-only] [--head-only] [--targets N,N,...] [--no-baselines] [--dump DIR] [--hash] [--threads N] [--first-variant N]\n");
            return 2;
        }
    }
    if (quick && !runsGiven) runs = 1;
    if (targets.empty()) targets = quick ? std::vector<size_t>{100, 419, 1000} : std::vector<size_t>{419, 3638, 11716};
    openvdb::initialize();
    std::vector<Row> rows;
    try {
        if (phantom) {
            VolumeCase vc;
            vdb::PhantomOptions options;
            options.dims = quick ? Coord(256, 256, 128) : Coord(512, 512, 256);
            vc.vol = vdb::makePhantom(options);
            vc.scene.name = "phantom-" + std::to_string(options.dims.x()) + "x" + std::to_string(options.dims.y()) + "x" +
                      std::to_string(options.dims.z());
            const IndexFrame f = frameOf(vc.vol);
            runVolume(vc, f.toIndex(glm::dvec3(0, 0, vdb::phantomLandmarks().leFortZ)).z, targets, runs, rows);
        }
        if (head) {
            const std::string path = std::string(MTCUT_SHARED_DATA) + (quick ? "/vhm_head_4mm.nhdr" : "/vhm-head-dicom");
            if (std::filesystem::exists(path)) {
                VolumeCase vc;
                vc.vol = vdb::readVolume(path);
                vc.scene.name = quick ? "vhm-head-4mm" : "vhm-head-dicom";
                runVolume(vc, 0.32 * double(vc.vol.dims.z() - 1), targets, runs, rows);
            } else {
                std::printf("case=vhm-head skipped: %s not found\n", path.c_str());
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench_cut: %s\n", e.what());
        return 1;
    }
    printTables(rows);
    return 0;
}
