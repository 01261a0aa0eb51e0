#include "cutter/BladePath.h"

#include "vdb/Error.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace mtcut::cutter {

glm::ivec3 IndexFrame::cellCount() const
{
    return glm::max(dims - glm::ivec3(1), glm::ivec3(0));
}

glm::ivec3 IndexFrame::cellOf(const glm::dvec3& ijk) const
{
    constexpr double kLimit = double(1 << 30);
    glm::ivec3 c;
    for (int a = 0; a < 3; ++a) c[a] = int(std::floor(std::clamp(ijk[a], -kLimit, kLimit)));
    return c;
}

namespace {

double maxAbs(const glm::dvec3& v)
{
    return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
}

bool finite3(const glm::dvec3& v)
{
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

/// Largest distance of a corner from the quad's plane (0 for degenerate quads).
double planarityError(const Quad& q)
{
    if (q.degenerate) return 0.0;
    double e = 0.0;
    for (uint32_t i = 0; i < q.cornerCount; ++i)
        e = std::max(e, std::abs(glm::dot(q.normal, q.corners[i]) - q.offset));
    return e;
}

double extent(const Quad& q)
{
    glm::dvec3 lo = q.corners[0], hi = q.corners[0];
    for (uint32_t i = 1; i < q.cornerCount; ++i) {
        lo = glm::min(lo, q.corners[i]);
        hi = glm::max(hi, q.corners[i]);
    }
    return maxAbs(hi - lo);
}

/// Whether the two sticks of quad q (corners base0, tip0, tip1, base1, one
/// plane) cross each other: the blade turned about a point of itself between
/// the two poses. The outline then crosses itself, and its hull, which the
/// re-mesher cuts, has the sticks as diagonals, not edges.
bool sticksCross(const Quad& q)
{
    if (q.degenerate || q.cornerCount != 4) return false;
    const std::array<glm::dvec3, 4>& c = q.corners;
    auto orient = [&](const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& x) {
        return glm::dot(glm::cross(b - a, x - a), q.normal);
    };
    return orient(c[0], c[1], c[3]) * orient(c[0], c[1], c[2]) < 0.0 &&
           orient(c[3], c[2], c[0]) * orient(c[3], c[2], c[1]) < 0.0;
}

} // namespace

Quad makeQuad(const glm::dvec3* corners, uint32_t count, uint32_t stick)
{
    Quad q;
    q.cornerCount = count;
    q.stick = stick;
    for (uint32_t i = 0; i < count; ++i) q.corners[i] = corners[i];
    for (uint32_t i = count; i < 4; ++i) q.corners[i] = corners[count - 1];
    // Normal from the largest corner triangle (robust for darts and triangles).
    glm::dvec3 best(0.0);
    double bestLen = 0.0;
    for (uint32_t i = 0; i < count; ++i)
        for (uint32_t j = i + 1; j < count; ++j)
            for (uint32_t k = j + 1; k < count; ++k) {
                const glm::dvec3 c = glm::cross(corners[j] - corners[i], corners[k] - corners[i]);
                const double len = glm::length(c);
                if (len > bestLen) {
                    bestLen = len;
                    best = c;
                }
            }
    const double ext = extent(q);
    if (!(bestLen > 1e-12 * (ext * ext + 1.0))) {
        q.degenerate = true;
        return q;
    }
    glm::dvec3 n = best / bestLen;
    // Orientation: along (tip0 - base0) x (base1 - base0) (corners 0,1 and the last).
    const glm::dvec3 ref =
        glm::cross(corners[1] - corners[0], corners[count - 1] - corners[0]);
    if (glm::dot(n, ref) < 0.0) n = -n;
    q.normal = n;
    // Offset: mean over corners, so the plane is the least-biased fit.
    double d = 0.0;
    for (uint32_t i = 0; i < count; ++i) d += glm::dot(n, corners[i]);
    q.offset = d / count;
    return q;
}

// ---------------------------------------------------------------------------

PathFilter::PathFilter(const IndexFrame& frame, const PathFilterOptions& options)
    : mFrame(frame), mOptions(options)
{
    if (!std::isfinite(options.maxTwist) || options.maxTwist < 0.0)
        throw std::invalid_argument("PathFilterOptions::maxTwist must be finite and >= 0");
    if (!std::isfinite(options.planarTolerance) || options.planarTolerance < 0.0)
        throw std::invalid_argument("PathFilterOptions::planarTolerance must be finite and >= 0");
    if (std::isnan(options.slideTolerance) || options.slideTolerance > kMaxRetraceTolerance)
        throw std::invalid_argument("PathFilterOptions::slideTolerance must be at most " +
                                    std::to_string(kMaxRetraceTolerance) + " voxels (negative: off)");
    if (std::isnan(options.retraceTolerance) || options.retraceTolerance > kMaxRetraceTolerance)
        throw std::invalid_argument("PathFilterOptions::retraceTolerance must be at most " +
                                    std::to_string(kMaxRetraceTolerance) + " voxels (negative: off)");
}

void PathFilter::finishStroke(std::vector<Quad>& quads)
{
    if (!mHavePending || mSticks.empty()) return;
    mHavePending = mHaveSlid = false;
    const Stick& k = mSticks.back();
    if (glm::length(mFrame.toIndex(mPending.base) - mFrame.toIndex(k.base)) > kMinFinalStep) place(mPending, quads);
}

std::vector<Quad> PathFilter::endStroke()
{
    std::vector<Quad> quads;
    finishStroke(quads);
    mSticks.clear();
    // Forget the stroke's own quads (the tail of mQuads and of every index list).
    for (size_t i = mEarlierCount; i < mQuads.size(); ++i) {
        glm::ivec3 b0, b1;
        if (!indexedBlocks(mQuads[i], b0, b1)) continue;
        for (int x = b0.x; x <= b1.x; ++x)
            for (int y = b0.y; y <= b1.y; ++y)
                for (int z = b0.z; z <= b1.z; ++z) {
                    auto it = mQuadBlocks.find(blockKey(glm::ivec3(x, y, z)));
                    if (it == mQuadBlocks.end()) continue;
                    while (!it->second.empty() && it->second.back() >= mEarlierCount) it->second.pop_back();
                    if (it->second.empty()) mQuadBlocks.erase(it);
                }
    }
    while (!mHugeQuads.empty() && mHugeQuads.back() >= mEarlierCount) mHugeQuads.pop_back();
    mQuads.resize(mEarlierCount);
    mLastQuads.clear();
    mPoseCount = 0;
    mHaveTime = false;
    mHaveRetraced = mHaveRetracedInside = false;
    mLastKeptNear = mLastKeptInside = mEntering = mHavePending = mHaveSlid = false;
    return quads;
}

bool PathFilter::push(const Pose& pose, std::vector<Quad>& quads)
{
    auto fail = [&](const std::string& what) {
        std::ostringstream s;
        s << "pose " << mPoseCount << " of the stroke: " << what;
        throw InputError(s.str());
    };
    if (!std::isfinite(pose.time)) fail("time is not a finite number");
    if (!finite3(pose.base)) fail("base point (x,y,z) is not finite");
    if (!finite3(pose.direction)) fail("direction (dx,dy,dz) is not finite");
    if (!std::isfinite(pose.length)) fail("length is not a finite number");
    if (!(pose.length > 0.0)) fail("blade length must be > 0 mm");
    if (pose.length > kMaxPoseMm) fail("blade length is beyond 1e6 mm");
    if (std::abs(pose.base.x) > kMaxPoseMm || std::abs(pose.base.y) > kMaxPoseMm ||
        std::abs(pose.base.z) > kMaxPoseMm)
        fail("base point (x,y,z) is beyond 1e6 mm");
    const double dirLen = glm::length(pose.direction);
    if (!(dirLen >= 1e-9) || !std::isfinite(dirLen)) fail("direction (dx,dy,dz) is zero");
    if (mHaveTime && pose.time < mLastTime) {
        std::ostringstream s;
        s << "time goes backwards (" << pose.time << " s after " << mLastTime << " s)";
        fail(s.str());
    }
    mHaveTime = true;
    mLastTime = pose.time;
    const uint32_t poseIndex = mPoseCount++;

    Stick s1;
    s1.time = pose.time;
    s1.base = pose.base;
    s1.direction = pose.direction / dirLen;
    s1.length = pose.length;
    s1.poseIndex = poseIndex;

    if (mSticks.empty()) {
        bool inside = false;
        mSticks.push_back(s1);
        mLastKeptNear = mOptions.retraceTolerance >= 0.0 && retraces(s1, &inside);
        mLastKeptInside = mLastKeptNear && inside;
        mEntering = mHavePending = mHaveSlid = false;
        return true;
    }
    return consider(s1, quads);
}

bool PathFilter::slides(const Stick& s) const
{
    const Stick& s0 = mSticks.back();
    const glm::dvec3 a = mFrame.toIndex(s0.base), t = mFrame.toIndex(s0.tip()) - a;
    const double len = glm::length(t);
    if (!(len > 0.0)) return false;
    const glm::dvec3 d = t / len;
    const double tol = mOptions.slideTolerance;
    auto off = [&](const glm::dvec3& world) { return glm::length(glm::cross(mFrame.toIndex(world) - a, d)); };
    return off(s.base) <= tol && off(s.tip()) <= tol;
}

bool PathFilter::consider(const Stick& s1, std::vector<Quad>& quads)
{
    const Stick& s0 = mSticks.back();
    if (mFrame.cellOf(mFrame.toIndex(s1.base)) == mFrame.cellOf(mFrame.toIndex(s0.base))) {
        mPending = s1; // the stroke's last pose, if no other comes (finishStroke)
        mHavePending = true;
        // Back in the kept stick's cell after a slide: the slide is given up
        // (it swept within the tolerance of that stick's line), so that the
        // next quad starts where the blade is, not at the slide's far end.
        mHaveSlid = false;
        return false;
    }
    if (mOptions.slideTolerance >= 0.0 && slides(s1)) { // (2c) held back while the blade slides along its line
        mPending = s1;
        mHaveSlid = mHavePending = true;
        return false;
    }
    mHavePending = false;
    if (mHaveSlid) {
        // The blade leaves its line: first where the slide ended (one sliver
        // for the run), then this pose, judged against that stick.
        mHaveSlid = false;
        const Stick slid = mPending; // the slide's last pose (mHaveSlid: the last pushed)
        place(slid, quads);
        return consider(s1, quads);
    }
    return place(s1, quads);
}

bool PathFilter::place(const Stick& s1, std::vector<Quad>& quads)
{
    bool inside = false;
    // (2b) retracing the cut cuts nothing new.
    bool older = false;
    if (mOptions.retraceTolerance >= 0.0 && retraces(s1, &inside, &older)) {
        if (older && !mLastKeptInside && (!mHaveRetraced || mEntering)) {
            // Coming into the cut from fresh bone (or from the cut's edge):
            // the step sweeps bone up to the cut unless it lies in the cut.
            std::vector<Quad> entry;
            Stick kept;
            std::optional<Quad> swept;
            makeQuads(mSticks.back(), s1, uint32_t(mSticks.size() - 1), entry, kept, &swept);
            if (!coveredByCut(entry, !mLastKeptNear || mEntering)) {
                const size_t quadsBefore = quads.size();
                quads.insert(quads.end(), entry.begin(), entry.end());
                mSticks.push_back(kept);
                mLastQuads.clear();
                for (size_t i = quadsBefore; i < quads.size(); ++i)
                    if (indexQuad(swept ? *swept : quads[i])) mLastQuads.push_back(mQuads.back());
                mLastKeptNear = true;
                mLastKeptInside = inside;
                mEntering = !inside;
                mHaveRetraced = mHaveRetracedInside = false;
                return true;
            }
        }
        mRetraced = s1;
        mHaveRetraced = true;
        if (inside) {
            mRetracedInside = s1;
            mHaveRetracedInside = true;
        }
        return false;
    }
    const size_t quadsBefore = quads.size();
    if (mHaveRetraced) {
        // Leaving a retrace (rule 2b): the chord from the last kept stick only
        // where the blade just went; otherwise the strip restarts on the cut,
        // at the last retracing stick inside a quad's outline when the blade
        // left from near it (a stick only near the outline would leave an
        // uncut sliver up to the tolerance wide between the cuts).
        auto close = [&](const Stick& a, const Stick& b) {
            return glm::length(mFrame.toIndex(a.base) - mFrame.toIndex(b.base)) <= 2.0 * kChordTolerance &&
                   glm::length(mFrame.toIndex(a.tip()) - mFrame.toIndex(b.tip())) <= 2.0 * kChordTolerance;
        };
        const Stick& from = mHaveRetracedInside && close(mRetracedInside, mRetraced) ? mRetracedInside : mRetraced;
        std::vector<Quad> chord;
        Stick kept;
        makeQuads(mSticks.back(), s1, uint32_t(mSticks.size() - 1), chord, kept);
        if (!chordFollowsBlade(chord, from, s1)) {
            mSticks.push_back(from);
            ++mRestarts;
        }
        mHaveRetraced = mHaveRetracedInside = false;
    }
    std::optional<Quad> swept;
    appendQuads(s1, quads, &swept);
    mLastQuads.clear();
    for (size_t i = quadsBefore; i < quads.size(); ++i)
        if (indexQuad(swept ? *swept : quads[i])) mLastQuads.push_back(mQuads.back());
    mLastKeptNear = mLastKeptInside = mEntering = false;
    return true;
}

void PathFilter::addEarlierQuad(const Quad& quad)
{
    if (!mSticks.empty()) throw std::logic_error("PathFilter::addEarlierQuad: a stroke is in progress (call endStroke first)");
    if (indexQuad(quad)) mEarlierCount = mQuads.size();
}

void PathFilter::clearEarlierQuads()
{
    if (!mSticks.empty()) throw std::logic_error("PathFilter::clearEarlierQuads: a stroke is in progress (call endStroke first)");
    mQuads.clear();
    mQuadBlocks.clear();
    mHugeQuads.clear();
    mEarlierCount = 0;
}

bool PathFilter::indexedBlocks(const RetraceQuad& r, glm::ivec3& b0, glm::ivec3& b1) const
{
    b0 = blockOf(r.lo - mOptions.retraceTolerance);
    b1 = blockOf(r.hi + mOptions.retraceTolerance);
    const glm::dvec3 span = glm::dvec3(b1 - b0) + 1.0;
    return span.x * span.y * span.z <= double(kRetraceMaxBlocks);
}

bool PathFilter::indexQuad(const Quad& q)
{
    if (q.degenerate || mOptions.retraceTolerance < 0.0) return false;
    RetraceQuad r;
    r.count = q.cornerCount;
    r.lo = glm::dvec3(1e300);
    r.hi = glm::dvec3(-1e300);
    for (uint32_t c = 0; c < r.count; ++c) {
        r.corners[c] = mFrame.toIndex(q.corners[c]);
        r.lo = glm::min(r.lo, r.corners[c]);
        r.hi = glm::max(r.hi, r.corners[c]);
    }
    r.normal = glm::normalize(q.normal * mFrame.spacing); // the plane in index space
    r.hull = convexHullOrder(r.corners.data(), r.count, r.normal);
    if (r.count == 4) // corners {base0, tip0, tip1, base1}: the sticks are corners 0-1 and 2-3
        for (size_t i = 0; i < r.hull.size(); ++i) {
            const int a = r.hull[i], b = r.hull[(i + 1) % r.hull.size()];
            if (std::min(a, b) / 2 == std::max(a, b) / 2 && std::abs(a - b) == 1) r.stickEdges |= uint8_t(1u << i);
        }
    const uint32_t index = uint32_t(mQuads.size());
    glm::ivec3 b0, b1;
    if (!indexedBlocks(r, b0, b1)) {
        mHugeQuads.push_back(index); // tested for every pose
    } else {
        for (int x = b0.x; x <= b1.x; ++x)
            for (int y = b0.y; y <= b1.y; ++y)
                for (int z = b0.z; z <= b1.z; ++z) mQuadBlocks[blockKey(glm::ivec3(x, y, z))].push_back(index);
    }
    mQuads.push_back(std::move(r));
    return true;
}

bool PathFilter::chordFollowsBlade(const std::vector<Quad>& chord, const Stick& retraced, const Stick& next) const
{
    const double tol = kChordTolerance;
    // Where the blade went lately: the last step's quads (ending at the last
    // kept stick) and the two triangles from the last retracing stick to `next`.
    std::vector<RetraceQuad> recent = mLastQuads;
    const glm::dvec3 c[4] = {mFrame.toIndex(retraced.base), mFrame.toIndex(retraced.tip()), mFrame.toIndex(next.tip()),
                             mFrame.toIndex(next.base)};
    for (const std::array<int, 3>& t : {std::array<int, 3>{0, 1, 2}, std::array<int, 3>{0, 2, 3}}) {
        RetraceQuad r;
        r.count = 3;
        r.lo = glm::dvec3(1e300);
        r.hi = glm::dvec3(-1e300);
        for (size_t k = 0; k < 3; ++k) {
            r.corners[k] = c[t[k]];
            r.lo = glm::min(r.lo, r.corners[k]);
            r.hi = glm::max(r.hi, r.corners[k]);
        }
        const glm::dvec3 n = glm::cross(r.corners[1] - r.corners[0], r.corners[2] - r.corners[0]);
        if (!(glm::length(n) > 1e-12)) continue; // degenerate: the other triangle or the last quads cover it
        r.normal = glm::normalize(n);
        r.hull = {0, 1, 2};
        recent.push_back(std::move(r));
    }
    return everySample(chord, [&](const glm::dvec3& p) {
        for (const RetraceQuad& r : recent)
            if (near(r, p, tol)) return true;
        return false;
    });
}

bool PathFilter::everySample(const std::vector<Quad>& quads, const std::function<bool(const glm::dvec3&)>& test) const
{
    for (const Quad& q : quads) {
        glm::dvec3 u[4];
        for (uint32_t k = 0; k < q.cornerCount; ++k) u[k] = mFrame.toIndex(q.corners[k]);
        for (uint32_t t = 0; t + 2 < q.cornerCount; ++t) {
            // Samples kChordSampling voxels apart (at most 256 per edge) on the triangle (u0, u[t+1], u[t+2]).
            const glm::dvec3 a = u[0], e1 = u[t + 1] - a, e2 = u[t + 2] - a;
            const double longest = std::max({glm::length(e1), glm::length(e2), glm::length(e2 - e1)});
            const int n = int(std::clamp(std::ceil(longest / kChordSampling), 1.0, 256.0));
            for (int i = 0; i <= n; ++i)
                for (int j = 0; i + j <= n; ++j)
                    if (!test(a + (double(i) / n) * e1 + (double(j) / n) * e2)) return false;
        }
    }
    return true;
}

bool PathFilter::coveredByCut(const std::vector<Quad>& quads, bool sticksExact) const
{
    const double tol = mOptions.retraceTolerance;
    auto test = [&](uint32_t i, const glm::dvec3& p) { return near(mQuads[i], p, tol, nullptr, sticksExact); };
    return everySample(quads, [&](const glm::dvec3& p) {
        for (uint32_t i : mHugeQuads)
            if (test(i, p)) return true;
        auto it = mQuadBlocks.find(blockKey(blockOf(p)));
        if (it != mQuadBlocks.end())
            for (uint32_t i : it->second)
                if (test(i, p)) return true;
        return false;
    });
}

glm::ivec3 PathFilter::blockOf(const glm::dvec3& indexPoint)
{
    // Clamped far outside any volume, so huge or far-away quads stay finite work.
    const glm::dvec3 b = glm::clamp(glm::floor(indexPoint / double(kRetraceBlock)), glm::dvec3(-(1 << 20)),
                                    glm::dvec3((1 << 20) - 1));
    return glm::ivec3(b);
}

uint64_t PathFilter::blockKey(const glm::ivec3& b)
{
    auto field = [](int v) { return uint64_t(uint32_t(v + (1 << 20)) & 0x1fffff); };
    return field(b.x) | field(b.y) << 21 | field(b.z) << 42;
}

bool PathFilter::near(const RetraceQuad& r, const glm::dvec3& p, double tol, bool* inside, bool sticksExact)
{
    if (glm::any(glm::lessThan(p, r.lo - tol)) || glm::any(glm::greaterThan(p, r.hi + tol))) return false;
    // Within tol of the quad's plane, and its projection inside the outline or within tol of it.
    const double h = glm::dot(r.normal, p - r.corners[0]);
    if (!(std::abs(h) <= tol)) return false;
    const glm::dvec3 q = p - h * r.normal;
    bool in = true;
    double nearest = 1e300; // distance to the outline
    for (size_t i = 0; i < r.hull.size(); ++i) {
        const glm::dvec3& a = r.corners[size_t(r.hull[i])];
        const glm::dvec3 e = r.corners[size_t(r.hull[(i + 1) % r.hull.size()])] - a;
        const double ee = glm::dot(e, e);
        if (!(ee > 0.0)) continue;
        const double side = glm::dot(glm::cross(e, q - a), r.normal);
        if (sticksExact && (r.stickEdges >> i & 1u) && side < -1e-9 * std::sqrt(ee)) {
            if (inside) *inside = false;
            return false; // beyond a stick: no tolerance there
        }
        in = in && side >= 0.0;
        const double t = std::clamp(glm::dot(q - a, e) / ee, 0.0, 1.0);
        nearest = std::min(nearest, glm::length(q - (a + t * e)));
    }
    if (inside) *inside = in;
    return in || nearest <= tol;
}

bool PathFilter::retraces(const Stick& s, bool* inside, bool* older) const
{
    const double tol = mOptions.retraceTolerance;
    const glm::dvec3 base = mFrame.toIndex(s.base), tip = mFrame.toIndex(s.tip());
    const size_t recent = mQuads.size() - std::min(mQuads.size() - mEarlierCount, kRecentQuads);
    bool found = false;
    *inside = false;
    if (older) *older = false;
    auto test = [&](uint32_t i) { // true: done (retracing, inside a quad's outline, and older when asked)
        const RetraceQuad& r = mQuads[i];
        bool inBase = false, inTip = false;
        if (!near(r, base, tol, &inBase) || !near(r, tip, tol, &inTip)) return false;
        found = true;
        *inside = *inside || (inBase && inTip);
        if (older && i < recent) *older = true;
        return *inside && (!older || *older);
    };
    for (uint32_t i : mHugeQuads)
        if (test(i)) return true;
    auto it = mQuadBlocks.find(blockKey(blockOf(base)));
    if (it != mQuadBlocks.end())
        for (uint32_t i : it->second)
            if (test(i)) return true;
    return found;
}

void PathFilter::appendQuads(const Stick& s1, std::vector<Quad>& quads, std::optional<Quad>* swept)
{
    Stick kept;
    makeQuads(mSticks.back(), s1, uint32_t(mSticks.size() - 1), quads, kept, swept);
    mSticks.push_back(kept);
}

void PathFilter::makeQuads(const Stick& s0, const Stick& s1, uint32_t stickIndex, std::vector<Quad>& quads, Stick& kept,
                           std::optional<Quad>* swept) const
{
    if (swept) swept->reset();
    auto quadOf = [&](const Stick& a, const Stick& b) {
        const glm::dvec3 c[4] = {a.base, a.tip(), b.tip(), b.base};
        return makeQuad(c, 4, stickIndex);
    };
    auto planar = [&](const Quad& q) {
        return planarityError(q) <= mOptions.planarTolerance * (extent(q) + 1.0);
    };

    // (a') A stick that crosses the last one (the blade turned about a point
    // of itself: a saw sliding along its own line with the least tremor)
    // is turned about its base to the last one's direction when that is
    // within maxTwist: the quad is then a trapezoid whose edges are its two
    // sticks, so it joins the quads before and after it. The hull of the
    // crossed outline, which the re-mesher would cut instead, has neither
    // stick as an edge: it lay over its neighbours, nearly in their plane, as
    // a quad of its own (2 mm head, kerf 0, sawing along the blade, seeds
    // 75101 and 75107: "coplanar overlapping quads"). Off by default
    // (PathFilterOptions::turnCrossingSticks says why). The user's quad is
    // what rule 2b tests later sticks against (*swept): the blade went there.
    auto uncross = [&](Quad& q, Stick& k) {
        if (!mOptions.turnCrossingSticks || !sticksCross(q)) return;
        const double angle = std::atan2(glm::length(glm::cross(s1.direction, s0.direction)),
                                        glm::dot(s1.direction, s0.direction));
        if (!(angle <= mOptions.maxTwist)) return; // a blade pivoting in its plane (README: refused near the pivot)
        Stick turned = s1;
        turned.direction = s0.direction;
        turned.adjustAngle = angle;
        const Quad t = quadOf(s0, turned);
        if (!planar(t)) return;
        if (swept) *swept = q;
        q = t;
        k = turned;
    };

    // (a) already coplanar (includes collinear motion)
    Quad q = quadOf(s0, s1);
    if (planar(q)) {
        kept = s1;
        uncross(q, kept);
        quads.push_back(q);
        return;
    }
    // (b) rotate the new stick into span(dir0, m)
    const glm::dvec3 m = s1.base - s0.base;
    const glm::dvec3 nu = glm::cross(s0.direction, m);
    const double nuLen = glm::length(nu);
    if (nuLen > 0.0) {
        const glm::dvec3 nuHat = nu / nuLen;
        const glm::dvec3 projected = s1.direction - glm::dot(s1.direction, nuHat) * nuHat;
        const double pLen = glm::length(projected);
        if (pLen > 0.5) { // rotation below 60 degrees; the angle test below decides
            Stick s1r = s1;
            s1r.direction = projected / pLen;
            const double angle =
                std::asin(std::min(1.0, std::abs(glm::dot(s1.direction, nuHat))));
            s1r.adjustAngle = angle;
            if (angle <= mOptions.maxTwist) {
                Quad qr = quadOf(s0, s1r);
                if (planar(qr)) {
                    kept = s1r;
                    uncross(qr, kept);
                    quads.push_back(qr);
                    return;
                }
            }
        }
    }
    // (c) split into two planar triangles
    const glm::dvec3 t0[3] = {s0.base, s0.tip(), s1.tip()};
    const glm::dvec3 t1[3] = {s0.base, s1.tip(), s1.base};
    quads.push_back(makeQuad(t0, 3, stickIndex));
    quads.push_back(makeQuad(t1, 3, stickIndex));
    kept = s1;
}

std::vector<Quad> PathFilter::pushStroke(const std::vector<Pose>& poses)
{
    std::vector<Quad> quads;
    try {
        for (const Pose& p : poses) push(p, quads);
    } catch (...) {
        (void)endStroke();
        throw;
    }
    const std::vector<Quad> last = endStroke();
    quads.insert(quads.end(), last.begin(), last.end());
    return quads;
}

std::vector<Quad> filterStroke(const std::vector<Pose>& poses, const IndexFrame& frame,
                               const PathFilterOptions& options, std::vector<Stick>* sticks)
{
    PathFilter filter(frame, options);
    std::vector<Quad> quads;
    for (const Pose& p : poses) filter.push(p, quads);
    filter.finishStroke(quads);
    if (sticks) *sticks = filter.sticks();
    return quads;
}

std::vector<int> convexHullOrder(const glm::dvec3* points, uint32_t count, const glm::dvec3& n)
{
    const int m = int(count);
    glm::dvec3 e1 = std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    e1 = glm::normalize(e1 - n * glm::dot(n, e1));
    const glm::dvec3 e2 = glm::cross(n, e1);
    std::vector<std::pair<double, double>> p(static_cast<size_t>(m));
    for (int i = 0; i < m; ++i) p[size_t(i)] = {glm::dot(points[i], e1), glm::dot(points[i], e2)};
    int start = 0;
    for (int i = 1; i < m; ++i)
        if (p[size_t(i)] < p[size_t(start)]) start = i;
    std::vector<int> hull;
    int cur = start;
    do {
        hull.push_back(cur);
        int next = (cur + 1) % m;
        for (int i = 0; i < m; ++i) {
            if (i == cur) continue;
            const double ax = p[size_t(next)].first - p[size_t(cur)].first, ay = p[size_t(next)].second - p[size_t(cur)].second;
            const double bx = p[size_t(i)].first - p[size_t(cur)].first, by = p[size_t(i)].second - p[size_t(cur)].second;
            const double cr = ax * by - ay * bx;
            if (cr < 0 || (cr == 0 && bx * bx + by * by > ax * ax + ay * ay)) next = i;
        }
        cur = next;
    } while (cur != start && hull.size() <= size_t(m));
    return hull;
}

// ---------------------------------------------------------------------------
// Voxelisation

namespace {

/// `v` clamped to [lo, hi] as an int; `ifNaN` when v is not a number (a
/// product of values near the double range can be), so the conversion is
/// always defined. Callers pass the bound that keeps the widest range: the
/// exact cell test decides.
int cellBound(double v, int lo, int hi, int ifNaN)
{
    if (std::isnan(v)) return ifNaN;
    return int(std::clamp(v, double(lo), double(hi)));
}

} // namespace

QuadRegion::QuadRegion(const Quad& quad, double kerfMm, const IndexFrame& frame)
    : mCellLo(frame.cutCellLo()), mCellHi(frame.cutCellHi())
{
    const uint32_t n = quad.cornerCount;
    glm::dvec3 u[4];
    for (uint32_t i = 0; i < n; ++i) u[i] = frame.toIndex(quad.corners[i]);
    glm::dvec3 h(0.0);
    if (!quad.degenerate && kerfMm > 0.0) h = (0.5 * kerfMm) * quad.normal / frame.spacing;

    // Edge directions of K_q: corner differences and h (Minkowski-sum edges).
    std::vector<glm::dvec3> edges;
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t j = i + 1; j < n; ++j) {
            const glm::dvec3 e = u[j] - u[i];
            if (e != glm::dvec3(0.0)) edges.push_back(e);
        }
    if (h != glm::dvec3(0.0)) edges.push_back(h);

