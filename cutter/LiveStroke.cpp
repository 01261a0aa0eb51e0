#include "cutter/LiveStroke.h"

#include "vdb/Error.h"

#include <stdexcept>

namespace mtcut::cutter {

LiveStroke::LiveStroke(CutMask& mask, CutRemesher& remesher, int patience)
    : mMask(mask), mRemesher(remesher), mPatience(patience)
{
    if (patience < 1) throw std::invalid_argument("LiveStroke: patience must be at least 1");
}

bool LiveStroke::add(const Quad& quad)
{
    if (mStopped) return false;
    if (mQuads == 0) mMask.beginStroke();
    mMask.addQuad(quad);
    ++mQuads;
    mPending = true;
    return true;
}

LiveStroke::Result LiveStroke::update() { return run(false); }

LiveStroke::Result LiveStroke::finish() { return run(true); }

void LiveStroke::cutBack()
{
    if (mAccepted == 0) mMask.undoStroke();
    else mMask.undoToQuad(mAccepted);
    mQuads = mAccepted;
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
    mRefusedInARow = 0;
    // The re-mesher is as at the last accepted update: the mask follows it.
    cutBack();
    mRemesher.update(mMask);
    mStopped = true;
    r.outcome = Outcome::Stopped;
    return r;
}

} // namespace mtcut::cutter
