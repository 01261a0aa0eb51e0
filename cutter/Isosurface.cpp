#include "cutter/Isosurface.h"

#include "vdb/Error.h"

#include <openvdb/math/Maps.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <vector>

namespace mtcut::cutter {

namespace {

using openvdb::Coord;
using LeafT = openvdb::FloatTree::LeafNodeType;

// ------------------------------------------------------------------ tables --

int popcount3(int c) { return (c & 1) + ((c >> 1) & 1) + ((c >> 2) & 1); }

/// Corner c of a cell is even (belongs to the central tet) when its global
/// parity, cell parity + popcount(c), is even.
bool evenCorner(int parity, int c) { return ((parity + popcount3(c)) & 1) == 0; }

int orientation(const std::array<uint8_t, 4>& t)
{
    auto p = [](int c) { return openvdb::Vec3i(c & 1, (c >> 1) & 1, (c >> 2) & 1); };
    const openvdb::Vec3i a = p(t[1]) - p(t[0]), b = p(t[2]) - p(t[0]), c = p(t[3]) - p(t[0]);
    return a.dot(b.cross(c));
}

/// Even permutation of (0,1,2,3) that starts with `first` (1 or 2 entries).
std::array<int, 4> evenPermutationStartingWith(std::initializer_list<int> first)
{
    std::array<int, 4> p{};
    int n = 0;
    for (int f : first) p[n++] = f;
    for (int v = 0; v < 4; ++v) {
        if (std::find(p.begin(), p.begin() + n, v) == p.begin() + n) p[n++] = v;
    }
    int inversions = 0;
    for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) inversions += p[a] > p[b];
    if (inversions & 1) std::swap(p[2], p[3]);
    return p;
}

struct Tables
{
    std::array<std::array<std::array<uint8_t, 4>, kTetsPerCell>, 2> tets;
    std::array<std::array<CellEdge, kCellEdgeCount>, 2> edges;
    std::array<std::array<CellCase, 256>, 2> cases;

