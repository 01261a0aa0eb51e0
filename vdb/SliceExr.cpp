#include "vdb/SliceExr.h"

#include "vdb/AtomicFile.h"
#include "vdb/CutOutputs.h"
#include "vdb/Error.h"

#include <IexBaseExc.h>
#include <ImfChannelList.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfStringAttribute.h>
#include <ImfThreading.h>
#include <ImfVecAttribute.h>

#include <openvdb/tools/Dense.h>

#include <algorithm>
#include <cassert>
#include <cstdio>
#include <vector>

namespace mtcut::vdb {

namespace {

constexpr int kSlab = 8; // slices per dense copy: one layer of VDB leaf nodes

struct MaskVoxel
{
    openvdb::Coord ijk;
    uint32_t stroke;
};

/// The cut mask's active voxels inside box, bucketed by slab of kSlab slices.
std::vector<std::vector<MaskVoxel>> bucketMask(const openvdb::Int32Grid& cutMask, const openvdb::CoordBBox& box)
{
    std::vector<std::vector<MaskVoxel>> slabs(size_t((box.dim().z() + kSlab - 1) / kSlab));
    for (auto it = cutMask.cbeginValueOn(); it; ++it) {
        openvdb::CoordBBox b;
        it.getBoundingBox(b);
        b.intersect(box);
        if (b.empty()) continue;
        const int32_t id = *it;
        if (id < 1) {
            const openvdb::Coord c = b.min();
            throw InputError("cut mask voxel (" + std::to_string(c.x()) + "," + std::to_string(c.y()) + "," +
                             std::to_string(c.z()) + ") has stroke id " + std::to_string(id) +
                             "; stroke ids start at 1");
        }
        for (auto c = b.begin(); c; ++c) slabs[size_t((*c).z() / kSlab)].push_back({*c, uint32_t(id)});
    }
    return slabs;
}

} // namespace

std::string sliceName(int k)
{
    char name[32];
    std::snprintf(name, sizeof(name), "slice_%04d", k);
    return name;
}

void writeSliceStack(const std::string& path, const Volume& volume, const openvdb::Int32Grid& cutMask,
                     float isovalue, Interrupter* interrupter)
{
    assert(volume.grid);
    const openvdb::CoordBBox box = volume.indexBox();
    const int nx = volume.dims.x(), ny = volume.dims.y(), nz = volume.dims.z();
    const openvdb::Vec3d spacing = volume.spacing();
    const openvdb::Vec3d origin = volume.origin();

    const std::vector<std::vector<MaskVoxel>> maskSlabs = bucketMask(cutMask, box);

    std::vector<Imf::Header> headers;
    headers.reserve(size_t(nz));
    for (int k = 0; k < nz; ++k) {
        Imf::Header h(nx, ny, float(spacing.x() / spacing.y()));
        h.setName(sliceName(k));
        h.setType(Imf::SCANLINEIMAGE);
        h.compression() = Imf::ZIP_COMPRESSION;
        // zlib's fastest level: on the 1 mm head (245 slices of 512 x 512)
        // the stack took 3.5-3.9 s to write beside cut.vdb's level sets
        // instead of 5.5-5.6 s at OpenEXR's default level, for a file 9 %
        // larger (29.9 MB against 27.4). Readers need nothing different.
        h.zipCompressionLevel() = 1;
        h.channels().insert("density", Imf::Channel(Imf::FLOAT));
        h.channels().insert("mask", Imf::Channel(Imf::UINT));
        h.insert("mtcut:spacing_mm", Imf::V3dAttribute(Imath::V3d(spacing.x(), spacing.y(), spacing.z())));
        h.insert("mtcut:origin_mm", Imf::V3dAttribute(Imath::V3d(origin.x(), origin.y(), origin.z())));
        h.insert("mtcut:slice_index", Imf::IntAttribute(k));
        h.insert("mtcut:slice_z_mm", Imf::DoubleAttribute(volume.grid->indexToWorld(openvdb::Coord(0, 0, k)).z()));
        h.insert("mtcut:isovalue", Imf::FloatAttribute(isovalue));
        h.insert("mtcut:units", Imf::StringAttribute(volume.units));
        h.insert("mtcut:version", Imf::StringAttribute(kMtcutVersion));
        headers.push_back(std::move(h));
    }

    const size_t sliceVoxels = size_t(nx) * size_t(ny);
    std::vector<float> density(sliceVoxels * kSlab);
    std::vector<uint32_t> mask(sliceVoxels * kSlab);

    InterrupterScope scope(interrupter, "writing the slice stack");
    writeFileAtomically(path, [&](const std::string& tmp) {
        try {
            Imf::MultiPartOutputFile file(tmp.c_str(), headers.data(), nz);
            for (int z0 = 0; z0 < nz; z0 += kSlab) {
                const int z1 = std::min(nz, z0 + kSlab) - 1;
                const openvdb::CoordBBox slab(openvdb::Coord(0, 0, z0), openvdb::Coord(nx - 1, ny - 1, z1));
                openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(slab, density.data());
                openvdb::tools::copyToDense(*volume.grid, dense);
                std::fill(mask.begin(), mask.end(), 0u);
                for (const MaskVoxel& m : maskSlabs[size_t(z0 / kSlab)]) {
                    mask[size_t(m.ijk.z() - z0) * sliceVoxels + size_t(m.ijk.y()) * size_t(nx) +
                         size_t(m.ijk.x())] = m.stroke;
                }
                for (int k = z0; k <= z1; ++k) {
                    pollInterrupter(interrupter, int(100LL * k / nz));
                    const size_t offset = size_t(k - z0) * sliceVoxels;
                    Imf::FrameBuffer fb;
                    fb.insert("density", Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(density.data() + offset),
                                                    sizeof(float), sizeof(float) * size_t(nx)));
                    fb.insert("mask", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(mask.data() + offset),
                                                 sizeof(uint32_t), sizeof(uint32_t) * size_t(nx)));
                    Imf::OutputPart part(file, k);
                    part.setFrameBuffer(fb);
                    part.writePixels(ny);
                }
            }
        } catch (const Iex::BaseExc& e) {
            throw InputError(path + ": cannot write EXR (" + e.what() + ")");
        }
    });
}

void setExrThreadCount(unsigned threads) { Imf::setGlobalThreadCount(int(threads)); }

} // namespace mtcut::vdb
