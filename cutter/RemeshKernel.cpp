// The per-cell re-meshing kernel (DESIGN invariants 2 and 5-10): per tet
// of the cell, the arrangement of the isosurface pieces and the blade's
// planes, classified, merged into regions and triangulated; vertices named by
// their planes (CutVertexId) so neighbouring cells and tets weld by name.
// The front end (Remesh.cpp) builds the quads' geometry and calls it.
#include "cutter/RemeshKernel.h"

#include "cutter/FloatRepair.h"

#include "cutter/Isosurface.h"
#include "cutter/Polygon2.h"
#include "cutter/TriangleIntersect.h"

#include <boost/container/small_vector.hpp>

#include <algorithm>
#include <cassert>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace mtcut::cutter::remesh_detail {

namespace {

constexpr uint64_t kIsoA = 2, kIsoB = 3;
constexpr uint64_t kMid = 4;      ///< marks a Steiner midpoint of a slit chord between two rim points
constexpr uint64_t kCentroid = 5; ///< marks the Steiner centre of a cap region
double epsAt(const dvec3& x)
{
    return 1e-13 * (1.0 + std::max({std::abs(x.x), std::abs(x.y), std::abs(x.z)}));
}

/// A Steiner midpoint's name holds a word for each end of its chord: a hash
/// of the end's name, top bit clear and bit 62 set (above every plane id),
/// so the name is the same in every cell that closes the chord. Each word
/// is mixed through all of the name (mixBits, per field):
/// CutVertexIdHash, a hash-table hash, differs only in its low bits for two
/// names that differ in the kind of one plane (a quad's plane and its rim
/// side), and those bits were shifted out, so two chords of one quad that
/// share an end got one midpoint name and one vertex (2 mm head, kerf 0,
/// sawing along the blade, seed 75101: a cap piece folded over itself, "open
/// boundary loop"). As midpointWord in cut_arrange.glsl.
uint64_t midpointWord(const CutVertexId& key)
{
    uint64_t h = mixBits(0x9e3779b97f4a7c15ull ^ (uint64_t(key.dim) << 16 | uint64_t(key.planeCount) << 8));
    for (uint64_t f : key.feature) h = mixBits(h ^ f);
    for (int i = 0; i < key.planeCount; ++i) h = mixBits(h ^ key.planes[size_t(i)]);
    return h >> 2 | uint64_t(1) << 62;
}

/// conformPieces passes over vertices far from an edge's line without their
/// signs in a surface of more vertices than this (a cell where many prisms
/// cross: thousands; an ordinary tet: a few dozen).
constexpr size_t kFarVertices = 64;

/// Kerf > 0: two prism faces of different quads (coplanar consecutive quads'
/// offset faces) whose planes differ by less than this share of the tie
/// (epsAt) at every corner of a tet are one surface there (capSurfaces). The
/// planes of one flat stroke differ by rounding only: not at all on a level
/// stroke, by 1.2e-3 of the tie at most on bench_step's pitched one, and no
/// pair of faces measured there lay between 1/16 and 1e6 ties apart. A point
/// on either plane is then on the other by the tie, however it was made.
constexpr double kCoincident = 1.0 / 16.0;

/// A point farther than kApart (1 + |x|) from a plane is off it beyond any
/// tie (epsAt) the arrangement's vertices can make.
constexpr double kApart = 1e-9;

/// Kerf > 0: where the removed region's boundary has several fans at one
/// vertex inside a tet (the union of the prisms, or the solid left between
/// them, touches itself at that point: a blade pivoting on a corner), every
/// fan but the first gets its own copy of the vertex, so the surface is a
/// 2-manifold that touches itself there.
void splitPinches(const openvdb::Coord& cell, CutCellGeometry& out);

} // namespace

std::string cellText(const Coord& c)
{
    std::ostringstream os;
    os << "(" << c.x() << ", " << c.y() << ", " << c.z() << ")";
    return os.str();
}


using poly2::bestTriangulation;
using poly2::bridgeHoles;
using poly2::cross2;
using poly2::earClip;
using poly2::signedArea;
using poly2::Vec2;

/// Inline-storage vectors for the kernel's short per-vertex and per-polygon
/// lists (a few entries each), so building them allocates nothing.
template <class T, size_t N> using SmallVector = boost::container::small_vector<T, N>;
using PlaneList = SmallVector<uint64_t, 8>;

/// Sorts `v` ascending and drops repeats: by insertion when short (a
/// vertex's planes, a handful: std::sort's set-up cost more than the sort
/// in nameVertex), else std::sort.
template <class Vec> void sortUnique(Vec& v)
{
    auto* d = v.data();
    const size_t n = v.size();
    if (n > 24) {
        std::sort(v.begin(), v.end());
    } else {
        for (size_t i = 1; i < n; ++i) {
            const auto x = d[i];
            size_t j = i;
            for (; j > 0 && x < d[j - 1]; --j) d[j] = d[j - 1];
            d[j] = x;
        }
    }
    v.erase(std::unique(v.begin(), v.end()), v.end());
}

class RemeshKernel
{
public:
    RemeshKernel(const vdb::Volume& volume, float iso)
        : mAcc(volume.grid->tree()), mIso(iso), mDims(volume.dims), mBackground(volume.grid->background())
    {
    }

    /// prism: the quads are kerf > 0 prisms (makePrismGeom), else zero-kerf quads.
    void remesh(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out);
    /// remesh()'s work after the tets (the pinches split, kerf > 0) on `out`.
    void finishCell(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out);
    /// The first phase of tet t of the cell alone (CellKernel::phaseOneForTesting).
    TetPhaseOne phaseOne(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, int t);
    /// remesh() records each tet's vertices here when set (CellKernel::verticesForTesting).
    std::array<std::vector<VertexProbe>, kTetsPerCell>* mCapture = nullptr;
    /// makeVertex() records each name here when set (CellKernel::namesForTesting).
    std::vector<NameProbe>* mNameCapture = nullptr;
    /// remeshTet() records each tet's arrangement here when set (CellKernel::arrangementForTesting).
    std::array<ArrangementProbe, kTetsPerCell>* mArrangeCapture = nullptr;
    /// capSurfaces() leaves out the caps capOutside() rules out (CellKernel::skipOutsideCapsForTesting).
    bool mSkipOutsideCaps = true;
    /// capOutside() leaves out the mitres the partner prism holds (CellKernel::skipHeldMitresForTesting).
    bool mSkipHeldMitres = true;
    /// makeVertex answers repeats from its memo (CellKernel::useNameMemoForTesting).
    bool mUseMemo = true;
    size_t mMemoHits = 0; ///< calls the memo answered (for tests)
    size_t mCellMemoHits = 0; ///< namings the cell memo answered (for tests)
    /// splitSurface and conformPieces pass over what lies off a plane by
    /// far without asking signs (CellKernel::skipFarForTesting).
    bool mSkipFar = true;
    size_t mFarSkips = 0; ///< what they passed over (for tests)
    /// conformPieces looks only at the pieces a crossing plane left whole
    /// (Poly::open; CellKernel::conformOpenOnlyForTesting).
    bool mConformOpenOnly = true;
    size_t mConformPassed = 0; ///< pieces it passed over (for tests)
    /// capSurfaces joins coinciding faces of different quads
    /// (CellKernel::joinCoincidentFacesForTesting).
    bool mJoinCoincident = true;
    size_t mCoincidentJoins = 0; ///< faces it joined so (for tests)

private:
    // ---- per tet state
    struct Vert
    {
        CutVertexId key; // planes only, no tags
        dvec3 pos;
        uint8_t support = 0; // tet-local vertices of the smallest simplex holding it
        SmallVector<std::pair<uint64_t, int8_t>, 8> signs;
        int8_t member = 2; // P membership cache (2 = unknown)
        bool steiner = false; // a Steiner point: always a corner
    };
    struct Poly
    {
        SmallVector<int, 8> v;
        SmallVector<uint64_t, 8> lab; // lab[i]: edge v[i] -> v[i+1]
        /// A plane that crosses it (or the piece it was split from) left it
        /// whole, outside that plane's junction zone (splitSurface): a
        /// neighbour's split may end on its edges (conformPieces).
        bool open = false;
    };
    struct Support
    {
        dvec3 p[4];
        uint64_t id[4];
        float value[4];
        bool inside[4];
    };

    float value(const Coord& c) { return mAcc.getValue(c); }

