#include "vdb/CutOutputs.h"

#include "vdb/AtomicFile.h"
#include "vdb/Error.h"
#include "vdb/Formats.h"

#include <openvdb/io/File.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/Prune.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#ifndef MTCUT_VERSION
#error "MTCUT_VERSION must be defined by the build (vdb/CMakeLists.txt)"
#endif

namespace mtcut::vdb {

const char* const kMtcutVersion = MTCUT_VERSION;

namespace {

std::string fragmentPrefix(size_t index) { return "fragment " + std::to_string(index) + ": "; }

/// meshToVolume's mesh adapter over the caller's arrays: world mm to the
/// level set's index space (uniform scale, translation) on the fly.
class FragmentAdapter
{
public:
    FragmentAdapter(const FragmentMesh& mesh, const openvdb::Vec3d& worldOrigin, double voxelMm)
        : mMesh(mesh), mOrigin(worldOrigin), mInvVoxel(1.0 / voxelMm)
    {
    }
    size_t polygonCount() const { return mMesh.triangleCount; }
    size_t pointCount() const { return mMesh.vertexCount; }
    size_t vertexCount(size_t) const { return 3; }
    void getIndexSpacePoint(size_t n, size_t v, openvdb::Vec3d& pos) const
    {
        const float* p = mMesh.worldPositions + 3 * size_t(mMesh.triangleIndices[3 * n + v]);
        pos = (openvdb::Vec3d(p[0], p[1], p[2]) - mOrigin) * mInvVoxel;
    }

private:
    const FragmentMesh& mMesh;
    openvdb::Vec3d mOrigin;
    double mInvVoxel;
};

} // namespace

std::string fragmentGridName(size_t index)
{
    char name[32];
    std::snprintf(name, sizeof(name), "fragment_%03zu", index);
    return name;
}

FragmentStats checkFragmentMesh(const FragmentMesh& mesh, size_t index)
{
    assert(mesh.worldPositions || mesh.vertexCount == 0);
    assert(mesh.triangleIndices || mesh.triangleCount == 0);
    if (mesh.triangleCount == 0) throw InputError(fragmentPrefix(index) + "mesh has no triangles");
    for (size_t v = 0; v < 3 * mesh.vertexCount; ++v) {
        if (!std::isfinite(mesh.worldPositions[v])) {
            throw InputError(fragmentPrefix(index) + "vertex " + std::to_string(v / 3) +
                             " has a non-finite coordinate");
        }
    }
    FragmentStats stats;
    stats.triangles = mesh.triangleCount;
    // Relative to one vertex, so the signed volume does not cancel far from the origin.
    const float* ref = mesh.worldPositions;
    for (size_t t = 0; t < mesh.triangleCount; ++t) {
        openvdb::Vec3d p[3];
        for (int c = 0; c < 3; ++c) {
            const uint32_t v = mesh.triangleIndices[3 * t + size_t(c)];
            if (v >= mesh.vertexCount) {
                throw InputError(fragmentPrefix(index) + "triangle " + std::to_string(t) + " uses vertex " +
                                 std::to_string(v) + ", but the mesh has " +
                                 std::to_string(mesh.vertexCount) + " vertices");
            }
            const float* q = mesh.worldPositions + 3 * size_t(v);
            p[c] = openvdb::Vec3d(double(q[0]) - ref[0], double(q[1]) - ref[1], double(q[2]) - ref[2]);
        }
        const openvdb::Vec3d n = (p[1] - p[0]).cross(p[2] - p[0]);
        stats.areaMm2 += 0.5 * n.length();
        stats.volumeMm3 += p[0].dot(p[1].cross(p[2])) / 6.0;
    }
    if (!(stats.areaMm2 > 0.0)) {
        throw InputError(fragmentPrefix(index) + "mesh is degenerate (all " +
                         std::to_string(mesh.triangleCount) + " triangles have zero area)");
    }
    return stats;
}

openvdb::FloatGrid::Ptr fragmentToLevelSet(const FragmentMesh& mesh, size_t index, double voxelMm,
                                           const openvdb::Vec3d& worldOrigin, float halfWidthVoxels,
                                           Interrupter* interrupter)
{
    if (!(std::isfinite(voxelMm) && voxelMm > 0.0)) {
        throw InputError("level-set voxel size must be a positive number of mm, got " + std::to_string(voxelMm));
    }
    if (!(std::isfinite(halfWidthVoxels) && halfWidthVoxels >= 1.0f)) {
        throw InputError("level-set half-width must be at least 1 voxel, got " + std::to_string(halfWidthVoxels));
    }
    checkFragmentMesh(mesh, index);
    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxelMm);
    xform->postTranslate(worldOrigin);
    Interrupter none;
    openvdb::FloatGrid::Ptr grid = openvdb::tools::meshToVolume<openvdb::FloatGrid>(
        interrupter ? *interrupter : none, FragmentAdapter(mesh, worldOrigin, voxelMm), *xform,
        halfWidthVoxels, halfWidthVoxels);
    pollInterrupter(interrupter); // meshToVolume returns a partial grid when interrupted
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName(fragmentGridName(index));
    return grid;
}

void carveGrid(openvdb::FloatGrid& grid, const openvdb::MaskGrid& removed)
{
    const float background = grid.background();
    auto acc = grid.getAccessor();
    for (auto it = removed.cbeginValueOn(); it; ++it) {
        if (it.isVoxelValue()) {
            acc.setValueOff(it.getCoord(), background);
        } else {
            openvdb::CoordBBox box;
            it.getBoundingBox(box);
            grid.tree().fill(box, background, /*active=*/false);
        }
    }
    openvdb::tools::prune(grid.tree());
}