    std::vector<glm::dvec3> axes;
    // World plane n.x = d is (n * spacing).u = d - n.origin in index space.
    mHasPlane = !quad.degenerate;
    if (mHasPlane) axes.push_back(quad.normal * frame.spacing);
    for (int a = 0; a < 3; ++a) {
        glm::dvec3 e(0.0);
        e[a] = 1.0;
        axes.push_back(e);
    }
    for (size_t i = 0; i < edges.size(); ++i) {
        for (size_t j = i + 1; j < edges.size(); ++j) axes.push_back(glm::cross(edges[i], edges[j]));
        for (int a = 0; a < 3; ++a) {
            glm::dvec3 e(0.0);
            e[a] = 1.0;
            axes.push_back(glm::cross(edges[i], e));
        }
    }

    double scale = maxAbs(glm::abs(h)) + 1.0;
    for (uint32_t i = 0; i < n; ++i) scale = std::max(scale, maxAbs(u[i]) + maxAbs(glm::abs(h)) + 1.0);

    mLower = u[0];
    mUpper = u[0];
    for (uint32_t i = 1; i < n; ++i) {
        mLower = glm::min(mLower, u[i]);
        mUpper = glm::max(mUpper, u[i]);
    }
    mLower -= glm::abs(h);
    mUpper += glm::abs(h);