    // Tet-level data.
    Coord mCell;
    int mTet = 0;
    Support mT;
    std::vector<Vert> mVerts;
    /// An open-addressing memo whose slots hold only (hash, generation,
    /// entry): 16 bytes, four to a cache line, the entries themselves apart
    /// in the order they came. A cell where 30 prisms cross grows a memo to
    /// 131,072 slots; with the keys in the slots (56 and 136 bytes) the
    /// probes there missed the cache (the two memos' lookups were a tenth
    /// of a sawing replay's profile; with slots it runs 2-4 % faster).
    /// Valid for the entries of the current generation; reset() starts a
    /// new one.
    template <class Entry> struct SlotMemo
    {
        struct Slot
        {
            uint64_t hash = 0;
            uint32_t generation = 0;
            uint32_t entry = 0;
        };
        std::vector<Slot> slots = std::vector<Slot>(256);
        std::vector<Entry> entries;
        uint32_t generation = 1;
        /// The entry with `hash` that `same` accepts, or nullptr and in
        /// `at` the empty slot where it goes (add() there, before any other add).
        template <class Same> const Entry* find(uint64_t hash, Same&& same, size_t& at) const
        {
            const size_t mask = slots.size() - 1;
            for (size_t i = size_t(hash) & mask;; i = (i + 1) & mask) {
                const Slot& s = slots[i];
                if (s.generation != generation) {
                    at = i;
                    return nullptr;
                }
                if (s.hash == hash && same(entries[s.entry])) return &entries[s.entry];
            }
        }
        template <class Same> Entry* find(uint64_t hash, Same&& same, size_t& at)
        {
            return const_cast<Entry*>(std::as_const(*this).find(hash, std::forward<Same>(same), at));
        }
        void add(size_t at, uint64_t hash, const Entry& e)
        {
            slots[at] = Slot{hash, generation, uint32_t(entries.size())};
            entries.push_back(e);
            if (2 * entries.size() > slots.size()) grow();
        }
        void reset()
        {
            entries.clear();
            if (++generation == 0) { // wrapped: no slot may look current
                std::fill(slots.begin(), slots.end(), Slot{});
                generation = 1;
            }
        }
        void grow()
        {
            std::vector<Slot> old(2 * slots.size());
            old.swap(slots);
            const size_t mask = slots.size() - 1;
            for (const Slot& s : old) {
                if (s.generation != generation) continue;
                size_t i = size_t(s.hash) & mask;
                while (slots[i].generation == generation) i = (i + 1) & mask;
                slots[i] = s;
            }
        }
    };
    /// CutVertexIdHash of each mVerts[i].key: makeVertex's search for an
    /// existing name compares these first (a cell where many quads pivot has
    /// thousands of vertices per tet; comparing whole keys was most of its time).
    std::vector<uint64_t> mVertHash;
    /// Past kIndexFrom vertices, an index over mVertHash: per hash the first
    /// and last vertex holding it, chained in ascending order through
    /// mNextSameHash, so findVertex still returns the lowest match.
    static constexpr size_t kIndexFrom = 64;
    SlotMemo<std::pair<int, int>> mHashChain; ///< (its key is the hash itself)
    std::vector<int> mNextSameHash;
    bool mHashIndexed = false;
    /// Also past kIndexFrom: the tet-inside, non-Steiner vertices by position,
    /// in buckets of kNearCell voxels (far above mergeTolerance), for
    /// makeVertex's merge of one point made by different planes.
    static constexpr double kNearCell = 1e-5;
    /// Per bucket (nearKey, the key itself) its last vertex; each vertex's
    /// predecessor in its bucket in mNearNext (-1: none).
    SlotMemo<int> mNear;
    std::vector<int> mNearNext;
    static constexpr auto kAnyEntry = [](const auto&) { return true; };
    static uint64_t nearKey(int64_t x, int64_t y, int64_t z)
    {
        uint64_t h = uint64_t(x) * 0x9e3779b97f4a7c15ull;
        h ^= uint64_t(y) * 0xc2b2ae3d27d4eb4full + (h << 6) + (h >> 2);
        h ^= uint64_t(z) * 0x165667b19e3779f9ull + (h << 6) + (h >> 2);
        return h;
    }
    static double mergeTolerance(const dvec3& p)
    {
        return 1e-11 * (1.0 + std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}));
    }
    /// The farther a point named by a subset of another's planes may lie
    /// from it and still be it (mergeCandidate); below kNearCell.
    static double subsetMergeTolerance(const dvec3& p)
    {
        return std::min(1e-8 * (1.0 + std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)})), 0.5 * kNearCell);
    }
    /// Is one sorted plane list a subset of the other?
    static bool nested(const uint64_t* a, int na, const uint64_t* b, int nb)
    {
        if (na > nb) {
            std::swap(a, b);
            std::swap(na, nb);
        }
        return std::includes(b, b + nb, a, a + na);
    }
    /// The lowest tet-inside, non-Steiner vertex with this feature within
    /// mergeTolerance of `p`, or within subsetMergeTolerance when one name's
    /// planes are a subset of the other's (a dim-3 name fixes its point, so
    /// a vertex on all the planes of the other name is that point: where
    /// nearly parallel planes meet, two of them compute it 1e-9 voxel apart;
    /// 2 mm head, kerf 1, seed 16234), or -1.
    int mergeCandidate(const std::array<uint64_t, 3>& feature, const PlaneList& planes, const dvec3& p) const
    {
        auto fits = [&](const Vert& o) {
            if (o.key.dim != 3 || o.steiner || o.key.feature != feature) return false;
            const double d = glm::length(o.pos - p);
            return d <= mergeTolerance(p) ||
                   (d <= subsetMergeTolerance(p) &&
                    nested(o.key.planes.data(), o.key.planeCount, planes.data(), int(planes.size())));
        };
        if (!mHashIndexed) {
            for (size_t i = 0; i < mVerts.size(); ++i)
                if (fits(mVerts[i])) return int(i);
            return -1;
        }
        const int64_t bx = int64_t(std::floor(p.x / kNearCell)), by = int64_t(std::floor(p.y / kNearCell)),
                      bz = int64_t(std::floor(p.z / kNearCell));
        int best = -1;
        for (int64_t dx = -1; dx <= 1; ++dx)
            for (int64_t dy = -1; dy <= 1; ++dy)
                for (int64_t dz = -1; dz <= 1; ++dz) {
                    size_t at = 0;
                    const int* last = mNear.find(nearKey(bx + dx, by + dy, bz + dz), kAnyEntry, at);
                    for (int i = last ? *last : -1; i >= 0; i = mNearNext[size_t(i)])
                        if ((best < 0 || i < best) && fits(mVerts[size_t(i)])) best = i;
                }
        return best;
    }
    void indexVertex(int i)
    {
        const Vert& v = mVerts[size_t(i)];
        mNearNext.push_back(-1);
        size_t at = 0;
        if (v.key.dim == 3 && !v.steiner) {
            const uint64_t bucket = nearKey(int64_t(std::floor(v.pos.x / kNearCell)), int64_t(std::floor(v.pos.y / kNearCell)),
                                            int64_t(std::floor(v.pos.z / kNearCell)));
            if (int* last = mNear.find(bucket, kAnyEntry, at)) {
                mNearNext[size_t(i)] = *last;
                *last = i;
            } else {
                mNear.add(at, bucket, i);
            }
        }
        mNextSameHash.push_back(-1);
        if (std::pair<int, int>* chain = mHashChain.find(mVertHash[size_t(i)], kAnyEntry, at)) {
            mNextSameHash[size_t(chain->second)] = i;
            chain->second = i;
        } else {
            mHashChain.add(at, mVertHash[size_t(i)], {i, i});
        }
    }
    void rebuildHashIndex()
    {
        mHashChain.reset();
        mNextSameHash.clear();
        mNear.reset();
        mNearNext.clear();
        for (size_t i = 0; i < mVerts.size(); ++i) indexVertex(int(i));
        mHashIndexed = true;
    }
    /// The lowest vertex named `key` (hash: its CutVertexIdHash), or -1.
    int findVertex(const CutVertexId& key, uint64_t hash) const
    {
        if (!mHashIndexed) {
            for (size_t i = 0; i < mVerts.size(); ++i)
                if (mVertHash[i] == hash && mVerts[i].key == key) return int(i);
            return -1;
        }
        size_t at = 0;
        const std::pair<int, int>* chain = mHashChain.find(hash, kAnyEntry, at);
        for (int i = chain ? chain->first : -1; i >= 0; i = mNextSameHash[size_t(i)])
            if (mVerts[size_t(i)].key == key) return i;
        return -1;
    }
    void pushVertex(Vert&& v, uint64_t hash)
    {
        mVerts.push_back(std::move(v));
        mVertHash.push_back(hash);
        if (mHashIndexed) indexVertex(int(mVerts.size() - 1));
        else if (mVerts.size() >= kIndexFrom) rebuildHashIndex();
    }
    /// makeVertex's memo: the vertex a call with the same simplex and the
    /// same planes (as a set) made earlier in this tet. Such a call names the
    /// same point, computed along another edge or by another surface (a
    /// crossing of two pieces' common edge; a line's point on each surface
    /// through it): a third of the calls at kerf 0.5. Per tet.
    struct MemoEntry
    {
        int vertex = -1;
        uint8_t support = 0;
        uint8_t count = 0;
        std::array<uint64_t, 4> planes{};
    };
    SlotMemo<MemoEntry> mMemo;
    static uint64_t memoHash(uint8_t support, const std::array<uint64_t, 4>& planes, int count)
    {
        uint64_t h = 0x9e3779b97f4a7c15ull * (uint64_t(support) + 1);
        for (int i = 0; i < count; ++i) {
            h ^= planes[size_t(i)] + 0x632be59bd9b4e019ull + (h << 6) + (h >> 2);
            h *= 0xbf58476d1ce4e5b9ull;
        }
        return h ^ (h >> 31);
    }
    /// nameVertex's memo over a cell: the name (its planes) a point on a
    /// tet face or edge was given by an earlier tet of the same cell, by its
    /// simplex (grid vertex ids) and defining planes, the iso triangle's plane
    /// as kIso. The tets on either side of a face name such a point each; the
    /// name depends on the simplex, the planes through the point and the
    /// quads that reach it, which are the same from both tets except within
    /// the tie (the argument of makeVertex's memo). 39 % of the namings of
    /// the 1 mm head's 425-cell cut. Open addressing; valid for entries of
    /// the current cell's generation.
    struct CellMemoEntry
    {
        uint64_t hash = 0;
        uint8_t dim = 0, count = 0, planeCount = 0;
        std::array<uint64_t, 3> feature{};
        std::array<uint64_t, 4> defining{};
        std::array<uint64_t, 8> planes{};
        bool sameKey(const CellMemoEntry& o) const
        {
            return hash == o.hash && dim == o.dim && count == o.count && feature == o.feature &&
                   std::equal(defining.begin(), defining.begin() + count, o.defining.begin());
        }
    };
    SlotMemo<CellMemoEntry> mCellMemo;
    Coord mCellMemoCell{std::numeric_limits<int>::min()};
    /// The key of a naming of a face or edge point in `probe`; false when
    /// the point is not one the cell memo keeps (inside the tet, a
    /// tet-local plane among the defining ones, more than four of them).
    bool cellMemoKey(const CutVertexId& key, const PlaneList& mappedDefining, CellMemoEntry& probe) const
    {
        if (key.dim >= 3 || mappedDefining.size() > probe.defining.size()) return false;
        probe.count = 0;
        for (uint64_t p : mappedDefining) {
            if (p != kIso && p <= kCentroid) return false; // an iso triangle's own plane, a Steiner mark
            size_t j = probe.count++; // sorted, by insertion
            for (; j > 0 && probe.defining[j - 1] > p; --j) probe.defining[j] = probe.defining[j - 1];
            probe.defining[j] = p;
        }
        probe.dim = key.dim;
        probe.feature = key.feature;
        uint64_t h = 0x9e3779b97f4a7c15ull * (uint64_t(key.dim) + 1);
        auto mix = [&h](uint64_t x) {
            h ^= x + 0x632be59bd9b4e019ull + (h << 6) + (h >> 2);
            h *= 0xbf58476d1ce4e5b9ull;
        };
        for (uint64_t f : probe.feature) mix(f);
        for (int i = 0; i < probe.count; ++i) mix(probe.defining[size_t(i)]);
        probe.hash = h ^ (h >> 31);
        return true;
    }
    /// The entry of `probe`'s key, or nullptr and in `at` the empty slot
    /// where it goes (the memo restarts when the cell changes, and with each
    /// remesh()).
    const CellMemoEntry* cellMemoFind(const CellMemoEntry& probe, size_t& at)
    {
        if (mCellMemoCell != mCell) {
            mCellMemoCell = mCell;
            mCellMemo.reset();
        }
        return mCellMemo.find(probe.hash, [&](const CellMemoEntry& e) { return e.sameKey(probe); }, at);
    }
    void cellMemoAdd(size_t at, const CellMemoEntry& probe, const PlaneList& planes)
    {
        CellMemoEntry e = probe;
        e.planeCount = uint8_t(planes.size());
        std::copy(planes.begin(), planes.end(), e.planes.begin());
        mCellMemo.add(at, probe.hash, e);
    }
    /// sign() memo, one column per plane of mPlanes (a plane's signs over
    /// the vertices are contiguous: splitting pieces asks one plane about many
    /// nearby vertices): entry pidx * mSignCap + vi; 2 = not yet known. Ids
    /// not in mPlanes use Vert::signs. Reset per tet.
    std::vector<int8_t> mSignTab;
    size_t mSignStride = 0; ///< mPlanes.size() once mPlanes is final; 0 before
    size_t mSignCap = 0;    ///< vertices per column
    int8_t& signSlot(size_t vi, size_t pidx)
    {
        if (vi >= mSignCap) {
            size_t cap = std::max<size_t>(64, mSignCap);
            while (cap <= vi) cap *= 2;
            std::vector<int8_t> grown(mSignStride * cap, int8_t(2));
            for (size_t p = 0; p < mSignStride && mSignCap; ++p)
                std::copy_n(mSignTab.begin() + std::ptrdiff_t(p * mSignCap), mSignCap, grown.begin() + std::ptrdiff_t(p * cap));
            mSignTab.swap(grown);
            mSignCap = cap;
        }
        return mSignTab[pidx * mSignCap + vi];
    }
    void forgetSigns(size_t vi)
    {
        mVerts[vi].signs.clear();
        if (vi < mSignCap)
            for (size_t p = 0; p < mSignStride; ++p) mSignTab[p * mSignCap + vi] = 2;
        if (vi < mSlitKnown) {
            const size_t row = vi * mCellQuads->size() * 2;
            std::fill(mSlitMemo.begin() + std::ptrdiff_t(row), mSlitMemo.begin() + std::ptrdiff_t(row + mCellQuads->size() * 2), int8_t(2));
        }
    }
    // remeshTet's scratch, kept between tets for its capacity.
    std::vector<int> mNodeHead, mNodeNext, mParent, mEdgeOrder;
    std::vector<Poly> mPieces, mNextPieces;
    /// splitSurface's pieces by number, and the numbers of those in order.
    std::vector<Poly> mPiecePool;
    std::vector<int> mPieceOrder, mNextPieceOrder;
    std::vector<int> mOnLine;
    /// conformPieces' mark of the vertices it has listed (== mVertStampNow).
    std::vector<uint32_t> mVertStamp;
    uint32_t mVertStampNow = 0;
    using Tags = SmallVector<uint64_t, 4>;
    struct Node // a vertex of a region loop: the vertex and its side tags
    {
        int vert;
        Tags tags;
    };
    std::vector<Node> mNodes;
    std::vector<Vec2> mTriangulatePts;
    std::vector<int> mTriangulateNodes;
    std::vector<std::array<int, 4>> mEdgeUses, mEdgeSorted;
    std::vector<std::vector<std::array<int64_t, 3>>> mRegionEdges;
    std::vector<std::pair<int, int>> mBoundaryKeys;
    std::vector<const QuadGeom*> mQuads;             // quads crossing this tet
    std::vector<std::pair<uint64_t, Plane>> mPlanes; // sorted by id: ISO_A, ISO_B, quad planes and sides
    int mTriCount = 0;
    Plane mTriPlane[2];
    std::vector<int> mTriVerts[2];
    int mFaceTri[4];      // which iso triangle has its edge on tet face f (opposite vertex f), -1 none
    std::vector<uint8_t> mTriEdgeMasks[2]; // tet-local vertex masks of the grid edges of each iso triangle's corners
    /// Does iso triangle k (kIsoA + k) hold the MT geometry of the face or edge `support`?
    bool triOwns(int k, uint8_t support) const
    {
        if (mTriCount < 2) return true;
        if (bits(support) == 3) {
            int f = 0;
            while (support >> f & 1) ++f;
            return mFaceTri[f] == k;
        }
        return std::find(mTriEdgeMasks[k].begin(), mTriEdgeMasks[k].end(), support) != mTriEdgeMasks[k].end();
    }
    bool mFoldConvex = true;
    bool mPrism = false; ///< kerf > 0: quads are closed prisms, no slits, tags or Steiner points

    const Plane* planeById(uint64_t id) const
    {
        if (mSignStride) {
            const size_t i = planeIndex(id);
            return i == SIZE_MAX ? nullptr : &mPlanes[i].second;
        }
        auto it = std::lower_bound(mPlanes.begin(), mPlanes.end(), id,
                                   [](const std::pair<uint64_t, Plane>& a, uint64_t b) { return a.first < b; });
        return it != mPlanes.end() && it->first == id ? &it->second : nullptr;
    }
    /// Once mPlanes is final: an open-addressing table id -> index in mPlanes
    /// (sign() and planeById() ask it millions of times in a cell where many
    /// quads pivot; a binary search over mPlanes was half of sign()).
    std::vector<std::pair<uint64_t, uint32_t>> mPlaneSlots; ///< (id, index); index UINT32_MAX = empty
    static size_t slotHash(uint64_t id) { return size_t((id * 0x9e3779b97f4a7c15ull) >> 32); }
    void buildPlaneSlots()
    {
        size_t n = 16;
        while (n < 2 * mPlanes.size()) n *= 2;
        mPlaneSlots.assign(n, {0, UINT32_MAX});
        for (size_t i = 0; i < mPlanes.size(); ++i) {
            size_t h = slotHash(mPlanes[i].first) & (n - 1);
            while (mPlaneSlots[h].second != UINT32_MAX) h = (h + 1) & (n - 1);
            mPlaneSlots[h] = {mPlanes[i].first, uint32_t(i)};
        }
    }
    /// Index of plane `id` in mPlanes once it is final; SIZE_MAX when absent or before.
    size_t planeIndex(uint64_t id) const
    {
        if (!mSignStride) return SIZE_MAX;
        const size_t mask = mPlaneSlots.size() - 1;
        for (size_t h = slotHash(id) & mask;; h = (h + 1) & mask) {
            const auto& s = mPlaneSlots[h];
            if (s.second == UINT32_MAX) return SIZE_MAX;
            if (s.first == id) return s.second;
        }
    }

    static int bits(uint8_t m) { return (m & 1) + (m >> 1 & 1) + (m >> 2 & 1) + (m >> 3 & 1); }

    // Grid data for features.
    dvec3 mtPoint(int a, int b) const // tet-local vertices, MT crossing point
    {
        int lo = a, hi = b;
        if (mT.id[hi] < mT.id[lo]) std::swap(lo, hi);
        const double t = edgeCrossing(mT.value[lo], mT.value[hi], mIso);
        return mT.p[lo] + t * (mT.p[hi] - mT.p[lo]);
    }
    /// faceIsoLine's answers for the tet's faces (by the corner not on the
    /// face), each worked out once per tet (loadTet forgets them): naming a
    /// face point asks its face's line several times over.
    struct FaceIsoLine
    {
        int8_t known = 0; ///< 0: not yet; 1: crossed; -1: not crossed
        dvec3 p1, p2, normal;
        double inSign = 0, scale = 0; ///< scale: |p2 - p1| |normal| (faceIsoDistance)
    };
    mutable std::array<FaceIsoLine, 4> mFaceIsoLines;
    const FaceIsoLine& faceIsoLineOf(uint8_t mask) const
    {
        int missing = 0;
        while (mask >> missing & 1) ++missing;
        FaceIsoLine& f = mFaceIsoLines[size_t(missing)];
        if (f.known == 0) {
            f.known = faceIsoLineNow(mask, f.p1, f.p2, f.normal, f.inSign) ? 1 : -1;
            if (f.known > 0) f.scale = glm::length(f.p2 - f.p1) * glm::length(f.normal);
        }
        return f;
    }
    /// Face (tet-local vertex mask, 3 bits): canonical iso line p1, p2 and inside sign; false when not crossed.
    bool faceIsoLine(uint8_t mask, dvec3& p1, dvec3& p2, dvec3& normal, double& inSign) const
    {
        const FaceIsoLine& f = faceIsoLineOf(mask);
        if (f.known < 0) return false;
        p1 = f.p1;
        p2 = f.p2;
        normal = f.normal;
        inSign = f.inSign;
        return true;
    }
    bool faceIsoLineNow(uint8_t mask, dvec3& p1, dvec3& p2, dvec3& normal, double& inSign) const
    {
        int v[3], n = 0;
        for (int i = 0; i < 4; ++i)
            if (mask >> i & 1) v[n++] = i;
        std::sort(v, v + 3, [&](int a, int b) { return mT.id[a] < mT.id[b]; });
        const int ni = int(mT.inside[v[0]]) + int(mT.inside[v[1]]) + int(mT.inside[v[2]]);
        if (ni == 0 || ni == 3) return false;
        const int ends[3][2] = {{v[0], v[1]}, {v[0], v[2]}, {v[1], v[2]}};
        int k = 0;
        dvec3 pts[2];
        for (const auto& e : ends)
            if (mT.inside[e[0]] != mT.inside[e[1]]) pts[k++] = mtPoint(e[0], e[1]);
        p1 = pts[0];
        p2 = pts[1];
        normal = glm::cross(mT.p[v[1]] - mT.p[v[0]], mT.p[v[2]] - mT.p[v[0]]);
        const int in = mT.inside[v[0]] ? v[0] : mT.inside[v[1]] ? v[1] : v[2];
        inSign = glm::dot(glm::cross(p2 - p1, mT.p[in] - p1), normal) > 0 ? 1.0 : -1.0;
        return true;
    }
    /// Signed in-plane distance to the face's iso line (+ inside), or +-1e300 when uncrossed.
    double faceIsoDistance(uint8_t mask, const dvec3& x) const
    {
        const FaceIsoLine& f = faceIsoLineOf(mask);
        if (f.known < 0) {
            int any = 0;
            while (!(mask >> any & 1)) ++any;
            return mT.inside[any] ? 1e300 : -1e300;
        }
        return f.inSign * glm::dot(glm::cross(f.p2 - f.p1, x - f.p1), f.normal) / f.scale;
    }
    double edgeIsoDistance(uint8_t mask, const dvec3& x) const
    {
        int a = -1, b = -1;
        for (int i = 0; i < 4; ++i)
            if (mask >> i & 1) (a < 0 ? a : b) = i;
        if (mT.id[b] < mT.id[a]) std::swap(a, b);
        if (mT.inside[a] == mT.inside[b]) return mT.inside[a] ? 1e300 : -1e300;
        const dvec3 e = mT.p[b] - mT.p[a];
        const double len = glm::length(e);
        const double t = glm::dot(x - mT.p[a], e) / (len * len);
        const double ti = edgeCrossing(mT.value[a], mT.value[b], mIso);
        return (mT.inside[a] ? (ti - t) : (t - ti)) * len;
    }

    CutVertexId featureKey(uint8_t support) const
    {
        CutVertexId k;
        const int n = bits(support);
        k.dim = uint8_t(n - 1);
        if (n == 4) {
            k.feature = {gridVertexId(mCell.x(), mCell.y(), mCell.z()), uint64_t(mTet), 0};
            return k;
        }
        int m = 0;
        for (int i = 0; i < 4; ++i)
            if (support >> i & 1) k.feature[size_t(m++)] = mT.id[i];
        std::sort(k.feature.begin(), k.feature.begin() + n);
        return k;
    }

    dvec3 canonicalPosition(const CutVertexId& key, uint8_t support, const dvec3& pos0) const;
    int makeVertex(uint8_t support, PlaneList defining, const dvec3& pos0);
    /// makeVertex without its memo: names the point and finds or makes its vertex.
    int nameVertex(uint8_t support, PlaneList defining, const dvec3& pos0);
    /// nameVertex's end: the vertex named by `planes` (sorted; at most eight), found or made.
    int placeNamed(CutVertexId key, uint8_t support, const PlaneList& planes, const dvec3& pos0);
    /// The first of `planes` (in order; those with a plane in this tet)
    /// whose normals are independent, at most three: three fix one point.
    PlaneList independentPlanes(const PlaneList& planes) const
    {
        PlaneList chosen;
        dvec3 n0(0.0), n1(0.0);
        for (uint64_t id : planes) {
            const Plane* pl = planeById(id);
            if (!pl) continue;
            const dvec3& n = pl->n;
            const bool independent = chosen.empty()       ? glm::length(n) > 0.5
                                     : chosen.size() == 1 ? glm::length(glm::cross(n0, n)) > 1e-6
                                                          : std::abs(glm::dot(glm::cross(n0, n1), n)) > 1e-6;
            if (!independent) continue;
            (chosen.empty() ? n0 : n1) = n;
            chosen.push_back(id);
            if (chosen.size() == 3) break;
        }
        return chosen;
    }
    int makeSteiner(uint8_t support, PlaneList planes, const dvec3& pos);
    /// A slit chord of quad r between two rim points on different rim lines:
    /// the two sides of the slit need a tagged vertex on it.
    bool needsMidpoint(int u, int v, const QuadGeom& r)
    {
        if (mPrism || !chordEnd(u, r) || !chordEnd(v, r)) return false;
        for (const auto& sd : r.sides)
            if (sd.partner < 0 && sign(u, sd.id) == 0 && sign(v, sd.id) == 0) return false; // both on one rim
        return true;
    }
    /// needsMidpoint's test of each end: a rim point of r (on its plane, in
    /// its closed extent, not inside its open slit); memoised as slitInterior.
    bool chordEnd(int v, const QuadGeom& r)
    {
        int8_t e = slitMemo(v, r)[1];
        if (e == 2) slitMemo(v, r)[1] = e = int8_t(chordEndNow(v, r)); // (a fresh lookup: the memo may have grown)
        return e != 0;
    }
    bool chordEndNow(int v, const QuadGeom& r) { return sign(v, r.id) == 0 && inExtentClosed(v, r) && !slitInterior(v, r); }
    /// Side of vertex v on plane planeId: 1, -1, or 0 on it (by name, or
    /// within the tie rule); memoised.
    int sign(int v, uint64_t planeId)
    {
        const size_t pidx = planeIndex(planeId);
        if (pidx != SIZE_MAX && size_t(v) < mSignCap) {
            const int8_t known = mSignTab[pidx * mSignCap + size_t(v)];
            if (known != 2) return known;
        }
        return signSlow(v, planeId, pidx);
    }
    int signSlow(int v, uint64_t planeId, size_t pidx);
    int member(int v);
    bool inExtentClosed(int v, const QuadGeom& q)
    {
        for (const auto& s : q.sides)
            if (s.orient * sign(v, s.id) < 0) return false;
        return true;
    }
    bool inSlitOpen(int v, const QuadGeom& q)
    {
        for (const auto& s : q.sides) {
            const double o = s.orient * sign(v, s.id);
            if (s.partner >= 0 ? o < 0 : o <= 0) return false;
        }
        return true;
    }
    /// Zero kerf: v lies inside r's open slit, off every rim of r's strip
    /// (its sides there are the slit's two sides). Asked for every vertex of
    /// a surface's kept pieces about every quad, twice over (slit midpoints,
    /// then each side's regions), and again for the next surface's, so
    /// memoised for the tet (slitMemo).
    bool slitInterior(int v, const QuadGeom& r)
    {
        int8_t e = slitMemo(v, r)[0];
        if (e == 2) slitMemo(v, r)[0] = e = int8_t(slitInteriorNow(v, r));
        return e != 0;
    }
    bool slitInteriorNow(int v, const QuadGeom& r) { return sign(v, r.id) == 0 && inSlitOpen(v, r) && !onStripRim(v, r); }
    /// The memo of slitInterior and chordEnd for vertex v and quad r (2: not
    /// known yet). Both are functions of v's signs alone, which sign()
    /// memoises in turn, so an answer holds until forgetSigns(v) forgets it
    /// with them (a vertex merged into another name); per tet, grown as
    /// vertices are made.
    int8_t* slitMemo(int v, const QuadGeom& r)
    {
        const size_t quads = mCellQuads->size();
        if (size_t(v) >= mSlitKnown) {
            mSlitKnown = std::max<size_t>(std::max<size_t>(32, 2 * mSlitKnown), size_t(v) + 1);
            mSlitMemo.resize(mSlitKnown * quads * 2, int8_t(2));
        }
        return &mSlitMemo[(size_t(v) * quads + size_t(&r - mCellQuads->data())) * 2];
    }
    std::vector<int8_t> mSlitMemo; ///< (slitInterior, chordEnd) per vertex and cell quad
    size_t mSlitKnown = 0;         ///< vertices mSlitMemo has room for
    /// On the rim of a neighbouring quad of r's strip (a strip corner that r
    /// touches only at a point)? Then the point is rim for r too. Such a
    /// corner lies on one of r's junctions; a point inside r's quad, off its
    /// sides, is in r's slit whatever rim of another quad passes through it
    /// (tooth, kerf 0, random strokes seed 16929: quad 83 crosses a rim line
    /// of quad 81, two quads back, and the point where it does was one
    /// vertex for both sides of 83's slit, a pinch).
    bool onStripRim(int v, const QuadGeom& r)
    {
        bool onJunction = false;
        for (const auto& sd : r.sides) onJunction = onJunction || (sd.partner >= 0 && sign(v, sd.id) == 0);
        if (!onJunction) return false;
        for (const QuadGeom* o : mQuads) {
            if (o == &r || (o->id >> 36) != (r.id >> 36)) continue;
            const int64_t dq = int64_t((o->id >> 4) & 0xffffffff) - int64_t((r.id >> 4) & 0xffffffff);
            if (dq < -2 || dq > 2 || sign(v, o->id) != 0 || !inExtentClosed(v, *o)) continue;
            for (const auto& sd : o->sides)
                if (sd.partner < 0 && sign(v, sd.id) == 0 && !rimLineIn(*o, sd, r)) return true;
        }
        return false;
    }
    /// Does quad o's rim line on side sd (o's plane there) lie in the plane
    /// of quad r, which crosses o's? Then r's slit does not end at a point of
    /// it but runs along it (a dart r, whose hull reaches past the stick it
    /// shares with o). Coplanar quads are left out: they touch on a rim or
    /// overlap (refused).
    static bool rimLineIn(const QuadGeom& o, const QuadGeom::Side& sd, const QuadGeom& r)
    {
        if (!(glm::length(glm::cross(o.pi.n, r.pi.n)) > 1e-9)) return false;
        const dvec3 d = glm::cross(o.pi.n, sd.plane.n);
        const double len = glm::length(d);
        return len > 1e-12 && std::abs(glm::dot(d, r.pi.n)) <= 1e-9 * len;
    }
    /// A T-junction: v lies on a rim line of quad r that lies in the open
    /// slit of another quad o (r's slit ends on o's; 1 mm head, kerf 0,
    /// seed 2013). On the side of o where r lies, r's two sides are two
    /// regions, so v takes r's side tag there too. Returns that side of o
    /// (+1 or -1) and sets o; 0 when v is no such point for r.
    int tJunctionSide(int v, const QuadGeom& r, const QuadGeom*& o)
    {
        if (mTJunctions < 0) { // once a cell: can a rim line of one of its quads lie in another's plane?
            mTJunctions = 0;
            for (const QuadGeom& a : *mCellQuads)
                for (const auto& sd : a.sides)
                    for (const QuadGeom& q : *mCellQuads)
                        if (&q != &a && sd.partner < 0 && rimLineIn(a, sd, q)) mTJunctions = 1;
        }
        if (mTJunctions == 0 || mPrism || sign(v, r.id) != 0 || !inExtentClosed(v, r) || slitInterior(v, r)) return 0;
        for (const auto& sd : r.sides) {
            if (sd.partner >= 0 || sign(v, sd.id) != 0) continue;
            for (const QuadGeom* q : mQuads) {
                if (q == &r || !slitInterior(v, *q) || !rimLineIn(r, sd, *q)) continue;
                // r's corner, where its rim leaves q's plane: the end of the
                // T, round which q's slit goes on as one sheet (a dart's
                // successor whose rim along the shared stick ends inside
                // the dart's hull; tooth, kerf 0, sharp turns, seed 18048).
                if (cornerOffPlane(v, r, sd, *q)) return 0;
                // Into r from its rim: the side's inward normal in r's plane.
                const dvec3 in = sd.orient * (sd.plane.n - r.pi.n * glm::dot(sd.plane.n, r.pi.n));
                const double h = glm::dot(q->pi.n, in);
                if (h == 0.0) continue;
                o = q;
                return h > 0 ? 1 : -1;
            }
        }
        return 0;
    }
    int8_t mTJunctions = -1; ///< tJunctionSide's test of the cell's quads: -1 not yet, 0 none can meet so, 1 some can
    /// v on r's rim side sd (whose line lies in q's plane) and on another
    /// rim side of r whose line does not: r's corner where its rim leaves q.
    bool cornerOffPlane(int v, const QuadGeom& r, const QuadGeom::Side& sd, const QuadGeom& q)
    {
        for (const auto& s2 : r.sides)
            if (&s2 != &sd && s2.partner < 0 && sign(v, s2.id) == 0 && !rimLineIn(r, s2, q)) return true;
        return false;
    }
    const QuadGeom* quadById(uint64_t id) const
    {
        for (const QuadGeom* q : mQuads)
            if (q->id == id) return q;
        return nullptr;
    }

    /// Splits `in` (on plane polyPlane) by plane p into `out` (appended: the
    /// + side's piece, then the - side's, each kept when it has a corner
    /// strictly on its side); false, and nothing done, when p has no corner
    /// of `in` strictly on each side.
    bool splitPoly(const Poly& in, uint64_t polyPlane, uint64_t p, std::vector<Poly>& out);
    /// Appends `o` to `out`, split into simple loops where it visits a vertex twice.
    void pushSimple(Poly o, std::vector<Poly>& out);
    void remeshTet(CutCellGeometry& out);
    void splitIsoPinches(CutCellGeometry& out);
    bool isoStarOffPlane(const CutVertexId& v, const Plane& plane);
    // ---- remeshTet, phase by phase (its state: the members below and above)
    struct Surface
    {
        uint64_t plane;      // supporting plane id (ISO_A/B or a quad plane)
        const QuadGeom* quad; // cap: its quad
        /// Kerf > 0: further prisms with this very face plane (a rim shared
        /// along the stroke, facing the same way), or with a face plane that
        /// coincides with it over the tet (kCoincident: coplanar consecutive
        /// quads' offset faces): one surface, whose pieces are kept where any
        /// of these prisms' rule keeps them, so the faces merge into one
        /// region (no corner where one prism's face ends inside the other's,
        /// which the neighbouring cell need not see; no triangle edge along
        /// the mitre between them). Its triangles' vertices need not share a
        /// blade plane: CutCellGeometry::cap says which are cut face.
        SmallVector<const QuadGeom*, 2> also;
        int sides;           // cap: bit 0 = + side output, bit 1 = - side output
        dvec3 normal;        // reference normal (pieces are CCW around it)
        Poly poly;
    };
    // Split order: iso planes, junction planes, then the rest by id.
    struct SplitPlane
    {
        uint64_t id;
        const QuadGeom* owner; // restricts a quad's plane / rim side to its junction zone
    };
    struct Loop
    {
        SmallVector<int, 16> nodes;
        SmallVector<uint64_t, 16> labels; // labels[i]: edge nodes[i] -> nodes[i+1]
    };
    struct Region
    {
        dvec3 normal;
        SmallVector<Loop, 1> loops;
        const QuadGeom* cap = nullptr; // cap regions: the quad, and the side
        int side = 0;
    };
    SmallVector<SmallVector<std::array<int, 2>, 4>, 2> mTriEdges; ///< the MT triangles' corners, as tet edges
    SmallVector<dvec3, 4> mTriPts[2];                             ///< and as points
    SmallVector<Surface, 8> mSurfaces;
    SmallVector<SplitPlane, 16> mSplitOrder;
    SmallVector<Region, 8> mRegions;
    /// mT, mTet: corner t's of the cell's tet `t` (positions, ids, values, inside).
    void loadTet(int t);
    void resetTet();
    /// Quads whose region can reach the tet, and their planes (mQuads, mPlanes).
    void gatherQuads();
    bool isoTriangles();
    /// mPlanes sorted and final: the sign table's columns and the id lookup.
    void finishPlanes();
    /// The surfaces to arrange: the iso triangles, then the caps.
    void isoSurfaces();
    void capSurfaces();
    /// Can no point of a cap's section of the tet (`at`: its corners'
    /// simplices and positions), by kApart, lie inside both quad q (kerf > 0:
    /// the closed prism, its face `face` aside) and the solid P, or (kerf > 0,
    /// `face` a mitre) does the partner prism hold all of it?
    bool capOutside(const QuadGeom& q, uint64_t face, const SmallVector<std::pair<uint8_t, dvec3>, 8>& at) const;
    /// Two planes that agree at the tet's corners, so everywhere in it, far
    /// inside the tie (kCoincident of epsAt): each one's vertices are on the other.
    bool coincidentOverTet(const Plane& a, const Plane& b) const
    {
        for (int i = 0; i < 4; ++i)
            if (!(std::abs(a.h(mT.p[i]) - b.h(mT.p[i])) <= kCoincident * epsAt(mT.p[i]))) return false;
        return true;
    }
    /// Kerf > 0: the id of the surface a face `id` of another id is joined to
    /// (capSurfaces: one of its also-prisms' faces coinciding with its plane,
    /// facing the same way), else `id`. Asked of kept surfaces only.
    uint64_t joinedSurfaceId(uint64_t id) const;
    void chooseSplitOrder();
    /// The node of `vert` with these side tags (sorted in place), made if new.
    int nodeOf(int vert, Tags& tags);
    /// The side of plane `id` a piece lies on: its first corner off the plane's, 0 if none.
    int pieceSign(const Poly& p, uint64_t id);
    /// Whether p has corners strictly on both sides of plane id.
    bool crosses(const Poly& p, uint64_t id);
    /// Per surface: split by the planes into mPieces, made conforming, classified
    /// (kept), slit chords given midpoints, traced into regions per side.
    void splitSurface(const Surface& s);
    void conformPieces();
    void classifyPieces(const Surface& s, SmallVector<char, 32>& kept);
    void insertSlitMidpoints(const SmallVector<char, 32>& kept);
    bool splitChord(int u, int w, const QuadGeom& r, const SmallVector<char, 32>& kept, int& a, int& b);
    void traceRegions(const Surface& s, int side, const SmallVector<char, 32>& kept);
    /// The nodes kept as corners of the regions' loops, then the regions triangulated into `out`.
    void markCorners(SmallVector<char, 64>& corner);
    void triangulateRegions(const SmallVector<char, 64>& corner, CutCellGeometry& out);
    /// triangulateRegions' scratch, kept between regions for its capacity.
    std::vector<int> mLoopCorners, mPoly, mTris, mNodeOut;
    std::vector<std::pair<uint32_t, uint32_t>> mOuterLoops, mHoleLoops; ///< (first, count) in mLoopCorners
    /// The cell's output vertices by name (the tets weld there by name):
    /// open addressing over out.vertexIds, kept between cells for its capacity.
    struct CellIndex
    {
        std::vector<uint32_t> slots;  ///< out vertex + 1; 0 = empty; a power of two long
        std::vector<uint64_t> hashes; ///< per out vertex
        void clear()
        {
            if (slots.empty()) slots.assign(64, 0);
            else std::fill(slots.begin(), slots.end(), 0u);
            hashes.clear();
        }
        /// The index in `out` of the vertex named `id`, appended (at `pos`) if new.
        uint32_t findOrAdd(const CutVertexId& id, const dvec3& pos, CutCellGeometry& out)
        {
            const uint64_t h = CutVertexIdHash()(id);
            size_t mask = slots.size() - 1, i = size_t(h ^ h >> 29) & mask;
            for (; slots[i]; i = (i + 1) & mask) {
                const uint32_t v = slots[i] - 1;
                if (hashes[v] == h && out.vertexIds[v] == id) return v;
            }
            const uint32_t v = uint32_t(out.vertexIds.size());
            out.vertexIds.push_back(id);
            out.indexPositions.push_back(pos);
            hashes.push_back(h);
            slots[i] = v + 1;
            if (2 * hashes.size() > slots.size()) { // grow: rehash every vertex
                slots.assign(2 * slots.size(), 0);
                mask = slots.size() - 1;
                for (uint32_t k = 0; k < hashes.size(); ++k) {
                    size_t j = size_t(hashes[k] ^ hashes[k] >> 29) & mask;
                    while (slots[j]) j = (j + 1) & mask;
                    slots[j] = k + 1;
                }
            }
            return v;
        }
    };
    CellIndex mCellIndex;

    openvdb::tree::ValueAccessor<const openvdb::FloatTree> mAcc;
    float mIso;
    Coord mDims;
    float mBackground;
    const std::vector<QuadGeom>* mCellQuads = nullptr;
};

