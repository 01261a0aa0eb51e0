// Fusion of the cut geometry with the uncut isosurface, and the fragments
// (shells) of the result (MTCut paper section 4.3, "fuse it with the current
// isosurface"; DESIGN.md invariant 9).
#pragma once

#include "cutter/Mesh.h"

#include <cstddef>
#include <vector>

namespace mtcut::cutter {

/// One connected piece of a cut mesh.
struct Fragment
{
    Mesh mesh;           ///< the shell alone (vertices renumbered in order of first use)
    double volume = 0.0; ///< mm^3, positive for a closed outward-oriented shell
    double area = 0.0;   ///< mm^2
};

/// The shells of `mesh` as separate meshes, largest volume first (ties: the
/// order of their first triangle). Cost O(triangles).
std::vector<Fragment> fragmentsOf(const Mesh& mesh);

} // namespace mtcut::cutter
