#include "cutter/CutMask.h"

#include "vdb/Error.h"

#include <openvdb/tools/Prune.h>

#include <atomic>
#include <cassert>
#include <cmath>

namespace mtcut::cutter {

IndexFrame frameOf(const vdb::Volume& volume)
{
    IndexFrame f;
    const openvdb::Vec3d s = volume.spacing(), o = volume.origin();
    f.spacing = glm::dvec3(s.x(), s.y(), s.z());
    f.origin = glm::dvec3(o.x(), o.y(), o.z());
    f.dims = glm::ivec3(volume.dims.x(), volume.dims.y(), volume.dims.z());
    return f;
}

CutMask::CutMask(const IndexFrame& frame, double kerfMm) : mFrame(frame), mKerf(kerfMm)
{
    if (!(kerfMm >= 0.0 && kerfMm <= kMaxKerfMm))
        throw InputError("kerf must be a width from 0 to " + std::to_string(int(kMaxKerfMm)) + " mm");
    mGrid = openvdb::Int32Grid::create(0);
    mGrid->setName("cut_mask");
    mGrid->setGridClass(openvdb::GRID_UNKNOWN);
    // Same index -> world map as the volume: x = spacing * ijk + origin.
    auto xform = openvdb::math::Transform::createLinearTransform(1.0);
    xform->preScale(openvdb::Vec3d(frame.spacing.x, frame.spacing.y, frame.spacing.z));
    xform->postTranslate(openvdb::Vec3d(frame.origin.x, frame.origin.y, frame.origin.z));
    mGrid->setTransform(xform);
}

uint32_t CutMask::beginStroke()
{
    mRedo.clear();
    mStrokes.emplace_back();
    mStrokeOpen = true;
    mLastNew.clear();
    return uint32_t(mStrokes.size());
}

QuadRef CutMask::addQuad(const Quad& quad)
{
    std::vector<glm::ivec3> cells;
    voxelizeCut(quad, mKerf, mFrame, cells);
    return addQuad(quad, cells);
}

QuadRef CutMask::addQuad(const Quad& quad, const std::vector<glm::ivec3>& cells)
{
    if (!mStrokeOpen) beginStroke();
    mRedo.clear();
    static std::atomic<uint64_t> serials{0};
    QuadRecord rec;
    rec.quad = quad;
    rec.serial = serials.fetch_add(1, std::memory_order_relaxed) + 1;
    rec.cells.reserve(cells.size());
    const glm::ivec3 lo = mFrame.cutCellLo(), hi = mFrame.cutCellHi();
    for (const glm::ivec3& c : cells)
        if (c.x >= lo.x && c.y >= lo.y && c.z >= lo.z && c.x <= hi.x && c.y <= hi.y && c.z <= hi.z)
            rec.cells.emplace_back(c.x, c.y, c.z);
    return push(std::move(rec));
}

QuadRef CutMask::push(QuadRecord&& rec)
{
    StrokeRecord& s = mStrokes.back();
    const QuadRef ref{uint32_t(mStrokes.size()), uint32_t(s.quads.size())};
    mLastNew.clear();
    apply(ref.stroke, ref.quad, rec.cells);
    s.quads.push_back(std::move(rec));
    return ref;
}

void CutMask::apply(uint32_t stroke, uint32_t quadIndex, const std::vector<openvdb::Coord>& cells)
{
    auto acc = mGrid->getAccessor();
    for (const openvdb::Coord& c : cells) {
        auto [it, inserted] = mCells.try_emplace(c);
        std::vector<QuadRef>& list = it->second;
        if (inserted) list.reserve(4); // a cell's list is a few quads long: one allocation, not three
        // A cell listed twice by one quad is recorded once.
        if (!list.empty() && list.back() == QuadRef{stroke, quadIndex}) continue;
        list.push_back({stroke, quadIndex});
        if (inserted) {
            acc.setValueOn(c, int32_t(stroke));
            mLastNew.push_back(c);
        }
    }
}

void CutMask::unapply(uint32_t stroke, uint32_t quadIndex, const std::vector<openvdb::Coord>& cells)
{
    auto acc = mGrid->getAccessor();
    for (auto c = cells.rbegin(); c != cells.rend(); ++c) {
        auto it = mCells.find(*c);
        if (it == mCells.end()) continue; // duplicate cell already removed
        std::vector<QuadRef>& list = it->second;
        if (list.empty() || !(list.back() == QuadRef{stroke, quadIndex})) continue;
        list.pop_back();
        if (list.empty()) {
            mCells.erase(it);
            acc.setValueOff(*c, 0);
        }
    }
}

bool CutMask::undoStroke()
{
    if (mStrokes.empty()) return false;
    const uint32_t id = uint32_t(mStrokes.size());
    StrokeRecord& s = mStrokes.back();
    for (size_t q = s.quads.size(); q-- > 0;) unapply(id, uint32_t(q), s.quads[q].cells);
    RedoEntry e{id, std::move(s.quads)};
    mStrokes.pop_back();
    mRedo.push_back(std::move(e));
    mStrokeOpen = false;
    mLastNew.clear();
    openvdb::tools::pruneInactive(mGrid->tree());
    return true;
}

void CutMask::undoToQuad(uint32_t quadCount)
{
    if (mStrokes.empty()) return;
    const uint32_t id = uint32_t(mStrokes.size());
    StrokeRecord& s = mStrokes.back();
    if (quadCount >= s.quads.size()) return;
    for (size_t q = s.quads.size(); q-- > quadCount;) unapply(id, uint32_t(q), s.quads[q].cells);
    RedoEntry e{id, {}};
    e.quads.assign(std::make_move_iterator(s.quads.begin() + quadCount),
                   std::make_move_iterator(s.quads.end()));
    s.quads.resize(quadCount);
    mRedo.push_back(std::move(e));
    mStrokeOpen = true;
    mLastNew.clear();
    openvdb::tools::pruneInactive(mGrid->tree());
}

bool CutMask::redoStroke()
{
    if (mRedo.empty()) return false;
    RedoEntry e = std::move(mRedo.back());
    mRedo.pop_back();
    if (e.stroke == mStrokes.size() + 1) {
        mStrokes.emplace_back();
    }
    assert(e.stroke == mStrokes.size());
    mLastNew.clear();
    StrokeRecord& s = mStrokes.back();
    for (QuadRecord& rec : e.quads) {
        apply(e.stroke, uint32_t(s.quads.size()), rec.cells);
        s.quads.push_back(std::move(rec));
    }
    mStrokeOpen = false;
    return true;
}

void setEarlierQuads(const CutMask& mask, PathFilter& filter)
{
    filter.clearEarlierQuads();
    for (uint32_t stroke = 1; stroke <= mask.strokeCount(); ++stroke)
        for (uint32_t q = 0; q < mask.quadCount(stroke); ++q) filter.addEarlierQuad(mask.quad(QuadRef{stroke, q}));
}

const std::vector<QuadRef>* CutMask::quadsAt(const openvdb::Coord& cell) const
{
    auto it = mCells.find(cell);
    return it == mCells.end() ? nullptr : &it->second;
}

const Quad& CutMask::quad(const QuadRef& ref) const
{
    assert(ref.stroke >= 1 && ref.stroke <= mStrokes.size());
    return mStrokes[ref.stroke - 1].quads.at(ref.quad).quad;
}

const std::vector<openvdb::Coord>& CutMask::cellsOf(const QuadRef& ref) const
{
    assert(ref.stroke >= 1 && ref.stroke <= mStrokes.size());
    return mStrokes[ref.stroke - 1].quads.at(ref.quad).cells;
}

uint64_t CutMask::quadSerial(const QuadRef& ref) const
{
    assert(ref.stroke >= 1 && ref.stroke <= mStrokes.size());
    return mStrokes[ref.stroke - 1].quads.at(ref.quad).serial;
}

uint32_t CutMask::quadCount(uint32_t stroke) const
{
    return stroke >= 1 && stroke <= mStrokes.size() ? uint32_t(mStrokes[stroke - 1].quads.size())
                                                    : 0u;
}

void CutMask::forEachCutCell(
    const std::function<void(const openvdb::Coord&, const std::vector<QuadRef>&)>& f) const
{
    for (const auto& [c, list] : mCells) f(c, list);
}

size_t CutMask::memoryBytes() const
{
    size_t bytes = size_t(mGrid->memUsage());
    bytes += mCells.bucket_count() * sizeof(void*);
    for (const auto& [c, list] : mCells)
        bytes += sizeof(c) + sizeof(list) + 2 * sizeof(void*) + list.capacity() * sizeof(QuadRef);
    for (const StrokeRecord& s : mStrokes)
        for (const QuadRecord& q : s.quads) bytes += sizeof(q) + q.cells.capacity() * sizeof(openvdb::Coord);
    return bytes;
}

size_t drainCutInfo(SpscQueue<CutInfo>& queue, CutMask& mask, std::vector<std::string>* errors)
{
    size_t applied = 0;
    CutInfo info;
    while (queue.tryPop(info)) {
        switch (info.kind) {
        case CutInfo::Kind::Quad:
            if (info.quadIndex == 0) mask.beginStroke();
            if (info.cells.empty()) mask.addQuad(info.quad);
            else mask.addQuad(info.quad, info.cells);
            ++applied;
            break;
        case CutInfo::Kind::StrokeEnd: break;
        case CutInfo::Kind::Error:
            if (errors) errors->push_back(info.message);
            break;
        }
    }
    return applied;
}

} // namespace mtcut::cutter
