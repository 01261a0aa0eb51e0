// The local check of CutRemesher::update (DESIGN invariants 5-7): after a
// step, the surface around the changed cells, as fusedMesh() will write it
// (float world mm, snap rounded), must be closed and a 2-manifold, with no
// triangle of zero area and, with kerf, no triangle crossing or touching
// another; otherwise the step is refused and the last good mesh kept.
#include "cutter/Remesh.h"

#include "cutter/FloatRepair.h"
#include "cutter/RemeshKernel.h"
#include "cutter/TriangleIntersect.h"

#include <glm/common.hpp>
#include <glm/vector_relational.hpp>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <limits>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace mtcut::cutter {

using namespace remesh_detail;
using openvdb::Coord;

namespace {

/// The threads this call may use: the arena's, capped by a
/// tbb::global_control (`bench_cut` and the tests run on one).
size_t threadsAllowed()
{
    return std::min(size_t(tbb::this_task_arena::max_concurrency()),
                    tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

/// The cells whose closed box holds vertex v: [lo, hi] per axis.
void cellsHolding(const CutVertexId& v, Coord& lo, Coord& hi)
{
    if (v.dim == 3) {
        lo = hi = gridVertexCoord(v.feature[0]);
        return;
    }
    lo = Coord(std::numeric_limits<int>::min());
    hi = Coord(std::numeric_limits<int>::max());
    for (int i = 0; i <= int(v.dim); ++i) {
        const Coord g = gridVertexCoord(v.feature[size_t(i)]);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::max(lo[a], g[a] - 1);
            hi[a] = std::min(hi[a], g[a]);
        }
    }
}

CutVertexId isoEdgeVertex(const std::pair<uint64_t, uint64_t>& e)
{
    CutVertexId id;
    id.dim = 1;
    id.planeCount = 1;
    id.planes[0] = 1;
    id.feature = {e.first, e.second, 0};
    return id;
}

} // namespace

// Marks a bitmap over the box when it is compact (a haptic step's cells),
// else sorts packed integer keys (the 27 copies sorted as Coord were a
// quarter of a step).
std::vector<Coord> dilatedCells(const std::vector<Coord>& cells)
{
    std::vector<Coord> out;
    if (cells.empty()) return out;
    Coord lo = cells.front(), hi = cells.front();
    for (const Coord& c : cells) {
        lo.minComponent(c);
        hi.maxComponent(c);
    }
    lo -= Coord(1);
    hi += Coord(1);
    const uint64_t nx = uint64_t(hi.x() - lo.x() + 1), ny = uint64_t(hi.y() - lo.y() + 1), nz = uint64_t(hi.z() - lo.z() + 1);
    const uint64_t boxCells = nx * ny * nz;
    if (boxCells <= 256 * uint64_t(cells.size())) {
        std::vector<char> in(boxCells, 0);
        for (const Coord& c : cells) {
            const Coord b = c - lo;
            for (int dx = -1; dx <= 1; ++dx)
                for (int dy = -1; dy <= 1; ++dy) {
                    char* row = &in[(uint64_t(b.x() + dx) * ny + uint64_t(b.y() + dy)) * nz + uint64_t(b.z() - 1)];
                    row[0] = row[1] = row[2] = 1;
                }
        }
        for (uint64_t x = 0; x < nx; ++x)
            for (uint64_t y = 0; y < ny; ++y) {
                const char* row = &in[(x * ny + y) * nz];
                for (uint64_t z = 0; z < nz; ++z)
                    if (row[z]) out.push_back(lo + Coord(int(x), int(y), int(z)));
            }
        return out;
    }
    // Sorted as packed integers (offsets in the box, x major as Coord's order).
    std::vector<uint64_t> keys;
    keys.reserve(27 * cells.size());
    for (const Coord& c : cells) {
        const Coord b = c - lo;
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz)
                    keys.push_back((uint64_t(b.x() + dx) * ny + uint64_t(b.y() + dy)) * nz + uint64_t(b.z() + dz));
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    out.reserve(keys.size());
    for (uint64_t k : keys) out.push_back(lo + Coord(int(k / (ny * nz)), int(k / nz % ny), int(k % nz)));
    return out;
}

namespace {

/// A triangle of the local check's region, over the region's vertex names.
struct RegionTriangle
{
    uint32_t v[3];
    Coord cell;
    bool cut;     ///< a cut cell's (new geometry), else an uncut cell's
    bool changed; ///< its cell is a changed cell
    bool intoFace = false; ///< put into a cell face by the float repair (CutCellGeometry::intoFace)
};
using Tri = RegionTriangle;

/// Numbers of keys held elsewhere (the region's `ids`): open addressing
/// over (hash, number + 1), linear probing, grown at half full. In place of
/// the node-based unordered_maps the check used, which allocated and freed
/// one node per name (with the tables' growth, about a tenth of the
/// instructions of a haptic step's check). `same(number)` answers whether
/// the key of `number` is the one looked up.
class NameIndex
{
public:
    static constexpr uint32_t kNone = UINT32_MAX;