    Tables()
    {
        for (int parity = 0; parity < 2; ++parity) {
            // Tets: the four corner tets (apex = an odd corner, ascending), then the central one.
            int t = 0;
            std::array<uint8_t, 4> central{};
            int nc = 0;
            for (int c = 0; c < 8; ++c) {
                if (evenCorner(parity, c)) {
                    central[nc++] = uint8_t(c);
                } else {
                    tets[parity][t++] = {uint8_t(c), uint8_t(c ^ 1), uint8_t(c ^ 2), uint8_t(c ^ 4)};
                }
            }
            tets[parity][4] = central;
            for (auto& tet : tets[parity]) {
                if (orientation(tet) < 0) std::swap(tet[2], tet[3]);
            }
            // Edges: 12 axis edges, then the 6 face diagonals between even corners.
            int e = 0;
            int edgeId[8][8];
            for (auto& row : edgeId) std::fill(std::begin(row), std::end(row), -1);
            for (int c = 0; c < 8; ++c) {
                for (int d : {1, 2, 4}) {
                    if (!(c & d)) {
                        edgeId[c][c | d] = edgeId[c | d][c] = e;
                        edges[parity][e++] = {uint8_t(c), uint8_t(c | d)};
                    }
                }
            }
            for (int a = 0; a < 8; ++a) {
                for (int b = a + 1; b < 8; ++b) {
                    if (popcount3(a ^ b) == 2 && evenCorner(parity, a) && evenCorner(parity, b)) {
                        edgeId[a][b] = edgeId[b][a] = e;
                        edges[parity][e++] = {uint8_t(a), uint8_t(b)};
                    }
                }
            }
            // Cases: the union of the tets' triangles.
            for (int mask = 0; mask < 256; ++mask) {
                CellCase& cc = cases[parity][mask];
                auto tri = [&](int a0, int a1, int b0, int b1, int c0, int c1) {
                    uint8_t* out = &cc.edges[3 * cc.triangleCount++];
                    out[0] = uint8_t(edgeId[a0][a1]);
                    out[1] = uint8_t(edgeId[b0][b1]);
                    out[2] = uint8_t(edgeId[c0][c1]);
                };
                for (const auto& tet : tets[parity]) {
                    int inside[4], outside[4], ni = 0, no = 0;
                    for (int v = 0; v < 4; ++v) {
                        if (mask >> tet[v] & 1) inside[ni++] = v;
                        else outside[no++] = v;
                    }
                    if (ni == 1 || ni == 3) {
                        // One vertex alone: triangle on its three edges, facing away from
                        // the inside (towards the lone vertex when it is the outside one).
                        const int lone = ni == 1 ? inside[0] : outside[0];
                        const auto p = evenPermutationStartingWith({lone});
                        const int a = tet[p[0]], b = tet[p[1]], c = tet[p[2]], d = tet[p[3]];
                        if (ni == 1) tri(a, b, a, c, a, d);
                        else tri(a, b, a, d, a, c);
                    } else if (ni == 2) {
                        // Quad AC, AD, BD, BC (A,B inside; (A,B,C,D) an even permutation),
                        // split along AC-BD.
                        const auto p = evenPermutationStartingWith({inside[0], inside[1]});
                        const int a = tet[p[0]], b = tet[p[1]], c = tet[p[2]], d = tet[p[3]];
                        tri(a, c, a, d, b, d);
                        tri(a, c, b, d, b, c);
                    }
                }
            }
        }
    }
};

const Tables& tables()
{
    static const Tables t;
    return t;
}

// ------------------------------------------------------------------- edges --

/// Edge types by the edge's minimum corner c: 0,1,2 = axis x,y,z from c;
/// 3,4,5 = the face diagonal of the xy, xz, yz face whose min corner is c.
constexpr int kEdgeTypes = 6;

/// Endpoints of edge (c, type), lower-keyed first. A face diagonal joins the
/// two even-parity corners of its face.
inline void edgeEnds(const Coord& c, int type, Coord& p0, Coord& p1)
{
    static const int axisA[6] = {0, 1, 2, 0, 0, 1};
    static const int axisB[6] = {-1, -1, -1, 1, 2, 2};
    Coord da(0), db(0);
    da[axisA[type]] = 1;
    if (type < 3) {
        p0 = c;
        p1 = c + da;
        return;
    }
    db[axisB[type]] = 1;
    if (((c.x() + c.y() + c.z()) & 1) == 0) {
        p0 = c;
        p1 = c + da + db;
    } else {
        p0 = c + da; // smaller along the higher axis: the lower-keyed end
        p1 = c + db;
    }
}

/// Type of the edge between local corners lo, hi of a cell (see edgeEnds).
int edgeTypeOf(int lo, int hi)
{
    switch (lo ^ hi) {
    case 1: return 0;
    case 2: return 1;
    case 4: return 2;
    case 3: return 3;
    case 5: return 4;
    default: return 5;
    }
}

/// Group of an owned edge (local min corner c in [0,7]^3 of its block): the
/// lines and faces a block shares with its lower neighbours come first, so a
/// neighbour can rank them from the data it holds itself. 0: line x=0,y=0;
/// 1: line x=0,z=0; 2: line y=0,z=0; 3: face x=0; 4: face y=0; 5: face z=0; 6: rest.
constexpr int kGroups = 7;
inline int edgeGroup(int cx, int cy, int cz, int type)
{
    const bool inX = cx == 0 && (type == 1 || type == 2 || type == 5);
    const bool inY = cy == 0 && (type == 0 || type == 2 || type == 4);
    const bool inZ = cz == 0 && (type == 0 || type == 1 || type == 3);
    if (inX && inY) return 0;
    if (inX && inZ) return 1;
    if (inY && inZ) return 2;
    if (inX) return 3;
    if (inY) return 4;
    if (inZ) return 5;
    return 6;
}
/// edgeGroup for every (x, y, z, type) of a block, precomputed.
struct GroupTable
{
    uint8_t g[8][8][8][6];
    GroupTable()
    {
        for (int x = 0; x < 8; ++x)
            for (int y = 0; y < 8; ++y)
                for (int z = 0; z < 8; ++z)
                    for (int t = 0; t < 6; ++t) g[x][y][z][t] = uint8_t(edgeGroup(x, y, z, t));
    }
};
const GroupTable& groupTable()
{
    static const GroupTable t;
    return t;
}

/// Window-index offsets of the two ends of edge (c, type) from c's index, by
/// the parity of c, for a window of side n (z fastest).
struct EdgeOffsets
{
    int end[2][6][2];
    explicit EdgeOffsets(int n)
    {
        for (int parity = 0; parity < 2; ++parity) {
            const Coord c(parity, 0, 0);
            for (int type = 0; type < 6; ++type) {
                Coord p0, p1;
                edgeEnds(c, type, p0, p1);
                end[parity][type][0] = ((p0.x() - c.x()) * n + (p0.y() - c.y())) * n + (p0.z() - c.z());
                end[parity][type][1] = ((p1.x() - c.x()) * n + (p1.y() - c.y())) * n + (p1.z() - c.z());
            }
        }
    }
};

/// Bit a set: every edge of the group lies at local coordinate 0 along axis a.
constexpr int kGroupFixedAxes[kGroups] = {3, 5, 6, 1, 2, 4, 0};

// ------------------------------------------------------------------ blocks --

constexpr int kBlock = 8;

/// Dense copy of the values over the box [lo, lo + n - 1]^3 (z fastest), with
/// the inside flags. Vertices outside the scan box get the background value
/// and are outside.
struct Window
{
    Coord lo;
    int n = 0;
    std::vector<float> values;
    std::vector<uint8_t> inside;
    bool uniform = false; ///< all inside or all outside