dvec3 RemeshKernel::canonicalPosition(const CutVertexId& key, uint8_t support, const dvec3& pos0) const
{
    if (key.dim == 0) {
        for (int i = 0; i < 4; ++i)
            if (support >> i & 1) return mT.p[i];
    }
    if (key.dim == 3) return pos0;
    for (int i = 0; i < key.planeCount; ++i)
        if (key.planes[size_t(i)] == kMid || key.planes[size_t(i)] == kCentroid) return pos0;
    auto planeOf = [&](uint64_t id) -> const Plane* { return planeById(id); };
    if (key.dim == 1) {
        int a = -1, b = -1;
        for (int i = 0; i < 4; ++i)
            if (support >> i & 1) (a < 0 ? a : b) = i;
        if (mT.id[b] < mT.id[a]) std::swap(a, b);
        if (key.planes[0] == kIso) return mtPoint(a, b);
        for (int i = 0; i < key.planeCount; ++i) {
            const Plane* p = planeOf(key.planes[size_t(i)]);
            if (!p) continue;
            const double ha = p->h(mT.p[a]), hb = p->h(mT.p[b]);
            if (!(std::abs(ha - hb) > 1e-12)) continue;
            const double t = std::clamp(ha / (ha - hb), 0.0, 1.0);
            return mT.p[a] + t * (mT.p[b] - mT.p[a]);
        }
        return pos0;
    }
    // dim 2: a face.
    if (key.planes[0] == kIso) {
        dvec3 p1, p2, nrm;
        double s;
        if (faceIsoLine(support, p1, p2, nrm, s)) {
            const double len = glm::length(p2 - p1);
            for (int i = 1; i < key.planeCount; ++i) {
                const Plane* p = planeOf(key.planes[size_t(i)]);
                if (!p) continue;
                const double h1 = p->h(p1), h2 = p->h(p2);
                if (!(std::abs(h1 - h2) > 1e-9 * len)) continue;
                const double u = h1 / (h1 - h2);
                return p1 + u * (p2 - p1);
            }
        }
        return pos0;
    }
    int v[3], n = 0;
    for (int i = 0; i < 4; ++i)
        if (support >> i & 1) v[n++] = i;
    std::sort(v, v + 3, [&](int a, int b) { return mT.id[a] < mT.id[b]; });
    const dvec3 A = mT.p[v[0]], e1 = mT.p[v[1]] - A, e2 = mT.p[v[2]] - A;
    for (int i = 0; i < key.planeCount; ++i)
        for (int j = i + 1; j < key.planeCount; ++j) {
            const Plane* p = planeOf(key.planes[size_t(i)]);
            const Plane* q = planeOf(key.planes[size_t(j)]);
            if (!p || !q) continue;
            const double a11 = glm::dot(p->n, e1), a12 = glm::dot(p->n, e2), b1 = -p->h(A);
            const double a21 = glm::dot(q->n, e1), a22 = glm::dot(q->n, e2), b2 = -q->h(A);
            const double det = a11 * a22 - a12 * a21;
            if (!(std::abs(det) > 1e-9)) continue;
            const double s = (b1 * a22 - a12 * b2) / det, t = (a11 * b2 - b1 * a21) / det;
            return A + s * e1 + t * e2;
        }
    return pos0;
}

int RemeshKernel::makeVertex(uint8_t support, PlaneList defining, const dvec3& pos0)
{
    // A repeat of an earlier call in this tet (same simplex, same planes):
    // its vertex. The planes and simplex fix the point; only its computed
    // position differs, in the last bits, so the name is the same unless a
    // plane passes within the tie of one computed position and not the
    // other. There the memo keeps the first name where naming again could
    // give the point a second vertex (inside the tet, mergeCandidate would
    // join them). Measured: the output is the same bits with and without
    // the memo (test TheNameMemoChangesNoVertexOrTriangle; 1,204 random
    // strokes on the CT volumes). The GLSL port (cut_arrange.glsl) names
    // every call. Not while names are captured: the GPU port's tests
    // compare every call's name.
    std::array<uint64_t, 4> memoPlanes{};
    const int memoCount = int(defining.size());
    bool memoise = false;
    size_t slot = 0;
    uint64_t memoKey = 0;
    if (mUseMemo && !mNameCapture && memoCount <= 4) {
        for (int i = 0; i < memoCount; ++i) { // sorted, by insertion
            int j = i;
            for (; j > 0 && memoPlanes[size_t(j - 1)] > defining[size_t(i)]; --j) memoPlanes[size_t(j)] = memoPlanes[size_t(j - 1)];
            memoPlanes[size_t(j)] = defining[size_t(i)];
        }
        memoKey = memoHash(support, memoPlanes, memoCount);
        const MemoEntry* known = mMemo.find(
            memoKey,
            [&](const MemoEntry& e) {
                return e.support == support && e.count == memoCount &&
                       std::equal(memoPlanes.begin(), memoPlanes.begin() + memoCount, e.planes.begin());
            },
            slot);
        if (known) {
            ++mMemoHits;
            return known->vertex;
        }
        memoise = true;
    }
    const int made = nameVertex(support, std::move(defining), pos0);
    if (memoise) mMemo.add(slot, memoKey, MemoEntry{made, support, uint8_t(memoCount), memoPlanes});
    return made;
}

int RemeshKernel::nameVertex(uint8_t support, PlaneList defining, const dvec3& pos0)
{
    if (mNameCapture)
        mNameCapture->push_back({mTet, support, std::vector<uint64_t>(defining.begin(), defining.end()), pos0, {}, false});
    CutVertexId key = featureKey(support);
    const double eps = epsAt(pos0);
    // The name is the set of ACTIVE planes through the point (the iso surface,
    // quads holding it); the planes that happened to make it (in this tet's
    // arrangement) are used only when the active ones do not fix the point.
    PlaneList planes;
    for (uint64_t& p : defining) {
        // An iso triangle's plane is the iso surface only on the faces and
        // edges that hold that triangle's MT geometry; elsewhere (a fold's
        // plane extended over the other triangle's face) it is a tet-local plane.
        if (key.dim < 3 && (p == kIsoA || p == kIsoB) && triOwns(int(p - kIsoA), support)) p = kIso;
        if (p <= kIsoB) planes.push_back(p);
    }
    // A face or edge point an earlier tet of this cell named: its name.
    CellMemoEntry probe;
    bool memo = false;
    size_t memoAt = 0;
    if (mUseMemo && !mNameCapture && cellMemoKey(key, defining, probe)) {
        if (const CellMemoEntry* known = cellMemoFind(probe, memoAt)) {
            ++mCellMemoHits;
            planes.assign(known->planes.begin(), known->planes.begin() + known->planeCount);
            return placeNamed(key, support, planes, pos0);
        }
        memo = true;
    }
    if (key.dim < 3) {
        if (key.dim == 2 && std::abs(faceIsoDistance(support, pos0)) <= eps) planes.push_back(kIso);
        if (key.dim == 1 && std::abs(edgeIsoDistance(support, pos0)) <= eps) planes.push_back(kIso);
    }
    // Active quad planes: on the plane and in the closed quad; sides on which it lies.
    // Prisms (kerf > 0): on the closed prism's boundary, every bounding plane it lies on.
    for (const QuadGeom* q : mQuads) {
        if (!mPrism) continue;
        bool in = true, onAny = false;
        for (const auto& s : q->sides) {
            const double h = s.orient * s.plane.h(pos0);
            in = in && h >= -eps;
            onAny = onAny || std::abs(h) <= eps;
            if (!in) break;
        }
        if (!in || !onAny) continue;
        for (const auto& s : q->sides)
            if (std::abs(s.plane.h(pos0)) <= eps) planes.push_back(s.id);
    }
    for (const QuadGeom* q : mQuads) {
        if (mPrism) break;
        if (!(std::abs(q->pi.h(pos0)) <= eps)) continue;
        bool in = true;
        for (const auto& s : q->sides)
            if (!(in = s.orient * s.plane.h(pos0) >= -eps)) break;
        if (!in) continue;
        planes.push_back(q->id);
        for (const auto& s : q->sides)
            if (std::abs(s.plane.h(pos0)) <= eps) planes.push_back(s.id);
    }
    // Junctions: a point on a junction plane and on either quad's plane is on
    // both (the three meet in one line, the stick, whether or not the point is
    // inside the quads); at the ends of the shared edge, on either rim side is
    // on both. `on`: the planes the point lies on (made by them, or within eps).
    sortUnique(planes);
    PlaneList on;
    if (!mPrism) {
        on.assign(defining.begin(), defining.end());
        for (const auto& pl : mPlanes)
            if (pl.first > kIsoB && std::abs(pl.second.h(pos0)) <= eps) on.push_back(pl.first);
        on.insert(on.end(), planes.begin(), planes.end());
        sortUnique(on);
    }
    // Kerf > 0 asks `on` only of a few planes (a mitre side, offset planes):
    // whether the point is on one, answered per plane as `on` would hold it
    // (made by it, active on it so far, or within eps of it).
    const size_t activeCount = planes.size(); // planes[0, activeCount) sorted; the loop below appends
    auto onPlane = [&](uint64_t id) {
        if (std::binary_search(planes.begin(), planes.begin() + std::ptrdiff_t(activeCount), id)) return true;
        if (std::find(defining.begin(), defining.end(), id) != defining.end()) return true;
        if (id <= kIsoB) return false;
        const Plane* pl = planeById(id);
        return pl && std::abs(pl->h(pos0)) <= eps;
    };
    // Prisms: the offset planes of two quads meet on their mitre (it bisects
    // them), so a point on the mitre and on one quad's offset plane is on the
    // partner's same-side offset plane too; a point in neither closed prism
    // is on no face of them, and names none of their planes (the cells round
    // it need not know the quads: a level stroke whose tip face lies in a grid
    // plane, 1 mm head at z = 1106 mm, kerf 1, named a crossing one grid step
    // beyond the tip by the mitre in one cell and by nothing in the next).
    auto inClosedPrism = [&](const QuadGeom* q) {
        if (!q) return false;
        for (const auto& s : q->sides)
            if (s.orient * s.plane.h(pos0) < -eps) return false;
        return true;
    };
    for (const QuadGeom* q : mQuads) {
        if (!mPrism) break;
        const auto& has = onPlane;
        for (const auto& sd : q->sides) {
            if (sd.partnerId == 0 || !has(sd.id)) continue;
            if (!inClosedPrism(q) && !inClosedPrism(quadById(sd.partnerId))) continue;
            for (int kind : {kPlusKind, kMinusKind}) {
                const uint64_t mine = (q->id & ~uint64_t(15)) | uint64_t(kind);
                const uint64_t theirs = (sd.partnerId & ~uint64_t(15)) | uint64_t(kind);
                if (has(mine) || has(theirs)) {
                    planes.push_back(sd.id);
                    planes.push_back(mine);
                    planes.push_back(theirs);
                }
            }
        }
    }
    if (mPrism) {
        sortUnique(planes);
    }
    for (int round = 0; round < 4 && !mPrism; ++round) {
        PlaneList add;
        auto has = [&](uint64_t id) { return std::binary_search(on.begin(), on.end(), id); };
        for (const QuadGeom* q : mQuads) {
            for (const auto& s : q->sides) {
                if (s.partner < 0 || !has(s.id) || !(has(q->id) || has(s.partnerId)) || !quadById(s.partnerId)) continue;
                add.push_back(s.id);
                add.push_back(q->id);
                add.push_back(s.partnerId);
                for (const auto& cs : s.cornerSides) {
                    if (cs.first && cs.second && (has(cs.first) || has(cs.second))) {
                        add.push_back(cs.first);
                        add.push_back(cs.second);
                    }
                }
            }
        }
        if (add.empty()) break;
        const size_t before = on.size();
        on.insert(on.end(), add.begin(), add.end());
        sortUnique(on);
        planes.insert(planes.end(), add.begin(), add.end());
        sortUnique(planes);
        if (on.size() == before) break;
    }
    // A face needs two planes, an edge one, the inside three; inside the tet
    // the three must also be independent. Prisms: a mitre and the two offset
    // planes it bisects meet in one line, so a point on that line is named
    // by the three and nothing else when its other plane is not active
    // (outside that prism): two points of the line would share the name.
    // The planes that made it complete the name (inside points are named
    // only in this tet, so the union is the same whichever pair made it).
    if (int(planes.size()) < int(key.dim) || (key.dim == 3 && independentPlanes(planes).size() < 3)) {
        planes.insert(planes.end(), defining.begin(), defining.end());
        sortUnique(planes);
    }
    if (planes.size() > key.planes.size() && key.dim == 3) {
        // A point inside the tet on more planes than a name holds (a blade
        // pivoting exactly about it: every stick, so every mitre and quad
        // plane, passes through it). No other tet or cell names it and its
        // position is pos0, so any of its planes that fix the point name it
        // uniquely: three with independent normals (the lowest ids that are),
        // then the lowest others. The same plane set always gives the same
        // name; the dropped planes still hold it (sign() finds it on them).
        PlaneList chosen = independentPlanes(planes);
        if (chosen.size() == 3) {
            for (uint64_t id : planes)
                if (chosen.size() < key.planes.size() && std::find(chosen.begin(), chosen.end(), id) == chosen.end())
                    chosen.push_back(id);
            std::sort(chosen.begin(), chosen.end());
            planes = chosen;
        }
    }
    if (planes.size() > key.planes.size()) {
        if (mNameCapture) mNameCapture->back().refused = true;
        throw std::runtime_error("remesh: a point lies on more than 8 blade planes in cell " + cellText(mCell));
    }
    if (mNameCapture) mNameCapture->back().planes.assign(planes.begin(), planes.end());
    if (memo) cellMemoAdd(memoAt, probe, planes);
    return placeNamed(key, support, planes, pos0);
}