    /// The number of the key with hash `h`, or kNone.
    template <class Same> uint32_t find(uint64_t h, Same&& same) const
    {
        if (mSlots.empty()) return kNone;
        const size_t mask = mSlots.size() - 1;
        for (size_t i = home(h) & mask; mSlots[i].number; i = (i + 1) & mask)
            if (mSlots[i].hash == h && same(mSlots[i].number - 1)) return mSlots[i].number - 1;
        return kNone;
    }
    /// The number of the key with hash `h`; when it has none, it gets `next`
    /// (and `added` is set).
    template <class Same> uint32_t findOrAdd(uint64_t h, uint32_t next, bool& added, Same&& same)
    {
        if (2 * (mCount + 1) > mSlots.size()) grow();
        const size_t mask = mSlots.size() - 1;
        size_t i = home(h) & mask;
        for (; mSlots[i].number; i = (i + 1) & mask)
            if (mSlots[i].hash == h && same(mSlots[i].number - 1)) {
                added = false;
                return mSlots[i].number - 1;
            }
        mSlots[i] = {h, next + 1};
        ++mCount;
        added = true;
        return next;
    }

private:
    struct Slot
    {
        uint64_t hash = 0;
        uint32_t number = 0; ///< + 1; 0: empty
    };
    static size_t home(uint64_t h)
    {
        h ^= h >> 31;
        h *= 0xbf58476d1ce4e5b9ull;
        return size_t(h ^ (h >> 29));
    }
    void grow()
    {
        std::vector<Slot> old;
        old.swap(mSlots);
        mSlots.assign(std::max<size_t>(256, 2 * old.size()), Slot{});
        const size_t mask = mSlots.size() - 1;
        for (const Slot& s : old) {
            if (!s.number) continue;
            size_t i = home(s.hash) & mask;
            while (mSlots[i].number) i = (i + 1) & mask;
            mSlots[i] = s;
        }
    }
    std::vector<Slot> mSlots;
    size_t mCount = 0;
};

/// The local check's region: the triangles of the changed cells and of
/// their 26 neighbours, over vertex names (the fused mesh's identity: plain
/// marching-tetrahedra vertices by their grid edge, the others by their whole
/// name; one numbering, in order of first use), with float world positions.
struct LocalRegion
{
    const std::vector<Coord>* changed = nullptr; ///< sorted
    std::vector<Coord> cells;                    ///< the changed cells dilated by one, sorted
    std::vector<char> cellChanged;               ///< per cell of `cells`: a changed cell
    std::vector<CutVertexId> ids;                ///< per name
    NameIndex names;                             ///< the names not by grid edge, into `ids`
    /// The number of name `id` (not a plain marching-tetrahedra vertex's), or NameIndex::kNone.
    uint32_t numberOf(const CutVertexId& id) const
    {
        return names.find(CutVertexIdHash()(id), [&](uint32_t n) { return ids[n] == id; });
    }
    std::vector<Tri> tris;                       ///< in cell order, then each cell's order
    std::vector<glm::vec3> world;                ///< per name, as fusedMesh() writes it
    std::vector<char> known;                     ///< world[name] is set
    /// (vertex, a name snapRound joined into it), sorted: the vertex is
    /// used where any of them is.
    std::vector<std::pair<uint32_t, uint32_t>> joined;
    bool debug = false;                          ///< MTCUT_REMESH_DEBUG
    bool kerf = false;                           ///< the cut has a width (pinches are split in fusion)
    bool anyIntoFace = false;                    ///< a triangle has intoFace set
    /// Per cell of `cells`: a changed cell whose own pairs of triangles need
    /// not be asked again (CutCellGeometry::crossFree, and snap rounding
    /// left every vertex of it where the float repair judged it).
    std::vector<char> ownPairsClear;
    /// The changed cells' box [lo, lo + dim) as a bitmap, when it is small
    /// next to the region (a haptic step's, a straight cut's); else empty,
    /// and isChanged() searches `changed`.
    Coord lo, dim;
    std::vector<uint64_t> bitmap;
    /// Sets the bitmap and cellChanged; needs `changed` and `cells`.
    void indexChanged()
    {
        lo = dim = changed->front();
        for (const Coord& x : *changed) {
            lo.minComponent(x);
            dim.maxComponent(x);
        }
        dim = dim - lo + Coord(1);
        const uint64_t box = uint64_t(dim.x()) * uint64_t(dim.y()) * uint64_t(dim.z());
        if (box <= 64 * uint64_t(cells.size()) + 4096) {
            bitmap.assign((box + 63) / 64, 0);
            for (const Coord& x : *changed) bitmap[bitOf(x) / 64] |= uint64_t(1) << (bitOf(x) % 64);
        }
        cellChanged.resize(cells.size());
        for (size_t i = 0; i < cells.size(); ++i) cellChanged[i] = isChanged(cells[i]);
    }
    bool isChanged(const Coord& c) const
    {
        if (bitmap.empty()) return std::binary_search(changed->begin(), changed->end(), c);
        const Coord d = c - lo;
        if (d.x() < 0 || d.y() < 0 || d.z() < 0 || d.x() >= dim.x() || d.y() >= dim.y() || d.z() >= dim.z()) return false;
        return (bitmap[bitOf(c) / 64] >> (bitOf(c) % 64) & 1) != 0;
    }
    /// The bit of c, inside the box.
    uint64_t bitOf(const Coord& c) const
    {
        const Coord d = c - lo;
        return (uint64_t(d.x()) * uint64_t(dim.y()) + uint64_t(d.y())) * uint64_t(dim.z()) + uint64_t(d.z());
    }
    /// The cells whose closed boxes hold vertex v: cellsHolding of its name
    /// and of the names joined into it (their bounding box: they lie at one
    /// float position, so it is at most two cells across).
    void holding(uint32_t v, Coord& from, Coord& to) const
    {
        cellsHolding(ids[v], from, to);
        auto it = std::lower_bound(joined.begin(), joined.end(), std::make_pair(v, uint32_t(0)));
        for (; it != joined.end() && it->first == v; ++it) {
            Coord l, h;
            cellsHolding(ids[it->second], l, h);
            from.minComponent(l);
            to.maxComponent(h);
        }
    }
    [[noreturn]] void fail(const std::string& what, const Coord& c) const
    {
        throw std::runtime_error("remesh: open or inconsistent surface (" + what + ") in cell " + cellText(c));
    }
};

/// MTCUT_REMESH_DEBUG (Remesh.h): a vertex's name and float position on
/// stderr, planes as s<stroke>:q<quad>:k<kind>, tags as q<quad>+/-.
void describeVertex(const LocalRegion& reg, uint32_t v)
{
    const std::vector<CutVertexId>& ids = reg.ids;
    const std::vector<glm::vec3>& world = reg.world;
    using ull = unsigned long long;
    const CutVertexId& id = ids[v];
    std::fprintf(stderr, "  v%u dim %d at", v, id.dim);
    for (int i = 0; i <= std::min<int>(id.dim, 2); ++i) {
        if (id.dim == 3 && i == 1) {
            std::fprintf(stderr, " tet %llu", ull(id.feature[1]));
            break;
        }
        const Coord g = gridVertexCoord(id.feature[size_t(i)]);
        std::fprintf(stderr, " (%d,%d,%d)", g.x(), g.y(), g.z());
    }
    std::fprintf(stderr, " planes");
    for (int i = 0; i < id.planeCount; ++i) {
        const uint64_t p = id.planes[size_t(i)];
        if (p < 16) std::fprintf(stderr, " %llu", ull(p));
        else std::fprintf(stderr, " s%llu:q%llu:k%llu", ull(p >> 36), ull((p >> 4) & 0xffffffff), ull(p & 15));
    }
    std::fprintf(stderr, " tags");
    for (int i = 0; i < id.tagCount; ++i) {
        const uint64_t t = id.tags[size_t(i)];
        std::fprintf(stderr, " q%llu%c", ull((t >> 5) & 0xffffffff), t & 1 ? '-' : '+');
    }
    std::fprintf(stderr, " world %.6f %.6f %.6f\n", world[v].x, world[v].y, world[v].z);
}

/// The local check's last step when the cut has a width (DESIGN invariant
/// 7): no triangle of a changed cell may cross or touch another triangle,
/// in float world mm as written, decided exactly (TriangleIntersect.h) with
/// CGAL's adjacency rules over the names (after snap rounding), except that
/// the copies of a pinch vertex (Remesh.h, kerf > 0: the same name plus a
/// pinch tag) count as one vertex, so the fans of a pinch may touch there,
/// as the exact shape does, and two triangles may touch at one corner of
/// each at one float position (trianglesCross; the tests' CGAL check
/// counts both as pinch contacts, not intersections). Pairs of uncut
/// triangles are the isosurface's and are not asked. A triangle lies in its
/// cell's closed box (up to rounding), so only the 27 cells around a
/// changed cell's triangle are searched, and of those only triangles whose
/// float boxes overlap its. Two triangles each exactly inside its cell's
/// box (nearly all) meet only on the cells' common face, edge or corner:
/// such a pair is decided by their corners there
/// (trianglesCrossOnBoundary, the same answer), and a neighbour is asked
/// only when the triangle has a corner on the common part.
/// `tris` are in `region` order. Throws std::runtime_error("remesh: the
/// surface crosses or touches itself ...") naming the changed cell.
void refuseSelfContact(const vdb::Volume& volume, const LocalRegion& reg)
{
    const std::vector<Coord>& region = reg.cells;
    const std::vector<Tri>& tris = reg.tris;
    const std::vector<CutVertexId>& ids = reg.ids;
    const std::vector<glm::vec3>& world = reg.world;
    const std::vector<char>& known = reg.known;
    // Pinch copies -> the plain vertex of their name (or the first copy).
    std::vector<uint32_t> vertex(ids.size());
    std::unordered_map<CutVertexId, uint32_t, CutVertexIdHash> copies;
    for (uint32_t v = 0; v < uint32_t(ids.size()); ++v) {
        vertex[v] = v;
        const CutVertexId& id = ids[v];
        auto pinch = [](uint64_t t) { return (t & kPinchTag) != 0; };
        if (std::none_of(id.tags.begin(), id.tags.begin() + id.tagCount, pinch)) continue;
        CutVertexId plain = id;
        plain.tagCount = 0;
        plain.tags = {};
        for (int k = 0; k < id.tagCount; ++k)
            if (!pinch(id.tags[size_t(k)])) plain.tags[plain.tagCount++] = id.tags[size_t(k)];
        const uint32_t named = reg.numberOf(plain);
        vertex[v] = named != NameIndex::kNone ? named : copies.emplace(plain, v).first->second;
    }
    // Triangles per region cell (tris are in region order), and float boxes.
    std::vector<size_t> start(region.size() + 1, 0);
    for (size_t t = 0, r = 0; r < region.size(); ++r) {
        while (t < tris.size() && tris[t].cell == region[r]) ++t;
        start[r + 1] = t;
    }
    if (start.back() != tris.size()) throw std::logic_error("remesh: local check triangles out of region order");
    struct Box
    {
        glm::vec3 lo, hi;
        bool usable; ///< positions known
    };
    std::vector<Box> box(tris.size());
    std::vector<TrianglePlane> plane(tris.size()); // of the usable triangles
    // A triangle of non-zero area inside its cell's closed float box (as
    // nearly all are) meets one of a neighbouring cell's only on their
    // common face, edge or corner, where only the corners of each that lie
    // on it decide (trianglesCrossOnBoundary). Per such triangle, per
    // corner: the faces of the cell it lies on, bit 2 k (the face at the
    // cell's index on axis k) and 2 k + 1 (at index + 1).
    std::vector<std::array<uint8_t, 3>> onFaces(tris.size());
    std::vector<char> inBox(tris.size(), 0);
    std::vector<char> allInBox(region.size(), 1); // per region cell: every usable triangle inBox
    for (size_t r = 0; r < region.size(); ++r) {
        const Coord& c = region[r];
        const glm::vec3 face0 = worldPosition(volume, glm::dvec3(c.x(), c.y(), c.z()));
        const glm::vec3 face1 = worldPosition(volume, glm::dvec3(c.x() + 1, c.y() + 1, c.z() + 1));
        const glm::vec3 boxLo = glm::min(face0, face1), boxHi = glm::max(face0, face1);
        for (size_t t = start[r]; t < start[r + 1]; ++t) {
            const RegionTriangle& tr = tris[t];
            Box& b = box[t];
            b.usable = known[tr.v[0]] && known[tr.v[1]] && known[tr.v[2]];
            if (!b.usable) continue;
            const std::array<glm::vec3, 3> p{world[tr.v[0]], world[tr.v[1]], world[tr.v[2]]};
            b.lo = glm::min(p[0], glm::min(p[1], p[2]));
            b.hi = glm::max(p[0], glm::max(p[1], p[2]));
            plane[t] = trianglePlane(p);
            bool in = glm::all(glm::greaterThanEqual(b.lo, boxLo)) && glm::all(glm::lessThanEqual(b.hi, boxHi)) &&
                      hasArea(p, plane[t]);
            if (in)
                for (size_t k = 0; k < 3; ++k) {
                    const glm::vec3& x = p[k];
                    onFaces[t][k] = uint8_t(int(x.x == face0.x) | int(x.x == face1.x) << 1 | int(x.y == face0.y) << 2 |
                                            int(x.y == face1.y) << 3 | int(x.z == face0.z) << 4 | int(x.z == face1.z) << 5);
                }
            inBox[t] = in;
            if (!in) allInBox[r] = 0;
        }
    }
    // The common parts of a cell with its 26 neighbours by offset o, bit
    // partIndex(o) (13: the cell itself); per corner faces mask (onFaces),
    // the parts it lies on, and per triangle in its box their union.
    auto partIndex = [](int dx, int dy, int dz) { return (dx + 1) * 9 + (dy + 1) * 3 + (dz + 1); };
    constexpr int kSelf = 13;
    std::array<uint32_t, 64> partsOfCorner{};
    for (unsigned m = 0; m < 64; ++m) {
        int options[3][3], count[3];
        for (int k = 0; k < 3; ++k) {
            count[k] = 0;
            options[k][count[k]++] = 0;
            if (m >> (2 * k) & 1) options[k][count[k]++] = -1;
            if (m >> (2 * k + 1) & 1) options[k][count[k]++] = 1;
        }
        for (int x = 0; x < count[0]; ++x)
            for (int y = 0; y < count[1]; ++y)
                for (int z = 0; z < count[2]; ++z)
                    partsOfCorner[m] |= uint32_t(1) << partIndex(options[0][x], options[1][y], options[2][z]);
        partsOfCorner[m] &= ~(uint32_t(1) << kSelf);
    }
    std::vector<uint32_t> parts(tris.size(), 0);
    for (size_t t = 0; t < tris.size(); ++t)
        if (inBox[t]) parts[t] = partsOfCorner[onFaces[t][0]] | partsOfCorner[onFaces[t][1]] | partsOfCorner[onFaces[t][2]];
    // A triangle lies in its cell's closed box, rounded to float as the
    // vertices are (rounding is monotone), so a neighbour's triangles can
    // meet it only where its box reaches the common face, edge or corner:
    // within kSlack float steps of it, for the double rounding of points
    // computed on a cell face (and exactly there, for one in its box:
    // `parts`).
    constexpr int kSlack = 4;
    auto inward = [](glm::vec3 x, float to) { // kSlack float steps towards `to`, per axis
        for (int k = 0; k < 3; ++k)
            for (int i = 0; i < kSlack; ++i) x[k] = std::nextafter(x[k], to);
        return x;
    };
    struct Neighbour
    {
        size_t region = SIZE_MAX; ///< SIZE_MAX: none there
        bool changed = false;
    };
    // The first contact of changed cell r's triangles (with the pairs the
    // serial order gives it: a pair of changed cells' triangles belongs to
    // the lower triangle's cell), in that order: its triangles, and for each
    // the neighbours by offset (x, then y, then z), then theirs; None when
    // there is none.
    auto firstContact = [&](size_t r, std::array<Neighbour, 27>& around, size_t& ta, size_t& tb) -> Contact {
        const Coord& c = region[r];
        uint32_t present = 0, loose = 0; // neighbours there; those with triangles not in their box
        // (The region is sorted by x, then y, then z: the three cells of a
        // column (dx, dy) are consecutive when present.)
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy) {
                auto it = std::lower_bound(region.begin(), region.end(), c + Coord(dx, dy, -1));
                for (int dz = -1; dz <= 1; ++dz) {
                    const int p = partIndex(dx, dy, dz);
                    around[size_t(p)] = Neighbour();
                    if (it == region.end() || *it != c + Coord(dx, dy, dz)) continue;
                    const size_t at = size_t(it - region.begin());
                    around[size_t(p)] = {at, reg.cellChanged[at] != 0};
                    present |= uint32_t(1) << p;
                    if (!allInBox[at]) loose |= uint32_t(1) << p;
                    ++it;
                }
            }
        if (!reg.ownPairsClear.empty() && reg.ownPairsClear[r]) present &= ~(uint32_t(1) << kSelf); // (ownPairsClear)
        // The cell's faces, a few float steps inside.
        const glm::vec3 lo = worldPosition(volume, glm::dvec3(c.x(), c.y(), c.z()));
        const glm::vec3 hi = worldPosition(volume, glm::dvec3(c.x() + 1, c.y() + 1, c.z() + 1));
        const glm::vec3 nearLo = inward(lo, std::numeric_limits<float>::infinity());
        const glm::vec3 nearHi = inward(hi, -std::numeric_limits<float>::infinity());
        Contact found = Contact::None;
        for (size_t t = start[r]; t < start[r + 1]; ++t) {
            const Box& bt = box[t];
            if (!bt.usable) continue;
            const RegionTriangle& a = tris[t];
            bool reach[3][2]; // axis, (low, high) face
            for (int k = 0; k < 3; ++k) {
                reach[k][0] = bt.lo[k] <= nearLo[k];
                reach[k][1] = bt.hi[k] >= nearHi[k];
            }
            std::array<glm::vec3, 3> pa{world[a.v[0]], world[a.v[1]], world[a.v[2]]};
            std::array<uint32_t, 3> ia{vertex[a.v[0]], vertex[a.v[1]], vertex[a.v[2]]};
            // The neighbours to ask: for a triangle in its box, those whose
            // common part it has a corner on, and those with loose
            // triangles (its own cell too, when asked).
            uint32_t ask = inBox[t] ? present & (parts[t] | loose | (uint32_t(1) << kSelf)) : present;
            for (; ask; ask &= ask - 1) {
                const int p = __builtin_ctz(ask);
                const Neighbour& n = around[size_t(p)];
                const int offset[3] = {p / 9 - 1, p / 3 % 3 - 1, p % 3 - 1};
                bool needed = true;
                for (int k = 0; k < 3 && needed; ++k)
                    needed = offset[k] == 0 || reach[k][offset[k] > 0 ? 1 : 0];
                if (!needed) continue;
                // The common part's faces as each cell names them, the
                // corners of a on it, and axes spanning it (free ones first).
                const bool boundary = inBox[t] && p != kSelf;
                unsigned onA = 0, needA = 0, needB = 0;
                int axes[3] = {0, 1, 2};
                if (boundary) {
                    int free = 0, fixed = 2;
                    for (int k = 0; k < 3; ++k) {
                        const int o = offset[k];
                        if (o == 0) {
                            axes[free++] = k;
                            continue;
                        }
                        axes[fixed--] = k;
                        needA |= 1u << (2 * k + (o > 0));
                        needB |= 1u << (2 * k + (o < 0));
                    }
                    for (unsigned k = 0; k < 3; ++k) onA |= unsigned((onFaces[t][k] & needA) == needA) << k;
                }
                // A pair of changed cells' triangles once, from its lower triangle.
                const size_t from = n.changed ? std::max(start[n.region], t + 1) : start[n.region];
                auto meets = [&](size_t u) {
                    const Box& bu = box[u];
                    if (!bu.usable || (!a.cut && !tris[u].cut)) return false;
                    if (bt.hi.x < bu.lo.x || bu.hi.x < bt.lo.x || bt.hi.y < bu.lo.y || bu.hi.y < bt.lo.y ||
                        bt.hi.z < bu.lo.z || bu.hi.z < bt.lo.z)
                        return false;
                    const RegionTriangle& b = tris[u];
                    const std::array<glm::vec3, 3> pb{world[b.v[0]], world[b.v[1]], world[b.v[2]]};
                    const std::array<uint32_t, 3> ib{vertex[b.v[0]], vertex[b.v[1]], vertex[b.v[2]]};
                    std::optional<Contact> quick;
                    if (boundary && inBox[u]) {
                        unsigned onB = 0;
                        for (unsigned k = 0; k < 3; ++k) onB |= unsigned((onFaces[u][k] & needB) == needB) << k;
                        quick = trianglesCrossOnBoundary(pa, ia, onA, pb, ib, onB, axes[0], axes[1]);
                    }
                    found = quick ? *quick : trianglesCross(pa, ia, plane[t], pb, ib, plane[u]);
                    if (found == Contact::None) return false;
                    ta = t;
                    tb = u;
                    return true;
                };
                // In their boxes, two triangles meet only on the common part,
                // where each needs a corner.
                const int partB = 26 - p; // the part as the neighbour sees it
                for (size_t u = from; u < start[n.region + 1]; ++u) {
                    if (boundary && inBox[u] && (onA == 0 || !(parts[u] >> partB & 1))) continue;
                    if (meets(u)) return found;
                }
            }
        }
        return Contact::None;
    };
    // The changed cells with triangles, in region order; the refusal names
    // the first of them with a contact, whether they are checked in order on
    // this thread or in parallel (a step's few dozen cells: the test is a
    // quarter of a step at kerf 0.5 on the VHM head).
    std::vector<size_t> toCheck;
    for (size_t r = 0; r < region.size(); ++r)
        if (reg.cellChanged[r] && start[r] != start[r + 1]) toCheck.push_back(r);
    size_t failed = SIZE_MAX; // index into toCheck
    Contact contact = Contact::None;
    size_t ta = 0, tb = 0;
    const size_t threads = threadsAllowed();
    if (threads > 1 && toCheck.size() >= 8 && !reg.debug) {
        std::atomic<size_t> first{SIZE_MAX};
        tbb::parallel_for(tbb::blocked_range<size_t>(0, toCheck.size(), 2), [&](const tbb::blocked_range<size_t>& range) {
            std::array<Neighbour, 27> around;
            for (size_t i = range.begin(); i != range.end(); ++i) {
                if (i > first.load(std::memory_order_relaxed)) return; // a lower cell has failed already
                size_t x, y;
                if (firstContact(toCheck[i], around, x, y) == Contact::None) continue;
                size_t seen = first.load(std::memory_order_relaxed);
                while (i < seen && !first.compare_exchange_weak(seen, i, std::memory_order_relaxed)) {
                }
                return;
            }
        });
        failed = first.load();
        std::array<Neighbour, 27> around;
        if (failed != SIZE_MAX) contact = firstContact(toCheck[failed], around, ta, tb);
    } else {
        std::array<Neighbour, 27> around;
        for (size_t i = 0; i < toCheck.size() && failed == SIZE_MAX; ++i)
            if ((contact = firstContact(toCheck[i], around, ta, tb)) != Contact::None) failed = i;
    }
    if (failed == SIZE_MAX) return;
    const RegionTriangle& a = tris[ta];
    const RegionTriangle& b = tris[tb];
    if (reg.debug) {
        std::fprintf(stderr, "self-contact (%s), cells (%d,%d,%d) and (%d,%d,%d):\n",
                     contact == Contact::Intersect ? "exact" : "undecided", a.cell.x(), a.cell.y(), a.cell.z(),
                     b.cell.x(), b.cell.y(), b.cell.z());
        for (uint32_t v : a.v) describeVertex(reg, v);
        for (uint32_t v : b.v) describeVertex(reg, v);
    }
    throw std::runtime_error(std::string("remesh: the surface crosses or touches itself (two triangles meet in float mm") +
                             (contact == Contact::Undecided ? ", or the exact test cannot decide" : "") +
                             "; the cut has a width) in cell " + cellText(region[toCheck[failed]]));
}

/// Snap rounding, as fusedMesh() does it: an edge from a marching-tetrahedra
/// vertex along its grid edge used twice each way and shorter than two float
/// steps (remesh_detail::joinsAlongGridEdge) has its ends joined into the
/// iso vertex, two vertices of faces round a cube edge both rounded to
/// within two float steps of it and of each other (joinsRoundCubeEdge) are
/// one, at the lower name's position, names joined by an edge at one float
/// position are one vertex (the lowest name; the iso vertex, as fusedMesh
/// keeps the uncut one), then an edge from a vertex inside a tet face to
/// another of the closed face used twice each way and shorter than
/// kFloatStepsPinch float steps (joinsPinchInFace) has its ends joined into
/// the latter, and the triangles that collapse are dropped.
void snapRound(const vdb::Volume& volume, LocalRegion& reg)
{
    const std::vector<CutVertexId>& ids = reg.ids;
    std::vector<Tri>& tris = reg.tris;
    std::vector<glm::vec3>& world = reg.world;
    const std::vector<char>& known = reg.known;
    std::vector<uint32_t> rep(ids.size());
    for (size_t v = 0; v < rep.size(); ++v) rep[v] = uint32_t(v);
    auto find = [&](uint32_t x) {
        uint32_t r = x;
        while (rep[r] != r) r = rep[r];
        while (rep[x] != r) x = std::exchange(rep[x], r);
        return r;
    };
    // Only the edges a few float steps long can be joined
    // (remesh_detail::snapLookSq): all the uses of each, in triangle order.
    std::vector<std::array<uint32_t, 2>> shortEdges;
    {
        Coord cell;
        float lookSq = -1.0f;
        for (const Tri& tr : tris) {
            if (lookSq < 0.0f || tr.cell != cell) {
                cell = tr.cell;
                lookSq = remesh_detail::snapLookSq(cell, volume.origin(), volume.spacing());
            }
            for (int k = 0; k < 3; ++k) {
                const uint32_t a = tr.v[k], b = tr.v[(k + 1) % 3];
                const glm::vec3 d = world[a] - world[b];
                if (known[a] && known[b] && glm::dot(d, d) < lookSq) shortEdges.push_back({a, b});
            }
        }
    }
    // Edges along a grid edge from its iso vertex: (iso, other, direction).
    std::vector<std::array<uint32_t, 3>> along;
    for (const auto& [a, b] : shortEdges) {
        const CutVertexId &ia = ids[a], &ib = ids[b];
        if (ia.dim != 1 || ib.dim != 1 || ia.feature[0] != ib.feature[0] || ia.feature[1] != ib.feature[1] ||
            ia.isIsoEdgeVertex() == ib.isIsoEdgeVertex())
            continue;
        along.push_back(ia.isIsoEdgeVertex() ? std::array<uint32_t, 3>{a, b, 0} : std::array<uint32_t, 3>{b, a, 1});
    }
    std::sort(along.begin(), along.end());
    for (size_t i = 0, j = 0; i < along.size(); i = j) {
        size_t each[2] = {0, 0};
        for (j = i; j < along.size() && along[j][0] == along[i][0] && along[j][1] == along[i][1]; ++j) ++each[along[j][2]];
        const uint32_t iso = along[i][0], other = along[i][1];
        if (each[0] != 2 || each[1] != 2 ||
            !remesh_detail::joinsAlongGridEdge(ids[iso], ids[other], world[iso], world[other], volume.origin(),
                                               volume.spacing()))
            continue;
        rep[find(other)] = find(iso);
    }
    // Two vertices of faces round a cube edge (joinsRoundCubeEdge): one, at
    // the lower name's position.
    for (auto [a, b] : shortEdges) {
        if (ids[a].dim != 2 || ids[b].dim != 2) continue;
        if (ids[b] < ids[a]) std::swap(a, b);
        if (!remesh_detail::joinsRoundCubeEdge(ids[a], ids[b], world[a], world[b], volume.origin(), volume.spacing()))
            continue;
        world[b] = world[a];
        const uint32_t ra = find(a), rb = find(b);
        if (ra != rb) rep[std::max(ra, rb)] = std::min(ra, rb);
    }
    for (const auto& [a, b] : shortEdges) {
        if (a == b || !(world[a] == world[b])) continue;
        const uint32_t ra = find(a), rb = find(b);
        if (ra == rb) continue;
        // The group's iso vertex stays its root (fusedMesh keeps the uncut vertex).
        const bool isoA = ids[ra].isIsoEdgeVertex(), isoB = ids[rb].isIsoEdgeVertex();
        if (isoA != isoB) rep[isoA ? rb : ra] = isoA ? ra : rb;
        else rep[std::max(ra, rb)] = std::min(ra, rb);
    }
    // Edges from a vertex inside a tet face to another of the closed face
    // used twice each way once the rules above have joined their names
    // (joinsPinchInFace; tooth, seed 9273: two of the four uses end at a
    // blade vertex of the face's diagonal at the iso vertex's float point):
    // one vertex, the kept one's (the group's root: an iso vertex stays it,
    // as fusedMesh keeps the uncut vertex).
    struct InFace
    {
        uint32_t keep, other, dir; // roots; the use's direction
        uint32_t keepName, otherName;
        bool operator<(const InFace& o) const { return std::tie(keep, other, dir) < std::tie(o.keep, o.other, o.dir); }
    };
    std::vector<InFace> inFace;
    for (const auto& [a, b] : shortEdges) {
        if (ids[a].dim != 2 && ids[b].dim != 2) continue;
        if (remesh_detail::pinchInFaceCandidate(ids[a], ids[b])) inFace.push_back({find(a), find(b), 0, a, b});
        else if (remesh_detail::pinchInFaceCandidate(ids[b], ids[a])) inFace.push_back({find(b), find(a), 1, b, a});
    }
    std::sort(inFace.begin(), inFace.end());
    for (size_t i = 0, j = 0; i < inFace.size(); i = j) {
        size_t each[2] = {0, 0};
        for (j = i; j < inFace.size() && inFace[j].keep == inFace[i].keep && inFace[j].other == inFace[i].other; ++j)
            ++each[inFace[j].dir];
        const InFace& e = inFace[i];
        if (each[0] != 2 || each[1] != 2 || e.keep == e.other ||
            !remesh_detail::joinsPinchInFace(ids[e.keepName], ids[e.otherName], world[e.keep], world[e.other],
                                             volume.origin(), volume.spacing()))
            continue;
        world[e.other] = world[e.keep];
        const uint32_t ra = find(e.keep), rb = find(e.other);
        if (ra == rb) continue;
        if (ids[rb].isIsoEdgeVertex() && !ids[ra].isIsoEdgeVertex()) rep[ra] = rb;
        else rep[rb] = ra;
    }
    reg.joined.clear();
    for (uint32_t v = 0; v < uint32_t(rep.size()); ++v)
        if (find(v) != v) reg.joined.push_back({find(v), v});
    std::sort(reg.joined.begin(), reg.joined.end());
    // The cut cells' triangles that become cancelling pairs go, as in
    // fusedMesh (only where snap rounding joined something, or the float
    // repair put a triangle into a cell face).
    std::vector<std::array<uint32_t, 3>> cutTris, before;
    std::vector<char> intoFace;
    std::vector<size_t> cutAt;
    for (size_t t = 0; t < tris.size() && (!reg.joined.empty() || reg.anyIntoFace); ++t) {
        if (!tris[t].cut) continue;
        before.push_back({tris[t].v[0], tris[t].v[1], tris[t].v[2]});
        cutTris.push_back({find(tris[t].v[0]), find(tris[t].v[1]), find(tris[t].v[2])});
        intoFace.push_back(tris[t].intoFace);
        cutAt.push_back(t);
    }
    std::vector<char> cancelled, drop(tris.size(), 0);
    remesh_detail::markCancellingPairs(cutTris, before, intoFace, cancelled);
    for (size_t i = 0; i < cutAt.size(); ++i) drop[cutAt[i]] = cancelled[i];
    std::vector<Tri> kept;
    for (size_t t = 0; t < tris.size(); ++t) {
        Tri tr = tris[t];
        for (uint32_t& v : tr.v) v = find(v);
        if (tr.v[0] == tr.v[1] || tr.v[1] == tr.v[2] || tr.v[0] == tr.v[2] || drop[t]) continue;
        kept.push_back(tr);
    }
    tris.swap(kept);
}

/// Every edge that a changed cell's closed box holds is used once each way.
void checkEdgeUses(const LocalRegion& reg)
{
    const std::vector<Tri>& tris = reg.tris;
    const std::vector<CutVertexId>& ids = reg.ids;
    const std::vector<Coord>& changed = *reg.changed;
    auto isChanged = [&](const Coord& c) { return reg.isChanged(c); };
    auto fail = [&](const std::string& what, const Coord& c) { reg.fail(what, c); };
    auto desc = [&](uint32_t v) { describeVertex(reg, v); };
    const bool debug = reg.debug;
    // Directed edge uses; an edge matters when a changed cell's closed box holds it
    // (then every triangle that can use it is in the region). A vertex is
    // held where any name snapRound joined into it is (2 mm head, kerf 0,
    // seed 7039, an update half-way through a stroke: the blade's names on
    // two cube edges that meet at a grid vertex, both snapped onto it
    // (snapToGridVertices), are one vertex, and an unchanged cell that holds
    // only the second name's edge used an edge of it; that use was not
    // counted, and the edge looked open).
    // (Each vertex's cells once: a vertex is on about six edge uses.)
    std::vector<std::array<Coord, 2>> holding(ids.size());
    std::vector<char> held(ids.size(), 0);
    auto holdingOf = [&](uint32_t v) -> const std::array<Coord, 2>& {
        if (!held[v]) {
            reg.holding(v, holding[v][0], holding[v][1]);
            held[v] = 1;
        }
        return holding[v];
    };
    auto matters = [&](uint32_t a, uint32_t b, bool ofChangedCell) {
        if (ofChangedCell) return true;
        const Coord &la = holdingOf(a)[0], &ha = holdingOf(a)[1];
        const Coord &lb = holdingOf(b)[0], &hb = holdingOf(b)[1];
        Coord lo, hi;
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::max(la[k], lb[k]);
            hi[k] = std::min(ha[k], hb[k]);
            if (lo[k] > hi[k]) return false;
        }
        for (int x = lo.x(); x <= hi.x(); ++x)
            for (int y = lo.y(); y <= hi.y(); ++y)
                for (int z = lo.z(); z <= hi.z(); ++z)
                    if (isChanged(Coord(x, y, z))) return true;
        return false;
    };
    // Per use that matters, in triangle order: (undirected edge, direction,
    // triangle); per edge, its uses each way (an open-addressing table over
    // the edges, sized at most half full). An edge is fine when it is used
    // once each way; the one reported is the failing edge used first in
    // triangle order. (In place of sorting the uses by edge: the sort was
    // most of this check.)
    struct Use
    {
        uint64_t edge; ///< min vertex << 32 | max vertex
        uint32_t dir;  ///< 0: from the lower vertex to the higher, 1: back
        uint32_t tri;
    };
    std::vector<Use> uses;
    for (size_t t = 0; t < tris.size(); ++t) {
        const Tri& tr = tris[t];
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = tr.v[k], b = tr.v[(k + 1) % 3];
            if (!matters(a, b, tr.changed)) continue;
            const uint64_t edge = uint64_t(std::min(a, b)) << 32 | std::max(a, b);
            uses.push_back({edge, a < b ? 0u : 1u, uint32_t(t)});
        }
    }
    struct Slot
    {
        uint64_t edge = UINT64_MAX; ///< UINT64_MAX: empty (vertex numbers are below UINT32_MAX)
        uint32_t count[2] = {0, 0};
    };
    size_t size = 64;
    while (size < 2 * uses.size()) size *= 2;
    std::vector<Slot> table(size);
    std::vector<uint32_t> slotOf(uses.size());
    const size_t mask = size - 1;
    for (size_t i = 0; i < uses.size(); ++i) {
        const uint64_t e = uses[i].edge;
        uint64_t h = e * 0x9e3779b97f4a7c15ull;
        size_t at = size_t(h ^ (h >> 29)) & mask;
        while (table[at].edge != UINT64_MAX && table[at].edge != e) at = (at + 1) & mask;
        table[at].edge = e;
        ++table[at].count[uses[i].dir];
        slotOf[i] = uint32_t(at);
    }
    struct Uses
    {
        uint32_t count = 0, triangle = 0; ///< uses, and the first one's triangle
    };
    size_t failOrder = SIZE_MAX; // the failing edge's first use
    for (size_t i = 0; i < uses.size() && failOrder == SIZE_MAX; ++i) {
        const Slot& s = table[slotOf[i]];
        if (!(s.count[0] == 1 && s.count[1] == 1)) failOrder = i;
    }
    if (failOrder != SIZE_MAX) {
        // The first use's direction is "one way"; each direction's count and first triangle.
        Uses way[2];
        const uint64_t failEdge = uses[failOrder].edge;
        const uint32_t firstDir = uses[failOrder].dir;
        for (size_t i = failOrder; i < uses.size(); ++i) {
            if (uses[i].edge != failEdge) continue;
            Uses& w = way[uses[i].dir];
            if (w.count++ == 0) w.triangle = uses[i].tri;
        }
        const Uses u = way[firstDir], r = way[1 - firstDir];
        const uint32_t lo = uint32_t(failEdge >> 32), hi = uint32_t(failEdge);
        const uint64_t key = firstDir == 0 ? uint64_t(lo) << 32 | hi : uint64_t(hi) << 32 | lo;
        const uint32_t back = r.count;
        // Name a changed cell: the triangle's own, else a changed cell holding the edge.
        Coord cell = tris[u.triangle].cell;
        if (!isChanged(cell) && r.count && isChanged(tris[r.triangle].cell)) cell = tris[r.triangle].cell;
        if (!isChanged(cell)) {
            Coord la, ha, lb, hb;
            reg.holding(uint32_t(key >> 32), la, ha);
            reg.holding(uint32_t(key), lb, hb);
            for (const Coord& c : changed) {
                bool in = true;
                for (int k = 0; k < 3; ++k) in = in && std::max(la[k], lb[k]) <= c[k] && c[k] <= std::min(ha[k], hb[k]);
                if (in) {
                    cell = c;
                    break;
                }
            }
        }
        if (debug) {
            std::fprintf(stderr, "open edge, triangle cell (%d,%d,%d):\n", tris[u.triangle].cell.x(), tris[u.triangle].cell.y(), tris[u.triangle].cell.z());
            desc(uint32_t(key >> 32));
            desc(uint32_t(key));
            std::set<uint32_t> around; // the vertices of the triangles at either end
            for (const Tri& tr : tris) {
                if (std::none_of(tr.v, tr.v + 3, [&](uint32_t v) { return v == uint32_t(key >> 32) || v == uint32_t(key); }))
                    continue;
                std::fprintf(stderr, "   tri cell (%d,%d,%d): %u %u %u\n", tr.cell.x(), tr.cell.y(), tr.cell.z(), tr.v[0],
                             tr.v[1], tr.v[2]);
                around.insert(tr.v, tr.v + 3);
            }
            for (uint32_t v : around) desc(v);
        }
        std::ostringstream os;
        os << "an edge used " << u.count << " time(s) one way and " << back << " the other";
        fail(os.str(), cell);
    }
}

