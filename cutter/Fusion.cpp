#include "cutter/Fusion.h"

#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"

#include <functional>

#include <tbb/parallel_for.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <numeric>
#include <stdexcept>
#include <unordered_map>

namespace mtcut::cutter {

namespace {

struct Group
{
    std::vector<uint32_t> shells; ///< the outer (or lone) shell first, then its cavities
    double volume = 0.0, area = 0.0;
};

std::vector<Group> fragmentGroups(const std::vector<Shell>& shells, const std::vector<int>& parent)
{
    std::vector<int> groupOf(shells.size(), -1);
    std::vector<Group> groups;
    for (size_t s = 0; s < shells.size(); ++s) {
        if (parent[s] >= 0) continue;
        groupOf[s] = int(groups.size());
        groups.push_back(Group{{uint32_t(s)}, shells[s].volume, shells[s].area});
    }
    for (size_t s = 0; s < shells.size(); ++s) {
        if (parent[s] < 0) continue;
        Group& g = groups[size_t(groupOf[size_t(parent[s])])];
        g.shells.push_back(uint32_t(s));
        g.volume += shells[s].volume;
        g.area += shells[s].area;
    }
    // Largest solid first; ties by the outer shell's first triangle (groups
    // are made in that order).
    std::stable_sort(groups.begin(), groups.end(), [](const Group& a, const Group& b) { return a.volume > b.volume; });
    return groups;
}

std::vector<uint32_t> trianglesOf(const Group& g, const std::vector<Shell>& shells)
{
    std::vector<uint32_t> out;
    for (uint32_t s : g.shells) out.insert(out.end(), shells[s].triangles.begin(), shells[s].triangles.end());
    return out;
}

} // namespace

std::vector<std::vector<uint32_t>> fragmentTriangles(const Mesh& mesh)
{
    const std::vector<Shell> shells = findShells(mesh);
    std::vector<std::vector<uint32_t>> out;
    for (const Group& g : fragmentGroups(shells, enclosingShells(mesh, shells))) out.push_back(trianglesOf(g, shells));
    return out;
}

std::vector<Fragment> fragmentsOf(const Mesh& mesh)
{
    const std::vector<Shell> shells = findShells(mesh);
    const std::vector<Group> groups = fragmentGroups(shells, enclosingShells(mesh, shells));
    std::vector<Fragment> out(groups.size());
    tbb::parallel_for(size_t(0), groups.size(), [&](size_t i) {
        out[i].mesh = subMesh(mesh, trianglesOf(groups[i], shells));
        out[i].volume = groups[i].volume;
        out[i].area = groups[i].area;
        out[i].cavities = groups[i].shells.size() - 1;
    });
    return out;
}

Mesh CutRemesher::fusedMesh() const
{
    Mesh m;
    const size_t uncutVertices = mUncut.positions.size();
    m.positions = mUncut.positions;
    const bool normals = mUncut.normals.size() == uncutVertices && uncutVertices > 0;
    if (normals) m.normals = mUncut.normals;
    const size_t nt = mUncut.triangleCount();
    for (size_t t = 0; t < nt; ++t) {
        const glm::ivec3 c = mUncut.triangleVoxels[t];
        if (mCells.count(openvdb::Coord(c.x, c.y, c.z))) continue;
        m.indices.insert(m.indices.end(), mUncut.indices.begin() + long(3 * t), mUncut.indices.begin() + long(3 * t + 3));
        m.triangleVoxels.push_back(c);
    }
    std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash> added;
    std::vector<std::pair<std::pair<uint64_t, uint64_t>, uint32_t>> edgeMap;
    std::vector<std::pair<uint64_t, uint64_t>> corners;
    for (const auto& [cell, geom] : mCells) {
        // The uncut vertices of this cell's crossed edges (welding by key).
        edgeMap.clear();
        auto range = mUncutCells.find(cell);
        if (range != mUncutCells.end()) {
            uncutCornerEdges(cell, corners);
            for (size_t k = 0; k < corners.size(); ++k)
                edgeMap.push_back({corners[k], mUncut.indices[3 * size_t(range->second.first) + k]});
        }
        std::vector<uint32_t> index(geom.vertexIds.size());
        for (size_t v = 0; v < geom.vertexIds.size(); ++v) {
            const CutVertexId& id = geom.vertexIds[v];
            if (id.isIsoEdgeVertex()) {
                const std::pair<uint64_t, uint64_t> key{id.feature[0], id.feature[1]};
                auto it = std::find_if(edgeMap.begin(), edgeMap.end(), [&](const auto& e) { return e.first == key; });
                if (it == edgeMap.end()) throw std::logic_error("fusion: a cut cell's iso vertex has no uncut vertex");
                index[v] = it->second;
                continue;
            }
            auto [it, isNew] = added.emplace(id, uint32_t(m.positions.size()));
            if (isNew) {
                m.positions.push_back(worldPosition(*mVolume, geom.indexPositions[v]));
                if (normals) m.normals.push_back(glm::vec3(0.0f));
            }
            index[v] = it->second;
        }
        for (size_t i = 0; i < geom.indices.size(); i += 3) {
            for (int j = 0; j < 3; ++j) m.indices.push_back(index[geom.indices[i + size_t(j)]]);
            m.triangleVoxels.push_back(glm::ivec3(cell.x(), cell.y(), cell.z()));
        }
    }
    // Snap rounding: two vertices joined by an edge that land on the same
    // float position (a sub-micron sliver of the exact geometry, e.g. where a
    // grid plane passes within 1e-5 voxel of a blade corner) are one vertex
    // in the float mesh; the triangles that collapse are dropped. The lower
    // index is kept (an uncut vertex before a new one), so uncut triangles
    // never change. checkLocally() checks the mesh after this step.
    {
        std::vector<uint32_t> rep(m.positions.size());
        for (size_t v = 0; v < rep.size(); ++v) rep[v] = uint32_t(v);
        std::function<uint32_t(uint32_t)> find = [&](uint32_t x) { return rep[x] == x ? x : rep[x] = find(rep[x]); };
        bool any = false;
        for (size_t i = 0; i < m.indices.size(); i += 3)
            for (int k = 0; k < 3; ++k) {
                const uint32_t a = m.indices[i + size_t(k)], b = m.indices[i + size_t((k + 1) % 3)];
                if (a == b || !(m.positions[a] == m.positions[b])) continue;
                const uint32_t ra = find(a), rb = find(b);
                if (ra == rb) continue;
                rep[std::max(ra, rb)] = std::min(ra, rb);
                any = true;
            }
        if (any) {
            std::vector<uint32_t> indices;
            std::vector<glm::ivec3> voxels;
            indices.reserve(m.indices.size());
            voxels.reserve(m.triangleVoxels.size());
            for (size_t t = 0; t < m.triangleCount(); ++t) {
                const uint32_t a = find(m.indices[3 * t]), b = find(m.indices[3 * t + 1]), c = find(m.indices[3 * t + 2]);
                if (a == b || b == c || a == c) continue;
                indices.insert(indices.end(), {a, b, c});
                voxels.push_back(m.triangleVoxels[t]);
            }
            m.indices.swap(indices);
            m.triangleVoxels.swap(voxels);
        }
    }
    if (normals) {
        for (size_t t = 0; t < m.triangleCount(); ++t) {
            const uint32_t a = m.indices[3 * t], b = m.indices[3 * t + 1], c = m.indices[3 * t + 2];
            if (a < uncutVertices && b < uncutVertices && c < uncutVertices) continue;
            const glm::vec3 n = glm::cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]);
            for (uint32_t v : {a, b, c})
                if (v >= uncutVertices) m.normals[v] += n;
        }
        for (size_t v = uncutVertices; v < m.normals.size(); ++v) {
            const float l = glm::length(m.normals[v]);
            m.normals[v] = l > 0 ? m.normals[v] / l : glm::vec3(0, 0, 1);
        }
    }
    return m;
}

} // namespace mtcut::cutter
