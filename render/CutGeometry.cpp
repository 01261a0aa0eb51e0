#include "render/CutGeometry.h"

#include "cutter/Fusion.h"
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

namespace mtcut::render {

using openvdb::Coord;

namespace {

/// Trilinear interpolation, at index point p of `cell`, of the central
/// difference gradients at the cell's corners (pointing to lower values,
/// world space), normalised; zero when the field is flat there.
glm::vec3 trilinearGradientNormal(const openvdb::FloatGrid::ConstAccessor& acc, const openvdb::Vec3d& spacing,
                                  const Coord& cell, const glm::dvec3& p)
{
    glm::dvec3 g(0.0);
    const glm::dvec3 f = glm::clamp(p - glm::dvec3(cell.x(), cell.y(), cell.z()), 0.0, 1.0);
    for (int c = 0; c < 8; ++c) {
        const Coord q = cell + Coord(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        const double w = ((c & 1) ? f.x : 1.0 - f.x) * (((c >> 1) & 1) ? f.y : 1.0 - f.y) * (((c >> 2) & 1) ? f.z : 1.0 - f.z);
        for (int a = 0; a < 3; ++a) {
            Coord e(0);
            e[a] = 1;
            g[a] -= w * 0.5 * (double(acc.getValue(q + e)) - double(acc.getValue(q - e))) / spacing[a];
        }
    }
    const double len = glm::length(g);
    return len > 0.0 && std::isfinite(len) ? glm::vec3(g / len) : glm::vec3(0.0f);
}

/// The gradient normal of the marching-tetrahedra vertex on grid edge
/// (p0, p1), p0 the lower-keyed end: extractIsosurface's formula (central
/// differences at both ends, interpolated at the crossing, pointing to lower
/// values, world space), evaluated in the same float/double steps.
glm::vec3 gradientNormal(const openvdb::FloatGrid::ConstAccessor& acc, const Coord& dims, float iso,
                         const openvdb::Vec3d& spacing, const Coord& p0, const Coord& p1)
{
    auto value = [&](const Coord& p) { return acc.getValue(p); };
    auto inBox = [&](const Coord& p) {
        return p.x() >= 0 && p.y() >= 0 && p.z() >= 0 && p.x() < dims.x() && p.y() < dims.y() && p.z() < dims.z();
    };
    const float v0 = value(p0), v1 = value(p1);
    const double t = cutter::edgeCrossing(v0, v1, iso);
    glm::vec3 g;
    for (int a = 0; a < 3; ++a) {
        Coord e(0);
        e[a] = 1;
        const float g0 = 0.5f * (value(p0 + e) - value(p0 - e));
        const float g1 = 0.5f * (value(p1 + e) - value(p1 - e));
        g[a] = float(-(g0 + t * (g1 - g0)) * (1.0 / spacing[a]));
    }
    const float len = std::sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
    if (len > 0.0f && std::isfinite(len)) return g / len;
    const bool in0 = inBox(p0) && v0 >= iso;
    const float sign = in0 ? 1.0f : -1.0f;
    for (int a = 0; a < 3; ++a) g[a] = sign * float((p1[a] - p0[a]) * spacing[a]);
    return g / std::sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
}

/// The blade plane a cap triangle's vertices are welded under (Shading): the
/// one all three lie on (capPlaneOf); for a triangle of a cap region joined
/// across two quads' coincident faces, which may have none, the lowest blade
/// plane two of them lie on, else the first vertex's first one. The joined
/// faces are one plane, so a vertex keyed both ways gets one normal twice.
uint64_t capKeyPlane(const cutter::CutCellGeometry& geom, const uint32_t* corner)
{
    const cutter::CutVertexId* v[3] = {&geom.vertexIds[corner[0]], &geom.vertexIds[corner[1]], &geom.vertexIds[corner[2]]};
    if (const uint64_t p = cutter::capPlaneOf(*v[0], *v[1], *v[2])) return p;
    auto on = [](const cutter::CutVertexId& x, uint64_t p) {
        return std::find(x.planes.begin(), x.planes.begin() + x.planeCount, p) != x.planes.begin() + x.planeCount;
    };
    uint64_t best = 0;
    for (int a = 0; a < 3; ++a)
        for (int i = 0; i < v[a]->planeCount; ++i) {
            const uint64_t p = v[a]->planes[size_t(i)];
            if (cutter::isBladePlaneId(p) && (best == 0 || p < best) && on(*v[(a + 1) % 3], p)) best = p;
        }
    if (best) return best;
    for (int i = 0; i < v[0]->planeCount; ++i)
        if (cutter::isBladePlaneId(v[0]->planes[size_t(i)])) return v[0]->planes[size_t(i)];
    return 1; // (not reached: a cap vertex lies on a blade plane)
}

} // namespace

CutGeometry cutGeometryOf(const cutter::CutRemesher& remesher, const vdb::Volume& volume, float isovalue,
                          CutNormals normals)
{
    std::vector<std::pair<Coord, const cutter::CutCellGeometry*>> cells;
    cells.reserve(remesher.cells().size());
    for (const auto& [cell, geom] : remesher.cells()) cells.emplace_back(cell, &geom);
    return cutGeometryOfCells(cells, volume, isovalue, normals);
}

CutGeometry cutGeometryOfCells(const std::vector<std::pair<openvdb::Coord, const cutter::CutCellGeometry*>>& cells,
                               const vdb::Volume& volume, float isovalue, CutNormals normals)
{
    CutGeometry out;
    cutter::Mesh& m = out.mesh;
    const openvdb::Vec3d origin = volume.origin(), spacing = volume.spacing();
    const openvdb::FloatGrid::ConstAccessor acc = volume.grid->getConstAccessor();
    const bool shading = normals == CutNormals::Shading;
    // Vertex key: the cut vertex, and for shading which surface it is on
    // (0: the isosurface; otherwise the cap's blade plane id).
    struct Key
    {
        cutter::CutVertexId id;
        uint64_t surface;
        bool operator==(const Key& o) const { return surface == o.surface && id == o.id; }
    };
    struct KeyHash
    {
        size_t operator()(const Key& k) const { return cutter::CutVertexIdHash()(k.id) ^ (k.surface * 0x9e3779b97f4a7c15ull); }
    };
    std::unordered_map<Key, uint32_t, KeyHash> welded;
    std::vector<uint8_t> smooth; // 1: the normal is final (gradient); 0: area-weighted below
    for (const auto& [cell, geomPtr] : cells) {
        const cutter::CutCellGeometry& geom = *geomPtr;
        if (geom.cap.size() != geom.indices.size() / 3)
            throw std::invalid_argument("cutGeometryOfCells: a cell without one cap flag per triangle");
        for (size_t i = 0; i < geom.indices.size(); i += 3) {
            const uint32_t* corner = &geom.indices[i];
            const bool cap = geom.cap[i / 3] != 0;
            const uint64_t plane = cap ? capKeyPlane(geom, corner) : 0;
            out.triangleIsCap.push_back(uint8_t(cap));
            m.triangleVoxels.push_back(glm::ivec3(cell.x(), cell.y(), cell.z()));
            for (int j = 0; j < 3; ++j) {
                const uint32_t v = corner[j];
                const cutter::CutVertexId& id = geom.vertexIds[v];
                auto [it, isNew] = welded.emplace(Key{id, shading ? plane : 0}, uint32_t(m.positions.size()));
                m.indices.push_back(it->second);
                if (!isNew) continue;
                const glm::dvec3& p = geom.indexPositions[v];
                m.positions.push_back(glm::vec3(float(origin[0] + spacing[0] * p.x),
                                                float(origin[1] + spacing[1] * p.y),
                                                float(origin[2] + spacing[2] * p.z)));
                glm::vec3 n(0.0f);
                if (id.isIsoEdgeVertex() && !(shading && plane)) {
                    n = gradientNormal(acc, volume.dims, isovalue, spacing, cutter::gridVertexCoord(id.feature[0]),
                                       cutter::gridVertexCoord(id.feature[1]));
                } else if (shading && !plane) {
                    n = trilinearGradientNormal(acc, spacing, cell, p);
                }
                smooth.push_back(uint8_t(n != glm::vec3(0.0f)));
                m.normals.push_back(n);
            }
        }
    }
    // Area-weighted normals of the rest, in triangle order (as fusedMesh):
    // with Shading these are cap vertices (one plane each: the blade's
    // normal) and iso vertices in a flat field.
    for (size_t t = 0; t < m.triangleCount(); ++t) {
        const uint32_t a = m.indices[3 * t], b = m.indices[3 * t + 1], c = m.indices[3 * t + 2];
        if (smooth[a] && smooth[b] && smooth[c]) continue;
        const glm::vec3 n = glm::cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
        for (uint32_t v : {a, b, c})
            if (!smooth[v]) m.normals[v] += n;
    }
    for (size_t v = 0; v < m.normals.size(); ++v) {
        if (smooth[v]) continue;
        const float l = glm::length(m.normals[v]);
        m.normals[v] = l > 0 ? m.normals[v] / l : glm::vec3(0, 0, 1);
    }
    return out;
}

std::vector<uint32_t> fragmentIdsOf(const cutter::Mesh& mesh)
{
    std::vector<uint32_t> ids(mesh.triangleCount(), 0u);
    const std::vector<std::vector<uint32_t>> fragments = cutter::fragmentTriangles(mesh);
    for (size_t rank = 0; rank < fragments.size(); ++rank)
        for (uint32_t t : fragments[rank]) ids[t] = uint32_t(rank + 1);
    return ids;
}

void discardFragmentIds(const cutter::CutRemesher& remesher, const cutter::Mesh& fused,
                        const std::vector<uint32_t>& source, std::vector<uint32_t>& uncutIds,
                        std::vector<uint32_t>& cutIds)
{
    if (source.size() != fused.triangleCount())
        throw std::logic_error("discardFragmentIds: one source entry per fused triangle expected");
    const std::vector<uint32_t> ids = fragmentIdsOf(fused);
    const size_t uncutCount = remesher.uncut().triangleCount();
    size_t cutTriangles = 0;
    for (const auto& entry : remesher.cells()) cutTriangles += entry.second.indices.size() / 3;
    // Triangles snap rounding dropped (collapsed to zero area) keep id 0:
    // the discard pass drops them, as the fused mesh does.
    uncutIds.assign(uncutCount, 0u);
    cutIds.assign(cutTriangles, 0u);
    for (size_t t = 0; t < ids.size(); ++t) {
        const size_t s = source[t];
        if (s < uncutCount) uncutIds[s] = ids[t];
        else if (s - uncutCount < cutTriangles) cutIds[s - uncutCount] = ids[t];
        else throw std::logic_error("discardFragmentIds: a source entry out of range");
    }
}

} // namespace mtcut::render