/// Every vertex of a changed cell's triangles has one fan (a disc): all the
/// triangles that can use it are in the region.
void checkVertexLinks(const LocalRegion& reg)
{
    const std::vector<Tri>& tris = reg.tris;
    const std::vector<CutVertexId>& ids = reg.ids;
    const std::vector<Coord>& changed = *reg.changed;
    auto fail = [&](const std::string& what, const Coord& c) { reg.fail(what, c); };
    auto desc = [&](uint32_t v) { describeVertex(reg, v); };
    const bool debug = reg.debug;
    // Links (the edge opposite each corner), per vertex ascending, each in
    // triangle order.
    std::vector<char> ofChanged(ids.size(), 0);
    for (const Tri& tr : tris)
        if (tr.changed)
            for (uint32_t v : tr.v) ofChanged[v] = 1;
    // (A counting sort by vertex: names are dense, and it keeps triangle order.)
    std::vector<uint32_t> linkStart(ids.size() + 1, 0);
    for (const Tri& tr : tris)
        for (uint32_t v : tr.v)
            if (ofChanged[v]) ++linkStart[v + 1];
    for (size_t v = 0; v < ids.size(); ++v) linkStart[v + 1] += linkStart[v];
    std::vector<std::pair<uint32_t, uint32_t>> linkEdges(linkStart.back());
    {
        std::vector<uint32_t> fill(linkStart.begin(), linkStart.end() - 1);
        for (const Tri& tr : tris)
            for (int k = 0; k < 3; ++k)
                if (ofChanged[tr.v[k]]) linkEdges[fill[tr.v[k]]++] = {tr.v[(k + 1) % 3], tr.v[(k + 2) % 3]};
    }
    std::vector<std::pair<uint32_t, uint32_t>> link;
    for (uint32_t v = 0; v < uint32_t(ids.size()); ++v) {
        if (linkStart[v] == linkStart[v + 1]) continue;
        link.assign(linkEdges.begin() + linkStart[v], linkEdges.begin() + linkStart[v + 1]);
        size_t steps = 0;
        uint32_t at = link[0].second;
        while (steps < link.size()) {
            auto next = std::find_if(link.begin(), link.end(), [&](const auto& e) { return e.first == at; });
            if (next == link.end()) break;
            at = next->second;
            ++steps;
            if (at == link[0].second) break;
        }
        if (steps == link.size()) continue;
        // Fans that are each a closed disc are a pinch that fusedMesh()
        // splits (a copy of the vertex per fan but the first): at a new
        // vertex, or at a marching-tetrahedra vertex that only cut cells'
        // triangles use (all the cells round its grid edge are cut; the
        // region holds them all). With kerf or without: at kerf 0 three slits
        // of a stroke turning sharply cut out a cone that touches the rest
        // at its tip (2 mm head, random strokes seed 18088 with sharp turns).
        std::vector<int> fanOf;
        if (linkFans(link, fanOf) >= 2) {
            bool split = !ids[v].isIsoEdgeVertex();
            if (!split) {
                split = true;
                for (const Tri& tr : tris)
                    if (!tr.cut && (tr.v[0] == v || tr.v[1] == v || tr.v[2] == v)) split = false;
            }
            if (split) continue;
        }
        Coord lo, hi;
        reg.holding(v, lo, hi);
        Coord cell = changed.front();
        for (const Coord& c : changed)
            if (lo.x() <= c.x() && c.x() <= hi.x() && lo.y() <= c.y() && c.y() <= hi.y() && lo.z() <= c.z() &&
                c.z() <= hi.z()) {
                cell = c;
                break;
            }
        if (debug) {
            std::fprintf(stderr, "pinch at:\n");
            desc(v);
            std::set<uint32_t> seen;
            for (const auto& e : link) {
                std::fprintf(stderr, "   link edge %u -> %u\n", e.first, e.second);
                for (uint32_t u : {e.first, e.second})
                    if (seen.insert(u).second) desc(u);
            }
        }
        fail("a vertex where the surface pinches: not a 2-manifold", cell);
    }
}

