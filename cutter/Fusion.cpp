#include "cutter/Fusion.h"

#include "cutter/FloatRepair.h"
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"
#include "cutter/RemeshKernel.h"

#include <tbb/parallel_for.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <functional>
#include <numeric>
#include <stdexcept>
#include <tuple>
#include <unordered_map>

namespace mtcut::cutter {

namespace {

struct Group
{
    std::vector<uint32_t> shells; ///< the outer (or lone) shell first, then its cavities
    double volume = 0.0, area = 0.0;
};

/// Calls f(cell) for each cell round the grid edge of `id` (a vertex on a
/// grid edge: a cube edge has four, a face diagonal two) while f returns
/// true; false when one returned false.
template <class F>
bool everyCellRoundGridEdge(const CutVertexId& id, F&& f)
{
    const openvdb::Coord a = gridVertexCoord(id.feature[0]), b = gridVertexCoord(id.feature[1]);
    const openvdb::Coord lo = openvdb::Coord::maxComponent(a, b) - openvdb::Coord(1);
    const openvdb::Coord hi = openvdb::Coord::minComponent(a, b);
    for (int x = lo.x(); x <= hi.x(); ++x)
        for (int y = lo.y(); y <= hi.y(); ++y)
            for (int z = lo.z(); z <= hi.z(); ++z)
                if (!f(openvdb::Coord(x, y, z))) return false;
    return true;
}

/// The new vertices (index firstVertex on) of the triangles from
/// firstTriangle on whose fans are several closed discs (remesh_detail::
/// linkFans): every fan but the first (in triangle order) gets its own copy
/// of the vertex, at the same position, so the mesh is a 2-manifold that
/// touches itself there. Such a pinch spans cells: the exact shape where an
/// offset plane of the blade meets the isosurface at a saddle that sits on a
/// cell face (1 mm head, a level stroke at z = 1103 mm, kerf 1: the solid
/// under the plane is two wedges that meet at one marching-tetrahedra
/// vertex of a face diagonal; each cell holds part of both; at kerf 0, three
/// slits of a stroke turning sharply meeting at a point: 2 mm head, random
/// strokes seed 18088 with sharp turns). The split is a
/// function of the fused triangles, so incremental, from-scratch and undone
/// meshes stay equal. Cost O(new triangles).
/// `welded` (ascending): uncut vertices that new triangles use; those of
/// them with several such fans whose every triangle is a new one
/// (`allNew`: marching-tetrahedra vertices of grid edges whose cells are
/// all cut) are split the same way, after the new vertices: where snap
/// rounding joins a blade vertex of the grid edge into such a vertex
/// (remesh_detail::joinsAlongGridEdge), the solid round the edge is left as
/// two parts that meet there.
void splitCrossCellPinches(Mesh& m, size_t firstTriangle, size_t firstVertex, const std::vector<uint32_t>& welded,
                           const std::function<bool(uint32_t)>& allNew)
{
    const size_t nv = m.positions.size();
    if (nv <= firstVertex && welded.empty()) return;
    const bool normals = m.normals.size() == nv;
    // Slots: the new vertices, then `welded`.
    const size_t slots = nv - firstVertex + welded.size();
    auto slotOf = [&](uint32_t v) -> size_t {
        if (v >= firstVertex) return v - firstVertex;
        const auto it = std::lower_bound(welded.begin(), welded.end(), v);
        return it != welded.end() && *it == v ? nv - firstVertex + size_t(it - welded.begin()) : SIZE_MAX;
    };
    // The corners (3 t + k) at each slot's vertex, by a counting sort.
    std::vector<uint32_t> start(slots + 1, 0);
    for (size_t c = 3 * firstTriangle; c < m.indices.size(); ++c)
        if (const size_t s = slotOf(m.indices[c]); s != SIZE_MAX) ++start[s + 1];
    for (size_t v = 0; v + 1 < start.size(); ++v) start[v + 1] += start[v];
    std::vector<uint32_t> corners(start.back());
    {
        std::vector<uint32_t> fill(start.begin(), start.end() - 1);
        for (size_t c = 3 * firstTriangle; c < m.indices.size(); ++c)
            if (const size_t s = slotOf(m.indices[c]); s != SIZE_MAX) corners[fill[s]++] = uint32_t(c);
    }
    std::vector<std::pair<uint32_t, uint32_t>> link;
    std::vector<int> fan;
    for (size_t slot = 0; slot < slots; ++slot) {
        const size_t v = slot < nv - firstVertex ? firstVertex + slot : welded[slot - (nv - firstVertex)];
        const uint32_t b = start[slot], e = start[slot + 1];
        if (e - b < 6) continue; // two fans need three triangles each
        link.clear();
        for (uint32_t i = b; i < e; ++i) {
            const size_t t = corners[i] / 3, k = corners[i] % 3;
            link.push_back({m.indices[3 * t + (k + 1) % 3], m.indices[3 * t + (k + 2) % 3]});
        }
        const int fans = remesh_detail::linkFans(link, fan);
        if (fans >= 2 && v < firstVertex && !allNew(uint32_t(v))) continue;
        for (int f = 1; f < fans; ++f) {
            const uint32_t copy = uint32_t(m.positions.size());
            m.positions.push_back(m.positions[v]);
            if (normals) m.normals.push_back(glm::vec3(0.0f));
            for (uint32_t i = b; i < e; ++i)
                if (fan[i - b] == f) m.indices[corners[i]] = copy;
        }
    }
}

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

std::vector<Fragment> fragmentsOf(const Mesh& mesh, const std::vector<uint8_t>& onBlade)
{
    if (!onBlade.empty() && onBlade.size() != mesh.triangleCount())
        throw std::invalid_argument("fragmentsOf: one blade flag per triangle expected");
    const std::vector<Shell> shells = findShells(mesh);
    const std::vector<Group> groups = fragmentGroups(shells, enclosingShells(mesh, shells));
    std::vector<Fragment> out(groups.size());
    tbb::parallel_for(size_t(0), groups.size(), [&](size_t i) {
        const std::vector<uint32_t> triangles = trianglesOf(groups[i], shells);
        out[i].mesh = subMesh(mesh, triangles);
        out[i].volume = groups[i].volume;
        out[i].area = groups[i].area;
        out[i].cavities = groups[i].shells.size() - 1;
        if (onBlade.empty()) return;
        double cut = 0.0; // in double, as the shells' areas
        for (uint32_t t : triangles) {
            if (!onBlade[t]) continue;
            const glm::dvec3 a(mesh.positions[mesh.indices[3 * size_t(t)]]);
            const glm::dvec3 b(mesh.positions[mesh.indices[3 * size_t(t) + 1]]);
            const glm::dvec3 c(mesh.positions[mesh.indices[3 * size_t(t) + 2]]);
            cut += 0.5 * glm::length(glm::cross(b - a, c - a));
        }
        out[i].cutArea = cut;
    });
    return out;
}

std::vector<uint8_t> CutRemesher::bladeTriangles(const std::vector<uint32_t>& source) const
{
    // The cells' triangles in cells() order, then the fused triangles by source.
    std::vector<uint8_t> cellFlags;
    for (const auto& entry : mCells) {
        const CutCellGeometry& g = entry.second;
        if (g.cap.size() != g.indices.size() / 3)
            throw std::logic_error("bladeTriangles: cell " + remesh_detail::cellText(entry.first) + " has no cap flag per triangle");
        cellFlags.insert(cellFlags.end(), g.cap.begin(), g.cap.end());
    }
    const size_t nt = mUncut.triangleCount();
    std::vector<uint8_t> flags(source.size(), 0);
    for (size_t t = 0; t < source.size(); ++t) {
        if (source[t] < nt) continue;
        const size_t j = source[t] - nt;
        if (j >= cellFlags.size()) throw std::invalid_argument("bladeTriangles: not this remesher's fusedMesh source");
        flags[t] = cellFlags[j];
    }
    return flags;
}

Mesh CutRemesher::fusedMesh(std::vector<uint32_t>* source) const
{
    if (source) source->clear();
    Mesh m;
    const size_t uncutVertices = mUncut.positions.size();
    const bool normals = mUncut.normals.size() == uncutVertices && uncutVertices > 0;
    // The uncut triangles of the cut cells: runs (first, count), ascending
    // (extractIsosurface writes each cell's triangles together).
    std::vector<std::pair<uint32_t, uint32_t>> cutRuns;
    size_t cutTriangles = 0;
    UncutAccessor uncutAcc(mUncutFirst);
    VolumeAccessor volumeAcc(mVolume->grid->tree());
    for (const auto& entry : mCells) {
        const std::pair<uint32_t, uint32_t> run = uncutRun(uncutAcc, entry.first);
        if (run.second == 0) continue;
        cutRuns.push_back(run);
        cutTriangles += run.second;
    }
    std::sort(cutRuns.begin(), cutRuns.end());
    // The cut cells' triangles over fused vertex indices: all uncut vertices,
    // then the new ones in order of first use.
    m.positions.reserve(uncutVertices + 4 * mCells.size());
    m.positions = mUncut.positions;
    if (normals) m.normals = mUncut.normals;
    std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash> added;
    std::vector<std::pair<std::pair<uint64_t, uint64_t>, uint32_t>> edgeMap;
    std::vector<std::pair<uint64_t, uint64_t>> corners;
    std::vector<std::pair<uint32_t, const CutVertexId*>> welded; // uncut vertex, its iso edge vertex id
    std::vector<uint32_t> newIndices;
    std::vector<glm::ivec3> newVoxels;
    std::vector<char> intoFace; // per new triangle (CutCellGeometry::intoFace); empty when none is
    size_t intoFaceCount = 0;
    std::vector<uint32_t> index;
    struct Along
    {
        uint32_t iso, other, dir;
        const CutVertexId *isoId, *otherId;
    };
    std::vector<Along> along;
    struct RoundEdge // an edge between faces round a cube edge (joinsRoundCubeEdge)
    {
        uint32_t keep, other; // the lower name, the higher
        const CutVertexId *keepId, *otherId;
    };
    std::vector<RoundEdge> round;
    std::vector<Along> inFace; // edges inside a closed tet face (joinsPinchInFace): iso = the one kept
    for (const auto& [cell, geom] : mCells) {
        // The uncut vertices of this cell's crossed edges (welding by key).
        edgeMap.clear();
        const std::pair<uint32_t, uint32_t> run = uncutRun(uncutAcc, cell);
        uncutCornerEdges(volumeAcc, cell, run, corners);
        for (size_t k = 0; k < corners.size(); ++k)
            edgeMap.push_back({corners[k], mUncut.indices[3 * size_t(run.first) + k]});
        index.resize(geom.vertexIds.size());
        for (size_t v = 0; v < geom.vertexIds.size(); ++v) {
            const CutVertexId& id = geom.vertexIds[v];
            if (id.isIsoEdgeVertex()) {
                const std::pair<uint64_t, uint64_t> key{id.feature[0], id.feature[1]};
                auto it = std::find_if(edgeMap.begin(), edgeMap.end(), [&](const auto& e) { return e.first == key; });
                if (it == edgeMap.end()) throw std::logic_error("fusion: a cut cell's iso vertex has no uncut vertex");
                index[v] = it->second;
                welded.push_back({it->second, &id});
                continue;
            }
            auto [it, isNew] = added.emplace(id, uint32_t(m.positions.size()));
            if (isNew) {
                m.positions.push_back(worldPosition(*mVolume, geom.indexPositions[v]));
                if (normals) m.normals.push_back(glm::vec3(0.0f));
            }
            index[v] = it->second;
        }
        const size_t firstOfCell = newVoxels.size();
        const float lookSq = remesh_detail::snapLookSq(cell, mVolume->origin(), mVolume->spacing());
        for (size_t i = 0; i < geom.indices.size(); i += 3) {
            for (int j = 0; j < 3; ++j) {
                newIndices.push_back(index[geom.indices[i + size_t(j)]]);
                const CutVertexId& a = geom.vertexIds[geom.indices[i + size_t(j)]];
                const CutVertexId& b = geom.vertexIds[geom.indices[i + size_t(j + 1) % 3]];
                if (a.dim == 2 && b.dim == 2 && a < b && remesh_detail::facesMeetAtCubeEdge(a, b))
                    round.push_back(RoundEdge{index[geom.indices[i + size_t(j)]],
                                              index[geom.indices[i + size_t(j + 1) % 3]], &a, &b});
                if (a.dim == 2 || b.dim == 2) {
                    const uint32_t ia = index[geom.indices[i + size_t(j)]],
                                   ib = index[geom.indices[i + size_t(j + 1) % 3]];
                    const glm::vec3 d = m.positions[ia] - m.positions[ib];
                    if (glm::dot(d, d) < lookSq) { // (remesh_detail::snapLookSq)
                        if (remesh_detail::pinchInFaceCandidate(a, b)) inFace.push_back(Along{ia, ib, 0, &a, &b});
                        else if (remesh_detail::pinchInFaceCandidate(b, a)) inFace.push_back(Along{ib, ia, 1, &b, &a});
                    }
                }
                // An edge along a grid edge from its iso vertex (joinsAlongGridEdge).
                if (a.dim != 1 || b.dim != 1 || a.feature[0] != b.feature[0] || a.feature[1] != b.feature[1] ||
                    a.isIsoEdgeVertex() == b.isIsoEdgeVertex())
                    continue;
                const uint32_t ia = index[geom.indices[i + size_t(j)]], ib = index[geom.indices[i + size_t(j + 1) % 3]];
                along.push_back(a.isIsoEdgeVertex() ? Along{ia, ib, 0, &a, &b} : Along{ib, ia, 1, &b, &a});
            }
            newVoxels.push_back(glm::ivec3(cell.x(), cell.y(), cell.z()));
        }
        if (!geom.intoFace.empty()) {
            intoFace.resize(newVoxels.size(), 0);
            for (uint32_t t : geom.intoFace) intoFace[firstOfCell + t] = 1;
            intoFaceCount += geom.intoFace.size();
        }
    }
    if (intoFaceCount) intoFace.resize(newVoxels.size(), 0);
    // Snap rounding: two vertices joined by an edge that land on the same
    // float position (a sub-micron sliver of the exact geometry, e.g. where a
    // grid plane passes within 1e-5 voxel of a blade corner) are one vertex
    // in the float mesh; the triangles that collapse are dropped. The lowest
    // index of each such group is kept (an uncut vertex before a new one), so
    // uncut triangles only change where they held such an edge themselves.
    // checkLocally() checks the mesh after this step. Only the edges that can
    // be of zero length are looked at: the new triangles' and those of the
    // uncut triangles listed in mSnapTriangles (outside cut cells).
    std::unordered_map<uint32_t, uint32_t> rep; // vertex -> a lower vertex of its group; absent: itself
    auto find = [&](uint32_t x) {
        uint32_t r = x;
        for (auto it = rep.find(r); it != rep.end(); it = rep.find(r)) r = it->second;
        while (x != r) {
            auto it = rep.find(x);
            x = it->second;
            it->second = r;
        }
        return r;
    };
    auto uniteZeroLength = [&](const uint32_t* tri) {
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = tri[k], b = tri[(k + 1) % 3];
            if (a == b || !(m.positions[a] == m.positions[b])) continue;
            const uint32_t ra = find(a), rb = find(b);
            if (ra != rb) rep[std::max(ra, rb)] = std::min(ra, rb);
        }
    };
    // An edge from an iso vertex along its grid edge, used twice each way
    // and shorter than two float steps: its ends are one vertex, the iso
    // vertex (remesh_detail::joinsAlongGridEdge; the local check's snapRound).
    auto byEdge = [](const Along& x, const Along& y) {
        return std::tie(x.iso, x.other, x.dir) < std::tie(y.iso, y.other, y.dir);
    };
    // Runs of one edge in a sorted list, with its uses each way.
    auto usedTwiceEachWay = [](const std::vector<Along>& edges, auto&& visit) {
        for (size_t i = 0, j = 0; i < edges.size(); i = j) {
            size_t each[2] = {0, 0};
            for (j = i; j < edges.size() && edges[j].iso == edges[i].iso && edges[j].other == edges[i].other; ++j)
                ++each[edges[j].dir];
            if (each[0] == 2 && each[1] == 2) visit(edges[i]);
        }
    };
    std::sort(along.begin(), along.end(), byEdge);
    usedTwiceEachWay(along, [&](const Along& e) {
        if (!remesh_detail::joinsAlongGridEdge(*e.isoId, *e.otherId, m.positions[e.iso], m.positions[e.other],
                                               mVolume->origin(), mVolume->spacing()))
            return;
        const uint32_t ra = find(e.iso), rb = find(e.other);
        if (ra != rb) rep[std::max(ra, rb)] = std::min(ra, rb);
    });
    // Two vertices of faces round a cube edge, both rounded to within two
    // float steps of it and of each other: one vertex, the lower name's position
    // (remesh_detail::joinsRoundCubeEdge; the local check's snapRound).
    for (const RoundEdge& e : round) {
        if (!remesh_detail::joinsRoundCubeEdge(*e.keepId, *e.otherId, m.positions[e.keep], m.positions[e.other],
                                               mVolume->origin(), mVolume->spacing()))
            continue;
        m.positions[e.other] = m.positions[e.keep];
        const uint32_t ra = find(e.keep), rb = find(e.other);
        if (ra != rb) rep[std::max(ra, rb)] = std::min(ra, rb);
    }
    auto isCutCell = [&](const glm::ivec3& c) { return mCells.count(openvdb::Coord(c.x, c.y, c.z)) != 0; };
    for (uint32_t t : mSnapTriangles)
        if (!isCutCell(mUncut.triangleVoxels[t])) uniteZeroLength(&mUncut.indices[3 * size_t(t)]);
    for (size_t i = 0; i < newIndices.size(); i += 3) uniteZeroLength(&newIndices[i]);
    // An edge from a vertex inside a tet face to another of the closed face,
    // used twice each way once the rules above have joined their names, and
    // shorter than kFloatStepsPinch float steps: its ends are one vertex,
    // the kept one's (inside with a lower name, or on an edge of the face:
    // an uncut one stays the group's root, as the lower index)
    // (remesh_detail::joinsPinchInFace; the local check's snapRound).
    for (Along& e : inFace) {
        e.iso = find(e.iso);
        e.other = find(e.other);
    }
    std::sort(inFace.begin(), inFace.end(), byEdge);
    usedTwiceEachWay(inFace, [&](const Along& e) {
        if (e.iso == e.other ||
            !remesh_detail::joinsPinchInFace(*e.isoId, *e.otherId, m.positions[e.iso], m.positions[e.other],
                                             mVolume->origin(), mVolume->spacing()))
            return;
        m.positions[e.other] = m.positions[e.iso];
        const uint32_t ra = find(e.iso), rb = find(e.other);
        if (ra != rb) rep[std::max(ra, rb)] = std::min(ra, rb);
    });
    // Uncut triangles (outside cut cells) that change: those holding a
    // vertex that is not the lowest of its group: the candidates of
    // mSnapTriangles, and the uncut triangles next to the cut cells around
    // a welded iso vertex. Value: the new corners, or none (collapsed).
    std::vector<std::pair<uint32_t, std::array<uint32_t, 3>>> patches;
    if (!rep.empty()) {
        std::vector<uint32_t> candidates;
        for (uint32_t t : mSnapTriangles)
            if (!isCutCell(mUncut.triangleVoxels[t])) candidates.push_back(t);
        for (const auto& [v, id] : welded) {
            if (find(v) == v) continue;
            everyCellRoundGridEdge(*id, [&, v = v](const openvdb::Coord& c) {
                const std::pair<uint32_t, uint32_t> run = uncutRun(uncutAcc, c);
                if (run.second == 0 || mCells.count(c)) return true;
                for (uint32_t t = run.first; t < run.first + run.second; ++t)
                    for (int k = 0; k < 3; ++k)
                        if (mUncut.indices[3 * size_t(t) + size_t(k)] == v) candidates.push_back(t);
                return true;
            });
        }
        std::sort(candidates.begin(), candidates.end());
        candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
        for (uint32_t t : candidates) {
            const uint32_t* tri = &mUncut.indices[3 * size_t(t)];
            const std::array<uint32_t, 3> mapped{find(tri[0]), find(tri[1]), find(tri[2])};
            if (mapped[0] != tri[0] || mapped[1] != tri[1] || mapped[2] != tri[2]) patches.push_back({t, mapped});
        }
    }
    // The uncut triangles outside the cut cells, in their order (copied in
    // runs between the cut cells' triangles and the patched ones).
    const size_t nt = mUncut.triangleCount();
    m.indices.reserve(3 * (nt - cutTriangles) + newIndices.size());
    m.triangleVoxels.reserve(nt - cutTriangles + newVoxels.size());
    size_t from = 0;
    auto copyTo = [&](size_t to) {
        if (to <= from) return;
        m.indices.insert(m.indices.end(), mUncut.indices.begin() + long(3 * from), mUncut.indices.begin() + long(3 * to));
        m.triangleVoxels.insert(m.triangleVoxels.end(), mUncut.triangleVoxels.begin() + long(from),
                                mUncut.triangleVoxels.begin() + long(to));
        if (source)
            for (size_t t = from; t < to; ++t) source->push_back(uint32_t(t));
        from = to;
    };
    // A patched uncut triangle: its new corners, or nothing when it collapsed.
    auto emitPatch = [&](const std::pair<uint32_t, std::array<uint32_t, 3>>& patch) {
        copyTo(patch.first);
        const auto& tri = patch.second;
        if (tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]) {
            m.indices.insert(m.indices.end(), tri.begin(), tri.end());
            m.triangleVoxels.push_back(mUncut.triangleVoxels[patch.first]);
            if (source) source->push_back(patch.first);
        }
        from = size_t(patch.first) + 1;
    };
    size_t p = 0;
    for (const auto& run : cutRuns) {
        for (; p < patches.size() && patches[p].first < run.first; ++p) emitPatch(patches[p]);
        copyTo(run.first);
        from = size_t(run.first) + run.second;
    }
    for (; p < patches.size(); ++p) emitPatch(patches[p]);
    copyTo(nt);
    // Then the cut cells' triangles, cells ascending, less those that snap
    // rounding collapsed, and the cancelling pairs that snap rounding or the
    // float repair's face rule made (markCancellingPairs).
    const size_t firstNew = m.triangleCount();
    std::vector<char> cancelled;
    const bool pairs = !rep.empty() || intoFaceCount != 0;
    if (pairs) {
        std::vector<std::array<uint32_t, 3>> snapped(newIndices.size() / 3), before(snapped.size());
        for (size_t t = 0; t < snapped.size(); ++t) {
            before[t] = {newIndices[3 * t], newIndices[3 * t + 1], newIndices[3 * t + 2]};
            snapped[t] = {find(before[t][0]), find(before[t][1]), find(before[t][2])};
        }
        remesh_detail::markCancellingPairs(snapped, before, intoFace, cancelled);
    }
    for (size_t i = 0, t = 0; i < newIndices.size(); i += 3, ++t) {
        uint32_t a = newIndices[i], b = newIndices[i + 1], c = newIndices[i + 2];
        if (pairs) {
            a = find(a);
            b = find(b);
            c = find(c);
            if (a == b || b == c || a == c || cancelled[t]) continue;
        }
        m.indices.insert(m.indices.end(), {a, b, c});
        m.triangleVoxels.push_back(newVoxels[t]);
        if (source) source->push_back(uint32_t(nt + t));
    }
    {
        // The welded marching-tetrahedra vertices; all of one's triangles are
        // new ones when its grid edge's cells with triangles are all cut.
        auto byVertex = [](const std::pair<uint32_t, const CutVertexId*>& x, const std::pair<uint32_t, const CutVertexId*>& y) {
            return x.first < y.first;
        };
        std::sort(welded.begin(), welded.end(), byVertex);
        std::vector<uint32_t> weldedVertices;
        for (const auto& w : welded)
            if (weldedVertices.empty() || weldedVertices.back() != w.first) weldedVertices.push_back(w.first);
        auto allNew = [&](uint32_t v) {
            const CutVertexId& id =
                *std::lower_bound(welded.begin(), welded.end(), std::make_pair(v, (const CutVertexId*)nullptr), byVertex)->second;
            return everyCellRoundGridEdge(id, [&](const openvdb::Coord& c) {
                return mCells.count(c) != 0 || uncutRun(uncutAcc, c).second == 0;
            });
        };
        splitCrossCellPinches(m, firstNew, uncutVertices, weldedVertices, allNew);
    }
    if (normals) {
        // Only the cut cells' triangles can hold a new vertex.
        for (size_t t = firstNew; t < m.triangleCount(); ++t) {
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

namespace remesh_detail {

void markCancellingPairs(const std::vector<std::array<uint32_t, 3>>& tris,
                         const std::vector<std::array<uint32_t, 3>>& before, const std::vector<char>& intoFace,
                         std::vector<char>& drop)
{
    if (before.size() != tris.size()) throw std::logic_error("markCancellingPairs: one unsnapped triangle per triangle");
    if (!intoFace.empty() && intoFace.size() != tris.size())
        throw std::logic_error("markCancellingPairs: one intoFace flag per triangle");
    auto moved = [&](uint32_t t) { return (!intoFace.empty() && intoFace[t]) || tris[t] != before[t]; };
    auto sameSet = [](std::array<uint32_t, 3> a, std::array<uint32_t, 3> b) {
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        return a == b;
    };
    drop.assign(tris.size(), 0);
    // Each triangle rotated to start at its least vertex: (set, whether its
    // last two corners are in descending order, index).
    struct Entry
    {
        std::array<uint32_t, 3> set;
        bool flipped;
        uint32_t t;
    };
    auto entryOf = [](uint32_t t, std::array<uint32_t, 3> v) {
        while (v[0] > v[1] || v[0] > v[2]) std::rotate(v.begin(), v.begin() + 1, v.end());
        const bool flipped = v[1] > v[2];
        if (flipped) std::swap(v[1], v[2]);
        return Entry{v, flipped, t};
    };
    // A pair has a triangle that snapping or the face rule changed: those,
    // and the unchanged ones on a set that a changed one has (most of a mesh
    // is neither).
    std::vector<Entry> e;
    std::vector<std::array<uint32_t, 3>> changedSets;
    for (uint32_t t = 0; t < uint32_t(tris.size()); ++t)
        if (moved(t)) {
            e.push_back(entryOf(t, tris[t]));
            changedSets.push_back(e.back().set);
        }
    if (e.empty()) return;
    std::sort(changedSets.begin(), changedSets.end());
    for (uint32_t t = 0; t < uint32_t(tris.size()); ++t) {
        if (moved(t)) continue;
        const Entry x = entryOf(t, tris[t]);
        if (std::binary_search(changedSets.begin(), changedSets.end(), x.set)) e.push_back(x);
    }
    std::sort(e.begin(), e.end(), [](const Entry& a, const Entry& b) { return a.set != b.set ? a.set < b.set : a.t < b.t; });
    for (size_t i = 0, j = 0; i < e.size(); i = j) {
        for (j = i; j < e.size() && e[j].set == e[i].set; ++j) {
        }
        if (j - i < 2) continue;
        // In triangle order: each one pairs with the first unpaired one facing the other way.
        for (size_t a = i; a < j; ++a) {
            if (drop[e[a].t]) continue;
            for (size_t b = a + 1; b < j; ++b)
                if (!drop[e[b].t] && e[b].flipped != e[a].flipped &&
                    ((!intoFace.empty() && (intoFace[e[a].t] || intoFace[e[b].t])) ||
                     !sameSet(before[e[a].t], before[e[b].t]))) {
                    drop[e[a].t] = drop[e[b].t] = 1;
                    break;
                }
        }
    }
}

int linkFans(const std::vector<std::pair<uint32_t, uint32_t>>& link, std::vector<int>& fanOf)
{
    const size_t n = link.size();
    if (n < 3) return 0;
    // Every link vertex starts one edge and ends one: the starts are distinct,
    // the ends are distinct, and they are the same set.
    std::vector<std::pair<uint32_t, uint32_t>> starts(n); // (start vertex, edge)
    std::vector<uint32_t> ends(n);
    for (size_t i = 0; i < n; ++i) {
        starts[i] = {link[i].first, uint32_t(i)};
        ends[i] = link[i].second;
    }
    std::sort(starts.begin(), starts.end());
    std::sort(ends.begin(), ends.end());
    for (size_t i = 0; i < n; ++i)
        if (starts[i].first != ends[i] || (i > 0 && ends[i] == ends[i - 1])) return 0;
    // Each edge is followed by the one starting where it ends; walk the cycles.
    auto next = [&](size_t i) {
        const auto it = std::lower_bound(starts.begin(), starts.end(), std::make_pair(link[i].second, uint32_t(0)));
        return size_t(it->second);
    };
    fanOf.assign(n, -1);
    int fans = 0;
    for (size_t i = 0; i < n; ++i) {
        if (fanOf[i] >= 0) continue;
        size_t length = 0;
        for (size_t j = i; fanOf[j] < 0; j = next(j), ++length) fanOf[j] = fans;
        if (length < 3) return 0; // two triangles back to back: no disc
        ++fans;
    }
    return fans;
}

} // namespace remesh_detail

} // namespace mtcut::cutter