    int index(int x, int y, int z) const { return ((x - lo.x()) * n + (y - lo.y())) * n + (z - lo.z()); }
    int index(const Coord& p) const { return index(p.x(), p.y(), p.z()); }

    void load(const openvdb::tree::ValueAccessor<const openvdb::FloatTree>& acc, const Coord& lower, int size,
              const Coord& dims, float background, float iso)
    {
        lo = lower;
        n = size;
        values.resize(size_t(n) * n * n);
        inside.resize(values.size());
        const Coord hi = lo + Coord(n - 1);
        for (int bx = lo.x() & ~(kBlock - 1); bx <= hi.x(); bx += kBlock) {
            for (int by = lo.y() & ~(kBlock - 1); by <= hi.y(); by += kBlock) {
                for (int bz = lo.z() & ~(kBlock - 1); bz <= hi.z(); bz += kBlock) {
                    const Coord origin(bx, by, bz);
                    const int x0 = std::max(lo.x(), bx), x1 = std::min(hi.x(), bx + kBlock - 1);
                    const int y0 = std::max(lo.y(), by), y1 = std::min(hi.y(), by + kBlock - 1);
                    const int z0 = std::max(lo.z(), bz), z1 = std::min(hi.z(), bz + kBlock - 1);
                    if (const LeafT* leaf = acc.probeConstLeaf(origin)) {
                        const float* data = leaf->buffer().data();
                        for (int x = x0; x <= x1; ++x)
                            for (int y = y0; y <= y1; ++y) {
                                const float* in = data + (((x & 7) << 6) | ((y & 7) << 3) | (z0 & 7));
                                std::memcpy(&values[size_t(index(x, y, z0))], in, sizeof(float) * size_t(z1 - z0 + 1));
                            }
                    } else {
                        const float v = acc.getValue(origin);
                        for (int x = x0; x <= x1; ++x)
                            for (int y = y0; y <= y1; ++y)
                                std::fill_n(&values[size_t(index(x, y, z0))], z1 - z0 + 1, v);
                    }
                }
            }
        }
        const bool inBox = lo.x() >= 0 && lo.y() >= 0 && lo.z() >= 0 && hi.x() < dims.x() && hi.y() < dims.y() &&
                           hi.z() < dims.z();
        if (inBox) {
            uint8_t any = 0, all = 1;
            for (size_t i = 0; i < values.size(); ++i) {
                const uint8_t b = values[i] >= iso;
                inside[i] = b;
                any |= b;
                all &= b;
            }
            uniform = any == all;
            return;
        }
        uniform = false;
        size_t i = 0;
        for (int x = lo.x(); x <= hi.x(); ++x)
            for (int y = lo.y(); y <= hi.y(); ++y)
                for (int z = lo.z(); z <= hi.z(); ++z, ++i) {
                    if (x < 0 || y < 0 || z < 0 || x >= dims.x() || y >= dims.y() || z >= dims.z()) {
                        values[i] = background;
                        inside[i] = 0;
                    } else {
                        inside[i] = values[i] >= iso;
                    }
                }
    }
};

/// Inside mask of the cell whose corner 0 is at window index i (bit c = x + 2y + 4z).
inline uint8_t cornerMask(const uint8_t* in, int i, int n)
{
    const int nn = n * n;
    return uint8_t(in[i] | in[i + nn] << 1 | in[i + n] << 2 | in[i + nn + n] << 3 | in[i + 1] << 4 |
                   in[i + nn + 1] << 5 | in[i + n + 1] << 6 | in[i + nn + n + 1] << 7);
}

struct Block
{
    Coord origin;
    uint32_t groupOffset[kGroups + 1] = {}; ///< prefix sums of crossed owned edges per group
    uint32_t triangleCount = 0;
    uint64_t vertexBase = 0;
    uint64_t triangleBase = 0;
};

/// Dense map over block positions (origin / 8) in the box [lo, lo + n - 1]:
/// the index of the block there (-1: none) and the state of the leaf there
/// (0: none or all outside, 1: all inside within the scan box, 2: mixed).
/// Empty when the leaves are too scattered for a dense map.
struct BlockMap
{
    Coord lo, n;
    std::vector<int32_t> blockIndex;
    std::vector<uint8_t> leafState;

