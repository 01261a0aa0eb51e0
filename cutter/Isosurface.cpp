#include "cutter/Isosurface.h"

#include "vdb/Error.h"

#include <openvdb/math/Maps.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

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
    Coord delta[2][6][2]; ///< the ends minus c (edgeEnds without its branches)
    explicit EdgeOffsets(int n)
    {
        for (int parity = 0; parity < 2; ++parity) {
            const Coord c(parity, 0, 0);
            for (int type = 0; type < 6; ++type) {
                Coord p0, p1;
                edgeEnds(c, type, p0, p1);
                delta[parity][type][0] = p0 - c;
                delta[parity][type][1] = p1 - c;
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

/// Inside bits of one leaf (8^3 voxels): byte x * 8 + y holds the (x, y)
/// row, bit z set when the voxel's value is >= the isovalue and the voxel is
/// in the scan box. Made once per leaf; the passes read signs only from here.
struct LeafRows
{
    uint8_t row[64];
};

/// Fill rows from a leaf's values: the signs of the 8 values of each row.
inline void makeLeafRows(const float* data, float iso, LeafRows& rows)
{
    for (int r = 0; r < 64; ++r) {
        const float* v = data + 8 * r;
        uint32_t m = 0;
        for (int z = 0; z < 8; ++z) m |= uint32_t(v[z] >= iso) << z;
        rows.row[r] = uint8_t(m);
    }
}

/// Signs of a block's vertices, local (x, y, z) in [0, 8]^3 (its leaf and the
/// +1 layer of its upper neighbours): entry x * 9 + y, bit z.
constexpr int kSignN = kBlock + 1;
using SignRows = std::array<uint16_t, kSignN * kSignN>;

/// leaf[(dx * 2 + dy) * 2 + dz]: the rows of the leaf at block + (dx, dy, dz).
inline void makeSignRows(const LeafRows* const leaf[8], SignRows& rows)
{
    for (int x = 0; x < kSignN; ++x)
        for (int y = 0; y < kSignN; ++y) {
            const int l = ((x >> 3) * 2 + (y >> 3)) * 2, r = (x & 7) * 8 + (y & 7);
            rows[size_t(x * kSignN + y)] = uint16_t(leaf[l]->row[r] | (leaf[l + 1]->row[r] & 1) << 8);
        }
}

/// The cells of row (x, y) of a block, bit z each (block origins are even, so
/// a cell's parity is (x + y + z) & 1).
struct CellRow
{
    uint32_t r00, r10, r01, r11; ///< sign rows (x, y), (x+1, y), (x, y+1), (x+1, y+1)

    CellRow(const SignRows& rows, int x, int y)
        : r00(rows[size_t(x * kSignN + y)]), r10(rows[size_t((x + 1) * kSignN + y)]),
          r01(rows[size_t(x * kSignN + y + 1)]), r11(rows[size_t((x + 1) * kSignN + y + 1)])
    {
    }
    /// Crossed owned edges of each type (see edgeEnds) by the cell's z.
    void crossed(int x, int y, uint32_t t[kEdgeTypes]) const
    {
        const uint32_t even = ((x + y) & 1) ? 0xAAu : 0x55u, odd = even ^ 0xFFu;
        t[0] = (r00 ^ r10) & 0xFFu;
        t[1] = (r00 ^ r01) & 0xFFu;
        t[2] = (r00 ^ r00 >> 1) & 0xFFu;
        t[3] = ((r00 ^ r11) & even) | ((r10 ^ r01) & odd);
        t[4] = ((r00 ^ r10 >> 1) & even) | ((r10 ^ r00 >> 1) & odd);
        t[5] = ((r00 ^ r01 >> 1) & even) | ((r01 ^ r00 >> 1) & odd);
    }
    /// Cells with corners both inside and outside.
    uint32_t mixed() const
    {
        const uint32_t any = r00 | r10 | r01 | r11, all = r00 & r10 & r01 & r11;
        return (any | any >> 1) & ~(all & all >> 1) & 0xFFu;
    }
    /// Inside mask of cell z (bit c = x + 2y + 4z of the local corner).
    uint8_t cellMask(int z) const
    {
        const uint32_t q = (r00 >> z & 3) | (r10 >> z & 3) << 2 | (r01 >> z & 3) << 4 | (r11 >> z & 3) << 6;
        // q holds (corner xy, z) at bit 2 * xy + z; reorder to xy + 4 z.
        return uint8_t((q & 1) | (q >> 1 & 2) | (q >> 2 & 4) | (q >> 3 & 8) | (q << 3 & 16) | (q << 2 & 32) |
                       (q << 1 & 64) | (q & 128));
    }
};

inline int popcount8(uint32_t v)
{
    v = v - ((v >> 1) & 0x55u);
    v = (v & 0x33u) + ((v >> 2) & 0x33u);
    return int((v + (v >> 4)) & 0x0Fu);
}

inline int popcount64(uint64_t v)
{
    v = v - ((v >> 1) & 0x5555555555555555ull);
    v = (v & 0x3333333333333333ull) + ((v >> 2) & 0x3333333333333333ull);
    v = (v + (v >> 4)) & 0x0F0F0F0F0F0F0F0Full;
    return int((v * 0x0101010101010101ull) >> 56);
}

inline int lowestBit(uint32_t v) { return __builtin_ctz(v); }

/// Dense copy of the values over the window [origin - 1, origin + 9]^3 of a
/// block (z fastest). Vertices outside the scan box get the background value.
struct ValueWindow
{
    static constexpr int n = kBlock + 3;
    std::vector<float> values = std::vector<float>(size_t(n) * n * n);

    /// leaf[(lx * 3 + ly) * 3 + lz]: the values of the leaf at block +
    /// (lx, ly, lz) - 1, or null with the tile value in tile[].
    void load(const float* const leaf[27], const float tile[27], const Coord& origin, const Coord& dims,
              float background)
    {
        float* out = values.data();
        auto put = [&](float* dst, int l, int offset, int count) {
            if (leaf[l]) {
                const float* src = leaf[l] + offset;
                for (int k = 0; k < count; ++k) dst[k] = src[k];
            } else {
                for (int k = 0; k < count; ++k) dst[k] = tile[l];
            }
        };
        for (int xi = 0; xi < n; ++xi) {
            const int lx = (xi + 7) >> 3, fx = (xi + 7) & 7;
            for (int yi = 0; yi < n; ++yi) {
                const int ly = (yi + 7) >> 3, fy = (yi + 7) & 7;
                float* dst = out + (xi * n + yi) * n;
                const int l = (lx * 3 + ly) * 3, row = fx << 6 | fy << 3;
                put(dst, l, row + 7, 1);
                put(dst + 1, l + 1, row, 8);
                put(dst + 9, l + 2, row, 2);
            }
        }
        const Coord lo = origin - Coord(1), hi = origin + Coord(kBlock + 1);
        if (lo.x() >= 0 && lo.y() >= 0 && lo.z() >= 0 && hi.x() < dims.x() && hi.y() < dims.y() && hi.z() < dims.z()) {
            return;
        }
        size_t i = 0;
        for (int x = lo.x(); x <= hi.x(); ++x)
            for (int y = lo.y(); y <= hi.y(); ++y)
                for (int z = lo.z(); z <= hi.z(); ++z, ++i) {
                    if (x < 0 || y < 0 || z < 0 || x >= dims.x() || y >= dims.y() || z >= dims.z()) out[i] = background;
                }
    }
};

struct Block
{
    Coord origin;
    uint32_t groupOffset[kGroups + 1] = {}; ///< prefix sums of crossed owned edges per group
    uint32_t triangleCount = 0;
    uint64_t vertexBase = 0;
    uint64_t triangleBase = 0;
};

/// Dense map over block positions (origin / 8) in the box [lo, lo + n - 1]:
/// the index of the block there (-1: none), the state of the leaf there
/// (0: none or all outside, 1: all inside within the scan box, 2: mixed) and
/// its index. The box reaches 2 positions past the seeds, so it holds every
/// leaf that a visited block's value window touches. Empty when the leaves
/// are too scattered for a dense map.
struct BlockMap
{
    Coord lo, n;
    std::vector<int32_t> blockIndex;
    std::vector<uint8_t> leafState;
    std::vector<int32_t> leafIndex; ///< index of the leaf there in the leaf list, -1: none

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
    uint8_t row0, z0, row1, z1; ///< the ends: sign row (x * 9 + y) and bit z
    uint16_t slot;
    uint8_t group;
};
struct UpperEdges
{
    std::vector<UpperEdge> edges[7];
    uint8_t groupMask[7] = {}; ///< bit g: the owner's group g lies in this block's upper faces
    UpperEdges()
    {
        constexpr int slotN = kBlock + 1;
        for (int offset = 1; offset < 7; ++offset) {
            const Coord d(offset & 1, offset >> 1 & 1, offset >> 2 & 1);
            bool wanted[kGroups];
            for (int g = 0; g < kGroups; ++g) {
                wanted[g] = g < 6 && (kGroupFixedAxes[g] & offset) == offset;
                groupMask[offset] |= uint8_t(wanted[g] ? 1 << g : 0);
            }
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
                            for (const Coord& p : {p0, p1}) {
                                assert(p.x() >= 0 && p.y() >= 0 && p.z() >= 0 && p.x() < kSignN && p.y() < kSignN &&
                                       p.z() < kSignN);
                                (void)p;
                            }
                            const int slot = ((c.x() * slotN + c.y()) * slotN + c.z()) * kEdgeTypes + type;
                            edges[offset].push_back({uint8_t(p0.x() * kSignN + p0.y()), uint8_t(p0.z()),
                                                     uint8_t(p1.x() * kSignN + p1.y()), uint8_t(p1.z()), uint16_t(slot),
                                                     uint8_t(g)});
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

/// Ask the kernel to back a freshly reserved output buffer with huge pages
/// (Linux, THP in "madvise" mode): value-initialising the ~35 bytes per
/// triangle of output then takes one page fault per 2 MiB instead of one per
/// 4 KiB (that was ~40% of a 2-thread phantom extraction). Only a hint: the
/// contents are the same whatever the kernel does.
void adviseHugePages(const void* data, size_t bytes)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    constexpr size_t kMinBytes = size_t(4) << 20;
    static const uintptr_t page = uintptr_t(sysconf(_SC_PAGESIZE));
    const uintptr_t begin = (uintptr_t(data) + page - 1) & ~(page - 1);
    const uintptr_t end = (uintptr_t(data) + bytes) & ~(page - 1);
    if (data && bytes >= kMinBytes && end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
    (void)data;
    (void)bytes;
#endif
}

/// v.resize(n) for an empty v, its pages advised as huge first.
template <class T>
void resizeOutput(std::vector<T>& v, size_t n)
{
    v.reserve(n);
    adviseHugePages(v.data(), n * sizeof(T));
    v.resize(n);
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
    std::vector<LeafRows> leafRows(leaves.size());
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
            LeafRows& rows = leafRows[i];
            if (!any) {
                rows = LeafRows{};
            } else {
                makeLeafRows(data, iso, rows);
                if (!inBox) { // vertices outside the scan box are outside
                    uint32_t zMask = 0;
                    for (int z = 0; z < kBlock; ++z) zMask |= uint32_t(o.z() + z >= 0 && o.z() + z < dims.z()) << z;
                    for (int x = 0; x < kBlock; ++x)
                        for (int y = 0; y < kBlock; ++y) {
                            const bool rowIn = o.x() + x >= 0 && o.x() + x < dims.x() && o.y() + y >= 0 && o.y() + y < dims.y();
                            rows.row[x * 8 + y] &= uint8_t(rowIn ? zMask : 0);
                        }
                }
            }
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
    std::vector<std::pair<Coord, int32_t>> sortedLeaves; // (origin / 8, leaf index) without a dense map
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
            map.lo = lo - Coord(2);
            map.n = hi - lo + Coord(5);
            const size_t mapSize = size_t(map.n.x()) * size_t(map.n.y()) * size_t(map.n.z());
            map.blockIndex.assign(mapSize, -1);
            map.leafState.assign(mapSize, 0);
            map.leafIndex.assign(mapSize, -1);
            for (size_t i = 0; i < leaves.size(); ++i) {
                const Coord b = leaves[i]->origin() >> 3;
                if (!map.contains(b)) continue; // far from every seed: not in any visited block's window
                map.leafIndex[map.index(b)] = int32_t(i);
                map.leafState[map.index(b)] = leafStates[i];
                if (!leafStates[i]) continue;
                for (int d = 0; d < 8; ++d) map.blockIndex[map.index(b - Coord(d & 1, d >> 1 & 1, d >> 2 & 1))] = 0;
            }
            size_t i = 0;
            for (int x = 0; x < map.n.x(); ++x)
                for (int y = 0; y < map.n.y(); ++y)
                    for (int z = 0; z < map.n.z(); ++z, ++i) {
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
            sortedLeaves.reserve(leaves.size());
            for (size_t i = 0; i < leaves.size(); ++i) sortedLeaves.emplace_back(leaves[i]->origin() >> 3, int32_t(i));
            std::sort(sortedLeaves.begin(), sortedLeaves.end());
        }
    }
    // The leaf at block position b (origin / 8) as an index into leaves, -1: none.
    auto findLeaf = [&](const Coord& b) -> int32_t {
        if (!map.blockIndex.empty()) {
            assert(map.contains(b));
            return map.leafIndex[map.index(b)];
        }
        auto it = std::lower_bound(sortedLeaves.begin(), sortedLeaves.end(), std::make_pair(b, int32_t(-1)));
        return it != sortedLeaves.end() && it->first == b ? it->second : -1;
    };
    static const LeafRows kOutsideRows{};
    // Signs of block b's vertices from its 8 leaves (no leaf: outside, since
    // tiles at or above the isovalue in the scan box were voxelised).
    auto loadSigns = [&](const Coord& b, SignRows& rows) {
        const LeafRows* rowsOf[8];
        for (int d = 0; d < 8; ++d) {
            const int32_t l = findLeaf(b + Coord(d >> 2 & 1, d >> 1 & 1, d & 1));
            rowsOf[d] = l >= 0 ? &leafRows[size_t(l)] : &kOutsideRows;
        }
        makeSignRows(rowsOf, rows);
    };
    const size_t nBlocks = blocks.size();
    std::atomic<size_t> done{0};
    auto progress = [&](size_t n, int from, int to) {
        const size_t d = done += n;
        pollInterrupter(options.interrupter, from + int(double(to - from) * double(d) / double(std::max<size_t>(nBlocks, 1))));
    };

    // Pass 1: per block, crossed owned edges per group and triangles, from the
    // leaves' sign rows alone. The group of an owned edge depends on whether
    // its min corner has x, y, z == 0: by row (x == 0, y == 0), for z == 0 and z > 0.
    uint8_t rowGroup[4][2][kEdgeTypes];
    for (int f = 0; f < 4; ++f)
        for (int type = 0; type < kEdgeTypes; ++type) {
            rowGroup[f][0][type] = uint8_t(edgeGroup(f & 1 ? 0 : 1, f & 2 ? 0 : 1, 0, type));
            rowGroup[f][1][type] = uint8_t(edgeGroup(f & 1 ? 0 : 1, f & 2 ? 0 : 1, 1, type));
        }
    using Accessor = openvdb::tree::ValueAccessor<const openvdb::FloatTree>;
    const GroupTable& groups = groupTable();
    const EdgeOffsets offsets2(kBlock + 3);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nBlocks, 16), [&](const tbb::blocked_range<size_t>& r) {
        SignRows rows;
        for (size_t b = r.begin(); b != r.end(); ++b) {
            Block& block = blocks[b];
            const Coord o = block.origin;
            if (map.uniformWindow(o >> 3)) continue; // no crossed edge, no triangle
            loadSigns(o >> 3, rows);
            uint32_t counts[kGroups] = {};
            uint32_t triangles = 0;
            for (int x = 0; x < kBlock; ++x)
                for (int y = 0; y < kBlock; ++y) {
                    const CellRow row(rows, x, y);
                    uint32_t t[kEdgeTypes];
                    row.crossed(x, y, t);
                    if (x && y) { // interior row: group 6, but group 5 (face z = 0) for types 0, 1, 3 at z = 0
                        const uint64_t all = t[0] | t[1] << 8 | t[2] << 16 | t[3] << 24 | uint64_t(t[4]) << 32 |
                                             uint64_t(t[5]) << 40;
                        const uint32_t z0 = (t[0] & 1) + (t[1] & 1) + (t[3] & 1);
                        counts[5] += z0;
                        counts[6] += uint32_t(popcount64(all)) - z0;
                    } else {
                        const auto& g = rowGroup[(x == 0) | (y == 0) << 1];
                        for (int type = 0; type < kEdgeTypes; ++type) {
                            counts[g[0][type]] += t[type] & 1;
                            counts[g[1][type]] += uint32_t(popcount8(t[type] & 0xFEu));
                        }
                    }
                    for (uint32_t m = row.mixed(); m; m &= m - 1) {
                        const int z = lowestBit(m);
                        triangles += tab.cases[(x + y + z) & 1][row.cellMask(z)].triangleCount;
                    }
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
    // The four arrays are value-initialised concurrently (std::vector writes
    // them once before pass 2 does; the page faults are most of that cost).
    tbb::parallel_invoke([&] { resizeOutput(mesh.positions, nVertices); },
                         [&] { resizeOutput(mesh.normals, options.normals ? nVertices : 0); },
                         [&] { resizeOutput(mesh.indices, nTriangles * 3); },
                         [&] { resizeOutput(mesh.triangleVoxels, nTriangles); });

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
        ValueWindow window;
        SignRows rows;
        std::vector<uint32_t> slots = std::vector<uint32_t>(size_t(kSlotN) * kSlotN * kSlotN * kEdgeTypes);
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    const UpperEdges& upper = upperEdges();
    const openvdb::Vec3d invSpacing(1.0 / geom.spacing.x(), 1.0 / geom.spacing.y(), 1.0 / geom.spacing.z());
    done = 0;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nBlocks, 16), [&](const tbb::blocked_range<size_t>& r) {
        Accessor acc(*tree);
        Scratch& s = scratch.local();
        const SignRows& rows = s.rows;
        uint32_t* slots = s.slots.data();
        auto slotIndex = [&](int x, int y, int z, int type) { return ((x * kSlotN + y) * kSlotN + z) * kEdgeTypes + type; };
        auto insideAt = [&](const Coord& local) { return rows[size_t(local.x() * kSignN + local.y())] >> local.z() & 1; };
        for (size_t b = r.begin(); b != r.end(); ++b) {
            const Block& block = blocks[b];
            if (block.groupOffset[kGroups] == 0 && block.triangleCount == 0) continue;
            const Coord o = block.origin;
            const Coord bc = o >> 3;
            loadSigns(bc, s.rows);
            {
                const float* leaf[27];
                float tile[27];
                for (int l = 0; l < 27; ++l) {
                    const Coord lb = bc + Coord(l / 9 - 1, l / 3 % 3 - 1, l % 3 - 1);
                    const int32_t li = findLeaf(lb);
                    leaf[l] = li >= 0 ? leaves[size_t(li)]->buffer().data() : nullptr;
                    tile[l] = li >= 0 ? 0.0f : acc.getValue(Coord(lb.x() * 8, lb.y() * 8, lb.z() * 8));
                }
                s.window.load(leaf, tile, o, dims, background);
            }
            const float* val = s.window.values.data();
            constexpr int n2 = kBlock + 3;
            constexpr int nn = n2 * n2;

            // Owned edges, in (x, y, z, type) order within each group.
            uint32_t next[kGroups];
            for (int g = 0; g < kGroups; ++g) next[g] = uint32_t(block.vertexBase) + block.groupOffset[g];
            for (int x = 0; x < kBlock; ++x)
                for (int y = 0; y < kBlock; ++y) {
                    uint32_t crossed[kEdgeTypes];
                    CellRow(rows, x, y).crossed(x, y, crossed);
                    uint32_t any = 0;
                    for (int type = 0; type < kEdgeTypes; ++type) any |= crossed[type];
                    for (; any; any &= any - 1) {
                        const int z = lowestBit(any);
                        const int i = ((x + 1) * n2 + y + 1) * n2 + z + 1; // window starts at o - 1
                        const int parity = (x + y + z) & 1; // = the global parity: block origins are even
                        const auto& ends = offsets2.end[parity];
                        const Coord cell = o + Coord(x, y, z);
                        uint32_t types = 0; // crossed edge types of cell z, bit per type
                        for (int type = 0; type < kEdgeTypes; ++type) types |= (crossed[type] >> z & 1) << type;
                        for (; types; types &= types - 1) {
                            const int type = lowestBit(types);
                            const int i0 = i + ends[type][0], i1 = i + ends[type][1];
                            const Coord p0 = cell + offsets2.delta[parity][type][0];
                            const Coord p1 = cell + offsets2.delta[parity][type][1];
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
                                const float sign = insideAt(p0 - o) ? 1.0f : -1.0f;
                                for (int a = 0; a < 3; ++a) g[a] = sign * float((p1[a] - p0[a]) * geom.spacing[a]);
                                g /= std::sqrt(g.x * g.x + g.y * g.y + g.z * g.z);
                            }
                            mesh.normals[v] = g;
                        }
                    }
                }

            // Edges in the upper faces: owned by the +x/+y/+z neighbours, which
            // number them first in their lower lines and faces; rank them here
            // from the same (global) classification.
            for (int offset = 1; offset < 7; ++offset) {
                const Coord d(offset & 1, offset >> 1 & 1, offset >> 2 & 1);
                const Block* owner = findBlock(o + Coord(d.x() * kBlock, d.y() * kBlock, d.z() * kBlock));
                if (!owner) continue; // no crossed edge there (its owner would have been visited)
                uint32_t rank[kGroups], remaining = 0; // crossed edges of those groups, all in the list
                for (int g = 0; g < kGroups; ++g) {
                    rank[g] = uint32_t(owner->vertexBase) + owner->groupOffset[g];
                    if (upper.groupMask[offset] >> g & 1) remaining += owner->groupOffset[g + 1] - owner->groupOffset[g];
                }
                for (auto e = upper.edges[offset].begin(); remaining; ++e) {
                    assert(e != upper.edges[offset].end());
                    if ((rows[e->row0] >> e->z0 ^ rows[e->row1] >> e->z1) & 1) {
                        slots[e->slot] = rank[e->group]++;
                        --remaining;
                    }
                }
            }

            // Triangles, cell by cell.
            uint64_t t = block.triangleBase;
            for (int x = 0; x < kBlock; ++x)
                for (int y = 0; y < kBlock; ++y) {
                    const CellRow row(rows, x, y);
                    for (uint32_t mixed = row.mixed(); mixed; mixed &= mixed - 1) {
                        const int z = lowestBit(mixed);
                        const Coord c = o + Coord(x, y, z);
                        const int parity = (x + y + z) & 1;
                        const CellCase& cc = tab.cases[parity][row.cellMask(z)];
                        const uint32_t* cellSlots = slots + slotIndex(x, y, z, 0);
                        for (int k = 0; k < cc.triangleCount; ++k, ++t) {
                            for (int j = 0; j < 3; ++j) {
                                mesh.indices[3 * t + j] = cellSlots[slotDelta[parity][cc.edges[3 * k + j]]];
                            }
                            mesh.triangleVoxels[t] = glm::ivec3(c.x(), c.y(), c.z());
                        }
                    }
                }
        }
        progress(r.size(), 30, 100);
    });
    return mesh;
}

} // namespace mtcut::cutter
