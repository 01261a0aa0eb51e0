#include "cutter/MeshCheck.h"

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/common.hpp>

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>
#include <tuple>

namespace mtcut::cutter {

namespace {

bool validTriangle(const Mesh& mesh, size_t t)
{
    const size_t n = mesh.positions.size();
    return mesh.indices[3 * t] < n && mesh.indices[3 * t + 1] < n && mesh.indices[3 * t + 2] < n;
}

bool finite(const glm::vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

glm::dvec3 pos(const Mesh& mesh, uint32_t v) { return glm::dvec3(mesh.positions[v]); }

/// Keeps, of each kind, the MeshCheck::kSitesPerKind sites of lowest key,
/// ordered by kind, then key.
void trimSites(std::vector<DefectSite>& sites)
{
    std::sort(sites.begin(), sites.end(), [](const DefectSite& x, const DefectSite& y) {
        return std::tie(x.kind, x.key) < std::tie(y.kind, y.key);
    });
    std::vector<DefectSite> kept;
    for (size_t i = 0, run = 0; i < sites.size(); ++i) {
        run = i > 0 && sites[i].kind == sites[i - 1].kind ? run + 1 : 0;
        if (run < MeshCheck::kSitesPerKind) kept.push_back(sites[i]);
    }
    sites = std::move(kept);
}

/// A site at triangle t (any of its valid indices' positions when
/// `position` is null) with the voxel of t where the mesh has them.
DefectSite siteAt(const Mesh& mesh, DefectSite::Kind kind, uint64_t key, std::string what, size_t t,
                  const glm::dvec3* position)
{
    DefectSite site;
    site.kind = kind;
    site.key = key;
    site.what = std::move(what);
    if (position) {
        site.hasPosition = true;
        site.position = *position;
    }
    if (mesh.triangleVoxels.size() * 3 == mesh.indices.size() && t < mesh.triangleVoxels.size()) {
        site.hasVoxel = true;
        site.voxel = mesh.triangleVoxels[t];
    }
    return site;
}

glm::dvec3 centroid(const Mesh& mesh, size_t t)
{
    return (glm::dvec3(mesh.positions[mesh.indices[3 * t]]) + glm::dvec3(mesh.positions[mesh.indices[3 * t + 1]]) +
            glm::dvec3(mesh.positions[mesh.indices[3 * t + 2]])) /
           3.0;
}

/// Union-find with path halving.
struct DisjointSets
{
    std::vector<uint32_t> parent;
    explicit DisjointSets(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
    uint32_t find(uint32_t a)
    {
        while (parent[a] != a) a = parent[a] = parent[parent[a]];
        return a;
    }
    void unite(uint32_t a, uint32_t b)
    {
        a = find(a);
        b = find(b);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
};

/// Compressed rows: for each key in [0, n), the values pushed for it.
struct Csr
{
    std::vector<uint32_t> start;  // n + 1
    std::vector<uint64_t> values; // packed payloads
};

/// A shell that can be a cavity (facing inward, or flat) and one that can be
/// an outer shell (facing outward, not flat): Shell::flat.
bool inward(const Shell& s) { return s.volume < 0.0 || s.flat; }
bool outward(const Shell& s) { return s.volume > 0.0 && !s.flat; }

/// Whether a shell whose other shells' winding numbers at a point it
/// encloses add up to `winding` is nested the way it faces: a cavity inside
/// one solid, an outer shell in none.
bool nestedRight(const Shell& s, int winding) { return (inward(s) && winding == 1) || (outward(s) && winding == 0); }

/// For each shell, the winding number of each other shell at a point of
/// the shell's material (a cavity's: the solid round it): the middle of the chord through it from
/// the centroid of one of up to 16 of its triangles, the deepest of those
/// whose ray is clear of the other shells' surfaces, edges and vertices
/// (only the shells with a non-zero number, ascending): rays along the generic direction (a, b, 1), i.e.
/// along +z after the shear x' = x - a z, y' = y - b z (determinant 1, so
/// orientation is kept); a crossing counts +1 where the ray leaves a solid
/// (projected triangle counter-clockwise), -1 where it enters.
std::vector<std::vector<std::pair<uint32_t, int>>> windingByOtherShell(const Mesh& mesh, const std::vector<Shell>& shells)
{
    constexpr double a = 0.013703599, b = 0.0071828183;
    auto shear = [&](uint32_t v) {
        const glm::dvec3 p(mesh.positions[v]);
        return glm::dvec3(p.x - a * p.z, p.y - b * p.z, p.z);
    };
    std::vector<uint32_t> triangles;
    std::vector<uint32_t> shellOf;
    for (size_t s = 0; s < shells.size(); ++s) {
        for (uint32_t t : shells[s].triangles) {
            triangles.push_back(t);
            shellOf.push_back(uint32_t(s));
        }
    }
    glm::dvec2 lo(1e300), hi(-1e300);
    for (uint32_t t : triangles)
        for (int k = 0; k < 3; ++k) {
            const glm::dvec3 p = shear(mesh.indices[3 * size_t(t) + k]);
            lo = glm::min(lo, glm::dvec2(p));
            hi = glm::max(hi, glm::dvec2(p));
        }
    // Twice the signed area of the projection of (u, v, q): positive when counter-clockwise.
    auto cross2 = [](const glm::dvec3& u, const glm::dvec3& v, const glm::dvec3& q) {
        return (v.x - u.x) * (q.y - u.y) - (v.y - u.y) * (q.x - u.x);
    };
    const int n = std::max(1, std::min(4096, int(std::sqrt(double(triangles.size()) / 4.0))));
    const glm::dvec2 size = glm::max(hi - lo, glm::dvec2(1e-12));
    auto cellOf = [&](const glm::dvec2& p) {
        const glm::dvec2 c = (p - lo) / size * double(n);
        return glm::ivec2(std::clamp(int(c.x), 0, n - 1), std::clamp(int(c.y), 0, n - 1));
    };
    std::vector<uint32_t> start(size_t(n) * n + 1, 0);
    auto forCells = [&](size_t i, auto&& f) {
        const uint32_t t = triangles[i];
        glm::dvec2 tlo(1e300), thi(-1e300);
        for (int k = 0; k < 3; ++k) {
            const glm::dvec3 p = shear(mesh.indices[3 * size_t(t) + k]);
            tlo = glm::min(tlo, glm::dvec2(p));
            thi = glm::max(thi, glm::dvec2(p));
        }
        const glm::ivec2 c0 = cellOf(tlo), c1 = cellOf(thi);
        for (int x = c0.x; x <= c1.x; ++x)
            for (int y = c0.y; y <= c1.y; ++y) f(size_t(y) * n + x);
    };
    for (size_t i = 0; i < triangles.size(); ++i) forCells(i, [&](size_t c) { ++start[c + 1]; });
    for (size_t c = 0; c + 1 < start.size(); ++c) start[c + 1] += start[c];
    std::vector<uint32_t> bucket(start.back());
    {
        std::vector<uint32_t> fill(start.begin(), start.end() - 1);
        for (size_t i = 0; i < triangles.size(); ++i) forCells(i, [&](size_t c) { bucket[fill[c]++] = uint32_t(i); });
    }
    std::vector<std::vector<std::pair<uint32_t, int>>> winding(shells.size());
    tbb::parallel_for(size_t(0), shells.size(), [&](size_t s) {
        std::vector<std::pair<uint32_t, int>> crossings, first, touching, best;
        std::vector<std::pair<uint32_t, int>> through; // crossed from behind t0, through its centroid
        bool touchingKnown = false;
        double bestDepth = -1.0; // of `best`, a clear ray's; -1: none yet
        std::vector<std::pair<uint32_t, int>> right; // the first clear ray's that finds the shell nested right
        bool rightKnown = false;
        // The ray through the centroid of triangle t0 of the shell, counted
        // from the middle of its chord through the shell's material (behind
        // t0: an outer shell's solid, the solid round a cavity) up to the
        // shell's next triangle, if any: the point on that line farthest
        // from the shell's own surface. A shell's triangles may lie a float
        // step or two inside another's where the two touch: at kerf 0 the
        // two sides of a cut lie on each other, and where passes of the
        // blade cross, each side's vertices rounded to float make them
        // overlap (the tooth's pivoting fan: pieces 10-100 um across, whose
        // every point just behind some triangles is inside the main body,
        // by 1-10 um; the middle of every chord longer than 3.7 um is not).
        // A ray is ambiguous when it starts on another shell's triangle or
        // passes through another shell's edge or vertex (the count
        // would depend on rounding); the centroids of up to kTries of the
        // shell's triangles are tried, and of the clear rays the one whose
        // start is deepest is taken (the first kDeep float steps deep ends
        // the search). Without a chord (t0 upright in the projection, a flat
        // shell, no triangle of its own beyond) the ray starts at t0's
        // centroid. At kerf 0 a piece cut out between two passes of the
        // blade can have every cap triangle on another shell's (2 mm head,
        // random strokes seed 18002 with sharp turns: 158 triangles, 1-4 um
        // thick); when no ray is clear, the first that starts inside other
        // shells' triangles and is otherwise clear is taken from just behind
        // t0, in the shell's material (so in a valid mesh no other shell is
        // there): it crosses a triangle through the centroid when it leaves
        // through t0 (t0 counter-clockwise in the projection). Else the first
        // ray. A shell thinner than rounding everywhere (below) has no point
        // far enough from its surface to tell: the first ray that finds it
        // nested the way it faces is taken, if any (the fan's cavities of
        // 1e-13 mm^3 among a dozen such pieces).
        constexpr size_t kTries = 16;
        constexpr double kDeep = 16.0, kShallow = 2.0;
        auto isRight = [&](const std::vector<std::pair<uint32_t, int>>& list) {
            int sum = 0;
            for (const auto& x : list) sum += x.second;
            return nestedRight(shells[s], sum);
        };
        const std::vector<uint32_t>& own = shells[s].triangles;
        const size_t stride = std::max<size_t>(1, own.size() / kTries);
        for (size_t attempt = 0; attempt < kTries && attempt * stride < own.size(); ++attempt) {
            const uint32_t t0 = own[attempt * stride];
            const double ownArea = cross2(shear(mesh.indices[3 * size_t(t0)]), shear(mesh.indices[3 * size_t(t0) + 1]),
                                          shear(mesh.indices[3 * size_t(t0) + 2]));
            glm::dvec3 p(0.0);
            for (int k = 0; k < 3; ++k) p += glm::dvec3(mesh.positions[mesh.indices[3 * size_t(t0) + k]]) / 3.0;
            const double scale = 1.0 + std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
            const double tol = 1e-9 * scale;
            const double floatStep = scale * std::ldexp(1.0, -23);
            p = glm::dvec3(p.x - a * p.z, p.y - b * p.z, p.z);
            const glm::ivec2 c = cellOf(glm::dvec2(p));
            const size_t cell = size_t(c.y) * n + c.x;
            // The chord: the shell's nearest other triangle behind t0 (below
            // it when t0 faces up, counter-clockwise in the projection).
            double depth = 0.0, pz = p.z;
            if (ownArea != 0.0 && !shells[s].flat) {
                const bool below = ownArea > 0.0;
                double chord = std::numeric_limits<double>::infinity();
                for (uint32_t k = start[cell]; k < start[cell + 1]; ++k) {
                    const uint32_t i = bucket[k];
                    const uint32_t t = triangles[i];
                    if (shellOf[i] != s || t == t0) continue;
                    const glm::dvec3 q0 = shear(mesh.indices[3 * size_t(t)]), q1 = shear(mesh.indices[3 * size_t(t) + 1]),
                                     q2 = shear(mesh.indices[3 * size_t(t) + 2]);
                    const double area = cross2(q0, q1, q2);
                    if (area == 0.0) continue;
                    const double w0 = cross2(q1, q2, p), w1 = cross2(q2, q0, p), w2 = cross2(q0, q1, p);
                    if (area > 0 ? (w0 < 0 || w1 < 0 || w2 < 0) : (w0 > 0 || w1 > 0 || w2 > 0)) continue;
                    const double d = below ? p.z - (w0 * q0.z + w1 * q1.z + w2 * q2.z) / area
                                           : (w0 * q0.z + w1 * q1.z + w2 * q2.z) / area - p.z;
                    if (d > 0.0) chord = std::min(chord, d);
                }
                if (chord < std::numeric_limits<double>::infinity()) {
                    depth = chord / 2.0;
                    pz = below ? p.z - depth : p.z + depth;
                }
            }
            bool onOther = false, ambiguous = false; // starts inside another shell's triangle; any other ambiguity
            crossings.clear();
            through.clear();
            for (uint32_t k = start[cell]; k < start[cell + 1]; ++k) {
                const uint32_t i = bucket[k];
                if (shellOf[i] == s) continue;
                const uint32_t t = triangles[i];
                const glm::dvec3 q0 = shear(mesh.indices[3 * size_t(t)]), q1 = shear(mesh.indices[3 * size_t(t) + 1]),
                                 q2 = shear(mesh.indices[3 * size_t(t) + 2]);
                const double area = cross2(q0, q1, q2);
                if (area == 0.0) continue;
                const double w0 = cross2(q1, q2, p), w1 = cross2(q2, q0, p), w2 = cross2(q0, q1, p);
                const bool inside = area > 0 ? (w0 > 0 && w1 > 0 && w2 > 0) : (w0 < 0 && w1 < 0 && w2 < 0);
                const bool closed = area > 0 ? (w0 >= 0 && w1 >= 0 && w2 >= 0) : (w0 <= 0 && w1 <= 0 && w2 <= 0);
                if (!closed) continue;
                const double z = (w0 * q0.z + w1 * q1.z + w2 * q2.z) / area;
                if (std::abs(z - pz) <= tol) { // through the start
                    if (depth == 0.0 && inside && ownArea != 0.0) {
                        onOther = true;
                        if (ownArea > 0.0) through.push_back({shellOf[i], area > 0 ? 1 : -1});
                    } else {
                        ambiguous = true;
                    }
                    continue;
                }
                if (!inside && z > pz) ambiguous = true;
                if (inside && z > pz) crossings.push_back({shellOf[i], area > 0 ? 1 : -1});
            }
            if (attempt == 0) first = crossings;
            if (!onOther && !ambiguous) { // a clear ray
                if (depth > bestDepth) {
                    best = crossings;
                    bestDepth = depth;
                }
                if (!rightKnown && isRight(crossings)) {
                    right = crossings;
                    rightKnown = true;
                }
                if (depth >= kDeep * floatStep) break;
            } else if (!ambiguous && !touchingKnown) {
                touching = crossings;
                touching.insert(touching.end(), through.begin(), through.end());
                touchingKnown = true;
            }
        }
        // A shell thinner than rounding: 3 |volume| / area (a slab's 1.5 x
        // thickness) under kShallow float steps of its coordinates.
        const Shell& sh = shells[s];
        const double reach = std::max({std::abs(sh.boundsMin.x), std::abs(sh.boundsMin.y), std::abs(sh.boundsMin.z),
                                       std::abs(sh.boundsMax.x), std::abs(sh.boundsMax.y), std::abs(sh.boundsMax.z)});
        const bool thin = 3.0 * std::abs(sh.volume) < kShallow * (1.0 + reach) * std::ldexp(1.0, -23) * sh.area;
        if (thin && rightKnown) crossings = right;
        else if (thin && touchingKnown && isRight(touching)) crossings = touching;
        else if (bestDepth >= 0.0) crossings = best;
        else crossings = touchingKnown ? touching : first;
        std::sort(crossings.begin(), crossings.end());
        for (const auto& [other, sign] : crossings) {
            if (winding[s].empty() || winding[s].back().first != other) winding[s].push_back({other, 0});
            winding[s].back().second += sign;
        }
        winding[s].erase(std::remove_if(winding[s].begin(), winding[s].end(), [](const auto& w) { return w.second == 0; }),
                         winding[s].end());
    });
    return winding;
}

} // namespace

size_t MeshCheck::defects() const
{
    return badIndexTriangles + boundaryEdges + nonManifoldEdges + inconsistentEdges + nonManifoldVertices +
           degenerateTriangles + nonFiniteTriangles + negativeVolumeShells + malformedArrays;
}

const char* DefectSite::name(Kind kind)
{
    switch (kind) {
    case Kind::BadIndexTriangle: return "bad_index_triangle";
    case Kind::NonFiniteTriangle: return "non_finite_triangle";
    case Kind::DegenerateTriangle: return "degenerate_triangle";
    case Kind::BoundaryEdge: return "boundary_edge";
    case Kind::NonManifoldEdge: return "non_manifold_edge";
    case Kind::InconsistentEdge: return "inconsistent_edge";
    case Kind::NonManifoldVertex: return "non_manifold_vertex";
    case Kind::WrongWayShell: return "wrong_way_shell";
    }
    return "unknown";
}

const char* DefectSite::label(Kind kind)
{
    switch (kind) {
    case Kind::BadIndexTriangle: return "bad-index triangle";
    case Kind::NonFiniteTriangle: return "non-finite triangle";
    case Kind::DegenerateTriangle: return "degenerate triangle";
    case Kind::BoundaryEdge: return "boundary edge";
    case Kind::NonManifoldEdge: return "non-manifold edge";
    case Kind::InconsistentEdge: return "inconsistent edge";
    case Kind::NonManifoldVertex: return "non-manifold vertex";
    case Kind::WrongWayShell: return "wrong-way shell";
    }
    return "unknown";
}

std::string DefectSite::describe() const
{
    std::ostringstream os;
    os << label(kind) << " " << what;
    os.setf(std::ios::fixed);
    os.precision(4);
    if (hasPosition) os << ", at (" << position.x << ", " << position.y << ", " << position.z << ") mm";
    if (hasVoxel) os << ", voxel (" << voxel.x << ", " << voxel.y << ", " << voxel.z << ")";
    return os.str();
}

std::string MeshCheck::report() const
{
    std::ostringstream os;
    os << "triangles:              " << triangles << "\n"
       << "vertices:               " << vertices << " (" << unusedVertices << " unused)\n"
       << "shells:                 " << shells << "\n"
       << "boundary edges:         " << boundaryEdges << "\n"
       << "non-manifold edges:     " << nonManifoldEdges << "\n"
       << "inconsistent edges:     " << inconsistentEdges << "\n"
       << "non-manifold vertices:  " << nonManifoldVertices << "\n"
       << "degenerate triangles:   " << degenerateTriangles << "\n"
       << "non-finite triangles:   " << nonFiniteTriangles << "\n"
       << "negative-volume shells: " << negativeVolumeShells << " (wrong way for their nesting; " << cavities
       << " cavities face inward correctly)\n"
       << "bad-index triangles:    " << badIndexTriangles << "\n"
       << "malformed arrays:       " << malformedArrays << "\n"
       << "defects:                " << defects() << (ok() ? " (valid)" : " (INVALID)") << "\n";
    if (!sites.empty()) {
        os << "where (the first " << kSitesPerKind << " of each kind):\n";
        for (const DefectSite& site : sites) os << "  " << site.describe() << "\n";
    }
    return os.str();
}


MeshCheck checkMesh(const Mesh& mesh)
{
    MeshCheck r;
    const size_t nV = mesh.positions.size();
    const size_t nT = mesh.indices.size() / 3;
    r.triangles = nT;
    r.vertices = nV;
    r.malformedArrays = (mesh.indices.size() % 3 != 0) + (!mesh.normals.empty() && mesh.normals.size() != nV) +
                        (!mesh.triangleVoxels.empty() && mesh.triangleVoxels.size() != nT);

    // Per triangle: bad index, non-finite, degenerate. Edges are taken from
    // triangles with three distinct valid indices.
    std::vector<uint8_t> usable(nT, 0);
    struct Counts
    {
        size_t bad = 0, nonFinite = 0, degenerate = 0;
        std::vector<DefectSite> sites;
    };
    using Kind = DefectSite::Kind;
    tbb::combinable<Counts> counts;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nT, 4096), [&](const tbb::blocked_range<size_t>& range) {
        Counts& c = counts.local();
        for (size_t t = range.begin(); t != range.end(); ++t) {
            if (c.sites.size() >= 8 * MeshCheck::kSitesPerKind) trimSites(c.sites);
            const uint32_t a = mesh.indices[3 * t], b = mesh.indices[3 * t + 1], d = mesh.indices[3 * t + 2];
            auto corners = [&] { // (made only for a defect: this loop runs over every triangle)
                return std::to_string(t) + " (" + std::to_string(a) + ", " + std::to_string(b) + ", " +
                       std::to_string(d) + ")";
            };
            if (!validTriangle(mesh, t)) {
                ++c.bad;
                c.sites.push_back(siteAt(mesh, Kind::BadIndexTriangle, t,
                                         corners() + ": an index past the " + std::to_string(nV) + " vertices", t, nullptr));
                continue;
            }
            if (!finite(mesh.positions[a]) || !finite(mesh.positions[b]) || !finite(mesh.positions[d])) {
                ++c.nonFinite;
                c.sites.push_back(siteAt(mesh, Kind::NonFiniteTriangle, t, corners(), t, nullptr));
                continue;
            }
            if (a == b || b == d || a == d) {
                ++c.degenerate;
                const glm::dvec3 middle = centroid(mesh, t);
                c.sites.push_back(siteAt(mesh, Kind::DegenerateTriangle, t, corners() + ": a repeated vertex", t, &middle));
                continue;
            }
            const glm::dvec3 n = glm::cross(pos(mesh, b) - pos(mesh, a), pos(mesh, d) - pos(mesh, a));
            if (n.x == 0.0 && n.y == 0.0 && n.z == 0.0) {
                ++c.degenerate;
                const glm::dvec3 middle = centroid(mesh, t);
                c.sites.push_back(siteAt(mesh, Kind::DegenerateTriangle, t, corners() + ": no area", t, &middle));
            }
            usable[t] = 1;
        }
    });
    counts.combine_each([&](const Counts& c) {
        r.badIndexTriangles += c.bad;
        r.nonFiniteTriangles += c.nonFinite;
        r.degenerateTriangles += c.degenerate;
        r.sites.insert(r.sites.end(), c.sites.begin(), c.sites.end());
    });

    // Edges, bucketed by their lower vertex: payload = hi << 1 | (runs lo->hi).
    Csr edges;
    edges.start.assign(nV + 1, 0);
    std::vector<uint32_t> useCount(nV, 0);
    for (size_t t = 0; t < nT; ++t) {
        if (!usable[t]) continue;
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = mesh.indices[3 * t + k], b = mesh.indices[3 * t + (k + 1) % 3];
            ++edges.start[std::min(a, b) + 1];
            ++useCount[a];
        }
    }
    for (size_t v = 0; v < nV; ++v) edges.start[v + 1] += edges.start[v];
    edges.values.resize(edges.start[nV]);
    {
        std::vector<uint32_t> fill(edges.start.begin(), edges.start.end() - 1);
        for (size_t t = 0; t < nT; ++t) {
            if (!usable[t]) continue;
            for (int k = 0; k < 3; ++k) {
                const uint32_t a = mesh.indices[3 * t + k], b = mesh.indices[3 * t + (k + 1) % 3];
                edges.values[fill[std::min(a, b)]++] = uint64_t(std::max(a, b)) << 1 | uint64_t(a < b);
            }
        }
    }
    // Triangles around each vertex: payload = triangle index.
    Csr fans;
    fans.start.assign(nV + 1, 0);
    for (size_t v = 0; v < nV; ++v) fans.start[v + 1] = fans.start[v] + useCount[v];
    fans.values.resize(fans.start[nV]);
    {
        std::vector<uint32_t> fill(fans.start.begin(), fans.start.end() - 1);
        for (size_t t = 0; t < nT; ++t) {
            if (!usable[t]) continue;
            for (int k = 0; k < 3; ++k) fans.values[fill[mesh.indices[3 * t + k]]++] = t;
        }
    }