    size_t index(const Coord& b) const
    {
        return (size_t(b.x() - lo.x()) * size_t(n.y()) + size_t(b.y() - lo.y())) * size_t(n.z()) + size_t(b.z() - lo.z());
    }
    bool contains(const Coord& b) const
    {
        return b.x() >= lo.x() && b.y() >= lo.y() && b.z() >= lo.z() && b.x() < lo.x() + n.x() &&
               b.y() < lo.y() + n.y() && b.z() < lo.z() + n.z();
    }
    int32_t find(const Coord& b) const { return contains(b) ? blockIndex[index(b)] : -1; }
    /// True when block b's window (its leaf and the +1 layer of the upper
    /// neighbours) is all inside or all outside, from the leaf states alone.
    bool uniformWindow(const Coord& b) const
    {
        if (blockIndex.empty()) return false;
        int state = -1;
        for (int d = 0; d < 8; ++d) {
            const Coord c = b + Coord(d & 1, d >> 1 & 1, d >> 2 & 1);
            const int s = contains(c) ? leafState[index(c)] : 0;
            if (s == 2 || (state >= 0 && s != state)) return false;
            state = s;
        }
        return true;
    }
};

/// For each upper neighbour offset (bit 0: +x, 1: +y, 2: +z) the edges of its
/// lower lines and faces that lie in this block's upper faces, in the owner's
/// (x, y, z, type) order: window indices of the two ends in the 11^3 window
/// that starts at origin - 1, the slot of the edge, the owner's group.
struct UpperEdge
{
    int16_t i0, i1;
    uint16_t slot;
    uint8_t group;
};
struct UpperEdges
{
    std::vector<UpperEdge> edges[7];
    UpperEdges()
    {
        constexpr int n = kBlock + 3, slotN = kBlock + 1;
        for (int offset = 1; offset < 7; ++offset) {
            const Coord d(offset & 1, offset >> 1 & 1, offset >> 2 & 1);
            bool wanted[kGroups];
            for (int g = 0; g < kGroups; ++g) wanted[g] = g < 6 && (kGroupFixedAxes[g] & offset) == offset;
            const int xEnd = d.x() ? 1 : kBlock, yEnd = d.y() ? 1 : kBlock, zEnd = d.z() ? 1 : kBlock;
            for (int x = 0; x < xEnd; ++x)
                for (int y = 0; y < yEnd; ++y)
                    for (int z = 0; z < zEnd; ++z) {
                        const Coord c = Coord(d.x() * kBlock + x, d.y() * kBlock + y, d.z() * kBlock + z); // relative to this block's origin
                        for (int type = 0; type < kEdgeTypes; ++type) {
                            const int g = edgeGroup(x, y, z, type);
                            if (!wanted[g]) continue;
                            Coord p0, p1;
                            edgeEnds(c, type, p0, p1);
                            auto windowIndex = [&](const Coord& p) { return ((p.x() + 1) * n + p.y() + 1) * n + p.z() + 1; };
                            const int slot = ((c.x() * slotN + c.y()) * slotN + c.z()) * kEdgeTypes + type;
                            edges[offset].push_back(
                                {int16_t(windowIndex(p0)), int16_t(windowIndex(p1)), uint16_t(slot), uint8_t(g)});
                        }
                    }
        }
    }
};
const UpperEdges& upperEdges()
{
    static const UpperEdges t;
    return t;
}

struct Grid
{
    openvdb::Vec3d origin, spacing;
};

Grid gridGeometry(const openvdb::FloatGrid& grid)
{
    const openvdb::math::Transform& xf = grid.transform();
    const openvdb::Mat4d m = xf.baseMap()->getAffineMap()->getMat4();
    bool ok = xf.isLinear();
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) ok = ok && (r == c ? m(r, c) > 0.0 : m(r, c) == 0.0);
    if (!ok) throw InputError("isosurface: the grid's transform must be a positive scale and a translation");
    return {openvdb::Vec3d(m(3, 0), m(3, 1), m(3, 2)), openvdb::Vec3d(m(0, 0), m(1, 1), m(2, 2))};
}

inline glm::vec3 edgePoint(const Coord& p0, const Coord& p1, double t, const openvdb::Vec3d& origin,
                           const openvdb::Vec3d& spacing)
{
    glm::vec3 out;
    for (int a = 0; a < 3; ++a) {
        const double index = double(p0[a]) + t * double(p1[a] - p0[a]);
        out[a] = float(origin[a] + spacing[a] * index);
    }
    return out;
}

std::string coordText(const Coord& c)
{
    std::ostringstream os;
    os << "(" << c.x() << ", " << c.y() << ", " << c.z() << ")";
    return os.str();
}

} // namespace

// ------------------------------------------------------------------ kernel --

const std::array<std::array<uint8_t, 4>, kTetsPerCell>& cellTets(int parity) { return tables().tets[parity & 1]; }

const std::array<CellEdge, kCellEdgeCount>& cellEdges(int parity) { return tables().edges[parity & 1]; }

const CellCase& cellCase(int parity, uint8_t insideMask) { return tables().cases[parity & 1][insideMask]; }

double edgeCrossing(float valueLo, float valueHi, float isovalue)
{
    const double d = double(valueHi) - double(valueLo);
    double t = d != 0.0 ? (double(isovalue) - double(valueLo)) / d : 0.5;
    if (!(t >= kEdgeClamp)) t = kEdgeClamp; // also catches NaN
    if (t > 1.0 - kEdgeClamp) t = 1.0 - kEdgeClamp;
    return t;
}

