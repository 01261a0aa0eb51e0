// The CPU-made cut geometry in the form the GPU passes draw it (the GPU cut
// pass, render/CutKernelGpu.h, writes the same with the same normals): the
// re-meshed cells of a CutRemesher as one world-space mesh, plus per-triangle data (fragment ids,
// cap flags). No GL here.
#pragma once

#include "cutter/Mesh.h"
#include "cutter/Remesh.h"
#include "vdb/Volume.h"

#include <cstdint>
#include <utility>
#include <vector>

namespace mtcut::render {

/// How the cut geometry's vertices get their normals.
enum class CutNormals
{
    /// For shading (DESIGN: gradient normals on the isosurface, the blade's
    /// normal on caps): isosurface pieces get the volume's gradient normal at
    /// every vertex (on grid edges exactly extractIsosurface's; elsewhere the
    /// trilinear interpolation of the cell corners' central differences);
    /// cap triangles get their blade plane's normal (vertices are not shared
    /// between caps and isosurface pieces, nor between caps of two planes).
    Shading,
    /// As CutRemesher::fusedMesh(): vertices welded by CutVertexId,
    /// marching-tetrahedra vertices with their gradient normal, every other
    /// vertex the area-weighted normal of its triangles (caps and isosurface
    /// pieces mixed). For comparing frames with the fused mesh's.
    Fused,
};

/// The cut cells' triangles as one mesh.
struct CutGeometry
{
    /// World mm; cells ascending, each cell's triangles in order (so the
    /// triangles are, in order, those fusedMesh() appends after the uncut
    /// ones), the same positions; normals as CutNormals says.
    cutter::Mesh mesh;
    /// 1 for a cap triangle (its three vertices share a plane of the blade's
    /// removed region: the quad's plane with zero kerf; with kerf > 0 a
    /// prism face, i.e. an offset plane at +-w/2, a side or a mitre), 0 for
    /// isosurface pieces. One per triangle.
    std::vector<uint8_t> triangleIsCap;
};

/// Builds the cut geometry of `remesher` (updated to its mask) on `volume`
/// at `isovalue` (the remesher's). Cost O(cut cells' triangles).
CutGeometry cutGeometryOf(const cutter::CutRemesher& remesher, const vdb::Volume& volume, float isovalue,
                          CutNormals normals = CutNormals::Shading);

/// The same for the cells given (in that order), e.g. those the CPU kernel
/// re-meshed for the GPU cut pass (render/CutKernelGpu.h).
CutGeometry cutGeometryOfCells(const std::vector<std::pair<openvdb::Coord, const cutter::CutCellGeometry*>>& cells,
                               const vdb::Volume& volume, float isovalue, CutNormals normals = CutNormals::Shading);

/// Fragment id of every triangle of `mesh`: 1 + the index of its fragment
/// (an outer shell with its cavities) in cutter::fragmentsOf order (largest
/// solid volume first), i.e. fragment_000 -> 1. Cost O(triangles).
std::vector<uint32_t> fragmentIdsOf(const cutter::Mesh& mesh);

/// Fragment ids for the discard render of a cut, from the fragments of
/// `fused` = remesher.fusedMesh(&source) (fragmentIdsOf): one per uncut
/// triangle (0 where its cell is re-meshed: the discard pass drops it) and
/// one per cut-geometry triangle (cutGeometryOf order); 0 also for the
/// triangles snap rounding dropped. Throws std::logic_error when `source`
/// does not fit.
void discardFragmentIds(const cutter::CutRemesher& remesher, const cutter::Mesh& fused,
                        const std::vector<uint32_t>& source, std::vector<uint32_t>& uncutIds,
                        std::vector<uint32_t>& cutIds);

} // namespace mtcut::render