    struct EdgeCounts
    {
        size_t boundary = 0, nonManifold = 0, inconsistent = 0, nonManifoldVertices = 0, unused = 0;
        std::vector<DefectSite> sites;
    };
    // A site on edge v-w (v < w): its middle, and a triangle of v's fan that has w.
    auto edgeSite = [&](Kind kind, uint32_t v, uint32_t w, std::string what) {
        size_t t = 0;
        for (uint32_t f = fans.start[v]; f < fans.start[v + 1]; ++f) {
            const size_t u = size_t(fans.values[f]);
            if (mesh.indices[3 * u] == w || mesh.indices[3 * u + 1] == w || mesh.indices[3 * u + 2] == w) {
                t = u;
                break;
            }
        }
        const glm::dvec3 middle = (pos(mesh, v) + pos(mesh, w)) / 2.0;
        return siteAt(mesh, kind, uint64_t(v) << 32 | w, std::to_string(v) + "-" + std::to_string(w) + what, t, &middle);
    };
    tbb::combinable<EdgeCounts> edgeCounts;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nV, 1024), [&](const tbb::blocked_range<size_t>& range) {
        EdgeCounts& c = edgeCounts.local();
        std::vector<std::pair<uint32_t, uint32_t>> link; // (other vertex, fan position)
        std::vector<uint32_t> parent;
        for (size_t v = range.begin(); v != range.end(); ++v) {
            uint64_t* e0 = edges.values.data() + edges.start[v];
            uint64_t* e1 = edges.values.data() + edges.start[v + 1];
            std::sort(e0, e1);
            for (uint64_t* e = e0; e != e1;) {
                uint64_t* g = e;
                size_t forward = 0;
                while (g != e1 && (*g >> 1) == (*e >> 1)) forward += *g++ & 1;
                const size_t n = size_t(g - e);
                const uint32_t w = uint32_t(*e >> 1);
                if (c.sites.size() >= 8 * MeshCheck::kSitesPerKind) trimSites(c.sites);
                if (n == 1) {
                    ++c.boundary;
                    c.sites.push_back(edgeSite(Kind::BoundaryEdge, uint32_t(v), w, ", in 1 triangle"));
                } else if (n > 2) {
                    ++c.nonManifold;
                    c.sites.push_back(
                        edgeSite(Kind::NonManifoldEdge, uint32_t(v), w, ", in " + std::to_string(n) + " triangles"));
                } else if (forward != 1) {
                    ++c.inconsistent;
                    c.sites.push_back(
                        edgeSite(Kind::InconsistentEdge, uint32_t(v), w, ": both its triangles run it the same way"));
                }
                e = g;
            }
            // One fan: the triangles around v, linked through shared edges, must
            // form a single component.
            const uint32_t f0 = fans.start[v], f1 = fans.start[v + 1];
            const uint32_t k = f1 - f0;
            if (k == 0) {
                ++c.unused;
                continue;
            }
            link.clear();
            for (uint32_t i = 0; i < k; ++i) {
                const uint32_t t = uint32_t(fans.values[f0 + i]);
                for (int j = 0; j < 3; ++j) {
                    const uint32_t w = mesh.indices[3 * size_t(t) + j];
                    if (w != v) link.emplace_back(w, i);
                }
            }
            std::sort(link.begin(), link.end());
            parent.resize(k);
            std::iota(parent.begin(), parent.end(), 0u);
            auto find = [&](uint32_t a) {
                while (parent[a] != a) a = parent[a] = parent[parent[a]];
                return a;
            };
            uint32_t components = k;
            for (size_t i = 1; i < link.size(); ++i) {
                if (link[i].first != link[i - 1].first) continue;
                const uint32_t a = find(link[i].second), b = find(link[i - 1].second);
                if (a != b) {
                    parent[std::max(a, b)] = std::min(a, b);
                    --components;
                }
            }
            if (components > 1) {
                ++c.nonManifoldVertices;
                const glm::dvec3 p = pos(mesh, uint32_t(v));
                c.sites.push_back(siteAt(mesh, Kind::NonManifoldVertex, v,
                                         std::to_string(v) + ": its " + std::to_string(k) + " triangles make " +
                                             std::to_string(components) + " fans",
                                         size_t(fans.values[f0]), &p));
            }
        }
    });
    edgeCounts.combine_each([&](const EdgeCounts& c) {
        r.boundaryEdges += c.boundary;
        r.nonManifoldEdges += c.nonManifold;
        r.inconsistentEdges += c.inconsistent;
        r.nonManifoldVertices += c.nonManifoldVertices;
        r.unusedVertices += c.unused;
        r.sites.insert(r.sites.end(), c.sites.begin(), c.sites.end());
    });

    const std::vector<Shell> shells = findShells(mesh);
    r.shells = shells.size();
    if (!shells.empty()) {
        const auto byShell = windingByOtherShell(mesh, shells);
        for (size_t s = 0; s < shells.size(); ++s) {
            int winding = 0;
            for (const auto& w : byShell[s]) winding += w.second;
            const Shell& shell = shells[s];
            r.cavities += inward(shell) && winding == 1;
            if (nestedRight(shell, winding)) continue;
            ++r.negativeVolumeShells;
            if (r.negativeVolumeShells > MeshCheck::kSitesPerKind) continue;
            std::ostringstream what;
            what << s << ": " << shell.triangles.size() << " triangles, volume " << shell.volume << " mm^3"
                 << (shell.flat ? " (flat)" : "") << ", ";
            if (inward(shell))
                what << "faces inward (a cavity) but the other shells' winding number there is " << winding
                     << ", not 1";
            else if (outward(shell))
                what << "faces outward but lies inside other solids (their winding number there is " << winding
                     << ", not 0)";
            else
                what << "encloses nothing";
            const size_t t = shell.triangles.front();
            const glm::dvec3 p = centroid(mesh, t);
            r.sites.push_back(siteAt(mesh, Kind::WrongWayShell, s, what.str(), t, &p));
        }
    }
    trimSites(r.sites);
    return r;
}

