// The project's one hand-off mesh type (after manifold's MeshGL): flat,
// GPU-ready arrays that the isosurface, the cut, the GPU passes and the file
// writers all share. OpenMesh is used only at the edges (files, topology).
#pragma once

#include <glm/vec3.hpp>
#include <glm/ext/vector_int3.hpp>

#include <cstdint>
#include <vector>

namespace mtcut::cutter {

/// A triangle mesh in world millimetres (LPS, as vdb::Volume).
///
/// Winding: every triangle (a,b,c) is counter-clockwise seen from outside the
/// solid, so (b-a)x(c-a) points out of it, and a closed shell has positive
/// signed volume. Vertices are shared between triangles (welded by exact
/// keys where they are made, never by comparing floats).
struct Mesh
{
    std::vector<glm::vec3> positions; ///< world mm, one per vertex
    std::vector<glm::vec3> normals;   ///< unit outward normals, one per vertex (may be empty)
    std::vector<uint32_t> indices;    ///< 3 per triangle, into positions
    /// The voxel (i,j,k), in the volume's index space, whose cell produced
    /// each triangle; the GPU discard and cut passes key on it.
    std::vector<glm::ivec3> triangleVoxels;

    size_t vertexCount() const { return positions.size(); }
    size_t triangleCount() const { return indices.size() / 3; }
    bool empty() const { return indices.empty(); }
};

} // namespace mtcut::cutter
