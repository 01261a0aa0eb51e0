// Mesh files through OpenMesh: binary STL, OBJ, PLY (binary), OFF (ASCII).
#pragma once

#include "cutter/Mesh.h"

#include <string>
#include <vector>

namespace mtcut::cutter {

enum class MeshFormat { Stl, Obj, Ply, Off };

/// Whether the path ends in .stl, .obj, .ply or .off (any case).
bool hasMeshExtension(const std::string& path);

/// The format from the extension (.stl .obj .ply .off, any case); throws
/// InputError naming the path for anything else.
MeshFormat meshFormatFromPath(const std::string& path);

/// Writes the mesh (world mm, as it is) in the format of the extension:
/// binary STL (facet normals from the winding), OBJ and PLY with the vertex
/// normals when the mesh has them, OFF. Written to a temporary file and
/// renamed, so a failure leaves no half file. Throws InputError on an
/// unknown extension or a write failure. Cost: one copy into an OpenMesh
/// TriMesh (about 100 bytes per vertex).
void writeMesh(const Mesh& mesh, const std::string& path);

/// Writes one file per shell (findShells order) next to path:
/// "DIR/STEM_shell001.EXT", ... (at least three digits). Returns the paths.
std::vector<std::string> writeShells(const Mesh& mesh, const std::string& path);

/// Vertices whose position another vertex shares exactly: where the
/// surface touches itself (the two sides of a kerf-0 cut that ends inside
/// the solid, the fans of a pinch). OBJ, PLY and OFF keep such vertices
/// apart; STL keeps positions only, so a reader that welds STL by position
/// (OpenMesh's, and most others) joins them into a non-manifold surface
/// there. Cost: a sort of the vertices (parallel).
size_t coincidentVertices(const Mesh& mesh);

/// Reads a mesh file (any of the formats above). STL vertices are merged by
/// OpenMesh's reader where positions are equal; a face its half-edge mesh
/// cannot take (non-manifold there) gets vertices of its own, so it reads
/// back with open edges. triangleVoxels is empty;
/// normals are read where the file has them. Throws InputError.
Mesh readMesh(const std::string& path);

} // namespace mtcut::cutter