std::vector<int> enclosingShells(const Mesh& mesh, const std::vector<Shell>& shells)
{
    std::vector<int> out(shells.size(), -1);
    if (std::none_of(shells.begin(), shells.end(), inward)) return out;
    const auto byShell = windingByOtherShell(mesh, shells);
    for (size_t s = 0; s < shells.size(); ++s) {
        if (!inward(shells[s])) continue;
        int winding = 0;
        for (const auto& w : byShell[s]) winding += w.second;
        if (winding != 1) continue; // not a cavity: wrong way for its nesting
        for (const auto& [other, w] : byShell[s])
            if (w == 1 && outward(shells[other]) &&
                (out[s] < 0 || shells[other].volume < shells[size_t(out[s])].volume))
                out[s] = int(other);
    }
    return out;
}

std::vector<Shell> findShells(const Mesh& mesh)
{
    const size_t nT = mesh.indices.size() / 3;
    DisjointSets sets(mesh.positions.size());
    for (size_t t = 0; t < nT; ++t) {
        if (!validTriangle(mesh, t)) continue;
        sets.unite(mesh.indices[3 * t], mesh.indices[3 * t + 1]);
        sets.unite(mesh.indices[3 * t], mesh.indices[3 * t + 2]);
    }
    std::vector<Shell> shells;
    std::vector<uint32_t> shellOfRoot(mesh.positions.size(), UINT32_MAX);
    std::vector<glm::dvec3> reference;
    std::vector<double> magnitude; // per shell: the sum of its volume terms' magnitude bounds
    for (size_t t = 0; t < nT; ++t) {
        if (!validTriangle(mesh, t)) continue;
        const uint32_t root = sets.find(mesh.indices[3 * t]);
        uint32_t& s = shellOfRoot[root];
        if (s == UINT32_MAX) {
            s = uint32_t(shells.size());
            shells.emplace_back();
            const glm::dvec3 p = pos(mesh, mesh.indices[3 * t]);
            reference.push_back(p);
            magnitude.push_back(0.0);
            shells.back().boundsMin = shells.back().boundsMax = p;
        }
        Shell& shell = shells[s];
        shell.triangles.push_back(uint32_t(t));
        // Relative to a point of the shell, so far-away shells keep their precision.
        const glm::dvec3 o = reference[s];
        const glm::dvec3 a = pos(mesh, mesh.indices[3 * t]) - o, b = pos(mesh, mesh.indices[3 * t + 1]) - o,
                         c = pos(mesh, mesh.indices[3 * t + 2]) - o;
        shell.volume += glm::dot(a, glm::cross(b, c)) / 6.0;
        magnitude[s] += glm::length(a) * glm::length(b) * glm::length(c) / 6.0;
        shell.area += 0.5 * glm::length(glm::cross(b - a, c - a));
        for (const glm::dvec3& p : {a, b, c}) {
            shell.boundsMin = glm::min(shell.boundsMin, p + o);
            shell.boundsMax = glm::max(shell.boundsMax, p + o);
        }
    }
    std::vector<uint8_t> seen(mesh.positions.size(), 0);
    for (size_t s = 0; s < shells.size(); ++s) shells[s].flat = std::abs(shells[s].volume) <= 1e-12 * magnitude[s];
    for (Shell& shell : shells) {
        for (uint32_t t : shell.triangles) {
            for (int k = 0; k < 3; ++k) {
                uint8_t& s = seen[mesh.indices[3 * size_t(t) + k]];
                shell.vertexCount += !s;
                s = 1;
            }
        }
    }
    return shells;
}