int RemeshKernel::placeNamed(CutVertexId key, uint8_t support, const PlaneList& planes, const dvec3& pos0)
{
    key.planeCount = uint8_t(planes.size());
    for (size_t i = 0; i < planes.size(); ++i) key.planes[i] = planes[i];
    const uint64_t hash = CutVertexIdHash()(key);
    if (const int found = findVertex(key, hash); found >= 0) return found;
    // Inside the tet (no other tet or cell ever names it), one point made by
    // different planes (two pieces of one region split by the planes of two
    // joined quads whose rims are coplanar) is one vertex: its name is the
    // union of the planes, so the pieces share it and merge.
    if (const int i = key.dim == 3 ? mergeCandidate(key.feature, planes, pos0) : -1; i >= 0) {
        Vert& o = mVerts[size_t(i)];
        std::vector<uint64_t> all(o.key.planes.begin(), o.key.planes.begin() + o.key.planeCount);
        all.insert(all.end(), planes.begin(), planes.end());
        std::sort(all.begin(), all.end());
        all.erase(std::unique(all.begin(), all.end()), all.end());
        if (all.size() <= o.key.planes.size()) {
            o.key.planeCount = uint8_t(all.size());
            for (size_t k = 0; k < all.size(); ++k) o.key.planes[k] = all[k];
            mVertHash[size_t(i)] = CutVertexIdHash()(o.key);
            if (mHashIndexed) rebuildHashIndex();
            forgetSigns(size_t(i));
            o.member = 2;
            return i;
        }
    }
    Vert v;
    v.key = key;
    v.support = support;
    v.pos = canonicalPosition(key, support, pos0);
    pushVertex(std::move(v), hash);
    return int(mVerts.size() - 1);
}

int RemeshKernel::makeSteiner(uint8_t support, PlaneList planes, const dvec3& pos)
{
    CutVertexId key = featureKey(support);
    std::sort(planes.begin(), planes.end());
    key.planeCount = uint8_t(planes.size());
    for (size_t i = 0; i < planes.size(); ++i) key.planes[i] = planes[i];
    const uint64_t hash = CutVertexIdHash()(key);
    if (const int found = findVertex(key, hash); found >= 0) return found;
    Vert v;
    v.key = key;
    v.support = support;
    v.pos = pos;
    v.steiner = true;
    pushVertex(std::move(v), hash);
    return int(mVerts.size() - 1);
}

int RemeshKernel::signSlow(int vi, uint64_t id, size_t pidx)
{
    int8_t* slot = nullptr; // in mSignTab
    if (pidx != SIZE_MAX) {
        slot = &signSlot(size_t(vi), pidx);
        if (*slot != 2) return *slot;
    }
    Vert& v = mVerts[size_t(vi)];
    for (const auto& s : v.signs)
        if (s.first == id) return s.second;
    int r;
    const bool inKey = std::binary_search(v.key.planes.begin(), v.key.planes.begin() + v.key.planeCount, id);
    if (inKey) {
        r = 0;
    } else if ((id == kIsoA || id == kIsoB) && v.key.planeCount > 0 && v.key.planes[0] == kIso &&
               (v.key.dim == 1 || v.key.dim == 2)) {
        const int tri = int(id - kIsoA);
        bool on = false;
        if (v.key.dim == 1) {
            for (int c : mTriVerts[tri]) on = on || c == vi;
            // MT corner of this triangle with extra planes in its key: compare positions.
            if (!on)
                for (int c : mTriVerts[tri]) on = on || mVerts[size_t(c)].key.feature == v.key.feature;
        } else {
            int f = 0;
            while (v.support >> f & 1) ++f;
            on = mFaceTri[f] == tri;
        }
        if (on) {
            r = 0;
        } else {
            const double h = (pidx != SIZE_MAX ? &mPlanes[pidx].second : planeById(id))->h(v.pos);
            r = std::abs(h) <= epsAt(v.pos) ? 0 : (h > 0 ? 1 : -1);
        }
    } else {
        // (pidx, when known, is where planeById would find it.)
        const Plane* p = pidx != SIZE_MAX ? &mPlanes[pidx].second : planeById(id);
        assert(p);
        const double h = p->h(v.pos);
        r = std::abs(h) <= epsAt(v.pos) ? 0 : (h > 0 ? 1 : -1);
    }
    if (slot) *slot = int8_t(r);
    else v.signs.push_back({id, int8_t(r)});
    return r;
}

int RemeshKernel::member(int vi)
{
    Vert& v = mVerts[size_t(vi)];
    if (v.member != 2) return v.member;
    int r;
    const bool onIso = v.key.planeCount > 0 && v.key.planes[0] == kIso;
    if (v.key.dim == 0) {
        int i = 0;
        while (!(v.support >> i & 1)) ++i;
        r = mT.inside[i] ? 1 : -1;
    } else if (v.key.dim < 3) {
        if (onIso) {
            r = 0;
        } else {
            const double d = v.key.dim == 1 ? edgeIsoDistance(v.support, v.pos) : faceIsoDistance(v.support, v.pos);
            r = d > 0 ? 1 : -1;
        }
    } else if (mTriCount == 0) {
        r = mT.inside[0] ? 1 : -1;
    } else {
        const int a = sign(vi, kIsoA);
        if (mTriCount == 1) {
            r = a;
        } else {
            const int b = sign(vi, kIsoB);
            r = mFoldConvex ? std::min(a, b) : std::max(a, b);
        }
    }
    v.member = int8_t(r);
    return r;
}

bool RemeshKernel::splitPoly(const Poly& in, uint64_t polyPlane, uint64_t p, std::vector<Poly>& out)
{
    const size_t n = in.v.size();
    SmallVector<int, 8> sv(n);
    bool pos = false, neg = false;
    for (size_t i = 0; i < n; ++i) {
        sv[i] = sign(in.v[i], p);
        pos |= sv[i] > 0;
        neg |= sv[i] < 0;
    }
    if (!(pos && neg)) return false;
    const Plane* pl = planeById(p);
    // Cut points on crossing edges.
    SmallVector<int, 8> cut(n, -1);
    for (size_t i = 0; i < n; ++i) {
        const size_t j = (i + 1) % n;
        if (sv[i] * sv[j] >= 0) continue;
        const Vert& a = mVerts[size_t(in.v[i])];
        const Vert& b = mVerts[size_t(in.v[j])];
        const double ha = pl->h(a.pos), hb = pl->h(b.pos);
        double t = (ha - hb) != 0 ? ha / (ha - hb) : 0.5;
        if (!(t > 0.0 && t < 1.0)) t = 0.5;
        const dvec3 x = a.pos + t * (b.pos - a.pos);
        PlaneList def{p};
        if (polyPlane != 0) def.push_back(polyPlane);
        if (!(in.lab[i] & kBoundaryLabel)) def.push_back(in.lab[i]);
        cut[i] = makeVertex(uint8_t(a.support | b.support), def, x);
    }
    for (int keep : {1, -1}) {
        Poly o;
        o.open = in.open;
        for (size_t i = 0; i < n; ++i) {
            const size_t j = (i + 1) % n;
            const int sa = keep * sv[i], sb = keep * sv[j];
            if (sa >= 0) {
                o.v.push_back(in.v[i]);
                o.lab.push_back(sa == 0 && sb < 0 ? p : in.lab[i]);
            }
            if (cut[i] >= 0) {
                o.v.push_back(cut[i]);
                o.lab.push_back(sa > 0 ? p : in.lab[i]);
            }
        }
        // Keep only pieces with a vertex strictly on the kept side.
        bool strict = false;
        for (size_t i = 0; i < n; ++i) strict |= keep * sv[i] > 0;
        if (strict && o.v.size() >= 3) out.push_back(std::move(o));
    }
    return true;
}

void RemeshKernel::pushSimple(Poly o, std::vector<Poly>& out)
{
    // Conformity can put a vertex on an edge of a piece that already has it
    // (near-coincident lines whose points are one vertex by name: the offset
    // planes of two mitred quads on their mitre): the piece then runs out
    // along a line and back through that vertex, a loop plus a spike of zero
    // area, and its classification by its first off-plane vertex could be
    // the spike's. Split it at the repeat; loops of fewer than 3 go.
    const size_t n = o.v.size();
    for (size_t i = 0; i < n; ++i)
        for (size_t j = i + 1; j < n; ++j) {
            if (o.v[i] != o.v[j]) continue;
            Poly a, b;
            for (size_t k = i; k < j; ++k) {
                a.v.push_back(o.v[k]);
                a.lab.push_back(o.lab[k]);
            }
            for (size_t k = j; k < n + i; ++k) {
                b.v.push_back(o.v[k % n]);
                b.lab.push_back(o.lab[k % n]);
            }
            if (a.v.size() >= 3) pushSimple(std::move(a), out);
            if (b.v.size() >= 3) pushSimple(std::move(b), out);
            return;
        }
    out.push_back(std::move(o));
}

void RemeshKernel::remesh(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out)
{
    out.clear();
    mPrism = prism;
    mCell = cell;
    mCellQuads = &quads;
    mTJunctions = -1;
    mCellIndex.clear();
    mCellMemoCell = Coord(std::numeric_limits<int>::min()); // a new cell memo (the quads may differ from the last call's)
    for (int t = 0; t < kTetsPerCell; ++t) {
        loadTet(t);
        remeshTet(out);
        if (mCapture && (mT.inside[0] || mT.inside[1] || mT.inside[2] || mT.inside[3]))
            for (const Vert& v : mVerts) (*mCapture)[size_t(t)].push_back({v.key, v.support, v.pos, v.steiner});
    }
    finishCell(cell, quads, prism, out);
}

void RemeshKernel::finishCell(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out)
{
    mPrism = prism;
    mCell = cell;
    mCellQuads = &quads;
    mTJunctions = -1;
    if (mPrism) {
        splitPinches(cell, out);
        splitIsoPinches(out);
    }
}

void RemeshKernel::loadTet(int t)
{
    mTet = t;
    const auto& tet = cellTets(cellParity(mCell.x(), mCell.y(), mCell.z()))[size_t(t)];
    for (int i = 0; i < 4; ++i) {
        const int c = tet[size_t(i)];
        const Coord g = mCell + Coord(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        mT.p[i] = dvec3(g.x(), g.y(), g.z());
        mT.id[i] = gridVertexId(g.x(), g.y(), g.z());
        // As the isosurface: outside the scan box, the background and outside.
        const bool inBox =
            g.x() >= 0 && g.y() >= 0 && g.z() >= 0 && g.x() < mDims.x() && g.y() < mDims.y() && g.z() < mDims.z();
        mT.value[i] = inBox ? value(g) : mBackground;
        mT.inside[i] = inBox && mT.value[i] >= mIso;
    }
    for (FaceIsoLine& f : mFaceIsoLines) f.known = 0;
}

TetPhaseOne RemeshKernel::phaseOne(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, int t)
{
    mPrism = prism;
    mCell = cell;
    mCellQuads = &quads;
    mTJunctions = -1;
    loadTet(t);
    TetPhaseOne r;
    if (!mT.inside[0] && !mT.inside[1] && !mT.inside[2] && !mT.inside[3]) return r;
    r.solid = true;
    resetTet();
    gatherQuads();
    for (const QuadGeom* q : mQuads) r.quads.push_back(uint32_t(q - quads.data()));
    isoTriangles();
    r.triCount = mTriCount;
    for (int k = 0; k < mTriCount; ++k) {
        r.triEdges[size_t(k)].assign(mTriEdges[size_t(k)].begin(), mTriEdges[size_t(k)].end());
        r.triPts[size_t(k)].assign(mTriPts[k].begin(), mTriPts[k].end());
        r.triPlane[size_t(k)] = mTriPlane[k];
    }
    return r;
}

/// Kerf > 0: a marching-tetrahedra vertex exactly on one plane of the removed
/// region (integer CT values put a crossing at a quarter of an edge, and a
/// stroke at a whole-mm height with a 0.5 mm kerf puts an offset plane
/// there: 1 mm head, z = 1106 mm) whose isosurface star lies strictly on one
/// side of that plane: the isosurface touches the plane at that one point,
/// so the surface is a cone of it and the disc of cap round it, meeting only
/// there (a pinch). The vertex is on a grid edge, and the cells round the
/// edge each hold part of both: the cap triangles at it get a copy of the
/// vertex (pinch tag 1), as splitPinches does inside a tet. The rule is a
/// function of the edge's tets and the plane alone, so every cell round the
/// edge applies it alike.
void RemeshKernel::splitIsoPinches(CutCellGeometry& out)
{
    const uint32_t nv = uint32_t(out.vertexIds.size());
    for (uint32_t v = 0; v < nv; ++v) {
        const CutVertexId& id = out.vertexIds[v];
        if (id.dim != 1 || id.planeCount != 2 || id.planes[0] != 1 || id.tagCount != 0) continue;
        const uint64_t planeId = id.planes[1];
        const Plane* plane = nullptr;
        for (const QuadGeom& q : *mCellQuads) {
            if (q.id == planeId) plane = &q.pi;
            for (const QuadGeom::Side& side : q.sides)
                if (side.id == planeId) plane = &side.plane;
        }
        if (!plane || !isoStarOffPlane(id, *plane)) continue;
        auto onPlane = [&](uint32_t w) {
            const CutVertexId& k = out.vertexIds[w];
            return std::binary_search(k.planes.begin(), k.planes.begin() + k.planeCount, planeId);
        };
        uint32_t copy = UINT32_MAX;
        for (size_t t = 0; t + 2 < out.indices.size(); t += 3) {
            uint32_t* tri = &out.indices[t];
            if ((tri[0] != v && tri[1] != v && tri[2] != v) || !onPlane(tri[0]) || !onPlane(tri[1]) || !onPlane(tri[2]))
                continue;
            if (copy == UINT32_MAX) {
                CutVertexId c = id;
                c.tags[c.tagCount++] = kPinchTag | 1u;
                copy = uint32_t(out.vertexIds.size());
                out.vertexIds.push_back(c);
                out.indexPositions.push_back(out.indexPositions[v]);
            }
            for (int k = 0; k < 3; ++k)
                if (tri[k] == v) tri[k] = copy;
        }
    }
}

/// Whether every marching-tetrahedra crossing of the tets round grid edge
/// v.feature[0..1] (in every cell that has the edge), but v's own, lies
/// strictly on one side of `plane`: v's isosurface star then meets the plane
/// at v alone.
bool RemeshKernel::isoStarOffPlane(const CutVertexId& v, const Plane& plane)
{
    const Coord a = gridVertexCoord(v.feature[0]), b = gridVertexCoord(v.feature[1]);
    const Coord lo(std::min(a.x(), b.x()), std::min(a.y(), b.y()), std::min(a.z(), b.z()));
    auto local = [](const Coord& g, const Coord& c) {
        const Coord d = g - c;
        if (d.x() < 0 || d.y() < 0 || d.z() < 0 || d.x() > 1 || d.y() > 1 || d.z() > 1) return -1;
        return d.x() | d.y() << 1 | d.z() << 2;
    };
    auto sample = [&](const Coord& g, float& value) {
        const bool inBox = g.x() >= 0 && g.y() >= 0 && g.z() >= 0 && g.x() < mDims.x() && g.y() < mDims.y() &&
                           g.z() < mDims.z();
        value = inBox ? this->value(g) : mBackground;
        return inBox && value >= mIso;
    };
    int side = 0;
    for (int e = 0; e < 8; ++e) {
        const Coord c = lo - Coord(e & 1, e >> 1 & 1, e >> 2 & 1);
        const int la = local(a, c), lb = local(b, c);
        if (la < 0 || lb < 0) continue;
        for (const auto& tet : cellTets(cellParity(c.x(), c.y(), c.z()))) {
            if (std::find(tet.begin(), tet.end(), la) == tet.end() || std::find(tet.begin(), tet.end(), lb) == tet.end())
                continue;
            for (int i = 0; i < 4; ++i)
                for (int j = i + 1; j < 4; ++j) {
                    if ((tet[size_t(i)] == la && tet[size_t(j)] == lb) || (tet[size_t(i)] == lb && tet[size_t(j)] == la))
                        continue; // v's own edge
                    Coord gl = c + Coord(tet[size_t(i)] & 1, tet[size_t(i)] >> 1 & 1, tet[size_t(i)] >> 2 & 1);
                    Coord gh = c + Coord(tet[size_t(j)] & 1, tet[size_t(j)] >> 1 & 1, tet[size_t(j)] >> 2 & 1);
                    if (gridVertexId(gh.x(), gh.y(), gh.z()) < gridVertexId(gl.x(), gl.y(), gl.z())) std::swap(gl, gh);
                    float vl, vh;
                    if (sample(gl, vl) == sample(gh, vh)) continue;
                    const dvec3 pl(gl.x(), gl.y(), gl.z()), ph(gh.x(), gh.y(), gh.z());
                    const double h = plane.h(pl + edgeCrossing(vl, vh, mIso) * (ph - pl));
                    const int s = h > 0 ? 1 : h < 0 ? -1 : 0;
                    if (s == 0 || (side != 0 && s != side)) return false;
                    side = s;
                }
        }
    }
    return side != 0;
}

namespace {

void splitPinches(const openvdb::Coord& cell, CutCellGeometry& out)
{
    const uint32_t nv = uint32_t(out.vertexIds.size());
    const size_t nt = out.indices.size() / 3;
    // Triangles around each tet-inside vertex (only its tet's triangles can use it).
    std::vector<std::vector<uint32_t>> around;
    std::vector<int32_t> slot(nv, -1);
    for (size_t t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = out.indices[3 * t + size_t(k)];
            if (out.vertexIds[v].dim != 3) continue;
            if (slot[v] < 0) {
                slot[v] = int32_t(around.size());
                around.emplace_back();
            }
            around[size_t(slot[v])].push_back(uint32_t(t));
        }
    for (uint32_t v = 0; v < nv; ++v) {
        if (slot[v] < 0) continue;
        const std::vector<uint32_t>& tris = around[size_t(slot[v])];
        if (tris.size() < 6) continue; // two fans need at least 3 triangles each
        // Link edges b -> c of the triangles (v, b, c); fans = their components.
        std::vector<std::pair<uint32_t, uint32_t>> link(tris.size());
        for (size_t i = 0; i < tris.size(); ++i) {
            const uint32_t* tri = &out.indices[3 * tris[i]];
            const int k = tri[0] == v ? 0 : tri[1] == v ? 1 : 2;
            link[i] = {tri[(k + 1) % 3], tri[(k + 2) % 3]};
        }
        std::vector<int> fan(tris.size(), -1);
        int fans = 0;
        for (size_t s = 0; s < tris.size(); ++s) {
            if (fan[s] >= 0) continue;
            std::vector<size_t> stack{s};
            fan[s] = fans;
            while (!stack.empty()) {
                const size_t a = stack.back();
                stack.pop_back();
                for (size_t b = 0; b < tris.size(); ++b)
                    if (fan[b] < 0 && (link[b].first == link[a].second || link[b].second == link[a].first ||
                                       link[b].first == link[a].first || link[b].second == link[a].second)) {
                        fan[b] = fans;
                        stack.push_back(b);
                    }
            }
            ++fans;
        }
        if (fans < 2) continue;
        // Each fan must be one closed cycle (a disc); otherwise leave it to the
        // local check, which refuses the cell.
        bool discs = true;
        for (int f = 0; f < fans && discs; ++f) {
            std::map<uint32_t, int> out1, in1;
            for (size_t i = 0; i < tris.size(); ++i)
                if (fan[i] == f) {
                    ++out1[link[i].first];
                    ++in1[link[i].second];
                }
            for (const auto& [u, c] : out1) discs = discs && c == 1 && in1[u] == 1;
            discs = discs && out1.size() == in1.size();
        }
        if (!discs) continue;
        // Fan 0 (the one with the first triangle) keeps the vertex; each other
        // fan gets a copy at the same position, told apart by a pinch tag.
        for (int f = 1; f < fans; ++f) {
            CutVertexId id = out.vertexIds[v];
            if (id.tagCount >= id.tags.size())
                throw std::runtime_error("remesh: a pinch point whose vertex has no free tag in cell " + cellText(cell));
            id.tags[id.tagCount++] = kPinchTag | uint64_t(f);
            const uint32_t copy = uint32_t(out.vertexIds.size());
            out.vertexIds.push_back(id);
            out.indexPositions.push_back(out.indexPositions[v]);
            for (size_t i = 0; i < tris.size(); ++i)
                if (fan[i] == f)
                    for (int k = 0; k < 3; ++k)
                        if (out.indices[3 * tris[i] + size_t(k)] == v) out.indices[3 * tris[i] + size_t(k)] = copy;
        }
    }
}

} // namespace

/// Even permutation of (0,1,2,3) starting with the given 1 or 2 entries (as the isosurface tables).
static std::array<int, 4> evenPerm(std::initializer_list<int> first)
{
    std::array<int, 4> p{};
    int n = 0;
    for (int f : first) p[size_t(n++)] = f;
    for (int v = 0; v < 4; ++v)
        if (std::find(p.begin(), p.begin() + n, v) == p.begin() + n) p[size_t(n++)] = v;
    int inv = 0;
    for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) inv += p[size_t(a)] > p[size_t(b)];
    if (inv & 1) std::swap(p[2], p[3]);
    return p;
}

