// .vdb reading and writing through OpenVDB's own io::File.
#include "vdb/AtomicFile.h"
#include "vdb/Formats.h"

#include <openvdb/io/File.h>
#include <openvdb/math/Maps.h>
#include <openvdb/tools/Statistics.h>

#include <algorithm>

namespace mtcut::vdb {

namespace {

constexpr const char* kDims = "mtcut:dims";
constexpr const char* kUnits = "mtcut:units";
constexpr const char* kAir = "mtcut:air_threshold";
constexpr const char* kMin = "mtcut:min";
constexpr const char* kMax = "mtcut:max";
constexpr const char* kSource = "mtcut:source";

template <typename T, typename MetaT>
std::optional<T> meta(const openvdb::GridBase& grid, const char* name)
{
    if (auto m = grid.getMetadata<MetaT>(name)) return m->value();
    return std::nullopt;
}

} // namespace

void setVolumeMetadata(openvdb::GridBase& grid, const Volume& volume)
{
    grid.insertMeta(kDims, openvdb::Vec3IMetadata(openvdb::Vec3i(volume.dims.asVec3i())));
    grid.insertMeta(kUnits, openvdb::StringMetadata(volume.units));
    grid.insertMeta(kAir, openvdb::FloatMetadata(volume.airThreshold));
    grid.insertMeta(kMin, openvdb::FloatMetadata(volume.minValue));
    grid.insertMeta(kMax, openvdb::FloatMetadata(volume.maxValue));
    grid.insertMeta(kSource, openvdb::StringMetadata(volume.source));
}

void writeVdb(const Volume& volume, const std::string& path)
{
    openvdb::initialize();
    openvdb::FloatGrid::Ptr grid = volume.grid->copy(); // shares the tree
    setVolumeMetadata(*grid, volume);
    if (grid->getName().empty()) grid->setName("density");
    writeFileAtomically(path, [&](const std::string& tmp) {
        try {
            openvdb::io::File file(tmp);
            file.write({grid});
            file.close();
        } catch (const openvdb::Exception& e) {
            throw InputError(path + ": cannot write VDB (" + e.what() + ")");
        }
    });
}

Volume readVdb(const std::string& path, const ReadOptions& options)
{
    openvdb::initialize();
    openvdb::GridPtrVecPtr grids;
    try {
        openvdb::io::File file(path);
        file.open();
        grids = file.getGrids();
        file.close();
    } catch (const openvdb::Exception& e) {
        throw InputError(path + ": cannot read VDB (" + e.what() + ")");
    }
    openvdb::FloatGrid::Ptr grid;
    std::string found;
    for (const auto& g : *grids) {
        found += (found.empty() ? "" : ", ") + g->getName() + " (" + g->valueType() + ")";
        if (!options.gridName.empty() && g->getName() != options.gridName) continue;
        if (auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(g)) {
            grid = fg;
            break;
        }
    }
    if (!grid) {
        throw InputError(path + ": no float grid" +
                         (options.gridName.empty() ? std::string() : " named '" + options.gridName + "'") +
                         " (grids: " + (found.empty() ? "none" : found) + ")");
    }

    // Our index box starts at (0,0,0) and the transform is a positive scale plus
    // a translation; a foreign grid is shifted (world positions unchanged) or rejected.
    const auto map = grid->transform().baseMap();
    using namespace openvdb::math;
    if (!map->isType<ScaleMap>() && !map->isType<ScaleTranslateMap>() && !map->isType<UniformScaleMap>() &&
        !map->isType<UniformScaleTranslateMap>() && !map->isType<TranslationMap>()) {
        throw InputError(path + ": grid '" + grid->getName() + "' has a " + map->type() +
                         " transform; only axis-aligned scale and translation are supported");
    }
    const openvdb::Vec3d origin = grid->indexToWorld(openvdb::Vec3d(0.0));
    // A scale map with negative entries would flip axes; reject it.
    const openvdb::Vec3d unitStep = grid->indexToWorld(openvdb::Vec3d(1.0)) - origin;
    if (unitStep.x() <= 0 || unitStep.y() <= 0 || unitStep.z() <= 0) {
        throw InputError(path + ": grid '" + grid->getName() + "' has a flipping transform; not supported");
    }

    Volume vol;
    vol.source = path;
    openvdb::CoordBBox box;
    if (auto d = meta<openvdb::Vec3i, openvdb::Vec3IMetadata>(*grid, kDims)) {
        vol.dims = openvdb::Coord(*d);
        box = vol.indexBox();
    } else {
        box = grid->evalActiveVoxelBoundingBox();
        if (box.empty()) throw InputError(path + ": grid '" + grid->getName() + "' has no active voxels");
        vol.dims = box.dim();
    }
    checkDims(vol.dims, path);
    if (box.min() != openvdb::Coord(0)) {
        const openvdb::Coord shift = -box.min();
        auto moved = openvdb::FloatGrid::create(grid->background());
        auto acc = moved->getAccessor();
        for (auto it = grid->cbeginValueOn(); it; ++it) {
            openvdb::CoordBBox b;
            it.getBoundingBox(b);
            for (auto c = b.begin(); c; ++c) acc.setValue(*c + shift, *it);
        }
        moved->setTransform(grid->transform().copy());
        moved->transform().preTranslate(openvdb::Vec3d(box.min().asVec3d()));
        moved->setName(grid->getName());
        grid = moved;
    }
    const auto minMax = openvdb::tools::minMax(grid->tree());
    vol.minValue = meta<float, openvdb::FloatMetadata>(*grid, kMin).value_or(
        std::min(minMax.min(), grid->background()));
    vol.maxValue = meta<float, openvdb::FloatMetadata>(*grid, kMax).value_or(
        std::max(minMax.max(), grid->background()));
    vol.units = meta<std::string, openvdb::StringMetadata>(*grid, kUnits)
                    .value_or(vol.minValue >= -3100.0f && vol.minValue <= -900.0f ? "HU" : "");
    if (options.sparse.airThreshold) {
        vol.airThreshold = *options.sparse.airThreshold;
    } else {
        vol.airThreshold = meta<float, openvdb::FloatMetadata>(*grid, kAir).value_or(
            vol.units == "HU" ? std::max(-500.0f, vol.minValue)
                              : vol.minValue + 0.02f * (vol.maxValue - vol.minValue));
    }
    for (const char* name : {kDims, kUnits, kAir, kMin, kMax, kSource}) grid->removeMeta(name);
    vol.grid = grid;
    return vol;
}

} // namespace mtcut::vdb