    for (const glm::dvec3& a : axes) {
        const double a1 = std::abs(a.x) + std::abs(a.y) + std::abs(a.z);
        if (!(a1 > 0.0) || !std::isfinite(a1)) continue;
        double lo = glm::dot(a, u[0]), hi = lo;
        for (uint32_t i = 1; i < n; ++i) {
            const double p = glm::dot(a, u[i]);
            lo = std::min(lo, p);
            hi = std::max(hi, p);
        }
        const double ah = std::abs(glm::dot(a, h));
        const double tol = 1e-12 * a1 * scale;
        const double r = 0.5 * a1; // box half-extent along a
        // The cell [c, c+1] with centre x = c + 0.5 overlaps when
        // dot(a, x) in [lo - ah - r - tol, hi + ah + r + tol].
        mAxes.push_back({a, lo - ah - r - tol, hi + ah + r + tol});
    }
}

bool QuadRegion::touchesCell(const glm::ivec3& cell) const
{
    const glm::dvec3 c = glm::dvec3(cell) + 0.5;
    for (const Axis& ax : mAxes) {
        const double p = glm::dot(ax.a, c);
        if (p < ax.lo || p > ax.hi) return false;
    }
    return true;
}

void QuadRegion::appendCells(std::vector<glm::ivec3>& cells) const
{
    // Cell range from the bounding box, with the box axes' tolerance, clipped
    // to the cells a cut can reach. [c, c+1] meets [lo, hi] iff
    // ceil(lo) - 1 <= c <= floor(hi).
    // (A box outside the reachable cells, or not a number for a quad far
    // out of range, gives none; the int conversions see only clamped values.)
    glm::ivec3 lo, hi;
    for (int a = 0; a < 3; ++a) {
        const double t = 1e-12 * (std::max(std::abs(mLower[a]), std::abs(mUpper[a])) + 1.0);
        const double l = mLower[a] - t, u = mUpper[a] + t;
        const double first = double(mCellLo[a]), last = double(mCellHi[a]) + 1.0;
        if (!(l <= u) || !(l <= last) || !(u >= first)) return;
        lo[a] = std::max(int(std::ceil(std::max(l, first))) - 1, mCellLo[a]);
        hi[a] = std::min(int(std::floor(std::min(u, last))), mCellHi[a]);
        if (hi[a] < lo[a]) return;
    }
    for (const Axis& ax : mAxes)
        if (!(ax.lo <= ax.hi)) return; // not a number: nothing is decided
    // Inner axis: the one the plane normal is most aligned with, so the slab
    // test gives a short interval per column.
    int inner = 2;
    glm::dvec3 nrm(0.0);
    const bool havePlane = mHasPlane;
    if (havePlane) {
        nrm = mAxes[0].a;
        const glm::dvec3 an = glm::abs(nrm);
        inner = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
    }
    const int o1 = (inner + 1) % 3, o2 = (inner + 2) % 3;
    const int outer = std::min(o1, o2), middle = std::max(o1, o2);
    // The axes that do not involve the inner coordinate (K_q's outline seen
    // along the inner axis) bound the middle coordinate of each row, so a
    // long thin quad across the box costs its own cells, not its box's
    // columns. Same slab solve as below; touchesCell decides every cell.
    glm::dvec3 rowAxes[64];
    double rowLo[64], rowHi[64];
    int rowAxisCount = 0;
    for (const Axis& ax : mAxes) {
        const double a1 = std::abs(ax.a.x) + std::abs(ax.a.y) + std::abs(ax.a.z);
        if (ax.a[inner] != 0.0 || !(std::abs(ax.a[middle]) > 1e-9 * a1) || rowAxisCount == 64) continue;
        rowAxes[rowAxisCount] = ax.a;
        rowLo[rowAxisCount] = ax.lo;
        rowHi[rowAxisCount] = ax.hi;
        ++rowAxisCount;
    }
    glm::ivec3 c;
    for (c[outer] = lo[outer]; c[outer] <= hi[outer]; ++c[outer]) {
        int mLo = lo[middle], mHi = hi[middle];
        for (int r = 0; r < rowAxisCount && mLo <= mHi; ++r) {
            const glm::dvec3& a = rowAxes[r];
            const double rest = a[outer] * (c[outer] + 0.5);
            double x0 = (rowLo[r] - rest) / a[middle] - 0.5;
            double x1 = (rowHi[r] - rest) / a[middle] - 0.5;
            if (x0 > x1) std::swap(x0, x1);
            mLo = std::max(mLo, cellBound(std::floor(x0) - 1.0, lo[middle], hi[middle] + 1, lo[middle]));
            mHi = std::min(mHi, cellBound(std::ceil(x1) + 1.0, lo[middle] - 1, hi[middle], hi[middle]));
        }
        for (c[middle] = mLo; c[middle] <= mHi; ++c[middle]) {
            int kLo = lo[inner], kHi = hi[inner];
            if (havePlane && nrm[inner] != 0.0) {
                // dot(nrm, centre) in [lo, hi] solved for the inner coordinate.
                const Axis& ax = mAxes[0];
                const double rest = nrm[outer] * (c[outer] + 0.5) + nrm[middle] * (c[middle] + 0.5);
                double x0 = (ax.lo - rest) / nrm[inner] - 0.5;
                double x1 = (ax.hi - rest) / nrm[inner] - 0.5;
                if (x0 > x1) std::swap(x0, x1);
                // Widen by one cell against rounding in the division; the
                // full test below decides.
                const int l0 = kLo, h0 = kHi;
                kLo = cellBound(std::floor(x0) - 1.0, l0, h0 + 1, l0);
                kHi = cellBound(std::ceil(x1) + 1.0, l0 - 1, h0, h0);
            }
            for (c[inner] = kLo; c[inner] <= kHi; ++c[inner])
                if (touchesCell(c)) cells.push_back(c);
        }
    }
}

