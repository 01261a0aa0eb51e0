// A stroke cut while it is drawn (a haptic device, the mouse, a pose
// stream): its quads go into the mask as they come, and the cut is
// re-meshed now and then, once per frame or batch of poses (update()).
//
// An update in the middle of a stroke cuts a blade that stops where the
// device is at that moment. The re-mesher refuses rather than write a broken
// surface (Remesh.h), and some of its refusals are of that moment only: the
// blade's end inside a cell, which the next quads move on. Updating after
// every quad of random strokes (benchmarks/RESULTS.md, "Updates after every
// quad"), all 7 refusals of 200 strokes on the tooth at kerf 0 went through
// at the next quad. So a refused update does not end the stroke: the cut
// stays as the last accepted update left it (the re-mesher is as before a
// refused call), the quads stay in the mask, and the next update tries
// again with the quads added since. After `patience` refused updates in a
// row, or a refused last update (finish()), the stroke is cut back to the
// quads of its last accepted update and takes no more: a refusal that
// stays, as a fragment of the old one would (tooth, kerf 0.5, seed 8004).
//
// What is accepted is what a from-scratch update of the same mask gives
// (CutRemesher is exact and incremental), so deferring changes no geometry.
#pragma once

#include "cutter/CutMask.h"
#include "cutter/Remesh.h"

#include <cstdint>
#include <string>

namespace mtcut::cutter {

class LiveStroke
{
public:
    /// Refused updates in a row after which the stroke stops.
    static constexpr int kPatience = 8;

    enum class Outcome
    {
        Unchanged, ///< nothing new to re-mesh, or the stroke has stopped
        Accepted,  ///< the cut holds every quad added so far
        Deferred,  ///< refused: the cut is as at the last accepted update; the next update tries again
        Stopped,   ///< refused for good: the stroke is cut back to its last accepted update and takes no more quads
    };
    struct Result
    {
        Outcome outcome = Outcome::Unchanged;
        /// The re-mesher's message: Deferred, this update's; Stopped, that of
        /// the first refused update in the row (whose new quads the stroke
        /// is cut back before).
        std::string refusal;
    };

    /// A new stroke of `mask`, cut by `remesher` (which must be up to date
    /// with the mask); both must outlive this. patience >= 1.
    LiveStroke(CutMask& mask, CutRemesher& remesher, int patience = kPatience);

    /// Appends a quad to the stroke (the first begins the stroke in the
    /// mask). False, and nothing added, once the stroke has stopped.
    bool add(const Quad& quad);
    /// Re-meshes the quads added since the last accepted update (nothing
    /// when none were added since the last update). What the re-mesher
    /// throws that is not a refusal (InputError, Cancelled, std::logic_error)
    /// goes on; the cut is then as before the call, and the next update
    /// tries again.
    Result update();
    /// The stroke's last update: a refusal stops it.
    Result finish();

    bool stopped() const { return mStopped; }
    /// The stroke has quads in the mask.
    bool inMask() const { return mQuads > 0; }
    /// Quads of the stroke the cut holds.
    uint32_t acceptedQuads() const { return mAccepted; }
    /// Quads of the stroke in the mask (accepted, and waiting after a deferral).
    uint32_t quads() const { return mQuads; }

private:
    Result run(bool last);
    void cutBack();

    CutMask& mMask;
    CutRemesher& mRemesher;
    int mPatience;
    bool mStopped = false;
    bool mPending = false;   ///< quads added since the last update
    int mRefusedInARow = 0;
    std::string mFirstRefusal; ///< of the row of refused updates
    uint32_t mAccepted = 0, mQuads = 0;
};

} // namespace mtcut::cutter