int polygoniseCell(const float values[8], const bool inside[8], const Coord& cell, float isovalue,
                   const openvdb::Vec3d& originMm, const openvdb::Vec3d& spacingMm, glm::vec3* outPositions)
{
    uint8_t mask = 0;
    for (int c = 0; c < 8; ++c) mask |= uint8_t(inside[c] ? 1 << c : 0);
    const int parity = cellParity(cell.x(), cell.y(), cell.z());
    const CellCase& cc = cellCase(parity, mask);
    const auto& edges = cellEdges(parity);
    for (int i = 0; i < 3 * cc.triangleCount; ++i) {
        const CellEdge e = edges[cc.edges[i]];
        const Coord p0 = cell + Coord(e.lo & 1, (e.lo >> 1) & 1, (e.lo >> 2) & 1);
        const Coord p1 = cell + Coord(e.hi & 1, (e.hi >> 1) & 1, (e.hi >> 2) & 1);
        outPositions[i] = edgePoint(p0, p1, edgeCrossing(values[e.lo], values[e.hi], isovalue), originMm, spacingMm);
    }
    return cc.triangleCount;
}

// -------------------------------------------------------------- extraction --

std::string isosurfaceWarning(const vdb::Volume& volume, float isovalue)
{
    std::ostringstream os;
    if (!(isovalue >= volume.minValue && isovalue <= volume.maxValue)) {
        os << "isovalue " << isovalue << " is outside the volume's values [" << volume.minValue << ", "
           << volume.maxValue << "]: the surface is empty";
    } else if (isovalue <= volume.airThreshold) {
        os << "isovalue " << isovalue << " is at or below the air threshold " << volume.airThreshold
           << ": air is stored as background there, so the surface follows the pruned blocks (re-read with --air "
              "below the isovalue)";
    }
    return os.str();
}