void voxelizeQuad(const Quad& quad, double kerfMm, const IndexFrame& frame,
                  std::vector<glm::ivec3>& cells)
{
    QuadRegion(quad, kerfMm, frame).appendCells(cells);
}

namespace {

/// `quad` with its convex hull offset outward by `margin` mm in its plane;
/// in `strips`, for each edge at a corner whose reach is clamped
/// (kKerfMitreMinCornerGap), the edge offset out by `margin`, not past its
/// ends (each edge once).
Quad grownQuad(const Quad& quad, double margin, std::vector<Quad>& strips)
{
    const glm::dvec3 n = quad.normal;
    const std::vector<int> hull = convexHullOrder(quad.corners.data(), quad.cornerCount, n);
    if (hull.size() < 3 || hull.size() > 4) return quad;
    const size_t h = hull.size();
    glm::dvec3 out[4];
    std::vector<char> stripOf(h, 0); // edge k: corner k -> k + 1
    for (size_t k = 0; k < h; ++k) {
        const glm::dvec3& prev = quad.corners[size_t(hull[(k + h - 1) % h])];
        const glm::dvec3& v = quad.corners[size_t(hull[k])];
        const glm::dvec3& next = quad.corners[size_t(hull[(k + 1) % h])];
        // Outward in-plane normals of the edges prev->v and v->next (CCW around n).
        const glm::dvec3 u1 = glm::normalize(glm::cross(v - prev, n));
        const glm::dvec3 u2 = glm::normalize(glm::cross(next - v, n));
        const double gap = 1.0 + glm::dot(u1, u2);
        const double d = std::max(gap, kKerfMitreMinCornerGap);
        out[k] = v + margin * (u1 + u2) / d;
        if (!(gap >= kKerfMitreMinCornerGap)) stripOf[(k + h - 1) % h] = stripOf[k] = 1;
    }
    for (size_t k = 0; k < h; ++k) {
        if (!stripOf[k]) continue;
        const glm::dvec3& a = quad.corners[size_t(hull[k])];
        const glm::dvec3& b = quad.corners[size_t(hull[(k + 1) % h])];
        const glm::dvec3 u = glm::cross(b - a, n);
        const double len = glm::length(u);
        if (!(len > 0.0)) continue;
        const glm::dvec3 c[4] = {a, b, b + margin * u / len, a + margin * u / len};
        strips.push_back(makeQuad(c, 4, quad.stick));
    }
    return makeQuad(out, uint32_t(h), quad.stick);
}

} // namespace

