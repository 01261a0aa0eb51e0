// See KernelInput.h.
#include "cutter/KernelInput.h"

#include "cutter/Isosurface.h"
#include "cutter/RemeshKernel.h"

#include <openvdb/tree/ValueAccessor.h>

namespace mtcut::cutter {

namespace {

void putPlane(double out[4], const remesh_detail::Plane& p)
{
    out[0] = p.n.x;
    out[1] = p.n.y;
    out[2] = p.n.z;
    out[3] = p.d;
}

} // namespace

PackedKernelInput packKernelInput(const vdb::Volume& volume, float isovalue, const CutMask& mask,
                                  const std::vector<openvdb::Coord>& cells)
{
    PackedKernelInput in;
    in.prism = mask.kerf() > 0;
    in.isovalue = isovalue;
    for (int parity = 0; parity < 2; ++parity)
        for (int t = 0; t < kTetsPerCell; ++t)
            for (int i = 0; i < 4; ++i) in.tets[size_t(20 * parity + 4 * t + i)] = cellTets(parity)[size_t(t)][size_t(i)];
    openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(volume.grid->tree());
    const float background = volume.grid->background();
    const openvdb::CoordBBox box = volume.indexBox();
    in.cells.reserve(cells.size());
    in.blocks.reserve(64 * cells.size());
    for (int a = 0; a < 3; ++a) {
        in.origin[size_t(a)] = volume.origin()[a];
        in.spacing[size_t(a)] = volume.spacing()[a];
    }
    remesh_detail::KernelQuads kernelQuads(mask, volume, isovalue); // each quad's geometry once, for all the cells
    for (const openvdb::Coord& c : cells) {
        PackedKernelCell pc;
        pc.x = c.x();
        pc.y = c.y();
        pc.z = c.z();
        // As the kernel (RemeshKernel::loadTet): outside the scan box, the background and outside.
        for (int k = 0; k < 8; ++k) {
            const openvdb::Coord g = c + openvdb::Coord(k & 1, (k >> 1) & 1, (k >> 2) & 1);
            const bool inBox = box.isInside(g);
            pc.values[k] = inBox ? acc.getValue(g) : background;
            if (inBox && pc.values[k] >= isovalue) pc.insideMask |= 1u << k;
        }
        pc.firstQuad = uint32_t(in.quads.size());
        for (const remesh_detail::QuadGeom& q : kernelQuads.of(c)) {
            PackedKernelQuad pq;
            putPlane(pq.plane, q.pi);
            pq.id = q.id;
            pq.firstSide = uint32_t(in.sides.size());
            pq.sideCount = uint32_t(q.sides.size());
            for (const remesh_detail::QuadGeom::Side& s : q.sides) {
                PackedKernelSide ps;
                putPlane(ps.plane, s.plane);
                ps.id = s.id;
                ps.partnerId = s.partnerId;
                ps.orient = s.orient;
                ps.partner = s.partner;
                ps.fold = s.fold ? 1 : 0;
                for (int e = 0; e < 2; ++e) {
                    ps.cornerSides[2 * e] = s.cornerSides[size_t(e)].first;
                    ps.cornerSides[2 * e + 1] = s.cornerSides[size_t(e)].second;
                }
                in.sides.push_back(ps);
            }
            in.quads.push_back(pq);
        }
        pc.quadCount = uint32_t(in.quads.size()) - pc.firstQuad;
        in.cells.push_back(pc);
        for (int k = -1; k <= 2; ++k)
            for (int j = -1; j <= 2; ++j)
                for (int i = -1; i <= 2; ++i) in.blocks.push_back(acc.getValue(c + openvdb::Coord(i, j, k)));
    }
    return in;
}

} // namespace mtcut::cutter
