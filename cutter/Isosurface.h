// Marching Tetrahedra isosurface of a vdb::Volume (paper section 3.1, figure 2:
// the conformal 5-tetrahedra split), and the per-cell kernel that the cut
// re-meshing and the GPU shader reproduce.
//
// Grid and cells (index space). Grid vertices are voxel centres: vertex
// (i,j,k) carries the volume's value at voxel (i,j,k). Cell (i,j,k) is the
// cube with corners (i..i+1, j..j+1, k..k+1); Mesh::triangleVoxels stores this
// (i,j,k). Vertices outside the scan box [0, dims-1] count as outside (their
// value is the grid's background), so the surface closes at the edge of the
// grid: cells (i,j,k) with -1 <= i,j,k <= dims-1 can produce triangles.
//
// The split (DESIGN.md invariants 1-3). Local corner c = x + 2y + 4z of a
// cell. The four corners whose global parity (i+j+k of the grid vertex) is
// even form the central tetrahedron; each of the four others is the apex of a
// corner tetrahedron with its three axis neighbours. Neighbouring cells
// therefore agree on every face diagonal (it always joins the two even
// corners of the face), and the only edges are the 3 axis edges and the 6
// face diagonals; there is no body diagonal.
//
// Global decisions (nothing is decided per tet or per cell):
//  - vertex classification: inside = (value >= isovalue) and in the box;
//  - an edge's crossing point is edgeCrossing(value at its lower-keyed end,
//    value at the other end, isovalue), measured from the lower-keyed end
//    (the end with the smaller linear id, x fastest, i.e. smaller (z,y,x));
//  - output vertices are welded by their edge (its grid vertices), never by
//    comparing floats.
#pragma once

#include "cutter/Mesh.h"
#include "vdb/Progress.h"
#include "vdb/Volume.h"

#include <array>
#include <cstdint>
#include <string>

namespace mtcut::cutter {

// ---------------------------------------------------------------- kernel ----

/// An edge of a cell: local corners lo < hi (lo is the lower-keyed end).
struct CellEdge
{
    uint8_t lo, hi;
};

/// Triangles of one cell for one sign pattern: edge ids into cellEdges(parity).
struct CellCase
{
    uint8_t triangleCount = 0;           ///< 0..kMaxCellTriangles
    std::array<uint8_t, 30> edges{};     ///< 3 per triangle, outward CCW
};

constexpr int kTetsPerCell = 5;
constexpr int kCellEdgeCount = 18; ///< 12 axis edges + 6 face diagonals
constexpr int kMaxCellTriangles = 10;

/// Parity of cell (i,j,k): (i+j+k) & 1 (also right for negative indices).
inline int cellParity(int i, int j, int k) { return (i + j + k) & 1; }

/// The 5 tetrahedra of a cell of the given parity, as local corners, each
/// positively oriented (det(v1-v0, v2-v0, v3-v0) > 0). Tet 4 is the central one.
const std::array<std::array<uint8_t, 4>, kTetsPerCell>& cellTets(int parity);

/// The 18 edges of a cell of the given parity (12 axis edges, then the 6 face
/// diagonals that join even-parity corners).
const std::array<CellEdge, kCellEdgeCount>& cellEdges(int parity);

/// Triangles of a cell for insideMask (bit c set = local corner c inside), the
/// union of its 5 tets' triangles in tet order: a tet with one vertex A
/// inside (or outside) gives one triangle on A's three edges, two inside gives
/// the quad split along a fixed diagonal. Winding: CCW seen from outside.
/// Table lookup; parity as cellParity.
const CellCase& cellCase(int parity, uint8_t insideMask);

/// Fraction t in [kEdgeClamp, 1 - kEdgeClamp] along an edge from its
/// lower-keyed end (value valueLo) to the other (valueHi) where the linear
/// interpolant meets isovalue. Clamping keeps every triangle non-degenerate
/// when a grid value equals the isovalue exactly (integer CT data does that
/// often); it moves such vertices by at most kEdgeClamp of an edge. A pure
/// function of the edge's two values: neighbours compute bitwise the same t.
constexpr double kEdgeClamp = 1.0 / 256.0;
double edgeCrossing(float valueLo, float valueHi, float isovalue);

/// A cell's triangles, unwelded, for callers that re-mesh single cells.
/// values[c]: value at local corner c; inside[c]: classification (callers
/// pass value >= iso, or false outside the scan box). cell: the cell's (i,j,k).
/// Writes up to kMaxCellTriangles*3 world positions (origin + spacing * index,
/// mm, double arithmetic rounded to float; the same floats extractIsosurface
/// makes) to outPositions and returns the triangle count.
int polygoniseCell(const float values[8], const bool inside[8], const openvdb::Coord& cell, float isovalue,
                   const openvdb::Vec3d& originMm, const openvdb::Vec3d& spacingMm, glm::vec3* outPositions);

// -------------------------------------------------------------- extraction --

struct IsosurfaceOptions
{
    /// Polled once per batch of 8^3 blocks from the worker threads with the
    /// percentage done; throws Cancelled when it asks to stop.
    Interrupter* interrupter = nullptr;
    /// Gradient normals (central differences at the grid vertices,
    /// interpolated along the edge, pointing to lower values, world space).
    bool normals = true;
};

/// The isosurface {V >= isovalue} of the volume as a closed, outward-oriented
/// 2-manifold (see the file comment for cells, classification and welding).
///
/// Output: positions (world mm), normals (unit, outward) unless disabled,
/// one vertex per crossed edge, triangles CCW seen from outside, and each
/// triangle's cell in triangleVoxels. Order: 8^3 blocks in ascending
/// (x,y,z) origin order, within a block cells in (x,y,z) order with z
/// fastest, within a cell as cellCase; the same mesh whatever the thread count.
///
/// Work: per 8^3 block (an OpenVDB leaf plus the +1 layer of its neighbours),
/// two parallel passes (count, then fill) with TBB; blocks whose values
/// cannot straddle the isovalue are never visited. Memory: the mesh plus
/// ~60 bytes per visited block. Tiles at or above the isovalue (not made by
/// makeVolume) are voxelised in a temporary copy of the tree.
///
/// Isovalue outside [minValue, maxValue]: empty mesh (see isosurfaceWarning).
/// Throws InputError on a NaN or infinite isovalue or grid value (naming the
/// voxel), on a missing grid, or a transform that is not scale + translation.
Mesh extractIsosurface(const vdb::Volume& volume, float isovalue, const IsosurfaceOptions& options = {});

/// A one-line warning for an isovalue that extracts something other than the
/// user probably meant, or "" when it is fine: outside [minValue, maxValue]
/// (the mesh is empty) or at or below the air threshold (air is stored as
/// inactive background there, so the surface follows the pruned tiles).
std::string isosurfaceWarning(const vdb::Volume& volume, float isovalue);

} // namespace mtcut::cutter