CutRegion::CutRegion(const Quad& quad, double kerfMm, const IndexFrame& frame)
{
    if (!(kerfMm > 0.0) || quad.degenerate) {
        mParts.emplace_back(quad, kerfMm, frame);
        return;
    }
    const double lo = std::min({frame.spacing.x, frame.spacing.y, frame.spacing.z});
    const double hi = std::max({frame.spacing.x, frame.spacing.y, frame.spacing.z});
    const double margin = 1.01 * 0.5 * kerfMm * std::tan(0.5 * kKerfMitreMaxBend) * hi / lo;
    std::vector<Quad> strips;
    mParts.emplace_back(grownQuad(quad, margin, strips), kerfMm, frame);
    for (const Quad& s : strips)
        if (!s.degenerate) mParts.emplace_back(s, kerfMm, frame);
}

bool CutRegion::touchesCell(const glm::ivec3& cell) const
{
    for (const QuadRegion& r : mParts)
        if (r.touchesCell(cell)) return true;
    return false;
}

void CutRegion::appendCells(std::vector<glm::ivec3>& cells) const
{
    const size_t first = cells.size();
    for (const QuadRegion& r : mParts) r.appendCells(cells);
    if (mParts.size() == 1) return;
    auto less = [](const glm::ivec3& a, const glm::ivec3& b) {
        return a.x != b.x ? a.x < b.x : a.y != b.y ? a.y < b.y : a.z < b.z;
    };
    std::sort(cells.begin() + std::ptrdiff_t(first), cells.end(), less);
    cells.erase(std::unique(cells.begin() + std::ptrdiff_t(first), cells.end()), cells.end());
}