/// One tet (mT) of the cell: the surfaces to arrange (its marching-tetrahedra
/// triangles and the blade's caps through it), each split by the planes of the
/// others, the pieces kept by the removed region's rule, joined into regions
/// per side across shared edges (not across slits), their loops traced, and
/// the regions triangulated into `out`, vertices named (CutVertexId) so that
/// the tets and cells around weld by name; mCellIndex maps the names `out`
/// holds to their index.
void RemeshKernel::remeshTet(CutCellGeometry& out)
{
    // No solid in the tet (all four values below the isovalue): P is empty,
    // so there is neither an iso piece nor a cap (caps are kept inside P;
    // prism faces inside the solid). Most cells of a cut through a head are
    // air; they cost nothing now.
    if (!mT.inside[0] && !mT.inside[1] && !mT.inside[2] && !mT.inside[3]) return;
    resetTet();
    gatherQuads();
    if (!isoTriangles()) return;
    finishPlanes();
    isoSurfaces();
    capSurfaces();
    chooseSplitOrder();
    // Per surface: its arrangement, classified, traced into regions.
    SmallVector<char, 32> kept;
    for (const Surface& s : mSurfaces) {
        splitSurface(s);
        conformPieces();
        classifyPieces(s, kept);
        insertSlitMidpoints(kept);
        if (mArrangeCapture) {
            ArrangementProbe::Surface& probe = (*mArrangeCapture)[size_t(mTet)].surfaces.emplace_back();
            probe.plane = s.plane;
            for (size_t i = 0; i < mPieces.size(); ++i)
                probe.pieces.push_back({std::vector<int>(mPieces[i].v.begin(), mPieces[i].v.end()),
                                        std::vector<uint64_t>(mPieces[i].lab.begin(), mPieces[i].lab.end()), kept[i] != 0});
        }
        for (int side : {1, -1}) {
            if (s.quad && !mPrism ? !(s.sides & (side > 0 ? 1 : 2)) : side < 0) continue;
            traceRegions(s, side, kept);
        }
    }
    SmallVector<char, 64> corner;
    markCorners(corner);
    triangulateRegions(corner, out);
    if (mArrangeCapture) {
        ArrangementProbe& probe = (*mArrangeCapture)[size_t(mTet)];
        probe.solid = true;
        for (const Vert& v : mVerts) probe.verts.push_back({v.key, v.support, v.pos, v.steiner});
    }
}

void RemeshKernel::resetTet()
{
    mMemo.reset();
    mSlitKnown = 0; // the slit memo, per tet
    mSlitMemo.clear();
    mVerts.clear();
    mVertHash.clear();
    if (mHashIndexed) {
        mHashChain.reset();
        mNextSameHash.clear();
        mNear.reset();
        mNearNext.clear();
        mHashIndexed = false;
    }
    mSignTab.clear();
    mSignStride = 0;
    mSignCap = 0;
    mQuads.clear();
    mPlanes.clear();
    mTriCount = 0;
    std::fill(std::begin(mFaceTri), std::end(mFaceTri), -1);
    mSurfaces.clear();
    mSplitOrder.clear();
    mNodes.clear();
    mNodeHead.clear();
    mNodeNext.clear();
    mRegions.clear();
}

void RemeshKernel::gatherQuads()
{
    // Quads whose region can reach the tet.
    for (const QuadGeom& q : *mCellQuads) {
        auto crosses = [&](const Plane& p) {
            bool pos = false, neg = false;
            for (int i = 0; i < 4; ++i) {
                const double h = p.h(mT.p[i]), e = epsAt(mT.p[i]);
                pos |= h >= -e;
                neg |= h <= e;
            }
            return pos && neg;
        };
        if (!mPrism && !crosses(q.pi)) continue;
        bool reach = true;
        for (const auto& s : q.sides) {
            bool any = false;
            for (int i = 0; i < 4; ++i) any |= s.orient * s.plane.h(mT.p[i]) >= -epsAt(mT.p[i]);
            reach = reach && any;
        }
        if (!reach) continue;
        mQuads.push_back(&q);
        if (!mPrism) mPlanes.push_back({q.id, q.pi});
        for (const auto& s : q.sides) mPlanes.push_back({s.id, s.plane});
    }
}

/// The marching-tetrahedra triangles of the tet and their planes; false
/// when the tet holds no solid.
bool RemeshKernel::isoTriangles()
{
    // Marching-tetrahedra triangles of the tet (as the isosurface tables).
    int ni = 0, ins[4], outs[4], no = 0;
    for (int i = 0; i < 4; ++i) {
        if (mT.inside[i]) ins[ni++] = i;
        else outs[no++] = i;
    }
    if (ni == 0) return false; // nothing solid here
    auto& triEdges = mTriEdges;
    triEdges.clear();
    if (ni == 1 || ni == 3) {
        const int lone = ni == 1 ? ins[0] : outs[0];
        const auto p = evenPerm({lone});
        const int a = p[0], b = p[1], c = p[2], d = p[3];
        if (ni == 1) triEdges.push_back({{a, b}, {a, c}, {a, d}});
        else triEdges.push_back({{a, b}, {a, d}, {a, c}});
    } else if (ni == 2) {
        const auto p = evenPerm({ins[0], ins[1]});
        const int a = p[0], b = p[1], c = p[2], d = p[3];
        // The marching-tetrahedra quad; when its (clamped) corners are not
        // coplanar it is the two triangles of the isosurface, a fold.
        const dvec3 pac = mtPoint(a, c), pad = mtPoint(a, d), pbd = mtPoint(b, d), pbc = mtPoint(b, c);
        const dvec3 nrm = glm::cross(pad - pac, pbd - pac);
        const double dev = glm::dot(nrm, pbc - pac) / glm::length(nrm);
        if (std::abs(dev) <= 1e-7) {
            triEdges.push_back({{a, c}, {a, d}, {b, d}, {b, c}});
        } else {
            triEdges.push_back({{a, c}, {a, d}, {b, d}});
            triEdges.push_back({{a, c}, {b, d}, {b, c}});
        }
    }
    mTriCount = int(triEdges.size());
    // Iso planes first (so ISO_A/B sort first in mPlanes too).
    auto& triPts = mTriPts;
    triPts[0].clear();
    triPts[1].clear();
    for (int k = 0; k < mTriCount; ++k) {
        for (const auto& e : triEdges[size_t(k)]) triPts[k].push_back(mtPoint(e[0], e[1]));
        dvec3 nrm(0.0);
        const size_t n = triPts[k].size();
        for (size_t c = 0; c < n; ++c) nrm += glm::cross(triPts[k][c], triPts[k][(c + 1) % n]); // Newell
        const double len = glm::length(nrm);
        mTriPlane[k].n = len > 0 ? -nrm / len : dvec3(0.0);
        dvec3 centre(0.0);
        for (const dvec3& q : triPts[k]) centre += q / double(n);
        mTriPlane[k].d = glm::dot(mTriPlane[k].n, centre);
        mPlanes.push_back({kIsoA + uint64_t(k), mTriPlane[k]});
    }
    return true;
}

void RemeshKernel::finishPlanes()
{
    std::sort(mPlanes.begin(), mPlanes.end(),
              [](const std::pair<uint64_t, Plane>& a, const std::pair<uint64_t, Plane>& b) { return a.first < b.first; });
    mPlanes.erase(std::unique(mPlanes.begin(), mPlanes.end(),
                              [](const std::pair<uint64_t, Plane>& a, const std::pair<uint64_t, Plane>& b) {
                                  return a.first == b.first;
                              }),
                  mPlanes.end());
    mSignStride = mPlanes.size();
    buildPlaneSlots();
    if (mTriCount == 2) mFoldConvex = mTriPlane[0].h(mTriPts[1][2]) >= 0;
}

void RemeshKernel::isoSurfaces()
{
    auto& surfaces = mSurfaces;
    const auto& triEdges = mTriEdges;
    const auto& triPts = mTriPts;
    for (int k = 0; k < mTriCount; ++k) {
        Surface s;
        s.plane = kIsoA + uint64_t(k);
        s.quad = nullptr;
        s.sides = 1;
        s.normal = -mTriPlane[k].n;
        const size_t n = triEdges[size_t(k)].size();
        mTriVerts[k].clear();
        mTriEdgeMasks[k].clear();
        for (const auto& e : triEdges[size_t(k)]) mTriEdgeMasks[k].push_back(uint8_t(1 << e[0] | 1 << e[1]));
        for (size_t c = 0; c < n; ++c) {
            const auto& e = triEdges[size_t(k)][c];
            s.poly.v.push_back(makeVertex(uint8_t(1 << e[0] | 1 << e[1]), {kIsoA + uint64_t(k)}, triPts[k][c]));
            mTriVerts[k].push_back(s.poly.v.back());
        }
        for (size_t c = 0; c < n; ++c) {
            const auto& e0 = triEdges[size_t(k)][c];
            const auto& e1 = triEdges[size_t(k)][(c + 1) % n];
            const uint8_t m = uint8_t(1 << e0[0] | 1 << e0[1] | 1 << e1[0] | 1 << e1[1]);
            if (m == 15) {
                s.poly.lab.push_back(kIsoA + uint64_t(1 - k));
            } else {
                s.poly.lab.push_back(kBoundaryLabel | m);
                int f = 0;
                while (m >> f & 1) ++f;
                mFaceTri[f] = k;
            }
        }
        surfaces.push_back(std::move(s));
    }
}

void RemeshKernel::capSurfaces()
{
    auto& surfaces = mSurfaces;
    // Caps: the quad's plane through the tet; with kerf, every face plane of
    // the prism (one-sided, its surface normal pointing into the prism).
    struct FacePlane
    {
        const QuadGeom* q;
        uint64_t id;
        Plane plane;
        dvec3 normal; // surface normal (zero kerf: reference normal of the two-sided cap)
    };
    SmallVector<FacePlane, 8> facePlanes;
    for (const QuadGeom* q : mQuads) {
        if (!mPrism) {
            facePlanes.push_back({q, q->id, q->pi, q->pi.n});
            continue;
        }
        for (const auto& sd : q->sides) facePlanes.push_back({q, sd.id, sd.plane, sd.orient * sd.plane.n});
    }
    // The section of the tet by a face plane: its corners (the plane through
    // the tet's corners and edges: simplex and position, in this order).
    using Corners = SmallVector<std::pair<uint8_t, dvec3>, 8>;
    auto section = [&](const Plane& plane, Corners& at, double h[4]) {
        int on = 0;
        for (int i = 0; i < 4; ++i) {
            h[i] = plane.h(mT.p[i]);
            if (std::abs(h[i]) <= epsAt(mT.p[i])) {
                h[i] = 0;
                ++on;
            }
        }
        at.clear();
        for (int i = 0; i < 4; ++i)
            if (h[i] == 0) at.push_back({uint8_t(1 << i), mT.p[i]});
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j) {
                if (!(h[i] * h[j] < 0)) continue;
                int a = i, b = j;
                if (mT.id[b] < mT.id[a]) std::swap(a, b);
                const double t = h[a] / (h[a] - h[b]);
                at.push_back({uint8_t(1 << i | 1 << j), mT.p[a] + t * (mT.p[b] - mT.p[a])});
            }
        return on;
    };
    // First the faces that are surfaces (a section with an area, not a tet
    // face this tet's side of which the prism is on) and, kerf > 0, the
    // coincident faces of later prisms joined to them (Surface::also).
    const size_t first = surfaces.size();
    SmallVector<const FacePlane*, 8> faceOf; // per new surface
    SmallVector<Corners, 8> sectionOf;       // per new surface: its section's corners
    Corners at;
    double h[4];
    for (const FacePlane& fp : facePlanes) {
        const QuadGeom* q = fp.q;
        if (mPrism) {
            // The same face plane, or another quad's that coincides with it
            // over the tet (coplanar consecutive quads: their offset faces),
            // facing the same way: joined, so the region runs on across the
            // mitre between them instead of ending at it on both sides.
            size_t k = first;
            while (k < surfaces.size() && !(glm::dot(surfaces[k].normal, fp.normal) > 0 &&
                                            (surfaces[k].plane == fp.id ||
                                             (mJoinCoincident && coincidentOverTet(faceOf[k - first]->plane, fp.plane)))))
                ++k;
            if (k < surfaces.size()) {
                mCoincidentJoins += surfaces[k].plane != fp.id;
                surfaces[k].also.push_back(q);
                continue;
            }
        }
        const int on = section(fp.plane, at, h);
        if (at.size() < 3) continue;
        Surface s;
        s.plane = fp.id;
        s.quad = q;
        s.normal = fp.normal;
        s.sides = 3;
        if (on == 3) { // the plane is a tet face: only the cap facing away from this tet
            int f = 0;
            while (h[f] == 0) ++f;
            s.sides = h[f] > 0 ? 1 : 2;
            if (mPrism && glm::dot(fp.normal, fp.plane.n) * h[f] > 0) continue; // faces into this tet
        }
        if (mPrism) s.sides = 1;
        surfaces.push_back(std::move(s));
        faceOf.push_back(&fp);
        sectionOf.push_back(at);
    }
    // Then each one's polygon, or, when no piece of it can be kept, none:
    // a cap's pieces are kept only inside its own quad (kerf > 0: its own
    // closed prism, or a joined one's) and inside the solid, and where the
    // section of the tet holds no such point by kApart (capOutside), the
    // cap is not arranged at all (at kerf 0.5, a third of the caps of the
    // 1 mm head's 11,748-cell cut).
    size_t kept = first;
    for (size_t k = first; k < surfaces.size(); ++k) {
        Surface& s = surfaces[k];
        const FacePlane& fp = *faceOf[k - first];
        const Corners& corners = sectionOf[k - first];
        bool outside = mSkipOutsideCaps && capOutside(*s.quad, fp.id, corners);
        for (const QuadGeom* o : s.also) outside = outside && capOutside(*o, fp.id, corners);
        if (outside) continue;
        SmallVector<std::pair<int, dvec3>, 8> pts; // vertex, position
        for (const auto& [support, x] : corners) pts.push_back({makeVertex(support, {fp.id}, x), x});
        dvec3 c(0.0);
        for (const auto& p : pts) c += p.second;
        c /= double(pts.size());
        dvec3 e1 = glm::normalize(pts[0].second - c);
        const dvec3 e2 = glm::cross(s.normal, e1);
        {
            // By angle about the centre (poly2::angleLess, atan2's order), in
            // a stable insertion sort (at most four corners).
            SmallVector<std::pair<Vec2, std::pair<int, dvec3>>, 8> byAngle;
            for (const auto& p : pts)
                byAngle.push_back({Vec2{glm::dot(p.second - c, e1), glm::dot(p.second - c, e2)}, p});
            for (size_t i = 1; i < byAngle.size(); ++i)
                for (size_t j = i; j > 0 && poly2::angleLess(byAngle[j].first, byAngle[j - 1].first); --j)
                    std::swap(byAngle[j], byAngle[j - 1]);
            for (size_t i = 0; i < pts.size(); ++i) pts[i] = byAngle[i].second;
        }
        for (size_t i = 0; i < pts.size(); ++i) {
            s.poly.v.push_back(pts[i].first);
            const uint8_t m = uint8_t(mVerts[size_t(pts[i].first)].support |
                                      mVerts[size_t(pts[(i + 1) % pts.size()].first)].support);
            s.poly.lab.push_back(kBoundaryLabel | m);
        }
        if (kept != k) surfaces[kept] = std::move(s);
        ++kept;
    }
    surfaces.erase(surfaces.begin() + std::ptrdiff_t(kept), surfaces.end());
}

uint64_t RemeshKernel::joinedSurfaceId(uint64_t id) const
{
    if (!mJoinCoincident) return id;
    for (const Surface& s : mSurfaces) {
        if (s.also.empty() || s.plane == id) continue;
        const Plane* plane = nullptr; // the surface's own face plane
        for (const auto& sd : s.quad->sides)
            if (sd.id == s.plane) plane = &sd.plane;
        if (!plane) continue;
        for (const QuadGeom* q : s.also)
            for (const auto& sd : q->sides)
                if (sd.id == id && glm::dot(sd.orient * sd.plane.n, s.normal) > 0 && coincidentOverTet(*plane, sd.plane))
                    return s.plane;
    }
    return id;
}

