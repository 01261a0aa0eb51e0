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
// row, or a refused last update (finish()), the refusal stays. Those seen
// are coincidences below a float step: blade planes, grid edges and the
// isosurface meeting within a few float steps of each other, which float
// cannot write apart (belowAFloatStep: the local check's refusals of the
// surface as written). The blade then steps round it: the first quad not
// yet accepted is turned about the edge it shares with the last accepted
// one (or, sharing none, moved along its normal) so that its farthest
// corner moves a thousandth of a voxel (of the smallest spacing) out of
// its plane, and the quads after it are joined to the moved corners (a
// quad with only some of its corners moved is split into two planar
// triangles, as the path filter splits a twisting step), so the stroke is
// back on its own path one step later and nothing drifts. Where that is
// not enough, the last accepted quad turns too, about the edge before it
// (the stick between them can be what is in the way). Tried at each of
// kStepRoundVoxels in turn (each way, then a hundredth of a voxel each
// way), with the refused quad and the one after it in the mask; the first
// the re-mesher accepts stays, and the quads that waited follow one update
// each, a further refusal among them stepped round in its turn
// (steppedRound() counts them; tooth, kerf 0.5, seed 8004, stroke 0 goes
// through so). When none is accepted, or the refusal is the kernel's own
// (coplanar overlapping quads at kerf 0: the same plane cut twice), the
// stroke is cut back to the quads of its last accepted update and takes no
// more.
//
// What is accepted is what a from-scratch update of the same mask gives
// (CutRemesher is exact and incremental), so deferring changes no geometry;
// stepping round moves the blade by a thousandth of a voxel or a
// hundredth, and the mask holds the quads as cut.
#pragma once

#include "cutter/CutMask.h"
#include "cutter/Remesh.h"

#include <glm/vec3.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace mtcut::cutter {

class LiveStroke
{
public:
    /// Refused updates in a row after which the stroke steps round the
    /// refusal or stops.
    static constexpr int kPatience = 8;
    /// How far (fractions of the smallest voxel spacing; the sign, which
    /// way) a refusal that stays is stepped round, tried in turn: 1e-3 voxel
    /// is a micrometre on a 1 mm grid, ten float steps at a world
    /// coordinate of 1000 mm. Where the coincidence lies near the stick the
    /// quad turns about, one way can leave it as it was.
    static constexpr std::array<double, 4> kStepRoundVoxels = {1e-3, -1e-3, 1e-2, -1e-2};
    /// The largest of them: no corner moves further.
    static constexpr double kStepRoundMostVoxels = 1e-2;
    static_assert(kStepRoundVoxels[2] == kStepRoundMostVoxels && -kStepRoundVoxels[3] == kStepRoundMostVoxels &&
                      kStepRoundVoxels[0] < kStepRoundMostVoxels && -kStepRoundVoxels[1] < kStepRoundMostVoxels,
                  "kStepRoundMostVoxels is the largest step");

    enum class Outcome
    {
        Unchanged, ///< nothing new to re-mesh, or the stroke has stopped
        Accepted,  ///< the cut holds every quad added so far (stepped round a refusal where `steppedRound`)
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
        /// The quads not yet accepted stepped round the refusal (`refusal`:
        /// the first of the row they stepped round), and any later one among
        /// them: Accepted when they all went through; Stopped at a later
        /// refusal that could not be stepped round (`refusal`: that one).
        bool steppedRound = false;
    };

    /// A new stroke of `mask`, cut by `remesher` (which must be up to date
    /// with the mask); both must outlive this. patience >= 1. Without
    /// `stepRound`, a refusal that stays stops the stroke at once (the mask
    /// then holds exactly the quads given).
    LiveStroke(CutMask& mask, CutRemesher& remesher, int patience = kPatience, bool stepRound = true);

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
    /// Quads given to add() that the cut holds (a quad split in stepping
    /// round a refusal counts once).
    uint32_t acceptedQuads() const { return mAccepted; }
    /// Quads given to add() and in the mask (accepted, and waiting after a deferral).
    uint32_t quads() const { return mQuads; }
    /// Times the stroke stepped round a refusal.
    uint32_t steppedRound() const { return mSteppedRound; }
    /// Whether a refusal (the re-mesher's message) is one the stroke steps
    /// round: the local check's, of the surface as written in float (it
    /// crosses or touches itself, or is open, inconsistent or has a triangle
    /// of no area once written). Not the kernel's own (coplanar overlapping
    /// quads at kerf 0: cutting the same plane twice, which moved by a
    /// micrometre would leave a micrometre of bone between the passes).
    static bool belowAFloatStep(const std::string& refusal);

private:
    Result run(bool last);
    /// The stroke back to its last accepted update (mMaskAccepted), the
    /// quads after it dropped.
    void cutBack();
    /// Adds `quad`, made from add()'s quad number `from`, to the mask.
    void addToMask(const Quad& quad, uint32_t from);
    /// Adds `quad` to the mask with the moved corners (mMoved) in place of
    /// their originals, split into two triangles when only some of a
    /// quad's corners moved (and `split`). Returns the quads the mask took.
    uint32_t addMoved(const Quad& quad, uint32_t from, bool split = true);
    /// The stroke's quads in the mask (accepted, and waiting).
    uint32_t maskQuads() const { return uint32_t(mAddOf.size()); }
    /// The add() quads the stroke's first `maskQuads` quads in the mask were made from.
    uint32_t addQuadsOf(uint32_t maskQuads) const { return maskQuads == 0 ? 0 : mAddOf[maskQuads - 1] + 1; }
    /// Steps the quads not yet accepted round their refusal (see the top),
    /// and round any further one among them, one at a time; true when the
    /// re-mesher accepted them all, the mask and the cut then holding the
    /// moved quads. Otherwise the stroke is cut back to its last accepted
    /// update (cutBack), which stepping round may have moved on
    /// (mStopRefusal: the refusal it stopped at).
    bool stepRound();
    /// stepRound from the `back`-th accepted quad before the waiting ones
    /// (0: the first waiting one turns); the mask as before when false.
    bool stepRound(uint32_t stroke, uint32_t back);
    /// The stroke's first `maskQuads` quads in the mask, the rest undone
    /// (with none, the stroke leaves the mask).
    void maskBackTo(uint32_t maskQuads);

    CutMask& mMask;
    CutRemesher& mRemesher;
    int mPatience;
    bool mStepRound;
    bool mStopped = false;
    bool mPending = false;   ///< quads added since the last update
    int mRefusedInARow = 0;
    std::string mFirstRefusal; ///< of the row of refused updates
    uint32_t mAccepted = 0, mQuads = 0; ///< add()'s quads
    uint32_t mMaskAccepted = 0;         ///< the stroke's quads in the mask that the cut holds
    /// Per quad of the stroke in the mask: the add() quad it was made from
    /// (stepping round splits some in two).
    std::vector<uint32_t> mAddOf;
    std::string mStopRefusal; ///< stepRound(): the later refusal it stopped at, if any
    uint32_t mSteppedRound = 0;
    /// Corners moved in stepping round (original, moved), for the quads to come.
    std::vector<std::pair<glm::dvec3, glm::dvec3>> mMoved;
};

} // namespace mtcut::cutter
