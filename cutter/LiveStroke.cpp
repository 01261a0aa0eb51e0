#include "cutter/LiveStroke.h"

#include "vdb/Error.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace mtcut::cutter {

bool LiveStroke::belowAFloatStep(const std::string& refusal)
{
    return refusal.rfind("remesh: the surface crosses or touches itself", 0) == 0 ||
           refusal.rfind("remesh: open or inconsistent surface (", 0) == 0;
}

LiveStroke::LiveStroke(CutMask& mask, CutRemesher& remesher, int patience, bool stepRound)
    : mMask(mask), mRemesher(remesher), mPatience(patience), mStepRound(stepRound)
{
    if (patience < 1) throw std::invalid_argument("LiveStroke: patience must be at least 1");
}

bool LiveStroke::add(const Quad& quad)
{
    if (mStopped) return false;
    if (maskQuads() == 0) mMask.beginStroke();
    addMoved(quad, mQuads);
    ++mQuads;
    mPending = true;
    return true;
}

void LiveStroke::addToMask(const Quad& quad, uint32_t from)
{
    mMask.addQuad(quad);
    mAddOf.push_back(from);
}

uint32_t LiveStroke::addMoved(const Quad& quad, uint32_t from, bool split)
{
    std::array<glm::dvec3, 4> c = quad.corners;
    uint32_t moved = 0;
    for (uint32_t i = 0; i < quad.cornerCount; ++i)
        for (const auto& [original, to] : mMoved)
            if (c[i] == original) {
                c[i] = to;
                ++moved;
                break;
            }
    if (moved == 0) {
        addToMask(quad, from);
        return 1;
    }
    if (split && quad.cornerCount == 4 && moved < 4) {
        // Corners {base0, tip0, tip1, base1}: the path filter's split (rule 3c).
        const glm::dvec3 t0[3] = {c[0], c[1], c[2]}, t1[3] = {c[0], c[2], c[3]};
        addToMask(makeQuad(t0, 3, quad.stick), from);
        addToMask(makeQuad(t1, 3, quad.stick), from);
        return 2;
    }
    addToMask(makeQuad(c.data(), quad.cornerCount, quad.stick), from);
    return 1;
}

LiveStroke::Result LiveStroke::update() { return run(false); }

LiveStroke::Result LiveStroke::finish() { return run(true); }

void LiveStroke::cutBack()
{
    maskBackTo(mMaskAccepted);
    mAccepted = addQuadsOf(mMaskAccepted);
    mQuads = mAccepted;
}

void LiveStroke::maskBackTo(uint32_t maskQuads)
{
    if (this->maskQuads() == maskQuads) return;
    if (maskQuads == 0) mMask.undoStroke();
    else mMask.undoToQuad(maskQuads);
    mAddOf.resize(maskQuads);
}