CutRegion cutRegion(const Quad& quad, double kerfMm, const IndexFrame& frame)
{
    return CutRegion(quad, kerfMm, frame);
}

void voxelizeCut(const Quad& quad, double kerfMm, const IndexFrame& frame, std::vector<glm::ivec3>& cells)
{
    cutRegion(quad, kerfMm, frame).appendCells(cells);
}

// ---------------------------------------------------------------------------
// Generators

LeFortOptions leFortOptionsFittedTo(const std::vector<glm::vec3>& bone)
{
    LeFortOptions options;
    if (bone.empty()) return options;
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (const glm::vec3& p : bone)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], double(p[a]));
            hi[a] = std::max(hi[a], double(p[a]));
        }
    options.boxLo = lo;
    options.boxHi = hi;
    options.path = LeFortOptions::Path::Across;
    options.zFraction = 0.42;
    options.reachFraction = 0.52;
    options.jitter = 0.0;
    options.tilt = 0.1;
    return options;
}

std::vector<Pose> makeLeFortStroke(const IndexFrame& frame, const LeFortOptions& o)
{
    const bool box = o.boxLo.x < o.boxHi.x && o.boxLo.y < o.boxHi.y && o.boxLo.z < o.boxHi.z;
    const glm::dvec3 lo = box ? o.boxLo : frame.toWorld(glm::dvec3(0.0));
    const glm::dvec3 hi = box ? o.boxHi : frame.toWorld(glm::dvec3(glm::max(frame.dims - 1, glm::ivec3(0))));
    const glm::dvec3 size = hi - lo;
    // Hand tremor; none at all when jitter is 0 (a normal distribution needs
    // a positive deviation).
    std::mt19937 rng(o.seed);
    std::normal_distribution<double> noise(0.0, o.jitter > 0.0 ? o.jitter : 1.0);
    auto tremor = [&] {
        if (!(o.jitter > 0.0)) return glm::dvec3(0.0);
        return glm::dvec3(noise(rng), noise(rng), noise(rng));
    };
    if (o.path == LeFortOptions::Path::Across) {
        constexpr double kMargin = 10.0; // mm in front of the box and past its sides
        const double x0 = lo.x - kMargin, x1 = hi.x + kMargin, y = lo.y - kMargin;
        const double z = lo.z + o.zFraction * size.z;
        const glm::dvec3 direction(0.0, std::cos(o.tilt), -std::sin(o.tilt));
        const double length = (lo.y + o.reachFraction * size.y - y) / direction.y;
        const int count = std::max(2, int((x1 - x0) / o.speed * o.rate));
        std::vector<Pose> poses(static_cast<size_t>(count));
        for (int i = 0; i < count; ++i) {
            Pose& pose = poses[size_t(i)];
            pose.time = double(i) / o.rate;
            pose.base = glm::dvec3(x0 + (x1 - x0) * double(i) / double(count - 1), y, z) + tremor();
            pose.direction = direction;
            pose.length = length;
        }
        return poses;
    }
    const double cx = lo.x + 0.5 * size.x;
    const double cy = lo.y + o.faceFraction * size.y;
    const double z = lo.z + o.zFraction * size.z;
    const double ax = o.halfWidthFraction * size.x, ay = o.depthFraction * size.y;
    // Every blade points at one focus (cx, cy + 0.6 ay) and reaches 0.7 L
    // inside the ellipse; the ellipse comes closest to the focus at its ends
    // (or its front). On a small box (a tooth) a 30 mm blade would pass
    // through the focus from every pose: every quad in one cell, which no
    // re-mesher should be asked to untangle. The blade is shortened so its
    // tip stops a fifth of that distance short of the focus (on the heads
    // and the phantom the 30 mm blade already does: unchanged there).
    const double focusDistance = std::min(std::hypot(ax, 0.6 * ay), 1.6 * ay);
    const double bladeLength = std::min(o.bladeLength, 0.8 * focusDistance / 0.7);
    // Half ellipse over the face side (y < cy): angle from pi (left, -x) .. 2 pi.
    const double arc = 3.14159265358979 * 0.5 * (ax + ay); // approx half perimeter
    const int count = std::max(2, int(arc / o.speed * o.rate));
    std::vector<Pose> poses;
    poses.reserve(size_t(count));
    for (int i = 0; i < count; ++i) {
        const double s = double(i) / double(count - 1);
        const double phi = 3.14159265358979 * (1.0 + s);
        // Ellipse point, sin(phi) <= 0 so y <= cy: the front of the face.
        glm::dvec3 p(cx + ax * std::cos(phi), cy + ay * std::sin(phi), z);
        // The base stays a blade-length outside the bone, pointing inward.
        glm::dvec3 inward = glm::normalize(glm::dvec3(cx - p.x, cy + 0.6 * ay - p.y, 0.0));
        const glm::dvec3 outward = -inward;
        inward = glm::dvec3(std::cos(o.tilt) * inward.x, std::cos(o.tilt) * inward.y, -std::sin(o.tilt));
        Pose pose;
        pose.time = double(i) / o.rate;
        pose.base = p + 0.3 * bladeLength * outward + tremor();
        pose.direction = inward;
        pose.length = bladeLength;
        poses.push_back(pose);
    }
    return poses;
}

