// Internal to cutter/ (kerf > 0): the prisms of a cell that the others
// cover there. A saw worked back and forth lays a prism over the whole
// blade each pass, so the cells near the top of the cut collect dozens of
// them, nearly parallel and a tremor apart (the 1 mm head's sawing seeds:
// 20-50 a cell, a live update 0.3-1.4 s). Of those, all but the outermost
// few lie inside the union of the rest: they remove nothing the others do
// not, and no face of theirs reaches the surface. The kernel's arrangement
// grows with every plane in a tet, so cellQuads (Remesh.cpp) drops them
// before the kernel, the GPU cut pass and removedVoxels see the cell. For
// the kernel and the GPU cut pass the others need cover a prism only where
// it meets the cell's solid: the cell's air removes the rest already.
// No GL.
#pragma once

#include "cutter/RemeshKernel.h"

#include <vector>

namespace mtcut::cutter::remesh_detail {

/// How far inside the union of the others (index-space distance from
/// their faces) every point of a prism's part of the cell must lie for it
/// to be dropped: far above the kernel's ties (epsAt: 1e-13 of the
/// coordinates) and the rounding of this test, so no point of the
/// surface, which lies on or outside that union, is ever on a dropped
/// prism's plane there.
constexpr double kCoverMargin = 1e-6;

/// Fewer prisms than this in a cell: none is tested (the common cell holds
/// one quad and its stroke neighbours).
constexpr size_t kCoverMinPrisms = 3;

/// Where a cell's solid can lie, tet by tet (kerf > 0, a cell with air at
/// some corner): each of its five tets that holds solid (a corner inside),
/// with the half-space that holds the convex hull of the tet's inside
/// corners and its marching-tetrahedra points (the kernel's: edgeCrossing
/// from the lower-keyed end), grown by kCoverMargin. The kernel's solid in
/// a tet is bounded by those points' polygons and the tet's faces, so it
/// lies in that hull.
struct CellSolid
{
    std::array<bool, kTetsPerCell> holds{};
    std::array<std::array<dvec3, 4>, kTetsPerCell> corners{}; ///< each tet's corners, index space
    std::array<Plane, kTetsPerCell> hull{};        ///< solid side: hull[t].h(x) >= 0 (n zero: the whole tet)
};

/// The cell's CellSolid from its corner values and inside mask (bit c for
/// corner (c & 1, c >> 1 & 1, c >> 2 & 1)) as the kernel reads them: a
/// corner outside the scan box has the background value and is outside.
CellSolid cellSolid(const Coord& cell, const std::array<float, 8>& values, uint8_t inside, float iso);

/// For each prism of `quads` (a cell's kernel input, kerf > 0, in its
/// order), whether it is covered in the closed box of `cell` (index space
/// [cell, cell + 1]): its part of the box is not empty and lies, with
/// kCoverMargin to spare, inside the union of the other prisms not found
/// covered before it (tested in order: each one dropped leaves that union
/// as it was, so the prisms kept remove what all of them do). Two prisms
/// that share a face both stay (neither lies inside the other by the
/// margin). Conservative: a prism whose pieces outrun the test's budget
/// counts as not covered.
/// With `solid` (a cell with air at some corner), the others need cover a
/// prism only where it meets the solid: the prism grown by half the margin,
/// in each tet that holds solid, cut to that tet's hull. A prism in the
/// cell's air alone is covered.
std::vector<char> coveredPrisms(const Coord& cell, const std::vector<QuadGeom>& quads,
                                const CellSolid* solid = nullptr);

/// The clip the test is built on, for the tests: the closed box of `cell`
/// cut to the side n . x - d >= 0 of each plane in turn, as its faces
/// (convex polygons, index space); none when nothing with volume is left.
std::vector<std::vector<dvec3>> clipCellForTesting(const Coord& cell, const std::vector<Plane>& planes);

/// Whether cellQuads leaves the covered prisms out (default true). For the
/// tests that hold a cell's geometry the same either way; process-wide.
void dropCoveredPrismsForTesting(bool drop);
bool dropCoveredPrisms();

} // namespace mtcut::cutter::remesh_detail
