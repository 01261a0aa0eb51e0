// The CPU side of the GPU coding of a sparse cell mask (DESIGN "GPU passes",
// mask coding): OpenVDB leaf nodes of the mask (8^3 cells = 512 bits = 16
// uint32) become slots of an atlas, found through an indirection table over
// the leaf grid. No GL here (render/MaskAtlas.h puts it on the GPU); it lives
// in render/ because vdb/ is another engineer's folder for now.
#pragma once

#include "cutter/CutMask.h"
#include "cutter/Remesh.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace mtcut::render {

/// Bits per tile and uint32 words per tile (one OpenVDB leaf of 8^3 cells).
constexpr int kTileBits = 512;
constexpr int kTileWords = 16;

/// Bit of cell (i,j,k) inside its tile: OpenVDB's leaf order
/// n = 64 (i & 7) + 8 (j & 7) + (k & 7), so a leaf's value mask is the tile as
/// it is. Word n >> 5, bit n & 31 (words are the little-endian halves of the
/// leaf mask's 64-bit words).
inline int tileBitOf(const openvdb::Coord& c) { return ((c.x() & 7) << 6) | ((c.y() & 7) << 3) | (c.z() & 7); }

/// A set of cells tiled for the GPU. Cells may be anywhere (negative too).
///
/// Slots are the mask's leaves in ascending origin order (x, then y, then z),
/// so CPU and GPU agree on them. The indirection covers the leaf box
/// [leafMin, leafMin + leafExtent): entry x + ex (y + ey z) of leaf
/// leafMin + (x,y,z) is slot + 1, or 0 when the leaf holds no cell. Memory:
/// 64 bytes per leaf plus 4 bytes per leaf of the bounding box.
struct MaskTiling
{
    openvdb::Coord leafMin{0, 0, 0};            ///< leaf coordinates (cell >> 3) of the box's low corner
    openvdb::Coord leafExtent{0, 0, 0};         ///< leaves per axis; 0 when empty
    std::vector<openvdb::Coord> leafOrigins;    ///< slot -> the leaf's origin cell (multiple of 8)
    std::vector<uint32_t> words;                ///< kTileWords per slot: the tile bits
    std::vector<uint32_t> indirection;          ///< per leaf of the box: slot + 1, or 0

    size_t slotCount() const { return leafOrigins.size(); }
    bool empty() const { return leafOrigins.empty(); }
    /// Slot + 1 of the leaf holding `cell`, or 0.
    uint32_t slotOf(const openvdb::Coord& cell) const;
    /// Whether `cell` is set (through the indirection and the tile bits).
    bool isSet(const openvdb::Coord& cell) const;
    /// Every set cell, in slot order then bit order.
    std::vector<openvdb::Coord> cells() const;
};

/// Tiles the active voxels of `mask` (active tiles are voxelised first).
/// Throws InputError when the leaf box has more than 2^31 leaves. Cost:
/// O(leaves + leaf box).
MaskTiling tileMask(const openvdb::MaskTree& mask);

/// The cut cells of a CutMask as a mask grid (its active topology).
openvdb::MaskGrid::Ptr cutCellGrid(const cutter::CutMask& mask);

/// The cells whose uncut triangles a fused mesh replaces: every cell of
/// CutRemesher::cells() (the mask's cut cells, plus border cells just
/// outside the scan box that a quad of a border cell touches). The discard
/// pass must drop exactly these for its frame to equal the fused mesh's.
openvdb::MaskGrid::Ptr remeshedCellGrid(const cutter::CutRemesher& remesher);

} // namespace mtcut::render