double meshVolume(const Mesh& mesh)
{
    double v = 0.0;
    for (const Shell& s : findShells(mesh)) v += s.volume;
    return v;
}

double meshArea(const Mesh& mesh)
{
    double a = 0.0;
    for (const Shell& s : findShells(mesh)) a += s.area;
    return a;
}

Mesh subMesh(const Mesh& mesh, const std::vector<uint32_t>& triangles)
{
    Mesh out;
    std::vector<uint32_t> remap(mesh.positions.size(), UINT32_MAX);
    const bool normals = mesh.normals.size() == mesh.positions.size() && !mesh.normals.empty();
    const bool voxels = mesh.triangleVoxels.size() == mesh.triangleCount();
    out.indices.reserve(triangles.size() * 3);
    for (uint32_t t : triangles) {
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = mesh.indices[3 * size_t(t) + k];
            if (remap[v] == UINT32_MAX) {
                remap[v] = uint32_t(out.positions.size());
                out.positions.push_back(mesh.positions[v]);
                if (normals) out.normals.push_back(mesh.normals[v]);
            }
            out.indices.push_back(remap[v]);
        }
        if (voxels) out.triangleVoxels.push_back(mesh.triangleVoxels[t]);
    }
    return out;
}

std::vector<Mesh> splitShells(const Mesh& mesh)
{
    std::vector<Mesh> out;
    for (const Shell& s : findShells(mesh)) out.push_back(subMesh(mesh, s.triangles));
    return out;
}

} // namespace mtcut::cutter