std::vector<std::vector<Pose>> makeRandomStrokes(const IndexFrame& frame, uint32_t seed,
                                                 int strokes, int steps, double stepMm,
                                                 double bladeLength, double turn)
{
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::normal_distribution<double> gauss(0.0, 1.0);
    const glm::dvec3 lo = frame.toWorld(glm::dvec3(0.0));
    const glm::dvec3 hi = frame.toWorld(glm::dvec3(glm::max(frame.dims - 1, glm::ivec3(0))));
    auto randomUnit = [&] {
        glm::dvec3 v(gauss(rng), gauss(rng), gauss(rng));
        const double l = glm::length(v);
        return l > 1e-9 ? v / l : glm::dvec3(0, 0, 1);
    };
    std::vector<std::vector<Pose>> out(size_t(std::max(strokes, 0)));
    for (auto& stroke : out) {
        glm::dvec3 p(lo.x + uni(rng) * (hi.x - lo.x), lo.y + uni(rng) * (hi.y - lo.y),
                     lo.z + uni(rng) * (hi.z - lo.z));
        glm::dvec3 dir = randomUnit();
        glm::dvec3 vel = glm::normalize(glm::cross(dir, randomUnit()) + 1e-9);
        double t = uni(rng);
        for (int i = 0; i < steps; ++i) {
            Pose pose;
            pose.time = t;
            pose.base = p;
            pose.direction = dir;
            pose.length = bladeLength;
            stroke.push_back(pose);
            t += 0.001;
            vel = glm::normalize(vel + turn * randomUnit());
            dir = glm::normalize(dir + 0.01 * randomUnit());
            p += stepMm * vel;
        }
    }
    return out;
}

