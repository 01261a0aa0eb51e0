// Mesh validation (DESIGN.md "Checks every mesh must pass") and shells
// (connected components) with their volume and area.
#pragma once

#include "cutter/Mesh.h"

#include <glm/vec3.hpp>
#include <glm/ext/vector_int3.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mtcut::cutter {

/// Where one defect is, for a report a person can act on (open the file at
/// that point, look at that voxel of the scan).
struct DefectSite
{
    enum class Kind : uint8_t {
        BadIndexTriangle,
        NonFiniteTriangle,
        DegenerateTriangle,
        BoundaryEdge,
        NonManifoldEdge,
        InconsistentEdge,
        NonManifoldVertex,
        WrongWayShell,
    };
    Kind kind = Kind::BoundaryEdge;
    /// Orders the sites of one kind: the triangle, the edge's vertices
    /// (lower << 32 | higher), the vertex or the shell (findShells order).
    uint64_t key = 0;
    std::string what; ///< "edge 17-42, in 1 triangle", "shell 3: 40 triangles, ..."
    bool hasPosition = false; ///< false for a triangle with a bad index or a non-finite vertex
    glm::dvec3 position{0.0}; ///< world mm: an edge's middle, the vertex, a triangle's centroid
    bool hasVoxel = false;    ///< the mesh carries triangleVoxels
    glm::ivec3 voxel{0};      ///< the voxel whose cell made a triangle at the site

    /// "snake_case" name, as in summary.json ("boundary_edge", ...).
    static const char* name(Kind kind);
    /// As the report words it ("boundary edge", "non-manifold vertex", ...).
    static const char* label(Kind kind);
    /// One line: "boundary edge 17-42, in 1 triangle, at (1.2500, ...) mm, voxel (3, 4, 5)".
    std::string describe() const;
};

/// Counts of every defect checkMesh finds; all zero means a valid closed,
/// outward-oriented 2-manifold. Triangles with an index out of range are
/// counted in badIndexTriangles and left out of every other count.
struct MeshCheck
{
    size_t triangles = 0;
    size_t vertices = 0;
    size_t shells = 0;        ///< connected components (sharing a vertex), not a defect
    size_t unusedVertices = 0; ///< vertices no triangle references, not a defect

    size_t badIndexTriangles = 0;       ///< an index >= vertexCount
    size_t boundaryEdges = 0;           ///< edges in exactly one triangle
    size_t nonManifoldEdges = 0;        ///< edges in three or more triangles
    size_t inconsistentEdges = 0;       ///< edges in two triangles that run it the same way
    size_t nonManifoldVertices = 0;     ///< vertices whose triangles form more than one fan
    size_t degenerateTriangles = 0;     ///< a repeated index, or zero area (cross product exactly 0)
    size_t nonFiniteTriangles = 0;      ///< a vertex with a NaN or infinite coordinate
    /// Shells facing the wrong way for their nesting: the winding number of
    /// the other shells at a point of the shell must be 0 for a positive
    /// (outer, or island in a cavity) shell and 1 for a negative one (a cavity
    /// inside the solid, e.g. the inner wall of a hollow bone). Any other
    /// case counts here: an outer shell with negative volume is inside-out.
    size_t negativeVolumeShells = 0;
    size_t cavities = 0;                ///< correctly inward-facing cavity shells, not a defect
    size_t malformedArrays = 0;         ///< indices not a multiple of 3, normals or triangleVoxels of the wrong size

    /// Where: the first kSitesPerKind defects of each kind (lowest key
    /// first), kinds in the order above; malformed arrays have no site.
    static constexpr size_t kSitesPerKind = 5;
    std::vector<DefectSite> sites;

    /// Sum of all defect counts.
    size_t defects() const;
    bool ok() const { return defects() == 0; }
    /// Multi-line "name: count" report, one line per count, then one line
    /// per site when there are defects.
    std::string report() const;
};

/// Validates the mesh (see MeshCheck). Cost: O(triangles) time, parallel
/// (TBB); about 60 bytes per triangle of temporary memory. The nesting test
/// casts one ray per shell along a fixed generic direction through a 2D
/// bucket grid of the triangles.
MeshCheck checkMesh(const Mesh& mesh);

/// A connected component: triangles that share vertices, transitively.
struct Shell
{
    std::vector<uint32_t> triangles; ///< ascending triangle indices
    size_t vertexCount = 0;
    double volume = 0.0; ///< signed, mm^3 (positive when outward oriented and closed)
    double area = 0.0;   ///< mm^2
    /// The volume is zero within its rounding (|volume| at most 1e-12 of the
    /// sum of its terms' magnitudes): a crack, both sides of a zero-width
    /// cut that ends inside the solid, whose volume's sign is noise. Such a
    /// shell is a cavity where it is enclosed (winding number 1), and never
    /// an outer shell.
    bool flat = false;
    glm::dvec3 boundsMin{0.0}, boundsMax{0.0}; ///< world mm
};

/// The shells of the mesh in the order of their first triangle. Triangles
/// with an out-of-range index are skipped. Cost: O(triangles) (union-find).
std::vector<Shell> findShells(const Mesh& mesh);

/// For each shell of `shells` (findShells(mesh)), the shell that directly
/// encloses it when it is a cavity (negative volume or flat, winding number 1
/// of the other shells): the smallest positive shell whose own winding number is 1
/// there. -1 for every other shell (outer shells, islands, and shells facing
/// the wrong way for their nesting). Cost O(triangles) when there are
/// cavities, nothing otherwise.
std::vector<int> enclosingShells(const Mesh& mesh, const std::vector<Shell>& shells);

/// Signed volume (mm^3, positive for closed outward-oriented meshes) and
/// area (mm^2) of the whole mesh, in double precision.
double meshVolume(const Mesh& mesh);
double meshArea(const Mesh& mesh);

/// One Mesh per shell, in findShells order; vertices renumbered in order of
/// first use; normals and triangleVoxels carried over.
std::vector<Mesh> splitShells(const Mesh& mesh);

/// The sub-mesh of the given triangles (vertices renumbered in order of
/// first use; normals and triangleVoxels carried over).
Mesh subMesh(const Mesh& mesh, const std::vector<uint32_t>& triangles);

} // namespace mtcut::cutter
