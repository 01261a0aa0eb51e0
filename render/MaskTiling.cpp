#include "render/MaskTiling.h"

#include "vdb/Error.h"

#include <algorithm>
#include <memory>

namespace mtcut::render {

using openvdb::Coord;

uint32_t MaskTiling::slotOf(const Coord& cell) const
{
    if (empty()) return 0;
    const Coord l(cell.x() >> 3, cell.y() >> 3, cell.z() >> 3);
    const Coord d = l - leafMin;
    for (int a = 0; a < 3; ++a)
        if (d[a] < 0 || d[a] >= leafExtent[a]) return 0;
    return indirection[size_t(d.x()) + size_t(leafExtent.x()) * (size_t(d.y()) + size_t(leafExtent.y()) * size_t(d.z()))];
}

bool MaskTiling::isSet(const Coord& cell) const
{
    const uint32_t s = slotOf(cell);
    if (!s) return false;
    const int n = tileBitOf(cell);
    return (words[size_t(s - 1) * kTileWords + size_t(n >> 5)] >> (n & 31)) & 1u;
}

std::vector<Coord> MaskTiling::cells() const
{
    std::vector<Coord> out;
    for (size_t s = 0; s < slotCount(); ++s) {
        for (int n = 0; n < kTileBits; ++n) {
            if ((words[s * kTileWords + size_t(n >> 5)] >> (n & 31)) & 1u) {
                out.push_back(leafOrigins[s] + Coord(n >> 6, (n >> 3) & 7, n & 7));
            }
        }
    }
    return out;
}

MaskTiling tileMask(const openvdb::MaskTree& maskIn)
{
    MaskTiling t;
    const openvdb::MaskTree* mask = &maskIn;
    std::unique_ptr<openvdb::MaskTree> voxelised;
    if (maskIn.hasActiveTiles()) {
        voxelised = std::make_unique<openvdb::MaskTree>(maskIn);
        voxelised->voxelizeActiveTiles();
        mask = voxelised.get();
    }
    std::vector<const openvdb::MaskTree::LeafNodeType*> leaves;
    for (auto it = mask->cbeginLeaf(); it; ++it) {
        if (!it->isEmpty()) leaves.push_back(&*it);
    }
    if (leaves.empty()) return t;
    std::sort(leaves.begin(), leaves.end(), [](const auto* a, const auto* b) { return a->origin() < b->origin(); });
    Coord lo = leaves.front()->origin() >> 3, hi = lo;
    for (const auto* leaf : leaves) {
        const Coord l = leaf->origin() >> 3;
        lo.minComponent(l);
        hi.maxComponent(l);
    }
    t.leafMin = lo;
    t.leafExtent = hi - lo + Coord(1);
    const uint64_t boxLeaves = uint64_t(t.leafExtent.x()) * uint64_t(t.leafExtent.y()) * uint64_t(t.leafExtent.z());
    if (boxLeaves > (uint64_t(1) << 31)) {
        throw InputError("mask tiling: the cut cells span " + std::to_string(boxLeaves) +
                         " leaves (more than 2^31); the indirection table would not fit");
    }
    t.indirection.assign(size_t(boxLeaves), 0u);
    t.leafOrigins.reserve(leaves.size());
    t.words.resize(leaves.size() * kTileWords);
    for (size_t s = 0; s < leaves.size(); ++s) {
        const auto* leaf = leaves[s];
        t.leafOrigins.push_back(leaf->origin());
        const auto& bits = leaf->getValueMask();
        for (int w = 0; w < kTileWords / 2; ++w) {
            const uint64_t word = bits.template getWord<openvdb::Index64>(openvdb::Index(w));
            t.words[s * kTileWords + size_t(2 * w)] = uint32_t(word);
            t.words[s * kTileWords + size_t(2 * w + 1)] = uint32_t(word >> 32);
        }
        const Coord d = (leaf->origin() >> 3) - lo;
        t.indirection[size_t(d.x()) + size_t(t.leafExtent.x()) * (size_t(d.y()) + size_t(t.leafExtent.y()) * size_t(d.z()))] =
            uint32_t(s + 1);
    }
    return t;
}

openvdb::MaskGrid::Ptr cutCellGrid(const cutter::CutMask& mask)
{
    openvdb::MaskGrid::Ptr g = openvdb::MaskGrid::create();
    g->tree().topologyUnion(mask.grid()->tree());
    g->tree().voxelizeActiveTiles();
    return g;
}

openvdb::MaskGrid::Ptr remeshedCellGrid(const cutter::CutRemesher& remesher)
{
    openvdb::MaskGrid::Ptr g = openvdb::MaskGrid::create();
    openvdb::MaskGrid::Accessor acc = g->getAccessor();
    for (const auto& entry : remesher.cells()) acc.setValueOn(entry.first);
    return g;
}

} // namespace mtcut::render