openvdb::FloatGrid::Ptr carveVolume(const Volume& volume, const openvdb::MaskGrid& removed)
{
    // Only what lies inside the scan: a removed voxel outside would add nodes.
    openvdb::MaskGrid::Ptr inside;
    const openvdb::CoordBBox box = volume.indexBox();
    const openvdb::CoordBBox removedBox = removed.evalActiveVoxelBoundingBox();
    if (!removedBox.empty() && !box.isInside(removedBox)) {
        inside = removed.deepCopy();
        inside->clip(box);
    }
    auto carved = openvdb::FloatGrid::create(std::make_shared<openvdb::FloatTree>(volume.grid->tree()));
    carved->setTransform(volume.grid->transform().copy());
    carved->setName(volume.grid->getName());
    carveGrid(*carved, inside ? *inside : removed);
    return carved;
}

double CutVdbOptions::voxelMmFor(const Volume& volume) const
{
    const openvdb::Vec3d spacing = volume.spacing();
    return levelSetVoxelMm == 0.0 ? std::min({spacing.x(), spacing.y(), spacing.z()}) : levelSetVoxelMm;
}

void writeCutVdb(const std::string& path, const Volume& volume, const openvdb::FloatGrid& carved,
                 const openvdb::Int32Grid& cutMask, const std::vector<FragmentMesh>& fragments,
                 const CutInfo& info, const CutVdbOptions& options, Interrupter* interrupter)
{
    openvdb::initialize();
    assert(volume.grid && carved.transform() == volume.grid->transform());
    if (!(std::isfinite(options.levelSetVoxelMm) && options.levelSetVoxelMm >= 0.0)) {
        throw InputError("level-set voxel size must be a positive number of mm (0 = smallest spacing), got " +
                         std::to_string(options.levelSetVoxelMm));
    }
    if (!(std::isfinite(options.halfWidthVoxels) && options.halfWidthVoxels >= 1.0f)) {
        throw InputError("level-set half-width must be at least 1 voxel, got " +
                         std::to_string(options.halfWidthVoxels));
    }
    const double voxelMm = options.voxelMmFor(volume);
    // Check every fragment before the (long) level sets are made.
    std::vector<FragmentStats> stats;
    stats.reserve(fragments.size());
    auto numberOf = [&](size_t f) { return fragments[f].index == FragmentMesh::kByPosition ? f : fragments[f].index; };
    for (size_t f = 0; f < fragments.size(); ++f) stats.push_back(checkFragmentMesh(fragments[f], numberOf(f)));

    openvdb::GridCPtrVec grids;

    // New grid objects sharing the caller's trees: only names, metadata and transforms are set.
    auto carvedOut = openvdb::ConstPtrCast<openvdb::FloatGrid>(carved.copy());
    carvedOut->setName(kCarvedGridName);
    setVolumeMetadata(*carvedOut, volume);
    grids.push_back(carvedOut);

    auto maskOut = openvdb::ConstPtrCast<openvdb::Int32Grid>(cutMask.copy());
    maskOut->setName(kCutMaskGridName);
    maskOut->setTransform(volume.grid->transform().copy());
    grids.push_back(maskOut);

    // The fragments' level sets are independent: made concurrently (a cut
    // of a head leaves one large fragment and hundreds of small chips, each
    // too small to keep the threads of its own meshToVolume busy), then
    // written in the given order. Progress counts fragments done; each
    // meshToVolume is only asked whether to stop (its own percentages would
    // run the bar back and forth).
    InterrupterScope scope(interrupter, "level sets of the fragments");
    pollInterrupter(interrupter, 0);
    struct CancelOnly : Interrupter
    {
        Interrupter* outer = nullptr;
        bool wasInterrupted(int) override { return outer && outer->wasInterrupted(-1); }
    } cancelOnly;
    cancelOnly.outer = interrupter;
    std::vector<openvdb::FloatGrid::Ptr> levelSets(fragments.size());
    std::atomic<size_t> done{0};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, fragments.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t f = range.begin(); f != range.end(); ++f) {
            openvdb::FloatGrid::Ptr ls = fragmentToLevelSet(fragments[f], numberOf(f), voxelMm, volume.origin(),
                                                            options.halfWidthVoxels, interrupter ? &cancelOnly : nullptr);
            ls->insertMeta("mtcut:volume_mm3", openvdb::DoubleMetadata(stats[f].volumeMm3));
            ls->insertMeta("mtcut:area_mm2", openvdb::DoubleMetadata(stats[f].areaMm2));
            ls->insertMeta("mtcut:triangles", openvdb::Int64Metadata(int64_t(stats[f].triangles)));
            levelSets[f] = std::move(ls);
            pollInterrupter(interrupter, int(100 * (done.fetch_add(1) + 1) / fragments.size()));
        }
    });
    for (openvdb::FloatGrid::Ptr& ls : levelSets) grids.push_back(std::move(ls));

    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("mtcut:version", openvdb::StringMetadata(kMtcutVersion));
    fileMeta.insertMeta("mtcut:isovalue", openvdb::FloatMetadata(info.isovalue));
    fileMeta.insertMeta("mtcut:kerf_mm", openvdb::FloatMetadata(info.kerfMm));
    fileMeta.insertMeta("mtcut:path_file", openvdb::StringMetadata(info.pathFile));
    fileMeta.insertMeta("mtcut:fragments", openvdb::Int32Metadata(int32_t(fragments.size())));

    writeFileAtomically(path, [&](const std::string& tmp) {
        try {
            openvdb::io::File file(tmp);
            file.write(grids, fileMeta);
            file.close();
        } catch (const openvdb::Exception& e) {
            throw InputError(path + ": cannot write VDB (" + e.what() + ")");
        }
    });
}

} // namespace mtcut::vdb