bool RemeshKernel::capOutside(const QuadGeom& q, uint64_t face, const SmallVector<std::pair<uint8_t, dvec3>, 8>& at) const
{
    // The section clipped by each half-space grown by kApart (1 + |x|)
    // (Sutherland-Hodgman): the quad's sides (kerf > 0: its prism's other
    // faces), then the solid P (one iso plane; a convex fold both; a concave
    // fold, the union, either). Grown, an empty clip leaves no point that
    // a tie (epsAt) could put inside.
    using Clip = SmallVector<dvec3, 16>;
    auto grow = [](const dvec3& x) { return kApart * (1.0 + std::max({std::abs(x.x), std::abs(x.y), std::abs(x.z)})); };
    // `in` clipped into `out`; *from points at the result: `in` itself
    // when every corner is kept (no copy), else `out`.
    auto clipInto = [&](const Clip& in, const Plane& plane, double orient, Clip& out, const Clip*& from) {
        const size_t n = in.size();
        SmallVector<double, 16> h(n); // each corner's grown value once
        bool allIn = true;
        for (size_t i = 0; i < n; ++i) {
            h[i] = orient * plane.h(in[i]) + grow(in[i]);
            allIn = allIn && h[i] >= 0;
        }
        if (allIn) { // every corner kept, no crossing
            from = &in;
            return n > 0;
        }
        out.clear();
        for (size_t i = 0; i < n; ++i) {
            const dvec3 &a = in[i], &b = in[(i + 1) % n];
            const double ha = h[i], hb = h[(i + 1) % n];
            if (ha >= 0) out.push_back(a);
            if ((ha >= 0) != (hb >= 0)) out.push_back(a + (ha / (ha - hb)) * (b - a));
        }
        from = &out;
        return !out.empty();
    };
    // The corners in their cyclic order: `at` lists four (a plane between
    // two pairs of tet corners) by edge, and the middle two then share no
    // tet face.
    Clip buffers[2];
    for (const auto& corner : at) buffers[0].push_back(corner.second);
    if (buffers[0].size() == 4 && bits(uint8_t(at[1].first | at[2].first)) == 4) std::swap(buffers[0][2], buffers[0][3]);
    const Clip* cur = &buffers[0]; // the section so far, in one of the buffers
    auto other = [&] { return cur == &buffers[0] ? &buffers[1] : &buffers[0]; };
    const QuadGeom::Side* mitre = nullptr;
    for (const auto& sd : q.sides) {
        if (sd.id == face) {
            mitre = sd.partnerId != 0 ? &sd : nullptr;
            continue;
        }
        if (!clipInto(*cur, sd.plane, sd.orient, *other(), cur)) return true;
    }
    const Clip& p = *cur;
    // Kerf > 0, a mitre (the junction face q shares with the previous or
    // the next prism of the stroke, which faces the other way there): its
    // pieces are kept only outside every other closed prism, so none is when
    // the partner prism, reaching this tet, holds the whole grown section.
    // Each of the partner's other faces holds it when it is one of q's faces
    // the same way (a rim continued through the joint: the pieces kept lie
    // inside q's), an offset face of the kind of one of q's (the two meet on
    // the mitre, which bisects them), or has every grown corner on its inner
    // side. Where the rims do not continue (the blade turns or changes
    // length), a wedge of the mitre is a face of the union and is arranged.
    // On the 1 mm head's 425-cell cut at kerf 0.5 no mitre kept a piece,
    // and the partner holds every one of them.
    if (mitre && mPrism && mSkipHeldMitres) {
        if (const QuadGeom* o = quadById(mitre->partnerId)) {
            bool holds = true;
            for (const auto& sd : o->sides) {
                if (sd.id == face) continue;
                const uint64_t kind = sd.id & 15;
                const bool offset = kind == uint64_t(kPlusKind) || kind == uint64_t(kMinusKind);
                const bool same = std::any_of(q.sides.begin(), q.sides.end(), [&](const QuadGeom::Side& m) {
                    return m.id == sd.id ? m.orient == sd.orient : offset && (m.id & 15) == kind;
                });
                if (same) continue;
                for (const dvec3& x : p) holds = holds && sd.orient * sd.plane.h(x) >= 0.0;
                if (!holds) break;
            }
            if (holds) return true;
        }
    }
    if (mTriCount == 0) return false; // solid throughout
    Clip spare; // (p is one of the buffers; the other is free)
    Clip& free = *other();
    const Clip* a = nullptr;
    const bool inA = clipInto(p, mTriPlane[0], 1.0, free, a);
    if (mTriCount == 1) return !inA;
    const Clip* b = nullptr;
    if (mFoldConvex) return !inA || !clipInto(*a, mTriPlane[1], 1.0, a == &free ? spare : free, b);
    return !inA && !clipInto(p, mTriPlane[1], 1.0, spare, b);
}

void RemeshKernel::chooseSplitOrder()
{
    auto& splitOrder = mSplitOrder;
    // A blade plane with the whole tet strictly on one side (every corner
    // farther than kApart from it) splits nothing here: every point of the
    // tet is on that side, none lies on it (the tie is 1e-13 (1 + |x|)),
    // so no vertex is named by it. Its signs are still asked (sides).
    auto apart = [&](const Plane& p) {
        bool pos = true, neg = true;
        for (int i = 0; i < 4; ++i) {
            const double h = p.h(mT.p[i]), e = kApart * (1.0 + std::max({std::abs(mT.p[i].x), std::abs(mT.p[i].y), std::abs(mT.p[i].z)}));
            pos = pos && h > e;
            neg = neg && h < -e;
        }
        return pos || neg;
    };
    for (const auto& pl : mPlanes)
        if (pl.first <= kIsoB) splitOrder.push_back({pl.first, nullptr});
    for (const auto& pl : mPlanes)
        if (pl.first > kIsoB && (pl.first & 15) == kJunctionKind && !apart(pl.second)) splitOrder.push_back({pl.first, nullptr});
    for (const auto& pl : mPlanes) {
        if (pl.first <= kIsoB || (pl.first & 15) == kJunctionKind || apart(pl.second)) continue;
        const QuadGeom* owner = nullptr;
        for (const QuadGeom* q : mQuads)
            if ((q->id >> 4) == (pl.first >> 4)) owner = q;
        // Prisms: a rim plane shared along the stroke by several quads here
        // splits everywhere (each of them needs it); one that a single quad
        // has among its sides splits within that quad's junction zone,
        // which need not be the quad it is named by (a cap at a sharp corner
        // of a mitred joint is named by the lower quad, and only the quad
        // whose corner is sharp has it: 1 mm head, kerf 0.5, seed 16497).
        if (mPrism && owner) {
            int users = 0;
            const QuadGeom* user = nullptr;
            for (const QuadGeom* q : mQuads)
                for (const auto& sd : q->sides)
                    if (sd.id == pl.first) {
                        ++users;
                        user = q;
                    }
            if (users > 1) owner = nullptr;
            else if (users == 1) owner = user;
        }
        splitOrder.push_back({pl.first, owner});
    }
}

int RemeshKernel::nodeOf(int vert, Tags& tags)
{
    std::vector<Node>& nodes = mNodes;
    std::vector<int>& nodeHead = mNodeHead;
    std::vector<int>& nodeNext = mNodeNext;
    std::sort(tags.begin(), tags.end());
    if (size_t(vert) >= nodeHead.size()) nodeHead.resize(mVerts.size() + 16, -1);
    int last = -1;
    for (int i = nodeHead[size_t(vert)]; i >= 0; i = nodeNext[size_t(i)]) {
        if (nodes[size_t(i)].tags == tags) return i;
        last = i;
    }
    nodes.emplace_back();
    nodes.back().vert = vert;
    nodes.back().tags.assign(tags.begin(), tags.end());
    nodeNext.push_back(-1);
    const int id = int(nodes.size() - 1);
    (last < 0 ? nodeHead[size_t(vert)] : nodeNext[size_t(last)]) = id;
    return id;
}

bool RemeshKernel::crosses(const Poly& p, uint64_t id)
{
    bool pos = false, neg = false;
    for (int v : p.v) {
        const int sg = sign(v, id);
        pos |= sg > 0;
        neg |= sg < 0;
    }
    return pos && neg;
}

int RemeshKernel::pieceSign(const Poly& p, uint64_t id)
{
    for (int v : p.v) {
        const int sg = sign(v, id);
        if (sg != 0) return sg;
    }
    return 0;
}

void RemeshKernel::splitSurface(const Surface& s)
{
    // Every piece made is kept in a pool by number, and the pieces now are
    // a list of numbers: a piece a plane splits is replaced in the list by
    // its pieces, in order (the others stay where they are). Once a plane
    // splits one, the numbers are copied into `nextOrder` as they come, so
    // that a plane costs one pass however many it splits, and a piece is
    // moved once, into mPieces at the end (a cell where 30 prisms cross has
    // thousands of pieces, and most planes split a few).
    std::vector<Poly>& pool = mPiecePool;
    std::vector<Poly>& made = mNextPieces; // one piece's split (splitPoly's out)
    std::vector<int>& order = mPieceOrder;
    std::vector<int>& nextOrder = mNextPieceOrder;
    const auto& splitOrder = mSplitOrder;
    pool.clear();
    pool.push_back(s.poly);
    order.assign(1, 0);
    for (const SplitPlane& sp : splitOrder) {
        if (sp.id == s.plane) continue;
        if (!s.quad && (sp.id == kIsoA || sp.id == kIsoB)) continue;
        bool moving = false; // order[0, i) is in `nextOrder`
        const Plane* plane = planeById(sp.id);
        for (size_t i = 0; i < order.size(); ++i) {
            const Poly& p = pool[size_t(order[i])];
            // Every corner strictly on one side of the plane: splitPoly would
            // find none on the other (a sign is 0 or that of h, sign()), so
            // the piece stays, without its corners' signs. Most pieces of a
            // cell where many prisms cross lie off most of the planes.
            bool above = plane && mSkipFar, below = above;
            for (size_t k = 0; k < p.v.size() && (above || below); ++k) {
                const double h = plane->h(mVerts[size_t(p.v[k])].pos);
                above = above && h > 0;
                below = below && h < 0;
            }
            // A quad's plane and rim sides only split inside its junction zone,
            // so near-coincident planes of consecutive quads never meet there.
            bool outside = above || below;
            mFarSkips += outside;
            if (sp.owner && !outside)
                for (const auto& sd : sp.owner->sides)
                    if (sd.partner >= 0 && sd.orient * pieceSign(p, sd.id) < 0) {
                        outside = true;
                        // Left whole though the plane may cross it: a split
                        // of a neighbour inside the zone can end on its edge.
                        if (!p.open) pool[size_t(order[i])].open = crosses(p, sp.id);
                        break;
                    }
            made.clear();
            if (!outside && splitPoly(p, s.plane, sp.id, made)) {
                if (!moving) { // the pieces before this one
                    nextOrder.assign(order.begin(), order.begin() + std::ptrdiff_t(i));
                    moving = true;
                }
                for (Poly& m : made) { // (p is not used again: the pool may move)
                    nextOrder.push_back(int(pool.size()));
                    pool.push_back(std::move(m));
                }
                continue;
            }
            if (moving) nextOrder.push_back(order[i]);
        }
        if (moving) order.swap(nextOrder);
    }
    mPieces.clear();
    for (int i : order) mPieces.push_back(std::move(pool[size_t(i)]));
}

/// Conformity: restricted splits end on junction lines; their end points
/// go on the neighbouring pieces' edges too (no T-junction inside). Then a
/// piece folded onto itself is split into simple loops.
void RemeshKernel::conformPieces()
{
    std::vector<Poly>& pieces = mPieces;
    std::vector<Poly>& next = mNextPieces;
    // The pieces' vertices, each once, as they come (an edge sorts the
    // points it takes by their place along it, so their order here does
    // not matter).
    SmallVector<int, 32> all;
    if (++mVertStampNow == 0) {
        std::fill(mVertStamp.begin(), mVertStamp.end(), 0u);
        mVertStampNow = 1;
    }
    if (mVertStamp.size() < mVerts.size()) mVertStamp.resize(mVerts.size() + 64, 0u);
    for (const Poly& p : pieces)
        for (int v : p.v)
            if (mVertStamp[size_t(v)] != mVertStampNow) {
                mVertStamp[size_t(v)] = mVertStampNow;
                all.push_back(v);
            }
    // The vertices of `all` on each edge label's line, found once per label
    // rather than once per edge: a cell where many quads pivot has
    // thousands of edges and vertices here. There they are sorted along the
    // axis their positions spread most, so that an edge looks only at those
    // within its own reach along that axis (a vertex the edge takes lies
    // within 1e-9 (1 + |d|) of it). onLabel: (label, begin, end, axis) of
    // its vertices in mOnLine.
    SmallVector<std::array<uint64_t, 4>, 8> onLabel;
    std::vector<int>& onLine = mOnLine;
    onLine.clear();
    // Per plane label: how far off its plane a vertex an edge of that label
    // takes can lie (the ends' |h| and the test's reach), so that one
    // farther off is passed over without its sign. Only where there are
    // many vertices: in an ordinary tet (a few dozen) finding the bounds
    // and sorting cost more than they save.
    const bool skipFar = mSkipFar && all.size() > kFarVertices;
    SmallVector<std::pair<uint64_t, double>, 16> offBound;
    if (skipFar)
        for (const Poly& p : pieces)
            for (size_t k = 0; k < p.v.size(); ++k) {
                const uint64_t L = p.lab[k];
                if (L & kBoundaryLabel) continue;
                const Plane* pl = planeById(L);
                if (!pl) continue;
                const dvec3 &a = mVerts[size_t(p.v[k])].pos, &b = mVerts[size_t(p.v[(k + 1) % p.v.size()])].pos;
                const double len = glm::length(b - a), nlen = glm::length(pl->n);
                const double far = std::max(std::abs(pl->h(a)), std::abs(pl->h(b))) + nlen * 2e-9 * (1 + len) +
                                   1e-9 * (1 + nlen) *
                                       (1 + std::max({std::abs(a.x), std::abs(a.y), std::abs(a.z), std::abs(b.x), std::abs(b.y),
                                                      std::abs(b.z)})) +
                                   1e-9 * std::abs(pl->d);
                auto it = std::find_if(offBound.begin(), offBound.end(), [&](const auto& e) { return e.first == L; });
                if (it == offBound.end()) offBound.push_back({L, far});
                else it->second = std::max(it->second, far);
            }
    auto onLineOf = [&](uint64_t L, int& axis) -> std::pair<const int*, const int*> {
        for (const auto& e : onLabel)
            if (e[0] == L) {
                axis = int(e[3]);
                return {onLine.data() + e[1], onLine.data() + e[2]};
            }
        const size_t begin = onLine.size();
        dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
        const Plane* pl = nullptr;
        double far = 0.0;
        if (!(L & kBoundaryLabel))
            for (const auto& e : offBound)
                if (e.first == L) {
                    pl = planeById(L);
                    far = e.second;
                }
        for (int x : all) {
            const Vert& vx = mVerts[size_t(x)];
            if (pl && !(std::abs(pl->h(vx.pos)) <= far)) { // no edge of L reaches it
                ++mFarSkips;
                continue;
            }
            const bool on = (L & kBoundaryLabel) ? (vx.support & ~uint8_t(L & 15)) == 0 : sign(x, L) == 0;
            if (!on) continue;
            onLine.push_back(x);
            if (!skipFar) continue;
            lo = glm::min(lo, vx.pos);
            hi = glm::max(hi, vx.pos);
        }
        const dvec3 spread = hi - lo;
        axis = !skipFar || (spread.x >= spread.y && spread.x >= spread.z) ? 0 : spread.y >= spread.z ? 1 : 2;
        if (skipFar)
            std::sort(onLine.begin() + std::ptrdiff_t(begin), onLine.end(), [&](int x, int y) {
                const double px = mVerts[size_t(x)].pos[axis], py = mVerts[size_t(y)].pos[axis];
                return px != py ? px < py : x < y;
            });
        onLabel.push_back({L, begin, onLine.size(), uint64_t(axis)});
        return {onLine.data() + begin, onLine.data() + onLine.size()};
    };
    for (Poly& p : pieces) {
        // Only a piece that some crossing plane left whole (Poly::open) can
        // have another's vertex inside an edge: every other piece was split
        // by each plane that crosses it, at the points its neighbours were
        // split at (one name, so one vertex).
        if (!p.open && mConformOpenOnly) {
            ++mConformPassed;
            continue;
        }
        // The piece with the points on its edges put in, built only once
        // an edge has one (most pieces have none).
        Poly q;
        bool grown = false;
        const size_t n = p.v.size();
        for (size_t k = 0; k < n; ++k) {
            const int u = p.v[k], w = p.v[(k + 1) % n];
            const uint64_t L = p.lab[k];
            if (grown) {
                q.v.push_back(u);
                q.lab.push_back(L);
            }
            const dvec3 a = mVerts[size_t(u)].pos, d = mVerts[size_t(w)].pos - a;
            const double dd = glm::dot(d, d);
            SmallVector<std::pair<double, int>, 4> on;
            int axis = 0;
            const auto [xsBegin, xsEnd] = onLineOf(L, axis);
            // The edge's reach along the axis: its ends' span, widened well
            // beyond the distance test's 1e-9 (1 + |d|) and rounding.
            const double pad = 4e-9 * (1 + std::sqrt(dd)) + 1e-9 * (1 + std::max(std::abs(a[axis]), std::abs(a[axis] + d[axis])));
            const double reachLo = std::min(a[axis], a[axis] + d[axis]) - pad, reachHi = std::max(a[axis], a[axis] + d[axis]) + pad;
            const int* first = skipFar ? std::lower_bound(xsBegin, xsEnd, reachLo,
                                                          [&](int x, double v) { return mVerts[size_t(x)].pos[axis] < v; })
                                       : xsBegin;
            for (const int* it = first; it != xsEnd && (!skipFar || mVerts[size_t(*it)].pos[axis] <= reachHi); ++it) {
                const int x = *it;
                if (x == u || x == w) continue;
                const Vert& vx = mVerts[size_t(x)];
                const double t = glm::dot(vx.pos - a, d) / dd;
                if (!(t > 1e-12 && t < 1 - 1e-12)) continue;
                if (glm::length(vx.pos - (a + t * d)) > 1e-9 * (1 + std::sqrt(dd))) continue;
                on.push_back({t, x});
            }
            if (on.empty()) continue;
            if (!grown) { // corners 0..k as they were
                grown = true;
                q.v.assign(p.v.begin(), p.v.begin() + std::ptrdiff_t(k + 1));
                q.lab.assign(p.lab.begin(), p.lab.begin() + std::ptrdiff_t(k + 1));
            }
            std::sort(on.begin(), on.end());
            for (const auto& o : on) {
                q.v.push_back(o.second);
                q.lab.push_back(L);
            }
        }
        if (grown) p = std::move(q);
    }
    // A piece folded onto itself (it runs out along a line and back
    // through the same vertex): its loop and the spike, apart. The pieces
    // before the first such stay where they are.
    auto simple = [](const Poly& p) {
        for (size_t i = 0; i < p.v.size(); ++i)
            for (size_t j = i + 1; j < p.v.size(); ++j)
                if (p.v[i] == p.v[j]) return false;
        return true;
    };
    const size_t folded = size_t(std::find_if_not(pieces.begin(), pieces.end(), simple) - pieces.begin());
    if (folded == pieces.size()) return;
    next.clear();
    next.insert(next.end(), std::make_move_iterator(pieces.begin()), std::make_move_iterator(pieces.begin() + std::ptrdiff_t(folded)));
    for (size_t i = folded; i < pieces.size(); ++i) pushSimple(std::move(pieces[i]), next);
    pieces.swap(next);
}

