// The re-meshing kernel's input for a batch of cut cells, packed flat in the
// memory layout the GPU cut pass reads (GLSL std430 storage buffers, declared
// in shaders/cut_kernel.glsl; DESIGN "GPU passes", pass 3). Each cell: its
// corner values and inside flags as the kernel classifies them, and its
// quads as update() hands them to the kernel (RemeshKernel.h QuadGeom: the
// quad's plane and id, each side's plane, orientation, junction partner and
// corner sides). Every double is the CPU kernel's own, bit for bit, so the
// port can make the same decisions. No GL here.
#pragma once

#include "cutter/CutMask.h"
#include "vdb/Volume.h"

#include <openvdb/math/Coord.h>

#include <array>
#include <cstdint>
#include <vector>

namespace mtcut::cutter {

/// One cut cell (64 bytes; GLSL `KernelCell`).
struct PackedKernelCell
{
    int32_t x = 0, y = 0, z = 0; ///< the cell (index space)
    uint32_t firstQuad = 0;      ///< its quads: PackedKernelInput::quads[firstQuad .. + quadCount]
    uint32_t quadCount = 0;
    uint32_t insideMask = 0; ///< bit c: corner c (x = c & 1, y = c >> 1 & 1, z = c >> 2 & 1) is inside the solid
    uint32_t pad[2] = {0, 0};
    float values[8] = {}; ///< corner values (the background outside the scan box)
};
static_assert(sizeof(PackedKernelCell) == 64, "std430 layout of KernelCell");

/// One quad of a cell (64 bytes; GLSL `KernelQuad`): the zero-kerf quad's
/// plane, or with kerf > 0 the prism (its faces are all sides).
struct PackedKernelQuad
{
    double plane[4] = {0, 0, 0, 0}; ///< n.x, n.y, n.z, d: h(x) = dot(n, x) - d
    uint64_t id = 0;                ///< plane id of the quad's plane (kind 0)
    uint32_t firstSide = 0;         ///< PackedKernelInput::sides[firstSide .. + sideCount]
    uint32_t sideCount = 0;
    uint64_t pad[2] = {0, 0};
};
static_assert(sizeof(PackedKernelQuad) == 64, "std430 layout of KernelQuad");

/// One side of a quad (96 bytes; GLSL `KernelSide`).
struct PackedKernelSide
{
    double plane[4] = {0, 0, 0, 0};
    uint64_t id = 0;
    uint64_t partnerId = 0;
    double orient = 1.0;  ///< inside the quad: orient * h >= 0
    int32_t partner = -1; ///< junction: the partner quad's index in the cell's list (-1: rim; quadCount: not in the cell)
    int32_t fold = 0;     ///< zero kerf: the partner's side goes on as the other side (QuadGeom::Side::fold)
    uint64_t cornerSides[4] = {0, 0, 0, 0}; ///< (own, partner's) rim side at each end of a junction
};
static_assert(sizeof(PackedKernelSide) == 96, "std430 layout of KernelSide");

/// A batch of cells for the kernel.
struct PackedKernelInput
{
    bool prism = false; ///< kerf > 0: the quads are closed prisms
    float isovalue = 0.0f;
    std::vector<PackedKernelCell> cells;
    std::vector<PackedKernelQuad> quads;
    std::vector<PackedKernelSide> sides;
    /// The 5-tet split (cellTets): [parity][tet][corner], corner as in insideMask.
    std::array<uint32_t, 40> tets{};
    /// For the cut pass's draw (its shading normals): per cell the grid's
    /// values at cell + (i, j, k), i, j, k in -1 .. 2 (64, i fastest; the
    /// grid's background where it has none), and index space to world mm.
    std::vector<float> blocks;
    std::array<double, 3> origin{}, spacing{};
};

/// Packs the kernel's input for `cells` (cut cells of `mask`, in that
/// order; a cell the mask does not cut gets no quads) on `volume` at
/// `isovalue`. Cost O(cells' quads).
PackedKernelInput packKernelInput(const vdb::Volume& volume, float isovalue, const CutMask& mask,
                                  const std::vector<openvdb::Coord>& cells);

} // namespace mtcut::cutter