bool LiveStroke::stepRound()
{
    const uint32_t stroke = mMask.strokeCount();
    if (maskQuads() <= mMaskAccepted || stroke == 0) {
        cutBack();
        return false;
    }
    // The waiting quads, as the mask holds them, with the add() quad each
    // came from. Once one refusal is stepped round, another may lie further
    // on among them (never cut while the first stood: 1 mm head, kerf 3,
    // seed 14123, stroke 3, quads 157 and 164): so the refusals are stepped
    // round one at a time. Each step puts the refused quad and the one after
    // it (which rejoins the path) in the mask; the rest follow one update
    // per add() quad, waiting on a refusal as update() does, and a refusal
    // that stays is stepped round in its turn.
    std::vector<std::pair<Quad, uint32_t>> rest;
    for (uint32_t q = mMaskAccepted; q < maskQuads(); ++q) rest.push_back({mMask.quad({stroke, q}), mAddOf[q]});
    size_t at = 0; // rest[at] on: not accepted
    // The end of the add() quad whose mask quads start at rest[i].
    auto groupEnd = [&](size_t i) {
        size_t j = i + 1;
        while (j < rest.size() && rest[j].second == rest[i].second) ++j;
        return j;
    };
    auto putBack = [&] { // the mask holds every quad again, those from rest[at] on waiting
        maskBackTo(mMaskAccepted);
        if (maskQuads() == 0) mMask.beginStroke();
        for (size_t i = at; i < rest.size(); ++i) addMoved(rest[i].first, rest[i].second);
    };
    try {
        while (at < rest.size()) {
            maskBackTo(mMaskAccepted);
            if (maskQuads() == 0) mMask.beginStroke();
            const size_t stepEnd = groupEnd(at) < rest.size() ? groupEnd(groupEnd(at)) : groupEnd(at);
            for (size_t i = at; i < stepEnd; ++i) addMoved(rest[i].first, rest[i].second);
            bool stepped = false;
            for (uint32_t back = 0; back <= 1 && back <= mMaskAccepted && !stepped; ++back)
                stepped = stepRound(stroke, back);
            if (!stepped) break;
            ++mSteppedRound;
            mMaskAccepted = maskQuads();
            at = stepEnd;
            mStopRefusal.clear();
            int refused = 0; // updates in a row
            for (size_t next = at; next < rest.size() && refused < mPatience;) {
                const size_t end = groupEnd(next);
                for (size_t i = next; i < end; ++i) addMoved(rest[i].first, rest[i].second);
                next = end;
                const std::string refusal = refusalOf(mRemesher, mMask);
                if (refusal.empty()) {
                    mMaskAccepted = maskQuads();
                    at = next;
                    refused = 0;
                    mStopRefusal.clear();
                } else if (refused++ == 0) {
                    mStopRefusal = refusal; // of the update the stroke would be cut back to
                }
            }
            if (at == rest.size()) {
                mAccepted = mQuads;
                return true;
            }
            if (!belowAFloatStep(mStopRefusal)) break; // the kernel's own: the stroke stops there
        }
    } catch (...) {
        putBack(); // the re-mesher is as at mMaskAccepted
        mAccepted = addQuadsOf(mMaskAccepted);
        throw;
    }
    cutBack();
    return false;
}

bool LiveStroke::stepRound(uint32_t stroke, uint32_t back)
{
    // The quads from the `back`-th accepted one before the waiting ones on,
    // as the mask holds them, and the quad before. With back = 1 the stick
    // the waiting ones start on moves too: it may be what is in the way
    // (0.45 x 0.45 x 1.25 mm voxels, 400 HU, kerf 0, random strokes seed
    // 11118: it crosses face x = 122 of cell (121, 65, 82) within a float
    // step, and the three planes through it, two quads' and their joint's,
    // meet the face there however the waiting quad turns).
    const uint32_t keep = mMaskAccepted - back;
    std::vector<Quad> moving;
    std::vector<uint32_t> from; // the add() quad of each
    for (uint32_t q = keep; q < maskQuads(); ++q) {
        moving.push_back(mMask.quad({stroke, q}));
        from.push_back(mAddOf[q]);
    }
    Quad before;
    if (keep > 0) before = mMask.quad({stroke, keep - 1});
    const Quad first = moving.front();
    // The first one's corners on the quad before (their stick) stay; the others move.
    std::vector<glm::dvec3> fixed, free;
    for (uint32_t i = 0; i < first.cornerCount; ++i) {
        bool shared = false;
        for (uint32_t k = 0; keep > 0 && k < before.cornerCount && !shared; ++k) shared = first.corners[i] == before.corners[k];
        (shared ? fixed : free).push_back(first.corners[i]);
    }
    const bool debug = std::getenv("MTCUT_REMESH_DEBUG") != nullptr; // (Remesh.h)
    if (free.empty() || (!fixed.empty() && fixed.size() != 2) || first.degenerate) {
        if (debug)
            std::fprintf(stderr, "live stroke: cannot step round from quad %u (%zu corners on the quad before)\n", keep,
                         fixed.size());
        return false;
    }
    const glm::dvec3 sp = mMask.frame().spacing;
    const double voxel = std::min({sp.x, sp.y, sp.z});
    glm::dvec3 axis(0.0);
    double reach = 0.0; // the free corners' largest distance from the axis
    if (!fixed.empty()) {
        axis = fixed[1] - fixed[0];
        const double len = glm::length(axis);
        if (!(len > 0.0)) return false;
        axis /= len;
        for (const glm::dvec3& p : free) {
            const glm::dvec3 r = p - fixed[0];
            reach = std::max(reach, glm::length(r - glm::dot(r, axis) * axis));
        }
        if (!(reach > 0.0)) return false;
    }
    const auto movedBefore = mMoved;
    // The mask from `keep` on: the quads moved, or as they were.
    auto put = [&](bool moved) {
        maskBackTo(keep);
        if (maskQuads() == 0) mMask.beginStroke();
        for (size_t i = 0; i < moving.size(); ++i) {
            if (!moved) addToMask(moving[i], from[i]);
            else addMoved(moving[i], from[i], i > 0); // the first turns whole: planar
        }
    };
    auto restore = [&] {
        mMoved = movedBefore;
        put(false);
    };
    for (const double step : kStepRoundVoxels) {
        const double by = step * voxel;
        auto move = [&](const glm::dvec3& p) {
            if (fixed.empty()) return p + by * first.normal;
            // Turned about the shared edge so that the farthest corner moves by `by` (Rodrigues).
            const double angle = by / reach, cs = std::cos(angle), sn = std::sin(angle);
            const glm::dvec3 r = p - fixed[0];
            return fixed[0] + r * cs + glm::cross(axis, r) * sn + axis * (glm::dot(axis, r) * (1.0 - cs));
        };
        mMoved = movedBefore;
        for (const glm::dvec3& p : free) mMoved.push_back({p, move(p)});
        put(true);
        try {
            mRemesher.update(mMask);
        } catch (const InputError&) {
            restore(); // as before the call
            throw;
        } catch (const Cancelled&) {
            restore();
            throw;
        } catch (const std::runtime_error& e) {
            if (debug)
                std::fprintf(stderr, "live stroke: stepping round from quad %u by %g voxel refused: %s\n", keep, step,
                             e.what());
            continue; // refused: the re-mesher is as before the call
        } catch (...) {
            restore();
            throw;
        }
        return true;
    }
    restore();
    return false;
}