void RemeshKernel::classifyPieces(const Surface& s, SmallVector<char, 32>& kept)
{
    std::vector<Poly>& pieces = mPieces;
    kept.assign(pieces.size(), 1);
    // A cap piece inside the solid P: every corner in closed P, and, where
    // P is the union of the two half-spaces of a concave fold (not convex,
    // so corners in P do not make the piece so), the piece's side of one
    // of them. A piece between the fold's planes whose corners all lie on
    // them is outside (tooth seed 1022: a 2e-3 voxel triangle of an offset
    // face there closed a cap region over the crease and opened the iso seam).
    auto inSolid = [&](const Poly& p) {
        for (int v : p.v)
            if (member(v) < 0) return false;
        if (mTriCount == 2 && !mFoldConvex) return std::max(pieceSign(p, kIsoA), pieceSign(p, kIsoB)) >= 0;
        return true;
    };
    if (mPrism) {
        // Kerf > 0 (DESIGN's sketch): iso pieces outside every closed prism;
        // prism face pieces inside closed P, on their own closed face and
        // outside every other closed prism, except that of two coincident
        // faces facing the same way the lower quad's is kept.
        auto insidePrism = [&](const Poly& p, const QuadGeom& q) {
            for (const auto& sd : q.sides)
                if (sd.orient * pieceSign(p, sd.id) < 0) return false;
            return true;
        };
        for (size_t i = 0; i < pieces.size(); ++i) {
            const Poly& p = pieces[i];
            bool ok = true;
            if (!s.quad) {
                for (const QuadGeom* q : mQuads) ok = ok && !insidePrism(p, *q);
            } else {
                ok = inSolid(p);
                auto keptBy = [&](const QuadGeom* own) {
                    bool k = insidePrism(p, *own);
                    for (const QuadGeom* q : mQuads) {
                        if (!k) break;
                        if (q == own || !insidePrism(p, *q)) continue;
                        bool sameFace = false;
                        for (const auto& sd : q->sides)
                            sameFace = sameFace || (pieceSign(p, sd.id) == 0 &&
                                                    glm::dot(sd.orient * sd.plane.n, s.normal) > 0);
                        k = sameFace && q->id > own->id;
                    }
                    return k;
                };
                bool any = ok && keptBy(s.quad);
                for (const QuadGeom* own : s.also) any = any || (ok && keptBy(own));
                ok = any;
            }
            kept[i] = ok;
        }
    } else if (s.quad) {
        for (size_t i = 0; i < pieces.size(); ++i) {
            bool ok = inSolid(pieces[i]);
            for (const auto& sd : s.quad->sides) ok = ok && sd.orient * pieceSign(pieces[i], sd.id) >= 0;
            kept[i] = ok;
        }
    }
}

void RemeshKernel::insertSlitMidpoints(const SmallVector<char, 32>& kept)
{
    if (mPrism) return; // closed prisms have no slits (needsMidpoint and splitChord say no at once)
    std::vector<Poly>& pieces = mPieces;
    // Steiner midpoints on slit chords between rim points (see needsMidpoint),
    // found on the pieces as they are (splitChord walks them; the GPU reads
    // them unchanged from its pool's region 0), then put in.
    SmallVector<std::array<int, 3>, 8> found; // (piece, edge, midpoint)
    for (size_t i = 0; i < pieces.size(); ++i) {
        if (!kept[i]) continue;
        Poly& p = pieces[i];
        for (size_t k = 0; k < p.v.size(); ++k) {
            const int u = p.v[k], w = p.v[(k + 1) % p.v.size()];
            for (const QuadGeom* r : mQuads) {
                int a = u, b = w;
                if (!needsMidpoint(u, w, *r) && !(splitChord(u, w, *r, kept, a, b) && needsMidpoint(a, b, *r))) continue;
                const Vert &vu = mVerts[size_t(a)], &vw = mVerts[size_t(b)];
                const dvec3 mid = 0.5 * (vu.pos + vw.pos);
                if (a != u || b != w) { // a piece of the chord: the midpoint goes in the piece that holds it
                    const dvec3 d = mVerts[size_t(w)].pos - mVerts[size_t(u)].pos;
                    const double t = glm::dot(mid - mVerts[size_t(u)].pos, d) / glm::dot(d, d);
                    if (!(t > 0.0 && t < 1.0)) continue;
                }
                const uint64_t hu = midpointWord(vu.key), hw = midpointWord(vw.key);
                PlaneList planes{kMid, r->id, std::min(hu, hw), std::max(hu, hw)};
                const uint8_t sup = uint8_t(vu.support | vw.support);
                if (bits(sup) < 4) {
                    const bool isoU = vu.key.planeCount && vu.key.planes[0] == kIso;
                    const bool isoW = vw.key.planeCount && vw.key.planes[0] == kIso;
                    if (isoU && isoW) planes.push_back(kIso);
                }
                found.push_back({int(i), int(k), makeSteiner(sup, planes, mid)});
                break;
            }
        }
    }
    for (size_t f = found.size(); f-- > 0;) { // last first: the earlier edges' indices stay
        Poly& p = pieces[size_t(found[f][0])];
        const long k = found[f][1];
        p.v.insert(p.v.begin() + k + 1, found[f][2]);
        p.lab.insert(p.lab.begin() + k + 1, p.lab[size_t(k)]);
    }
}

/// Edge u -> w of a kept piece lies on quad r's plane with an end inside
/// r's open slit: a piece of a chord that other planes of the cell split
/// (a side line of a quad the neighbouring cell does not have). Its whole
/// chord, followed along the kept pieces' collinear edges through points
/// inside the slit, is a -> b: whether the chord needs a midpoint, and
/// which, must not depend on those splits, or the neighbour, which sees
/// the chord whole, closes it with a vertex this cell lacks (tooth, kerf
/// 0, sharp turns, seed 18004: quad 31's side line splits quad 27's chord
/// in cell (35, 64, 35), not in (35, 64, 36)). False if it is not such a
/// piece or the chord does not end at rim points in the cell.
bool RemeshKernel::splitChord(int u, int w, const QuadGeom& r, const SmallVector<char, 32>& kept, int& a, int& b)
{
    if (mPrism || sign(u, r.id) != 0 || sign(w, r.id) != 0) return false;
    const bool su = slitInterior(u, r), sw = slitInterior(w, r);
    if (!(su || sw) || !(su || chordEnd(u, r)) || !(sw || chordEnd(w, r))) return false;
    const dvec3 d = mVerts[size_t(w)].pos - mVerts[size_t(u)].pos;
    const double len = glm::length(d);
    if (!(len > 0.0)) return false;
    // The kept pieces' edge that goes on from `cur` along `dir`, or -1 (the
    // pieces conform, so any two such edges end at one vertex). Along: off
    // the line through `cur` by at most 1e-9 of its length, or by two ties
    // (epsAt): a point named on two nearly parallel planes is placed within
    // the tie of both, and its distance from the chord's line can be all
    // of that (2 mm head, kerf 0, sawing along the blade, seed 75120: a
    // point of quad 28's rim on quad 26's chord in face x = 82, 3e-12 voxel
    // off it; the walk stopped there in cell (82, 16, 54) and not in (81,
    // 16, 54), where quad 28 is not, so only one of the two cells took the
    // chord's midpoint: an open edge). As chordNext in cut_arrange.glsl.
    auto next = [&](int cur, const dvec3& dir) {
        const dvec3& c = mVerts[size_t(cur)].pos;
        const double tie = 2.0 * epsAt(c);
        for (size_t i = 0; i < mPieces.size(); ++i) {
            if (!kept[i]) continue;
            const auto& v = mPieces[i].v;
            for (size_t k = 0; k < v.size(); ++k) {
                if (v[k] != cur) continue;
                for (int y : {v[(k + 1) % v.size()], v[(k + v.size() - 1) % v.size()]}) {
                    const dvec3 e = mVerts[size_t(y)].pos - c;
                    const double el = glm::length(e);
                    if (el > 0.0 && glm::dot(e, dir) > 0.0 && glm::length(glm::cross(e, dir)) <= (1e-9 * el + tie) * len &&
                        sign(y, r.id) == 0)
                        return y;
                }
            }
        }
        return -1;
    };
    // The chord is where another surface crosses r's slit, and ends where
    // that surface does: every surface that holds a piece of it must walk
    // it to the same ends, though a line of the arrangement may go on
    // beyond. A chord along the isosurface stays on it: past the fold
    // between the tet's two iso triangles, the plane of the one it runs on
    // goes on as a line of the caps' arrangement (tooth, kerf 0, sharp
    // turns, seed 18008: quad 120's chord in cell (74, 20, 83), tet 4; the
    // cap's walk passed the fold and took a midpoint, the isosurface's could
    // not: an edge used once). A chord along another quad's plane stays in
    // that quad's closed extent: past its rim that quad's cap has no piece
    // (seed 18018: quad 37's chord along quad 39's plane in cell (28, 31,
    // 111), tet 1).
    const bool onIso = member(u) == 0 && member(w) == 0;
    SmallVector<const QuadGeom*, 4> along;
    for (const QuadGeom* q : mQuads)
        if (q != &r && sign(u, q->id) == 0 && sign(w, q->id) == 0) along.push_back(q);
    auto keeps = [&](int y) {
        if (onIso && member(y) != 0) return false;
        for (const QuadGeom* q : along)
            if (!inExtentClosed(y, *q)) return false;
        return true;
    };
    // From prev through cur and on stays in the tet only if prev lies in the
    // smallest face that holds cur: else the chord leaves the tet at cur.
    auto staysIn = [&](int prev, int cur) {
        return (mVerts[size_t(prev)].support & ~mVerts[size_t(cur)].support) == 0;
    };
    // Each hop goes on along the line to another vertex, so a walk ends
    // within the tet's vertices; a chord may be split by every plane of
    // the cell (2 mm head, kerf 0, a saw swung across, 78115: 17 points of
    // 32 quads' lines on quad 8's chord in face z = 121 of cell (98, 68,
    // 120); a walk once stopped after 16 hops, and only the other cell of
    // the face, where the chord is whole, took its midpoint).
    const int maxHops = int(mVerts.size());
    a = u;
    b = w;
    for (int hops = 0, prev = w; slitInterior(a, r); ++hops) {
        if (hops == maxHops || !staysIn(prev, a)) return false;
        prev = std::exchange(a, next(a, -d));
        if (a < 0 || !keeps(a)) return false;
    }
    for (int hops = 0, prev = u; slitInterior(b, r); ++hops) {
        if (hops == maxHops || !staysIn(prev, b)) return false;
        prev = std::exchange(b, next(b, d));
        if (b < 0 || !keeps(b)) return false;
    }
    return chordEnd(a, r) && chordEnd(b, r);
}

void RemeshKernel::traceRegions(const Surface& s, int side, const SmallVector<char, 32>& kept)
{
    std::vector<Poly>& pieces = mPieces;
    std::vector<Node>& nodes = mNodes;
    auto& regions = mRegions;
    // Slit edges: on another quad's plane inside that quad.
    auto isSlit = [&](int a, int b) {
        if (mPrism) return false;
        for (const QuadGeom* r : mQuads) {
            if (r == s.quad) continue;
            if (sign(a, r->id) == 0 && sign(b, r->id) == 0 && inExtentClosed(a, *r) && inExtentClosed(b, *r))
                return true;
        }
        return false;
    };
    // Union-find over kept pieces across non-slit shared edges: each
    // later use of an edge joins its piece to the edge's first piece.
    std::vector<int>& parent = mParent;
    parent.resize(pieces.size());
    for (size_t i = 0; i < parent.size(); ++i) parent[i] = int(i);
    auto find = [&](int x) {
        int r = x;
        while (parent[size_t(r)] != r) r = parent[size_t(r)];
        while (parent[size_t(x)] != r) x = std::exchange(parent[size_t(x)], r);
        return r;
    };
    auto& uses = mEdgeUses; // (lower vertex, higher vertex, sequence, piece)
    uses.clear();
    for (size_t i = 0; i < pieces.size(); ++i) {
        if (!kept[i]) continue;
        const Poly& p = pieces[i];
        for (size_t k = 0; k < p.v.size(); ++k) {
            int a = p.v[k], b = p.v[(k + 1) % p.v.size()];
            if (a > b) std::swap(a, b);
            uses.push_back({a, b, int(uses.size()), int(i)});
        }
    }
    auto& order = mEdgeOrder; // first use of the same edge, per use in sequence
    order.assign(uses.size(), -1);
    {
        auto& sorted = mEdgeSorted;
        sorted.assign(uses.begin(), uses.end());
        std::sort(sorted.begin(), sorted.end());
        for (size_t k = 1; k < sorted.size(); ++k) {
            const auto& f = sorted[k - 1];
            const auto& g = sorted[k];
            if (f[0] == g[0] && f[1] == g[1]) order[size_t(g[2])] = order[size_t(f[2])] >= 0 ? order[size_t(f[2])] : f[3];
        }
    }
    for (const auto& u : uses)
        if (order[size_t(u[2])] >= 0 && !isSlit(u[0], u[1])) parent[size_t(find(u[3]))] = find(order[size_t(u[2])]);
    // Directed edges per region, with tagged nodes.
    auto stripSide = [&](const Poly& piece, const QuadGeom* r, int vert) -> int {
        if (r == s.quad) return side;
        for (const auto& sd : r->sides) {
            if (sd.partnerId == 0 || sign(vert, sd.id) != 0) continue;
            const QuadGeom* o = quadById(sd.partnerId);
            if (!o) continue;
            if (sd.orient * pieceSign(piece, sd.id) < 0) { // the piece is on the partner's half
                // (a fold: the partner's side there is r's other side)
                if (o == s.quad) return sd.fold ? -side : side;
                const int sg = pieceSign(piece, o->id);
                if (sg == 0) throw std::runtime_error("remesh: coplanar overlapping quads in cell " + cellText(mCell));
                return sd.fold ? -sg : sg;
            }
        }
        const int sg = pieceSign(piece, r->id);
        if (sg == 0) throw std::runtime_error("remesh: coplanar overlapping quads in cell " + cellText(mCell));
        return sg;
    };
    // Per root piece (ascending): (from node, to node, label).
    auto& regionEdges = mRegionEdges;
    if (regionEdges.size() < pieces.size()) regionEdges.resize(pieces.size());
    for (size_t i = 0; i < pieces.size(); ++i) regionEdges[i].clear();
    for (size_t i = 0; i < pieces.size(); ++i) {
        if (!kept[i]) continue;
        const Poly& p = pieces[i];
        const size_t n = p.v.size();
        SmallVector<int, 16> pn(n);
        for (size_t k = 0; k < n; ++k) {
            Tags tags;
            for (const QuadGeom* r : mQuads) {
                if (mPrism) break;
                if (!slitInterior(p.v[k], *r)) {
                    const QuadGeom* o = nullptr;
                    const int rSide = tJunctionSide(p.v[k], *r, o);
                    if (rSide == 0 || stripSide(p, o, p.v[k]) != rSide) continue;
                }
                const int sg = stripSide(p, r, p.v[k]);
                tags.push_back(r->id << 1 | (sg < 0 ? 1u : 0u));
            }
            pn[k] = nodeOf(p.v[k], tags);
        }
        auto& list = regionEdges[size_t(find(int(i)))];
        const bool reverse = s.quad && !mPrism && side > 0;
        for (size_t k = 0; k < n; ++k) {
            const int a = pn[k], b = pn[(k + 1) % n];
            if (reverse) list.push_back({b, a, int64_t(p.lab[k])});
            else list.push_back({a, b, int64_t(p.lab[k])});
        }
    }
    const dvec3 outNormal = s.quad && !mPrism && side > 0 ? -s.normal : s.normal;
    for (size_t root = 0; root < pieces.size(); ++root) {
        const auto& edges = regionEdges[root];
        if (edges.empty()) continue;
        // Boundary edges: those whose reverse is not in the region.
        auto& keys = mBoundaryKeys;
        keys.clear();
        for (const auto& e : edges) keys.push_back({int(e[0]), int(e[1])});
        std::sort(keys.begin(), keys.end());
        SmallVector<std::array<int64_t, 3>, 16> bnd;
        for (const auto& e : edges)
            if (!std::binary_search(keys.begin(), keys.end(), std::pair<int, int>(int(e[1]), int(e[0]))))
                bnd.push_back(e);
        if (bnd.empty()) continue;
        dvec3 e1 = std::abs(outNormal.x) < 0.9 ? dvec3(1, 0, 0) : dvec3(0, 1, 0);
        e1 = glm::normalize(e1 - outNormal * glm::dot(outNormal, e1));
        const dvec3 e2 = glm::cross(outNormal, e1);
        auto p2 = [&](int node) {
            const dvec3& x = mVerts[size_t(nodes[size_t(node)].vert)].pos;
            return Vec2{glm::dot(x, e1), glm::dot(x, e2)};
        };
        SmallVector<char, 16> used(bnd.size(), 0);
        Region region;
        region.normal = outNormal;
        region.cap = s.quad;
        region.side = side;
        for (size_t start = 0; start < bnd.size(); ++start) {
            if (used[start]) continue;
            Loop loop;
            size_t cur = start;
            for (size_t guard = 0; guard <= bnd.size(); ++guard) {
                used[cur] = 1;
                loop.nodes.push_back(int(bnd[cur][0]));
                loop.labels.push_back(uint64_t(bnd[cur][2]));
                const int at = int(bnd[cur][1]);
                if (at == loop.nodes.front()) break;
                // Next: unused edge from `at`, the most clockwise from the way back.
                size_t best = bnd.size();
                Vec2 bestDir{0.0, 0.0};
                const Vec2 pa = p2(at), pb = p2(int(bnd[cur][0]));
                const Vec2 back{pb.x - pa.x, pb.y - pa.y};
                for (size_t k = 0; k < bnd.size(); ++k) {
                    if (used[k] || bnd[k][0] != at) continue;
                    const Vec2 pc = p2(int(bnd[k][1]));
                    const Vec2 dir{pc.x - pa.x, pc.y - pa.y};
                    if (best == bnd.size() || poly2::clockwiseLess(back, dir, bestDir)) {
                        bestDir = dir;
                        best = k;
                    }
                }
                if (best == bnd.size()) {
                    throw std::runtime_error("remesh: open boundary loop in cell " + cellText(mCell));
                }
                cur = best;
            }
            region.loops.push_back(std::move(loop));
        }
        regions.push_back(std::move(region));
    }
}

void RemeshKernel::markCorners(SmallVector<char, 64>& corner)
{
    const std::vector<Node>& nodes = mNodes;
    const auto& regions = mRegions;
    // Corners: a node is kept when it is a corner of some loop of the tet.
    // A point of a quad's rim on the tet's boundary (zero kerf) is always
    // kept: where the rim lies in a tet face (a blade edge exactly on a grid
    // plane), the tet on the quad's side ends its slit there while the tet on
    // the other side sees a straight boundary through it; both must keep it.
    auto onOwnRim = [&](const CutVertexId& k) {
        if (mPrism || k.dim == 3) return false;
        for (int i = 0; i < k.planeCount; ++i) {
            const uint64_t p = k.planes[size_t(i)];
            const uint64_t kind = p & 15;
            if (p < (uint64_t(1) << 36) || kind < 1 || kind > 4) continue;
            if (std::binary_search(k.planes.begin(), k.planes.begin() + k.planeCount, p & ~uint64_t(15))) return true;
        }
        return false;
    };
    // joinedSurfaceId per label, asked once (the surfaces are final here;
    // a tet's loops hold a few labels, asked twice per node).
    SmallVector<std::pair<uint64_t, uint64_t>, 16> joinedOf;
    auto joined = [&](uint64_t id) {
        for (const auto& e : joinedOf)
            if (e.first == id) return e.second;
        const uint64_t j = joinedSurfaceId(id);
        joinedOf.push_back({id, j});
        return j;
    };
    corner.assign(nodes.size(), 0);
    for (const Region& r : regions) {
        for (const Loop& l : r.loops) {
            const size_t n = l.nodes.size();
            for (size_t i = 0; i < n; ++i) {
                const uint64_t in = l.labels[(i + n - 1) % n], outL = l.labels[i];
                // Two faces joined into one surface are one plane here: a
                // region bounded by both turns no corner where one gives way
                // to the other (at the mitre between them), as the joined
                // region runs straight through that point, and the tet
                // beside may hold either (a rim face on a grid plane cut by
                // a level stroke's offset faces: the sphere's third stroke).
                bool c = in != outL && (!mPrism || joined(in) != joined(outL));
                if (!c) {
                    const dvec3& a = mVerts[size_t(nodes[size_t(l.nodes[(i + n - 1) % n])].vert)].pos;
                    const dvec3& b = mVerts[size_t(nodes[size_t(l.nodes[i])].vert)].pos;
                    const dvec3& d = mVerts[size_t(nodes[size_t(l.nodes[(i + 1) % n])].vert)].pos;
                    c = glm::dot(b - a, d - b) < 0;
                }
                const Vert& vx = mVerts[size_t(nodes[size_t(l.nodes[i])].vert)];
                if (c || vx.steiner || onOwnRim(vx.key)) corner[size_t(l.nodes[i])] = 1;
            }
        }
    }
}