std::vector<Pose> makeSawingStroke(const glm::dvec3& centre, uint32_t seed, const SawingOptions& o)
{
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> gauss(0.0, 1.0);
    auto randomUnit = [&] {
        glm::dvec3 v(gauss(rng), gauss(rng), gauss(rng));
        const double l = glm::length(v);
        return l > 1e-9 ? v / l : glm::dvec3(0, 0, 1);
    };
    const glm::dvec3 d = randomUnit();
    glm::dvec3 across = glm::cross(d, randomUnit());
    if (!(glm::length(across) > 1e-9)) across = glm::cross(d, std::abs(d.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0));
    across = glm::normalize(across);
    // Across: swing along `across`, feed along d. Slide: swing along d, feed along `across`.
    const glm::dvec3 swing = o.slide ? d : across;
    const glm::dvec3 feed = o.slide ? across : d;
    // The tremor: Ornstein-Uhlenbeck walks (each step keeps 90 % of the last
    // offset), scaled so their spread is about tremorMm and tremorRad.
    const double keep = 0.9, kick = std::sqrt(1.0 - keep * keep);
    glm::dvec3 offset(0.0), tilt(0.0);
    const double pi = 3.14159265358979323846;
    const glm::dvec3 start = centre - 0.5 * o.bladeLength * d - 0.5 * o.feedMm * double(o.poses) * feed;
    std::vector<Pose> out;
    out.reserve(size_t(std::max(o.poses, 0)));
    for (int i = 0; i < o.poses; ++i) {
        offset = keep * offset + kick * o.tremorMm * glm::dvec3(gauss(rng), gauss(rng), gauss(rng));
        tilt = keep * tilt + kick * o.tremorRad * glm::dvec3(gauss(rng), gauss(rng), gauss(rng));
        Pose pose;
        pose.time = 0.001 * i;
        pose.base = start + o.amplitudeMm * std::sin(2.0 * pi * i / o.posesPerCycle) * swing +
                    o.feedMm * double(i) * feed + offset;
        pose.direction = glm::normalize(d + tilt);
        pose.length = o.bladeLength;
        out.push_back(pose);
    }
    return out;
}

std::vector<std::vector<Pose>> makeSawingStrokes(const std::vector<glm::vec3>& bone, uint32_t seed, int strokes,
                                                 SawMotion motion, double tremorMm)
{
    if (bone.empty()) throw std::invalid_argument("makeSawingStrokes: no bone points");
    std::mt19937_64 pick(seed);
    std::vector<std::vector<Pose>> out;
    for (int k = 0; k < strokes; ++k) {
        const size_t v = size_t(pick() % bone.size());
        const uint32_t sk = seed + uint32_t(k);
        SawingOptions o;
        o.slide = motion == SawMotion::Both ? sk % 2 == 1 : motion == SawMotion::Slide;
        o.amplitudeMm = 2.0 + 2.0 * double(sk % 3);
        o.feedMm = 0.01 + 0.02 * double(seed % 3);
        o.posesPerCycle = 16.0 + 8.0 * double((seed / 3) % 3);
        o.bladeLength = 10.0 + 10.0 * double(seed % 2);
        o.tremorMm = tremorMm;
        o.tremorRad = 0.08 * tremorMm;
        out.push_back(makeSawingStroke(glm::dvec3(bone[v]), seed * 16u + uint32_t(k), o));
    }
    return out;
}

} // namespace mtcut::cutter