LiveStroke::Result LiveStroke::run(bool last)
{
    Result r;
    // Nothing new: an accepted cut stays; a deferred one is retried only by
    // the last update (the same quads give the same refusal).
    if (mStopped || (!mPending && (!last || mQuads == mAccepted))) return r;
    mPending = false;
    std::string refusal;
    try {
        mRemesher.update(mMask);
    } catch (const InputError&) {
        mPending = true; // the re-mesher is as before the call: try again later
        throw;
    } catch (const Cancelled&) {
        mPending = true;
        throw;
    } catch (const std::runtime_error& e) {
        refusal = e.what();
    }
    if (refusal.empty()) {
        mAccepted = mQuads;
        mMaskAccepted = maskQuads();
        mRefusedInARow = 0;
        r.outcome = Outcome::Accepted;
        return r;
    }
    if (mRefusedInARow++ == 0) mFirstRefusal = refusal;
    if (!last && mRefusedInARow < mPatience) {
        r.refusal = refusal;
        r.outcome = Outcome::Deferred;
        return r;
    }
    r.refusal = mFirstRefusal; // of the update the stroke is cut back to: the quads it added first
    bool through = false;
    const uint32_t steppedBefore = mSteppedRound;
    try {
        if (mStepRound && belowAFloatStep(mFirstRefusal) && belowAFloatStep(refusal)) through = stepRound();
        else cutBack();
    } catch (...) {
        mPending = true; // the mask holds every quad, the re-mesher its accepted ones: try again later
        throw;
    }
    mRefusedInARow = 0;
    r.steppedRound = mSteppedRound > steppedBefore;
    if (through) {
        r.outcome = Outcome::Accepted;
        return r;
    }
    if (r.steppedRound && !mStopRefusal.empty()) r.refusal = mStopRefusal; // a later one, where it stops
    // Cut back (stepRound): the re-mesher is as at the last accepted update, and the mask follows it.
    mRemesher.update(mMask);
    mStopped = true;
    r.outcome = Outcome::Stopped;
    return r;
}

} // namespace mtcut::cutter