/// No triangle of a changed cell is degenerate in float world mm.
void checkFloatArea(const LocalRegion& reg)
{
    const std::vector<Tri>& tris = reg.tris;
    const std::vector<glm::vec3>& world = reg.world;
    const std::vector<char>& known = reg.known;
    auto fail = [&](const std::string& what, const Coord& c) { reg.fail(what, c); };
    auto desc = [&](uint32_t v) { describeVertex(reg, v); };
    const bool debug = reg.debug;
    for (const Tri& tr : tris) {
        if (!tr.changed || !tr.cut) continue;
        if (!known[tr.v[0]] || !known[tr.v[1]] || !known[tr.v[2]]) continue;
        const glm::dvec3 a(world[tr.v[0]]), b(world[tr.v[1]]), c(world[tr.v[2]]);
        const glm::dvec3 n = glm::cross(b - a, c - a);
        if (n.x == 0.0 && n.y == 0.0 && n.z == 0.0) {
            if (debug) {
                std::fprintf(stderr, "zero-area triangle, cell (%d,%d,%d):\n", tr.cell.x(), tr.cell.y(), tr.cell.z());
                for (uint32_t v : tr.v) desc(v);
                for (const Tri& o : tris) {
                    int shared = 0;
                    for (uint32_t v : o.v) shared += v == tr.v[0] || v == tr.v[1] || v == tr.v[2];
                    if (shared >= 2) std::fprintf(stderr, "   neighbour cell (%d,%d,%d): %u %u %u\n", o.cell.x(), o.cell.y(), o.cell.z(), o.v[0], o.v[1], o.v[2]);
                }
            }
            fail("a triangle of zero area in float mm", tr.cell);
        }
    }
}

} // namespace