Mesh extractIsosurface(const vdb::Volume& volume, float iso, const IsosurfaceOptions& options)
{
    if (!volume.grid) throw InputError("isosurface: the volume has no grid");
    if (!std::isfinite(iso)) throw InputError("isosurface: the isovalue must be a finite number");
    const Grid geom = gridGeometry(*volume.grid);
    Mesh mesh;
    if (!(iso >= volume.minValue && iso <= volume.maxValue)) return mesh;

    InterrupterScope scope(options.interrupter, "isosurface");
    const Tables& tab = tables();
    const Coord dims = volume.dims;
    const float background = volume.grid->background();

    // Tiles: values for whole blocks at once. makeVolume makes none at or above
    // the isovalue (unless the isovalue is the background); for other grids the
    // part of such tiles inside the scan box becomes leaves in a copy.
    const openvdb::FloatTree* tree = &volume.grid->tree();
    openvdb::FloatTree::Ptr voxelised;
    {
        const openvdb::CoordBBox box = volume.indexBox();
        std::vector<openvdb::CoordBBox> insideTiles;
        using TileIter = openvdb::FloatTree::ValueAllCIter;
        TileIter it = tree->cbeginValueAll();
        it.setMaxDepth(TileIter::LEAF_DEPTH - 1);
        for (; it; ++it) {
            if (it.getDepth() == TileIter::LEAF_DEPTH || *it < iso) continue; // (NaN falls through)
            openvdb::CoordBBox tile;
            it.getBoundingBox(tile);
            tile.intersect(box);
            if (tile.empty()) continue;
            if (!std::isfinite(*it)) {
                throw InputError("isosurface: the grid holds a non-finite value (NaN or Inf) at voxel " +
                                 coordText(tile.min()));
            }
            insideTiles.push_back(tile);
        }
        if (!insideTiles.empty()) {
            voxelised = std::make_shared<openvdb::FloatTree>(*tree);
            for (const openvdb::CoordBBox& tile : insideTiles) {
                for (int x = tile.min().x() & ~(kBlock - 1); x <= tile.max().x(); x += kBlock)
                    for (int y = tile.min().y() & ~(kBlock - 1); y <= tile.max().y(); y += kBlock)
                        for (int z = tile.min().z() & ~(kBlock - 1); z <= tile.max().z(); z += kBlock)
                            voxelised->touchLeaf(Coord(x, y, z));
            }
            tree = voxelised.get();
        }
    }

    // Leaves: non-finite values are errors; leaves holding an inside value seed
    // the blocks to visit (the leaf and its lower neighbours, whose +1 layer it is).
    // Each leaf's state: 0 all outside, 1 all inside and within the scan box, 2 mixed.
    std::vector<const LeafT*> leaves;
    leaves.reserve(tree->leafCount());
    for (auto it = tree->cbeginLeaf(); it; ++it) leaves.push_back(&*it);
    std::vector<uint8_t> leafStates(leaves.size(), 0);
    std::atomic<size_t> firstBad{leaves.size()};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const float* data = leaves[i]->buffer().data();
            int nInside = 0, nBad = 0; // counts, so that the loop vectorises
            for (int k = 0; k < int(LeafT::SIZE); ++k) {
                nInside += data[k] >= iso;
                nBad += !(std::fabs(data[k]) <= std::numeric_limits<float>::max()); // NaN or Inf
            }
            const bool any = nInside > 0, all = nInside == int(LeafT::SIZE), bad = nBad > 0;
            const Coord o = leaves[i]->origin();
            const bool inBox = o.x() >= 0 && o.y() >= 0 && o.z() >= 0 && o.x() + kBlock <= dims.x() &&
                               o.y() + kBlock <= dims.y() && o.z() + kBlock <= dims.z();
            leafStates[i] = !any ? 0 : all && inBox ? 1 : 2;
            if (bad) {
                size_t cur = firstBad.load();
                while (i < cur && !firstBad.compare_exchange_weak(cur, i)) {}
            }
        }
    });
    if (firstBad < leaves.size()) {
        const LeafT* leaf = leaves[firstBad];
        for (auto it = leaf->cbeginValueAll(); it; ++it) {
            if (!std::isfinite(*it)) {
                throw InputError("isosurface: the grid holds a non-finite value (NaN or Inf) at voxel " +
                                 coordText(it.getCoord()));
            }
        }
    }
    // Blocks in ascending origin order. Over the leaves' bounding box (one
    // block of margin each side) a dense map gives, per block position, the
    // block's index and the state of the leaf there (0 where there is none:
    // tiles at or above the isovalue inside the box were voxelised above), so
    // neighbours are found and uniform windows skipped without searching.
    std::vector<Block> blocks;
    BlockMap map;
    {
        Coord lo(std::numeric_limits<int>::max()), hi(std::numeric_limits<int>::min());
        size_t nSeeds = 0;
        for (size_t i = 0; i < leaves.size(); ++i) {
            if (!leafStates[i]) continue;
            ++nSeeds;
            const Coord b = leaves[i]->origin() >> 3;
            lo.minComponent(b);
            hi.maxComponent(b);
        }
        const Coord extent = hi - lo + Coord(3);
        const double cells = nSeeds ? double(extent.x()) * extent.y() * extent.z() : 0.0;
        if (nSeeds && cells <= std::max(double(1 << 20), 64.0 * double(nSeeds))) {
            map.lo = lo - Coord(1);
            map.n = extent;
            map.blockIndex.assign(size_t(cells), -1);
            map.leafState.assign(size_t(cells), 0);
            for (size_t i = 0; i < leaves.size(); ++i) {
                const Coord b = leaves[i]->origin() >> 3;
                if (b.x() < map.lo.x() || b.y() < map.lo.y() || b.z() < map.lo.z() || b.x() >= map.lo.x() + extent.x() ||
                    b.y() >= map.lo.y() + extent.y() || b.z() >= map.lo.z() + extent.z()) {
                    continue; // far from every seed: not in any visited block's window
                }
                map.leafState[map.index(b)] = leafStates[i];
                if (!leafStates[i]) continue;
                for (int d = 0; d < 8; ++d) map.blockIndex[map.index(b - Coord(d & 1, d >> 1 & 1, d >> 2 & 1))] = 0;
            }
            size_t i = 0;
            for (int x = 0; x < extent.x(); ++x)
                for (int y = 0; y < extent.y(); ++y)
                    for (int z = 0; z < extent.z(); ++z, ++i) {
                        if (map.blockIndex[i] < 0) continue;
                        map.blockIndex[i] = int32_t(blocks.size());
                        Block block;
                        const Coord b = map.lo + Coord(x, y, z); // block coords, may be -1
                        block.origin = Coord(b.x() * 8, b.y() * 8, b.z() * 8); // not << 3: UB when < 0
                        blocks.push_back(block);
                    }
        } else {
            std::vector<Coord> origins;
            for (size_t i = 0; i < leaves.size(); ++i) {
                if (!leafStates[i]) continue;
                const Coord o = leaves[i]->origin();
                for (int d = 0; d < 8; ++d) {
                    origins.push_back(o - Coord(d & 1 ? kBlock : 0, d & 2 ? kBlock : 0, d & 4 ? kBlock : 0));
                }
            }
            std::sort(origins.begin(), origins.end());
            origins.erase(std::unique(origins.begin(), origins.end()), origins.end());
            blocks.resize(origins.size());
            for (size_t i = 0; i < origins.size(); ++i) blocks[i].origin = origins[i];
        }
    }
    const size_t nBlocks = blocks.size();
    std::atomic<size_t> done{0};
    auto progress = [&](size_t n, int from, int to) {
        const size_t d = done += n;
        pollInterrupter(options.interrupter, from + int(double(to - from) * double(d) / double(std::max<size_t>(nBlocks, 1))));
    };

    // Pass 1: per block, crossed owned edges per group and triangles.
    using Accessor = openvdb::tree::ValueAccessor<const openvdb::FloatTree>;
    tbb::enumerable_thread_specific<Window> windows1;
    const GroupTable& groups = groupTable();
    const EdgeOffsets offsets1(kBlock + 1), offsets2(kBlock + 3);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nBlocks, 16), [&](const tbb::blocked_range<size_t>& r) {
        Accessor acc(*tree);
        Window& w = windows1.local();
        for (size_t b = r.begin(); b != r.end(); ++b) {
            Block& block = blocks[b];
            const Coord o = block.origin;
            if (map.uniformWindow(o >> 3)) continue; // no crossed edge, no triangle
            w.load(acc, o, kBlock + 1, dims, background, iso);
            uint32_t counts[kGroups] = {};
            uint32_t triangles = 0;
            const uint8_t* in = w.inside.data();
            if (w.uniform) {
                block.triangleCount = 0;
                continue;
            }
            constexpr int n1 = kBlock + 1;
            for (int x = 0; x < kBlock; ++x)
                for (int y = 0; y < kBlock; ++y)
                    for (int z = 0; z < kBlock; ++z) {
                        const int i = (x * n1 + y) * n1 + z;
                        const int parity = (x + y + z) & 1; // block origins are even
                        const auto& ends = offsets1.end[parity];
                        if (x && y && z) { // interior cell: every owned edge is in group 6
                            uint32_t crossed = 0;
                            for (int type = 0; type < kEdgeTypes; ++type)
                                crossed += in[i + ends[type][0]] != in[i + ends[type][1]];
                            counts[kGroups - 1] += crossed;
                        } else {
                            const uint8_t* group = groups.g[x][y][z];
                            for (int type = 0; type < kEdgeTypes; ++type) {
                                if (in[i + ends[type][0]] != in[i + ends[type][1]]) ++counts[group[type]];
                            }
                        }
                        triangles += tab.cases[parity][cornerMask(in, i, n1)].triangleCount;
                    }
            block.groupOffset[0] = 0;
            for (int g = 0; g < kGroups; ++g) block.groupOffset[g + 1] = block.groupOffset[g] + counts[g];
            block.triangleCount = triangles;
        }
        progress(r.size(), 0, 30);
    });

    uint64_t nVertices = 0, nTriangles = 0;
    for (Block& block : blocks) {
        block.vertexBase = nVertices;
        block.triangleBase = nTriangles;
        nVertices += block.groupOffset[kGroups];
        nTriangles += block.triangleCount;
    }
    if (nVertices > std::numeric_limits<uint32_t>::max()) {
        throw InputError("isosurface: more than 2^32 vertices; use a higher isovalue or a smaller volume");
    }
    mesh.positions.resize(nVertices);
    if (options.normals) mesh.normals.resize(nVertices);
    mesh.indices.resize(nTriangles * 3);
    mesh.triangleVoxels.resize(nTriangles);

    auto findBlock = [&](const Coord& origin) -> const Block* {
        if (!map.blockIndex.empty()) {
            const int32_t i = map.find(origin >> 3);
            return i >= 0 ? &blocks[size_t(i)] : nullptr;
        }
        auto it = std::lower_bound(blocks.begin(), blocks.end(), origin,
                                   [](const Block& b, const Coord& o) { return b.origin < o; });
        return it != blocks.end() && it->origin == origin ? &*it : nullptr;
    };

    // Per cell edge: slot offset relative to the cell's slot, by parity.
    constexpr int kSlotN = kBlock + 1;
    int slotDelta[2][kCellEdgeCount];
    for (int parity = 0; parity < 2; ++parity) {
        for (int e = 0; e < kCellEdgeCount; ++e) {
            const CellEdge ce = tab.edges[parity][e];
            const int m = ce.lo & ce.hi;
            slotDelta[parity][e] =
                (((m & 1) * kSlotN + (m >> 1 & 1)) * kSlotN + (m >> 2 & 1)) * kEdgeTypes + edgeTypeOf(ce.lo, ce.hi);
        }
    }

    // Pass 2: vertices of owned edges, indices of neighbours' edges, triangles.
    struct Scratch
    {
        Window window;
        std::vector<uint32_t> slots = std::vector<uint32_t>(size_t(kSlotN) * kSlotN * kSlotN * kEdgeTypes);
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    const UpperEdges& upper = upperEdges();
    const openvdb::Vec3d invSpacing(1.0 / geom.spacing.x(), 1.0 / geom.spacing.y(), 1.0 / geom.spacing.z());
    done = 0;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nBlocks, 16), [&](const tbb::blocked_range<size_t>& r) {
        Accessor acc(*tree);
        Scratch& s = scratch.local();
        Window& w = s.window;
        uint32_t* slots = s.slots.data();
        auto slotIndex = [&](int x, int y, int z, int type) { return ((x * kSlotN + y) * kSlotN + z) * kEdgeTypes + type; };
        for (size_t b = r.begin(); b != r.end(); ++b) {
            const Block& block = blocks[b];
            if (block.groupOffset[kGroups] == 0 && block.triangleCount == 0) continue;
            const Coord o = block.origin;
            w.load(acc, o - Coord(1), kBlock + 3, dims, background, iso);
            const uint8_t* in = w.inside.data();
            const float* val = w.values.data();
            constexpr int n2 = kBlock + 3;
            constexpr int nn = n2 * n2;

            // Owned edges, in (x, y, z, type) order within each group.
            uint32_t next[kGroups];
            for (int g = 0; g < kGroups; ++g) next[g] = uint32_t(block.vertexBase) + block.groupOffset[g];
            for (int x = 0; x < kBlock; ++x)
                for (int y = 0; y < kBlock; ++y)
                    for (int z = 0; z < kBlock; ++z) {
                        const int i = ((x + 1) * n2 + y + 1) * n2 + z + 1; // window starts at o - 1
                        const int parity = (x + y + z) & 1;
                        const auto& ends = offsets2.end[parity];
                        for (int type = 0; type < kEdgeTypes; ++type) {
                            const int i0 = i + ends[type][0], i1 = i + ends[type][1];
                            if (in[i0] == in[i1]) continue;
                            Coord p0, p1;
                            edgeEnds(o + Coord(x, y, z), type, p0, p1);
                            const uint32_t v = next[groups.g[x][y][z][type]]++;
                            slots[slotIndex(x, y, z, type)] = v;
                            const double t = edgeCrossing(val[i0], val[i1], iso);
                            mesh.positions[v] = edgePoint(p0, p1, t, geom.origin, geom.spacing);
                            if (!options.normals) continue;
                            glm::vec3 g;
                            const int step[3] = {nn, n2, 1};
                            for (int a = 0; a < 3; ++a) {
                                const float g0 = 0.5f * (val[i0 + step[a]] - val[i0 - step[a]]);
                                const float g1 = 0.5f * (val[i1 + step[a]] - val[i1 - step[a]]);
                                g[a] = float(-(g0 + t * (g1 - g0)) * invSpacing[a]);
                            }
                            const float len = std::sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
                            if (len > 0.0f && std::isfinite(len)) {
                                g /= len;
                            } else { // flat field: from the inside end towards the outside end
                                const float sign = in[i0] ? 1.0f : -1.0f;
                                for (int a = 0; a < 3; ++a) g[a] = sign * float((p1[a] - p0[a]) * geom.spacing[a]);
                                g /= std::sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
                            }
                            mesh.normals[v] = g;
                        }
                    }

            // Edges in the upper faces: owned by the +x/+y/+z neighbours, which
            // number them first in their lower lines and faces; rank them here
            // from the same (global) classification.
            for (int offset = 1; offset < 7; ++offset) {
                const Coord d(offset & 1, offset >> 1 & 1, offset >> 2 & 1);
                const Block* owner = findBlock(o + Coord(d.x() * kBlock, d.y() * kBlock, d.z() * kBlock));
                if (!owner) continue; // no crossed edge there (its owner would have been visited)
                uint32_t rank[kGroups];
                for (int g = 0; g < kGroups; ++g) rank[g] = uint32_t(owner->vertexBase) + owner->groupOffset[g];
                for (const UpperEdge& e : upper.edges[offset]) {
                    if (in[e.i0] != in[e.i1]) slots[e.slot] = rank[e.group]++;
                }
            }

            // Triangles, cell by cell.
            uint64_t t = block.triangleBase;
            for (int x = 0; x < kBlock; ++x)
                for (int y = 0; y < kBlock; ++y)
                    for (int z = 0; z < kBlock; ++z) {
                        const int i = ((x + 1) * n2 + y + 1) * n2 + z + 1;
                        const uint8_t m = cornerMask(in, i, n2);
                        if (m == 0 || m == 255) continue;
                        const Coord c = o + Coord(x, y, z);
                        const int parity = cellParity(c.x(), c.y(), c.z());
                        const CellCase& cc = tab.cases[parity][m];
                        const uint32_t* cellSlots = slots + slotIndex(x, y, z, 0);
                        for (int k = 0; k < cc.triangleCount; ++k, ++t) {
                            for (int j = 0; j < 3; ++j) {
                                mesh.indices[3 * t + j] = cellSlots[slotDelta[parity][cc.edges[3 * k + j]]];
                            }
                            mesh.triangleVoxels[t] = glm::ivec3(c.x(), c.y(), c.z());
                        }
                    }
        }
        progress(r.size(), 30, 100);
    });
    return mesh;
}

} // namespace mtcut::cutter
