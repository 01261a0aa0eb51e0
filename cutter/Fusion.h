// Fusion of the cut geometry with the uncut isosurface, and the fragments
// (shells) of the result (MTCut paper section 4.3, "fuse it with the current
// isosurface"; DESIGN.md invariant 9).
#pragma once

#include "cutter/Mesh.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace mtcut::cutter {

/// One solid piece of a cut mesh: an outer shell and the cavity shells it
/// directly encloses (e.g. the inner wall of a hollow bone, a marrow or air
/// pocket), so a fragment file is a closed solid on its own, never an
/// inside-out pocket.
struct Fragment
{
    Mesh mesh;             ///< its shells (vertices renumbered in order of first use)
    double volume = 0.0;   ///< mm^3 of solid: the outer shell's minus its cavities'
    double area = 0.0;     ///< mm^2, every shell's
    size_t cavities = 0;   ///< cavity shells inside the outer one
    /// mm^2 of its surface on the blade (the cut faces), when fragmentsOf is
    /// told which triangles those are; 0 for a piece the cut did not touch.
    double cutArea = 0.0;
};

/// The triangles of each fragment of `mesh`, in fragmentsOf order: each
/// positive shell followed by the cavity shells it directly encloses
/// (enclosingShells); a shell facing the wrong way for its nesting stays a
/// fragment of its own (checkMesh counts it as a defect). Largest solid
/// volume first, ties by the first triangle. Cost O(triangles).
std::vector<std::vector<uint32_t>> fragmentTriangles(const Mesh& mesh);

/// The fragments of `mesh` as separate meshes (fragmentTriangles order).
/// onBlade: empty, or one flag per triangle of `mesh`, 1 for a triangle on
/// the blade (CutRemesher::bladeTriangles); their area is each fragment's
/// cutArea.
std::vector<Fragment> fragmentsOf(const Mesh& mesh, const std::vector<uint8_t>& onBlade = {});

} // namespace mtcut::cutter