void RemeshKernel::triangulateRegions(const SmallVector<char, 64>& corner, CutCellGeometry& out)
{
    const std::vector<Node>& nodes = mNodes;
    const auto& regions = mRegions;
    // Each node's vertex in `out`, once looked up (-1: not yet).
    mNodeOut.assign(nodes.size(), -1);
    for (const Region& r : regions) {
        const dvec3& nrm = r.normal;
        dvec3 e1 = std::abs(nrm.x) < 0.9 ? dvec3(1, 0, 0) : dvec3(0, 1, 0);
        e1 = glm::normalize(e1 - nrm * glm::dot(nrm, e1));
        const dvec3 e2 = glm::cross(nrm, e1);
        std::vector<Vec2>& pts = mTriangulatePts;
        std::vector<int>& ptNode = mTriangulateNodes;
        pts.clear();
        ptNode.clear();
        // The loops' corners back to back in mLoopCorners; outer and hole
        // loops as (first, count) ranges of it.
        std::vector<int>& corners = mLoopCorners;
        corners.clear();
        auto& outers = mOuterLoops;
        auto& holes = mHoleLoops;
        outers.clear();
        holes.clear();
        for (const Loop& l : r.loops) {
            const size_t first = corners.size();
            for (int nd : l.nodes) {
                if (!corner[size_t(nd)]) continue;
                const dvec3& x = mVerts[size_t(nodes[size_t(nd)].vert)].pos;
                pts.push_back({glm::dot(x, e1), glm::dot(x, e2)});
                ptNode.push_back(nd);
                corners.push_back(int(pts.size() - 1));
            }
            const size_t n = corners.size() - first;
            if (n < 3) {
                if (n == 0) continue;
                throw std::runtime_error("remesh: degenerate boundary loop in cell " + cellText(mCell));
            }
            // A loop of (nearly) zero area is a slit inside the region (a blade
            // corner through the surface): a hole, whatever its rounding says.
            const int* loop = corners.data() + first;
            double perim = 0.0;
            for (size_t i = 0; i < n; ++i) {
                const Vec2 &a = pts[size_t(loop[i])], &b = pts[size_t(loop[(i + 1) % n])];
                perim += poly2::length2(a.x - b.x, a.y - b.y);
            }
            const double area = signedArea(loop, n, pts);
            (area > 1e-9 * perim * perim ? outers : holes).push_back({uint32_t(first), uint32_t(n)});
        }
        auto loopOf = [&](const std::pair<uint32_t, uint32_t>& range) {
            return std::vector<int>(corners.begin() + range.first, corners.begin() + range.first + range.second);
        };
        // A region whose one loop is too thin to span an area in double: a
        // cap piece a few nm across where planes meet near a grid edge (a
        // triangle; seed 2013 on the 1 mm head), or a strip between two
        // lines on a plane 1e-10 voxel apart, where the next quad's offset
        // face nearly continues this one's (four corners; tooth at 400, kerf
        // 0.5, seeds 9124 and 9159). Its one loop is its outline: a fan from
        // its first corner, as the loop runs (its edges are its neighbours'
        // reversed); snap rounding, repairFloatFolds or the local check see
        // to it once it is rounded.
        bool lone = false;
        if (outers.empty()) {
            if (holes.empty()) continue;
            if (holes.size() != 1)
                throw std::runtime_error("remesh: region without outer loop in cell " + cellText(mCell));
            outers.push_back(holes[0]);
            holes.clear();
            lone = true;
        }
        // Each hole's outer loop: the last one holding the hole's centroid.
        SmallVector<uint32_t, 4> holeOuter(holes.size(), 0);
        for (size_t h = 0; h < holes.size() && outers.size() > 1; ++h) {
            const int* hole = corners.data() + holes[h].first;
            const size_t hn = holes[h].second;
            Vec2 c{0, 0};
            for (size_t k = 0; k < hn; ++k) {
                c.x += pts[size_t(hole[k])].x / double(hn);
                c.y += pts[size_t(hole[k])].y / double(hn);
            }
            for (size_t o = 0; o < outers.size(); ++o) {
                bool in = false;
                const int* L = corners.data() + outers[o].first;
                const size_t ln = outers[o].second;
                for (size_t i = 0, j = ln - 1; i < ln; j = i++) {
                    const Vec2 &a = pts[size_t(L[i])], &b = pts[size_t(L[j])];
                    if ((a.y > c.y) != (b.y > c.y) && c.x < (b.x - a.x) * (c.y - a.y) / (b.y - a.y) + a.x) in = !in;
                }
                if (in) holeOuter[h] = uint32_t(o);
            }
        }
        for (size_t o = 0; o < outers.size(); ++o) {
            std::vector<int>& poly = mPoly;
            poly.assign(corners.begin() + outers[o].first, corners.begin() + outers[o].first + outers[o].second);
            bool hasHoles = false;
            for (size_t h = 0; h < holes.size(); ++h) hasHoles = hasHoles || holeOuter[h] == o;
            if (hasHoles) {
                std::vector<std::vector<int>> mine; // rare: a slit inside the region
                for (size_t h = 0; h < holes.size(); ++h)
                    if (holeOuter[h] == o) mine.push_back(loopOf(holes[h]));
                if (!bridgeHoles(poly, std::move(mine), pts))
                    throw std::runtime_error("remesh: cannot bridge a hole in cell " + cellText(mCell));
            }
            std::vector<int>& tris = mTris;
            tris.clear();
            // A zero-kerf cap region of one loop: fanned from a tagged centre
            // when convex (or, below, when an ear has no corner of its side).
            const bool plainCap = r.cap && !mPrism && outers.size() == 1 && !hasHoles;
            bool convex = plainCap;
            for (size_t i = 0; i < poly.size() && convex; ++i) {
                const Vec2 &a = pts[size_t(poly[(i + poly.size() - 1) % poly.size()])], &b = pts[size_t(poly[i])],
                           &c = pts[size_t(poly[(i + 1) % poly.size()])];
                // Straight within rounding counts as convex: the corners of a slit
                // chord's Steiner midpoint are collinear only up to rounding.
                convex = cross2(a, b, c) >= -1e-9 * poly2::length2(b.x - a.x, b.y - a.y) * poly2::length2(c.x - b.x, c.y - b.y);
            }
            // A triangle with a corner that only this side of the cap has
            // (tagged with its side) needs no centre: it has no chord, and
            // the other side's triangle cannot have its three vertices. A
            // centre would add three triangles, and in a region a few float
            // ulps wide one of them has zero area once rounded to float mm
            // (tooth seed 1021; kerf 0, updated after every quad: 2 mm head
            // seed 8006, 4 mm head seed 8014).
            const uint64_t sideTag = r.cap ? r.cap->id << 1 | (r.side < 0 ? 1u : 0u) : 0;
            auto ownCorner = [&](int i) {
                const auto& tags = nodes[size_t(ptNode[size_t(i)])].tags;
                return std::binary_search(tags.begin(), tags.end(), sideTag);
            };
            // A cap region: fan from a tagged centre, so no chord joins two rim
            // points (the two sides of the slit would share it).
            auto centreFan = [&](const dvec3& centre) {
                const int cv = makeSteiner(15, {kCentroid, r.cap->id, uint64_t(&r - regions.data()) + 8}, centre);
                Tags tags{sideTag};
                const int cn = nodeOf(cv, tags);
                pts.push_back({glm::dot(centre, e1), glm::dot(centre, e2)});
                ptNode.push_back(cn);
                const int ci = int(pts.size() - 1);
                for (size_t i = 0; i < poly.size(); ++i) {
                    tris.push_back(ci);
                    tris.push_back(poly[i]);
                    tris.push_back(poly[(i + 1) % poly.size()]);
                }
            };
            auto cornerMean = [&] {
                dvec3 centre(0.0);
                for (int i : poly) centre += mVerts[size_t(nodes[size_t(ptNode[size_t(i)])].vert)].pos / double(poly.size());
                return centre;
            };
            auto polyEdge = [&](int a, int b) {
                for (size_t i = 0; i < poly.size(); ++i) {
                    const int p = poly[i], q = poly[(i + 1) % poly.size()];
                    if ((p == a && q == b) || (p == b && q == a)) return true;
                }
                return false;
            };
            // A diagonal of the ears between two corners not this side's own.
            auto rimDiagonal = [&](int a, int b) { return !ownCorner(a) && !ownCorner(b) && !polyEdge(a, b); };
            // Where no centre sees the whole region: each such diagonal gets
            // a midpoint of this side's own (named as a slit chord's midpoint,
            // tagged with the side), the two ears on it split in two each, so
            // the two sides share no edge across the slit (tooth at 400, kerf
            // 0, a saw swung across, seed 79002, stroke 1, quad 34: a reflex
            // cap region of eight corners in cell (20, 9, 130), tet 0, whose
            // ears on both sides joined the same two rim points).
            auto splitRimDiagonals = [&] {
                for (size_t t = 0; t + 2 < tris.size(); t += 3)
                    for (size_t c = 0; c < 3; ++c) {
                        const int a = tris[t + c], b = tris[t + (c + 1) % 3];
                        if (!rimDiagonal(a, b)) continue;
                        const Vert &va = mVerts[size_t(nodes[size_t(ptNode[size_t(a)])].vert)],
                                   &vb = mVerts[size_t(nodes[size_t(ptNode[size_t(b)])].vert)];
                        const dvec3 mid = 0.5 * (va.pos + vb.pos);
                        const uint64_t ha = midpointWord(va.key), hb = midpointWord(vb.key);
                        const uint8_t sup = uint8_t(va.support | vb.support); // (makeSteiner may move mVerts)
                        const int mv = makeSteiner(sup, {kMid, r.cap->id, std::min(ha, hb), std::max(ha, hb)}, mid);
                        Tags tags{sideTag};
                        const int mn = nodeOf(mv, tags);
                        pts.push_back({glm::dot(mid, e1), glm::dot(mid, e2)});
                        ptNode.push_back(mn);
                        const int m = int(pts.size() - 1);
                        // Both ears on a -> b (this one, and the one on b -> a) split at m.
                        for (size_t u = 0; u + 2 < tris.size(); u += 3)
                            for (size_t k = 0; k < 3; ++k) {
                                const int x = tris[u + k], y = tris[u + (k + 1) % 3], z = tris[u + (k + 2) % 3];
                                if (!((x == a && y == b) || (x == b && y == a))) continue;
                                tris[u] = x;
                                tris[u + 1] = m;
                                tris[u + 2] = z;
                                tris.insert(tris.end(), {m, y, z});
                                break;
                            }
                    }
            };
            if (convex && poly.size() == 3 && std::any_of(poly.begin(), poly.end(), ownCorner)) {
                tris.insert(tris.end(), poly.begin(), poly.end());
            } else if (lone) {
                for (size_t i = 1; i + 1 < poly.size(); ++i) {
                    tris.push_back(poly[0]);
                    tris.push_back(poly[i]);
                    tris.push_back(poly[i + 1]);
                }
            } else if (convex) {
                centreFan(cornerMean());
            } else if (!(mPrism && bestTriangulation(poly, pts, tris)) && !earClip(poly, pts, tris)) {
                throw std::runtime_error("remesh: triangulation failed in cell " + cellText(mCell));
            } else if (plainCap) {
                // A cap region with a reflex corner at zero kerf, ear-clipped:
                // an ear none of whose corners is this side's own may be the
                // other side's ear too (the same three rim points: a triangle
                // shared back to back; body CT at 150 HU, seed 16285), and so
                // may a diagonal between two such corners (below). Then a fan
                // from the tagged centre where the region is star-shaped from
                // it; else each such diagonal split at a midpoint of the
                // side's own (splitRimDiagonals).
                bool shared = false;
                for (size_t t = 0; t + 2 < tris.size() && !shared; t += 3)
                    shared = !ownCorner(tris[t]) && !ownCorner(tris[t + 1]) && !ownCorner(tris[t + 2]);
                // So may a diagonal between two corners not this side's own
                // (a chord across the slit from rim to rim: the other side's
                // ears of other corners may have it too, the edge then used
                // by both sides).
                for (size_t t = 0; t + 2 < tris.size() && !shared; t += 3)
                    for (size_t c = 0; c < 3 && !shared; ++c) shared = rimDiagonal(tris[t + c], tris[t + (c + 1) % 3]);
                if (shared) {
                    const dvec3 centre = cornerMean();
                    const Vec2 c{glm::dot(centre, e1), glm::dot(centre, e2)};
                    bool star = true;
                    for (size_t i = 0; i < poly.size() && star; ++i) {
                        const Vec2 &a = pts[size_t(poly[i])], &b = pts[size_t(poly[(i + 1) % poly.size()])];
                        star = cross2(c, a, b) > 1e-9 * poly2::length2(a.x - c.x, a.y - c.y) * poly2::length2(b.x - c.x, b.y - c.y);
                    }
                    if (star) {
                        tris.clear();
                        centreFan(centre);
                    } else {
                        splitRimDiagonals();
                    }
                }
            }
            if (mArrangeCapture) {
                auto& probe = (*mArrangeCapture)[size_t(mTet)].triangles;
                auto& probeCap = (*mArrangeCapture)[size_t(mTet)].triangleCap;
                for (size_t t = 0; t + 2 < tris.size(); t += 3) {
                    probeCap.push_back(uint8_t(r.cap != nullptr));
                    auto& tri = probe.emplace_back();
                    for (size_t c = 0; c < 3; ++c) {
                        const Node& nd = nodes[size_t(ptNode[size_t(tris[t + c])])];
                        tri[c] = {nd.vert, std::vector<uint64_t>(nd.tags.begin(), nd.tags.end())};
                    }
                }
            }
            if (mNodeOut.size() < nodes.size()) mNodeOut.resize(nodes.size(), -1);
            for (int i : tris) {
                const int ndi = ptNode[size_t(i)];
                int& index = mNodeOut[size_t(ndi)];
                if (index < 0) {
                    const Node& nd = nodes[size_t(ndi)];
                    CutVertexId id = mVerts[size_t(nd.vert)].key;
                    id.tagCount = uint8_t(std::min<size_t>(nd.tags.size(), id.tags.size()));
                    if (nd.tags.size() > id.tags.size())
                        throw std::runtime_error("remesh: a point lies in more than 4 slits in cell " + cellText(mCell));
                    for (size_t k = 0; k < nd.tags.size(); ++k) id.tags[k] = nd.tags[k];
                    index = int(mCellIndex.findOrAdd(id, mVerts[size_t(nd.vert)].pos, out));
                }
                out.indices.push_back(uint32_t(index));
            }
            out.cap.insert(out.cap.end(), tris.size() / 3, uint8_t(r.cap != nullptr));
        }
    }
}

CellKernel::CellKernel(const vdb::Volume& volume, float iso)
    : mKernel(std::make_unique<RemeshKernel>(volume, iso)), mOrigin(volume.origin()), mSpacing(volume.spacing())
{
}

CellKernel::~CellKernel() = default;

std::array<TetPhaseOne, kTetsPerCell> CellKernel::phaseOneForTesting(const Coord& cell,
                                                                      const std::vector<QuadGeom>& quads, bool prism)
{
    std::array<TetPhaseOne, kTetsPerCell> r;
    for (int t = 0; t < kTetsPerCell; ++t) r[size_t(t)] = mKernel->phaseOne(cell, quads, prism, t);
    return r;
}

namespace {
/// Runs kernel.remesh(cell) with kernel.*capture pointing at a fresh T for
/// the duration (also when it throws), and returns that T.
template <class T>
T remeshCapturing(RemeshKernel& kernel, T* RemeshKernel::*capture, const Coord& cell,
                  const std::vector<QuadGeom>& quads, bool prism)
{
    T r;
    CutCellGeometry out;
    kernel.*capture = &r;
    try {
        kernel.remesh(cell, quads, prism, out);
    } catch (...) {
        kernel.*capture = nullptr;
        throw;
    }
    kernel.*capture = nullptr;
    return r;
}
} // namespace

std::array<std::vector<VertexProbe>, kTetsPerCell> CellKernel::verticesForTesting(const Coord& cell,
                                                                                   const std::vector<QuadGeom>& quads,
                                                                                   bool prism)
{
    return remeshCapturing(*mKernel, &RemeshKernel::mCapture, cell, quads, prism);
}

std::vector<NameProbe> CellKernel::namesForTesting(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism)
{
    std::vector<NameProbe> r;
    CutCellGeometry out;
    mKernel->mNameCapture = &r;
    try {
        mKernel->remesh(cell, quads, prism, out);
    } catch (const std::runtime_error&) {
        // a refusal: the names up to it stand
    }
    mKernel->mNameCapture = nullptr;
    return r;
}

void CellKernel::skipOutsideCapsForTesting(bool skip) { mKernel->mSkipOutsideCaps = skip; }

void CellKernel::skipHeldMitresForTesting(bool skip) { mKernel->mSkipHeldMitres = skip; }

void CellKernel::useNameMemoForTesting(bool use) { mKernel->mUseMemo = use; }

size_t CellKernel::nameMemoHitsForTesting() const { return mKernel->mMemoHits; }

size_t CellKernel::cellNameMemoHitsForTesting() const { return mKernel->mCellMemoHits; }

void CellKernel::skipFarForTesting(bool skip) { mKernel->mSkipFar = skip; }

void CellKernel::conformOpenOnlyForTesting(bool only) { mKernel->mConformOpenOnly = only; }
void CellKernel::joinCoincidentFacesForTesting(bool join) { mKernel->mJoinCoincident = join; }
size_t CellKernel::coincidentJoinsForTesting() const { return mKernel->mCoincidentJoins; }

size_t CellKernel::conformPassedForTesting() const { return mKernel->mConformPassed; }

size_t CellKernel::farSkipsForTesting() const { return mKernel->mFarSkips; }

std::array<ArrangementProbe, kTetsPerCell> CellKernel::arrangementForTesting(const Coord& cell,
                                                                             const std::vector<QuadGeom>& quads,
                                                                             bool prism)
{
    return remeshCapturing(*mKernel, &RemeshKernel::mArrangeCapture, cell, quads, prism);
}

namespace {
/// What follows the tets in a cell (remesh() and finish() alike): the
/// snaps, then the float repairs.
void repairCell(const Coord& cell, const openvdb::Vec3d& origin, const openvdb::Vec3d& spacing, bool prism,
                CutCellGeometry& g)
{
    snapToGridVertices(origin, spacing, g);
    liftOffCellFaces(cell, origin, spacing, g);
    keepFaceSidesOnceWritten(cell, origin, spacing, g);
    repairFloatFolds(cell, origin, spacing, g, false, !prism); // zero kerf: folded tents flattened
    if (prism) repairFloatFolds(cell, origin, spacing, g, true); // then its crossings, in a second pass
}
} // namespace

void CellKernel::remesh(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out)
{
    // Built in mScratch, whose vectors have grown before, and copied out at
    // their final sizes: `out` (a fresh cell record's) would otherwise grow
    // a handful of times per vector, and keep up to twice what it holds.
    CutCellGeometry& g = mScratch;
    auto deliver = [&] {
        out.vertexIds.assign(g.vertexIds.begin(), g.vertexIds.end());
        out.indexPositions.assign(g.indexPositions.begin(), g.indexPositions.end());
        out.indices.assign(g.indices.begin(), g.indices.end());
        out.cap.assign(g.cap.begin(), g.cap.end());
        out.intoFace.assign(g.intoFace.begin(), g.intoFace.end());
        out.crossFree = g.crossFree;
    };
    try {
        mKernel->remesh(cell, quads, prism, g);
        repairCell(cell, mOrigin, mSpacing, prism, g);
    } catch (...) {
        deliver(); // what was made before the refusal, as when built in place
        throw;
    }
    deliver();
}

void CellKernel::finish(const Coord& cell, const std::vector<QuadGeom>& quads, bool prism, CutCellGeometry& out)
{
    mKernel->finishCell(cell, quads, prism, out);
    repairCell(cell, mOrigin, mSpacing, prism, out);
}

} // namespace mtcut::cutter::remesh_detail