void CutRemesher::checkLocally(const std::vector<Coord>& changed, bool kerf) const
{
    // Each check is local to a changed cell's neighbourhood (the region holds
    // every triangle that can use its edges and vertices, and every triangle
    // that can meet its triangles), so a chunk of the changed cells checked
    // over its own region gives that chunk's verdict. Many changed cells (a
    // whole cut, a kerf change) are checked in chunks in parallel; only when a
    // chunk fails is the whole set checked again on this thread, so the
    // refusal names the cell a serial check names.
    constexpr size_t kChunk = 1024;
    const size_t threads = threadsAllowed();
    mLastCheckChunks = 0;
    if (threads > 1 && changed.size() >= 2 * kChunk && !std::getenv("MTCUT_REMESH_DEBUG")) {
        const size_t chunks = (changed.size() + kChunk - 1) / kChunk;
        mLastCheckChunks = chunks;
        std::atomic<bool> failed{false};
        tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
            if (failed.load(std::memory_order_relaxed)) return;
            const std::vector<Coord> part(changed.begin() + std::ptrdiff_t(c * kChunk),
                                          changed.begin() + std::ptrdiff_t(std::min(changed.size(), (c + 1) * kChunk)));
            try {
                checkRegion(part, kerf);
            } catch (const std::exception&) {
                failed.store(true, std::memory_order_relaxed);
            }
        });
        if (!failed) return;
    }
    checkRegion(changed, kerf);
}

void CutRemesher::checkRegion(const std::vector<Coord>& changed, bool kerf) const
{
    if (changed.empty()) return;
    LocalRegion reg;
    reg.changed = &changed;
    // The triangles of the changed cells and of their 26 neighbours, over
    // vertex names (the fused mesh's identity: iso edge vertices by edge).
    reg.cells = dilatedCells(changed);
    const std::vector<Coord>& region = reg.cells;
    reg.indexChanged();
    // Plain marching-tetrahedra vertices (most of them) by their grid edge,
    // the others by their whole name; one numbering, in order of first use.
    NameIndex edgeNames; // (lower, upper grid vertex) of a plain marching-tetrahedra vertex
    auto& names = reg.names;
    std::vector<CutVertexId>& ids = reg.ids;
    auto edgeHash = [](const std::pair<uint64_t, uint64_t>& e) {
        return e.first * 0x9e3779b97f4a7c15ull ^ (e.second + 0x632be59bd9b4e019ull);
    };
    auto sameEdge = [&](const std::pair<uint64_t, uint64_t>& e) {
        return [&ids, &e](uint32_t n) { return ids[n].feature[0] == e.first && ids[n].feature[1] == e.second; };
    };
    auto edgeNameOf = [&](const std::pair<uint64_t, uint64_t>& e) {
        bool added = false;
        const uint32_t n = edgeNames.findOrAdd(edgeHash(e), uint32_t(ids.size()), added, sameEdge(e));
        if (added) ids.push_back(isoEdgeVertex(e));
        return n;
    };
    auto nameOf = [&](const CutVertexId& id) {
        if (id.isIsoEdgeVertex()) return edgeNameOf({id.feature[0], id.feature[1]});
        bool added = false;
        const uint32_t n = names.findOrAdd(CutVertexIdHash()(id), uint32_t(ids.size()), added,
                                           [&](uint32_t k) { return ids[k] == id; });
        if (added) ids.push_back(id);
        return n;
    };
    using Tri = RegionTriangle;
    std::vector<Tri>& tris = reg.tris;
    // Per region cell: its cut geometry (or null), its uncut triangles' run
    // and their corners' grid edges (cornerStart[i] .. cornerStart[i + 1]).
    std::vector<const CutCellGeometry*> cutOf(region.size(), nullptr);
    std::vector<std::pair<uint32_t, uint32_t>> runOf(region.size());
    std::vector<size_t> cornerStart(region.size() + 1, 0);
    std::vector<std::pair<uint64_t, uint64_t>> corners, cellCorners;
    size_t cutVertices = 0, cutTriangles = 0, uncutTriangles = 0;
    {
        UncutAccessor uncutAcc(mUncutFirst);
        for (size_t i = 0; i < region.size(); ++i) {
            auto cut = mCells.find(region[i]);
            if (cut != mCells.end()) {
                cutOf[i] = &cut->second;
                cutVertices += cut->second.vertexIds.size();
                cutTriangles += cut->second.indices.size() / 3;
            }
            runOf[i] = uncutRun(uncutAcc, region[i]);
            uncutTriangles += runOf[i].second;
        }
        // The tables at about their full size at once (a name of the uncut
        // mesh is shared by about six triangles).
        corners.reserve(3 * uncutTriangles);
        ids.reserve(cutVertices + uncutTriangles);
        tris.reserve(cutTriangles + uncutTriangles);
        VolumeAccessor volumeAcc(mVolume->grid->tree());
        for (size_t i = 0; i < region.size(); ++i) {
            const Coord& c = region[i];
            uncutCornerEdges(volumeAcc, c, runOf[i], cellCorners);
            corners.insert(corners.end(), cellCorners.begin(), cellCorners.end());
            cornerStart[i + 1] = corners.size();
        }
    }
    // The names of each cut cell's vertices: localNames[localStart[i] ..].
    std::vector<uint32_t> localNames;
    localNames.reserve(cutVertices);
    std::vector<size_t> localStart(region.size() + 1, 0);
    for (size_t i = 0; i < region.size(); ++i) {
        const Coord& c = region[i];
        if (cutOf[i]) {
            const CutCellGeometry& g = *cutOf[i];
            const size_t base = localNames.size();
            for (const CutVertexId& id : g.vertexIds) localNames.push_back(nameOf(id));
            const uint32_t* local = localNames.data() + base;
            auto face = g.intoFace.begin();
            for (size_t k = 0; k + 2 < g.indices.size(); k += 3) {
                tris.push_back({{local[g.indices[k]], local[g.indices[k + 1]], local[g.indices[k + 2]]}, c, true,
                                reg.cellChanged[i] != 0});
                if (face != g.intoFace.end() && *face == k / 3) {
                    tris.back().intoFace = true;
                    reg.anyIntoFace = true;
                    ++face;
                }
            }
        } else {
            for (size_t k = cornerStart[i]; k + 2 < cornerStart[i + 1]; k += 3)
                tris.push_back({{edgeNameOf(corners[k]), edgeNameOf(corners[k + 1]), edgeNameOf(corners[k + 2])}, c,
                                false, reg.cellChanged[i] != 0});
        }
        localStart[i + 1] = localNames.size();
    }
    for (const Tri& tr : tris)
        if (tr.changed && (tr.v[0] == tr.v[1] || tr.v[1] == tr.v[2] || tr.v[0] == tr.v[2]))
            reg.fail("a triangle repeats a vertex", tr.cell);
    // Float world positions as fusedMesh() gives them (iso edge vertices: the
    // uncut mesh's; a new vertex: from the first cell, ascending, that makes
    // it), then its snap rounding.
    // Held as float, as written: GCC 12.2's SLP vectoriser folded the
    // round trip double(float(x)) of two lanes away when these were
    // dvec3(vec3(float(..), ..)), so the check judged unrounded positions
    // and let two float-degenerate triangles through (seed 1021).
    std::vector<glm::vec3>& world = reg.world;
    world.assign(ids.size(), glm::vec3(std::numeric_limits<float>::quiet_NaN()));
    std::vector<char>& known = reg.known;
    known.assign(ids.size(), 0);
    for (size_t i = 0; i < region.size(); ++i) {
        for (size_t k = cornerStart[i]; k < cornerStart[i + 1]; ++k) {
            const uint32_t vertex = mUncut.indices[3 * size_t(runOf[i].first) + (k - cornerStart[i])];
            const uint32_t n = edgeNames.find(edgeHash(corners[k]), sameEdge(corners[k]));
            if (n != NameIndex::kNone && !known[n]) {
                world[n] = mUncut.positions[vertex];
                known[n] = 1;
            }
        }
        if (!cutOf[i]) continue;
        const CutCellGeometry& g = *cutOf[i];
        for (size_t v = 0; v < g.vertexIds.size(); ++v) {
            const uint32_t name = localNames[localStart[i] + v];
            if (known[name] || g.vertexIds[v].isIsoEdgeVertex()) continue;
            world[name] = worldPosition(*mVolume, g.indexPositions[v]);
            known[name] = 1;
        }
    }
    snapRound(*mVolume, reg);
    if (kerf) {
        // The float repair asked the pairs of a crossFree cell's triangles
        // at these float points with these vertices (trianglesCross, the
        // pinch copies of a name one vertex); where snap rounding joined or
        // moved none of the cell's vertices, the self-contact test would ask
        // the same again (nearly half its pairs in a haptic step).
        std::vector<char> joinedName(ids.size(), 0);
        for (const auto& [root, v] : reg.joined) joinedName[root] = joinedName[v] = 1;
        reg.ownPairsClear.assign(region.size(), 0);
        for (size_t i = 0; i < region.size(); ++i) {
            if (!reg.cellChanged[i] || !cutOf[i] || !cutOf[i]->crossFree) continue;
            const CutCellGeometry& g = *cutOf[i];
            bool same = true;
            for (size_t v = 0; v < g.vertexIds.size() && same; ++v) {
                const uint32_t name = localNames[localStart[i] + v];
                const glm::vec3 at = worldPosition(*mVolume, g.indexPositions[v]);
                same = !joinedName[name] && known[name] && world[name].x == at.x && world[name].y == at.y &&
                       world[name].z == at.z;
            }
            reg.ownPairsClear[i] = same;
        }
    }
    reg.debug = std::getenv("MTCUT_REMESH_DEBUG") != nullptr;
    reg.kerf = kerf;
    auto closedManifold = [&] {
        checkEdgeUses(reg);
        checkVertexLinks(reg);
        checkFloatArea(reg);
    };
    // With kerf the surface neither crosses nor touches itself (two triangles
    // on the same three float points, where a removed sliver thinner than a
    // float step rounded its two faces onto each other: 1 mm head, kerf 1,
    // random strokes seed 3015; two sheets 4e-6 mm apart that cross once
    // rounded: the tooth, kerf 2, seed 3016). At kerf 0 the two sides of the
    // cut lie on each other by design.
    if (!kerf || reg.debug || threadsAllowed() < 2) {
        closedManifold();
        if (kerf) refuseSelfContact(*mVolume, reg);
        return;
    }
    // Both read the region only, so the self-contact test (two thirds of the
    // check, itself parallel over the changed cells) runs beside the other
    // three; a failure is reported as the order above reports it. (The three
    // split further measured slower on two threads.)
    std::exception_ptr manifoldError, contactError;
    tbb::parallel_invoke(
        [&] {
            try {
                closedManifold();
            } catch (...) {
                manifoldError = std::current_exception();
            }
        },
        [&] {
            try {
                refuseSelfContact(*mVolume, reg);
            } catch (...) {
                contactError = std::current_exception();
            }
        });
    if (manifoldError) std::rethrow_exception(manifoldError);
    if (contactError) std::rethrow_exception(contactError);
}

} // namespace mtcut::cutter
