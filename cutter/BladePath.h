// The blade and its path (MTCut paper, section 3: the haptic thread turns tool
// poses into sticks, sticks into a quad strip, the quad strip into cut cells).
//
// Everything here is plain geometry on GLM + std (no OpenVDB), so the input
// thread and the ThreadSanitizer build (tests/tsan) use it as is. The sparse
// mask that stores the cut cells is cutter/CutMask.h.
//
// Spaces: poses, sticks and quads are in WORLD millimetres (LPS, as
// vdb::Volume). Cells are in INDEX space: cell (i,j,k) is the marching-
// tetrahedra cell with corners at index (i..i+1, j..j+1, k..k+1), i.e. between
// the voxel centres of the scan; a scan of dims voxels has dims-1 cells per axis.
#pragma once

#include <glm/vec3.hpp>
#include <glm/ext/vector_int3.hpp>

#include <array>
#include <optional>
#include <cstdint>
#include <functional>
#include <random>
#include <unordered_map>
#include <vector>

namespace mtcut::cutter {

/// Index <-> world map of a canonical vdb::Volume (scale + translation, see
/// vdb/Volume.h) plus its size. Build one with frameOf(volume) (CutMask.h).
struct IndexFrame
{
    glm::dvec3 origin{0.0};  ///< world mm of the centre of voxel (0,0,0)
    glm::dvec3 spacing{1.0}; ///< mm between voxel centres along x, y, z; all > 0
    glm::ivec3 dims{0};      ///< voxels along x, y, z

    glm::dvec3 toIndex(const glm::dvec3& worldPos) const { return (worldPos - origin) / spacing; }
    glm::dvec3 toWorld(const glm::dvec3& ijk) const { return origin + ijk * spacing; }
    /// Cells per axis: dims - 1 (0 when dims is 0 or 1).
    glm::ivec3 cellCount() const;
    /// The cells a cut can reach, lowest and highest per axis (inclusive):
    /// the box's cells and the ring of cells just outside it, -1 and dims - 1,
    /// where the isosurface closes (voxels outside the scan are outside the
    /// bone), so a cut through bone at the scan's edge cuts the closing
    /// surface too. Empty (hi < lo) when dims is 0.
    glm::ivec3 cutCellLo() const { return glm::ivec3(-1); }
    glm::ivec3 cutCellHi() const
    {
        glm::ivec3 hi = dims - glm::ivec3(1);
        for (int a = 0; a < 3; ++a)
            if (dims[a] <= 0) hi[a] = -2;
        return hi;
    }
    /// The cell containing index point ijk (floor), clamped to +-2^30 so far
    /// away or huge inputs cannot overflow. Not clamped to the volume.
    glm::ivec3 cellOf(const glm::dvec3& ijk) const;
};

/// One tool sample. World mm, seconds.
/// The largest |x|, |y|, |z| of a base point and the longest blade a pose may
/// give, in mm (a kilometre: far past any scanner, well inside the range where
/// index-space arithmetic stays exact enough to decide cells). Path lines and
/// PathFilter::push refuse poses beyond it.
constexpr double kMaxPoseMm = 1e6;

struct Pose
{
    double time = 0.0;        ///< seconds; non-decreasing along a stroke
    glm::dvec3 base{0.0};     ///< the blade's base point, world mm
    glm::dvec3 direction{0.0, 0.0, -1.0}; ///< from base to tip; normalised by the filter
    double length = 0.0;      ///< blade length, mm, > 0
};

/// A kept blade position: the segment [base, base + length * direction].
struct Stick
{
    double time = 0.0;
    glm::dvec3 base{0.0};      ///< world mm
    glm::dvec3 direction{0.0}; ///< unit
    double length = 0.0;       ///< mm
    uint32_t poseIndex = 0;    ///< which pose of the stroke (0-based, counting every push) gave it
    /// Angle (radians) between the kept direction and the user's (normalised)
    /// direction: 0 unless the path filter rotated the stick to make its quad
    /// planar; always <= PathFilterOptions::maxTwist.
    double adjustAngle = 0.0;

    glm::dvec3 tip() const { return base + length * direction; }
};

/// The planar piece of swept surface between two consecutive sticks.
///
/// Corners (world mm): a quad is {base0, tip0, tip1, base1}; when the filter
/// had to split a non-planar step (see PathFilter) each half is a triangle
/// {base0, tip0, tip1} / {base0, tip1, base1} with cornerCount 3.
/// The removed region K_q with kerf w is the convex hull of the corners,
/// thickened by w/2 on both sides along the unit normal (a prism). With w = 0
/// (or for a degenerate quad) it is the hull itself. The hull equals the quad
/// when the quad is convex; a non-convex (dart-shaped) quad, from a blade that
/// pivots about a point inside its length, is conservatively replaced by its hull.
struct Quad
{
    std::array<glm::dvec3, 4> corners{};
    uint32_t cornerCount = 4; ///< 4 (quad) or 3 (triangle: corners[3] unused)
    /// Unit normal of the corners' plane (world); (0,0,0) when degenerate.
    /// Oriented along (tip0 - base0) x (base1 - base0) where that is not zero.
    glm::dvec3 normal{0.0};
    double offset = 0.0;        ///< plane: dot(normal, x) == offset (mm)
    bool degenerate = false;    ///< zero area (corners collinear or equal): a segment or a point
    uint32_t stick = 0;         ///< joins sticks `stick` and `stick + 1` of its stroke
};

/// Builds a Quad/triangle from its corners (count 3 or 4), fitting the plane
/// through them (largest corner triangle; degenerate when twice its area is
/// below 1e-12 * (extent^2 + 1) mm^2).
Quad makeQuad(const glm::dvec3* corners, uint32_t count, uint32_t stick);

/// Indices of the convex hull of points[0..count) (count <= 4), counter-
/// clockwise seen along `normal` (unit), by gift wrapping in the plane; the
/// start is the lexicographically smallest projected point. A deterministic
/// function of its inputs: the re-mesher names quad sides by this order.
std::vector<int> convexHullOrder(const glm::dvec3* points, uint32_t count, const glm::dvec3& normal);

// ---------------------------------------------------------------------------
// Path filter

struct PathFilterOptions
{
    /// Largest rotation (radians) the filter applies to a user's stick to make
    /// its quad planar. Beyond it the step is split into two triangles instead.
    double maxTwist = 0.035; // 2 degrees
    /// Relative planarity tolerance: a quad counts as planar when each corner
    /// lies within planarTolerance * (quad extent + 1 mm) of the fitted plane.
    double planarTolerance = 1e-9;
    /// Retracing (rule 2b): a stick whose base and tip lie within this many
    /// voxels of one of the stroke's quads (of its plane, and inside its
    /// outline) is dropped. Negative: never dropped. At most
    /// kMaxRetraceTolerance. The bound it sets: the cut lags the blade by at
    /// most this much (a pose dropped lies within it of the swept surface).
    /// Raising it trades that lag for speed where a saw goes back and forth
    /// over its cut: each pass that deepens the cut by more than the
    /// tolerance lays a new quad over the whole blade, and the cells along
    /// the blade gather them (benchmarks/RESULTS.md, "A saw worked back and
    /// forth" and "The retrace tolerance").
    double retraceTolerance = 0.25;
    /// Sliding (rule 2c): a pose whose stick's base and tip both lie within
    /// this many voxels of the line through the last kept stick is held
    /// back: the blade slid along its own line, and the quad to it would be
    /// a sliver no wider than this. The run's last such pose is placed
    /// before the next pose that leaves the line (or at the stroke's end,
    /// as rule 2's), so a run of slides makes one quad instead of one per
    /// cell the base passes. Negative: off. At most kMaxRetraceTolerance.
    double slideTolerance = 0.25;
    /// Rule 3 (a'): a stick that crosses the last one is turned to the last
    /// one's direction (within maxTwist). Off by default: it was written for
    /// the kerf-0 stops of saws slid along their blades (9 in 160 strokes on
    /// the 2 mm head and the tooth, all such crossings), and took them away,
    /// but one stroke it let through (tooth, seed 75405, stroke 2) then left
    /// two shells nested the wrong way at a fold between two slivers,
    /// accepted (benchmarks/RESULTS.md, "Crossing sticks"). Rule 2c
    /// (slideTolerance) holds those slides back instead, and with it the
    /// same sweeps stop none. bench_strokes --turn-crossing-sticks.
    bool turnCrossingSticks = false;
};
/// The largest PathFilterOptions::retraceTolerance a PathFilter accepts, voxels.
constexpr double kMaxRetraceTolerance = 4.0;

/// The paper's path filter, for one stroke at a time (section 3), exactly:
///
/// 1. Validation (throws InputError, message names the field): every number
///    finite; length > 0; direction non-zero (|d| >= 1e-9), then NORMALISED
///    (any length is accepted); time >= the previous pose's time.
/// 2. One stick per voxel: a pose whose base lies in the same cell as the
///    last KEPT stick's base is dropped (the first pose of a stroke is always
///    kept). So consecutive sticks never share a cell; a stroke that returns
///    to a cell later (sawing back and forth) gets a new stick there. What this
///    changes: the swept surface follows the kept sticks only, so a blade that
///    pivots about its base without the base leaving the cell cuts nothing new.
///    The stroke's last pose is the exception (finishStroke, called by
///    endStroke): when rule 2 dropped it, it is placed anyway (rules 2b and
///    3), so the cut ends where the blade stopped, not up to a cell short of
///    it (two strokes meeting end to end would otherwise leave a bridge of
///    bone between them).
/// 2b. Retracing: a pose whose stick lies within retraceTolerance voxels of
///    one of the stroke's quads, or of a quad of an earlier stroke given with
///    addEarlierQuad (of its plane, and inside its outline), cuts nothing
///    new, so it is dropped. A hand's tremor moving the base back into the
///    cell it just left, a saw going back and forth over its cut (however
///    long), or a second stroke going back into the cut would otherwise fold
///    the cut onto itself: quads overlapping in one plane, which the
///    re-mesher refuses (or, a few micrometres apart, thin slivers of bone
///    between two passes). Bound: the swept surface misses only poses within
///    that tolerance of it (where rule 3 (a') turned a stick, of the quad to
///    the user's stick, which lies within the turn's move of the tip of the
///    quad kept: the blade went there, and a saw sliding back over it would
///    otherwise lay a quad on every pass). The quads are found through a grid of
///    kRetraceBlock^3-voxel blocks over their bounding boxes, so a pose costs
///    the quads near its base, not the stroke's length.
///    Coming into the cut (a pose that retraces a quad other than the
///    stroke's last kRecentQuads: an earlier stroke's, or the stroke's own
///    start closing a loop; the last few quads are a tremor's): the first
///    retracing pose after a kept stick that
///    does not itself lie inside the cut is kept, with its quad, unless every
///    sample of that quad (kChordSampling apart) lies within the tolerance of
///    the cut's quads (a tremor back over the step just cut), where from a
///    stick that does not retrace at all, or that came into the cut, there is
///    no tolerance across the quads' sticks (a stroke's end): the step sweeps
///    bone up to the cut, and dropping it would leave a bridge up to a step
///    wide where a second stroke meets the first (or a loop its own start). While the kept stick lies only near the cut
///    (within the tolerance of an outline, not inside), the retracing poses
///    after it are tested the same way, so no sliver is left between the
///    cuts; a step back over the stroke's own last quads is covered by them
///    and never kept (it would fold the strip).
///    Leaving a retrace: the next quad would join the last kept stick K to
///    the new stick N. That chord is kept when the blade went there lately:
///    every point of it (sampled kChordSampling voxels apart) lies within
///    kChordTolerance voxels of the quads that end at K or of the way from
///    the last retracing stick R to N (tremor; a saw that came back to where
///    it was). Otherwise the strip restarts at R: R is kept, with no quad
///    from K, and the next quad joins R to N. (R is the last retracing stick
///    whose base and tip project inside a quad's outline, when it is within
///    2 kChordTolerance of the last retracing one: a stick only near the
///    outline would leave a sliver up to the tolerance wide between the
///    cuts, which then would not separate.) So no quad spans ground the
///    blade did not just sweep: back along a curved cut and out past its
///    start, joining K would cut a chord straight across the bone; back
///    along a straight one it would overlap the whole cut. restarts() counts
///    these. A restarted quad starts on the old cut and overlaps it by up to
///    a step: where both lie exactly in one plane (a scripted path, not a
///    hand's) the re-mesher refuses that with kerf 0.
/// 2c. Sliding (before 2b, after 2): a pose whose stick's base and tip lie
///    within slideTolerance voxels of the line through the last kept stick
///    is held back, as rule 2 holds one back in the same cell: a blade slid
///    along its own line (a reciprocating saw) sweeps a line, and its quad
///    would be a sliver at most the tolerance wide (on the sliding-saw
///    sweeps 80-97 % of the quads were such slivers, and the source of their
///    crossing sticks and folds thinner than a float step). When a pose
///    leaves the line, the last one held back is placed first (rules 2b and
///    3), then the pose, judged against it: the run makes one sliver, and
///    the blade swings from where it was, not from where the run began. A
///    pose back in the kept stick's cell (rule 2) gives the slide up: the
///    next quad starts from the kept stick, within a cell of the blade. At
///    the stroke's end the last pose is placed as rule 2's. Bound: what the
///    poses held back sweep lies within the tolerance of the kept stick's
///    line (a band that wide along a line, which parts no bone).
/// 3. Coplanarity: let S0 be the last kept stick, S1 the new one, m = base1 -
///    base0. (a) If S0 and S1 are coplanar within planarTolerance the quad is
///    kept as is - this includes collinear motion (m parallel to S0), where
///    any S1 is coplanar. (a') With PathFilterOptions::turnCrossingSticks
///    (off by default): when S1 then crosses S0 (the blade turned about a
///    point of itself: a saw sliding along its own line, with the least
///    tremor) and S1's direction lies within maxTwist of S0's, S1 is turned
///    about its base to S0's direction (Stick::adjustAngle): the quad is a
///    trapezoid with the two sticks as edges, so it joins the quads before
///    and after it. The crossed outline's hull has the sticks as diagonals
///    instead; the re-mesher cuts it as a quad of its own lying over its
///    neighbours, nearly in their plane, which it refuses at kerf 0
///    ("coplanar overlapping quads"). Turns beyond maxTwist (a blade pivoting
///    in its own plane) are kept. (b) Otherwise S1's direction is projected onto the
///    plane span(dir0, m); when the rotation this applies is <= maxTwist the
///    rotated stick is kept (Stick::adjustAngle) and the quad is planar
///    (and (a') applies to it).
///    The rotation is measured against the user's own direction every time, so
///    it never accumulates along a stroke. (c) Otherwise (a fast twist) the
///    user's stick is kept unchanged and the step is emitted as two planar
///    triangles {base0,tip0,tip1}, {base0,tip1,base1}.
///    Bound: every kept stick has the user's base and length, and a direction
///    within maxTwist of the user's; every emitted polygon is planar within
///    planarTolerance; the strip has no gap (consecutive pieces share edges,
///    except at a retrace restart (2b), whose quad starts on the cut).
/// 4. Poses outside the volume are kept (the geometry stays exact); the
///    voxelisation clips cut cells to the volume.
///
/// Cost: O(1) per pose, plus rule 2b's test of the quads whose blocks hold
/// the base (a few, unless the cut passes the same place many times), and
/// on leaving a retrace the chord's samples against a few quads (its area
/// in quarter voxels: a few hundred for a short step).
class PathFilter
{
public:
    /// Edge of rule 2b's blocks, voxels.
    static constexpr int kRetraceBlock = 8;
    /// A quad whose box spans more blocks than this is not indexed but tested for every pose.
    static constexpr size_t kRetraceMaxBlocks = 4096;
    /// Rule 2b, leaving a retrace: the chord is kept when every sample of it
    /// lies within this many voxels of where the blade went lately (the
    /// order of rule 2's one stick per cell).
    static constexpr double kChordTolerance = 1.0;
    /// Spacing of the chord's samples, voxels.
    static constexpr double kChordSampling = 0.5;
    /// Rule 2b: a pose that retraces only the stroke's last this many quads
    /// is not coming into the cut (a tremor).
    static constexpr size_t kRecentQuads = 4;
    /// finishStroke: a last pose whose base lies within this many voxels of
    /// the last kept stick's base adds nothing.
    static constexpr double kMinFinalStep = 0.01;

    /// Throws std::invalid_argument on options out of range (a tolerance
    /// or twist not finite, retraceTolerance above kMaxRetraceTolerance).
    explicit PathFilter(const IndexFrame& frame, const PathFilterOptions& options = {});

    /// Feeds the next pose of the current stroke; appends the quads it makes
    /// to `quads`: 0, 1 or 2 of its own, after 0, 1 or 2 of a slide held
    /// back (rule 2c) that it places first, also when it is itself dropped.
    /// Returns true when the pose was kept as a stick.
    /// Throws InputError on a bad pose (the filter state is unchanged): a value
    /// not finite, a zero direction, a length not > 0, or a length or base
    /// coordinate beyond kMaxPoseMm, or a time before the last pose's.
    bool push(const Pose& pose, std::vector<Quad>& quads);
    /// Feeds a whole stroke (push for each pose, then endStroke) and returns
    /// its quads, endStroke's last. Throws InputError on a bad pose (the stroke is then ended).
    std::vector<Quad> pushStroke(const std::vector<Pose>& poses);
    /// Rule 2's last pose: when the stroke's last pose pushed was dropped
    /// because its base shares the last kept stick's cell, places it (as a
    /// pose of a new cell would be: rules 2b and 3) and appends its quads, so
    /// the cut reaches where the blade stopped; nothing when it lies within
    /// kMinFinalStep voxels of that stick's base (the blade pivoted on it), or
    /// when the last pose was kept or dropped by rule 2b. The stroke stays open.
    void finishStroke(std::vector<Quad>& quads);
    /// Ends the current stroke: finishStroke, then the next push starts a new
    /// one. Returns finishStroke's quads (0, 1 or 2), which belong to the
    /// stroke. The stroke's quads are forgotten (a caller that keeps them
    /// hands them back with addEarlierQuad).
    [[nodiscard]] std::vector<Quad> endStroke();
    /// Rule 2b also drops poses that retrace `quad`, a quad of an earlier
    /// stroke already in the cut. Only between strokes (throws
    /// std::logic_error while one is in progress); kept until
    /// clearEarlierQuads. Degenerate quads are ignored.
    void addEarlierQuad(const Quad& quad);
    /// Forgets the earlier strokes' quads (after an undo, before handing
    /// back those that remain). Only between strokes.
    void clearEarlierQuads();
    /// How many earlier quads rule 2b tests against.
    size_t earlierQuadCount() const { return mEarlierCount; }

    /// Sticks kept in the current stroke, in order.
    const std::vector<Stick>& sticks() const { return mSticks; }
    /// Poses pushed in the current stroke (kept or not).
    uint32_t posesSeen() const { return mPoseCount; }
    /// Strip restarts after retraces (rule 2b) since the filter was made.
    size_t restarts() const { return mRestarts; }
    const IndexFrame& frame() const { return mFrame; }

private:
    /// A quad as rule 2b tests sticks against it (index space, made once when
    /// the quad is emitted or handed in).
    struct RetraceQuad
    {
        std::array<glm::dvec3, 4> corners{};
        uint32_t count = 0;
        glm::dvec3 normal{0.0}; ///< unit
        glm::dvec3 lo{0.0}, hi{0.0};
        std::vector<int> hull; ///< convexHullOrder of the corners
        uint8_t stickEdges = 0; ///< bit i: hull edge i (hull[i] to hull[i+1]) is a stick (quads, not triangles)
    };
    /// Rules 2b and 3 for a validated stick s1 whose base is in another cell
    /// than the last kept stick's (or the stroke's last pose): push's result.
    bool place(const Stick& s1, std::vector<Quad>& quads);
    /// Rule 3: appends the quad(s) from the last kept stick to s1 and keeps
    /// s1; *swept as makeQuads sets it.
    void appendQuads(const Stick& s1, std::vector<Quad>& quads, std::optional<Quad>* swept = nullptr);
    /// Rule 3 from s0 (stick number stickIndex) to s1: appends the quad(s) to
    /// `quads` and sets `kept` to the stick to keep (s1, or s1 rotated).
    /// *swept (when given): where (a') turned the stick, the quad (a) or (b)
    /// made before, its sticks crossing (rule 2b tests later sticks against
    /// it: the blade went there); else empty.
    void makeQuads(const Stick& s0, const Stick& s1, uint32_t stickIndex, std::vector<Quad>& quads, Stick& kept,
                   std::optional<Quad>* swept = nullptr) const;
    /// Rule 2b: do the base and tip of s lie within the tolerance of one quad
    /// (the stroke's or an earlier one)? *inside: of one whose outline holds both projections.
    bool retraces(const Stick& s, bool* inside, bool* older = nullptr) const;
    /// Rule 2b, leaving a retrace: does every sample of `chord` lie within
    /// kChordTolerance of mLastQuads or of the way from `retraced` to `next`?
    bool chordFollowsBlade(const std::vector<Quad>& chord, const Stick& retraced, const Stick& next) const;
    /// Does `test` hold at every sample of `quads` (index space, kChordSampling apart)?
    bool everySample(const std::vector<Quad>& quads, const std::function<bool(const glm::dvec3&)>& test) const;
    /// Rule 2b, coming into the cut: does every sample of `quads` lie within
    /// the retrace tolerance of the quads (the stroke's and the earlier ones;
    /// near() with sticksExact)?
    bool coveredByCut(const std::vector<Quad>& quads, bool sticksExact) const;
    /// Adds a non-degenerate quad to mQuads and the block index; false (nothing added) otherwise.
    bool indexQuad(const Quad& quad);
    /// The blocks r is listed in; false when it is one of mHugeQuads instead.
    bool indexedBlocks(const RetraceQuad& r, glm::ivec3& b0, glm::ivec3& b1) const;
    /// Is index point p within tol of r (its plane, and inside or near its
    /// outline)? *inside: whether its projection is inside the outline.
    /// sticksExact: no tolerance across r's sticks (stickEdges), only across
    /// its base and tip lines (coming into the cut, the step beyond a
    /// stroke's end stick is fresh bone however short).
    static bool near(const RetraceQuad& r, const glm::dvec3& p, double tol, bool* inside = nullptr,
                     bool sticksExact = false);
    static glm::ivec3 blockOf(const glm::dvec3& indexPoint);
    static uint64_t blockKey(const glm::ivec3& block);

    IndexFrame mFrame;
    PathFilterOptions mOptions;
    std::vector<Stick> mSticks;
    /// Rule 2b's quads: the earlier strokes' (the first mEarlierCount), then
    /// the stroke's own, non-degenerate, oldest first.
    std::vector<RetraceQuad> mQuads;
    size_t mEarlierCount = 0;
    std::vector<RetraceQuad> mLastQuads; ///< the quads that end at the last kept stick (none after a restart)
    /// Rule 2b's index: block (packed) -> mQuads whose box, grown by the tolerance, meets it (ascending).
    std::unordered_map<uint64_t, std::vector<uint32_t>> mQuadBlocks;
    std::vector<uint32_t> mHugeQuads; ///< quads over more than kRetraceMaxBlocks blocks
    Stick mRetraced;            ///< the last stick rule 2b dropped since the last kept one
    bool mHaveRetraced = false; ///< whether mRetraced is set
    Stick mRetracedInside;      ///< the last of those inside a quad's outline
    bool mHaveRetracedInside = false;
    /// The last kept stick retraces the cut (rule 2b), and does so inside a quad's outline.
    bool mLastKeptNear = false;
    bool mLastKeptInside = false;
    /// The last kept stick came into the cut (rule 2b) and lies only near it,
    /// not inside: the retracing poses after it are tested as it was.
    bool mEntering = false;
    Stick mPending;             ///< the last pose pushed, when rule 2 or 2c dropped it (finishStroke)
    bool mHavePending = false;
    /// The last pose pushed (mPending) is one rule 2c held back: a slide
    /// since the last kept stick that no pose back in that stick's cell
    /// (rule 2) gave up.
    bool mHaveSlid = false;
    /// Rule 2c: s lies within slideTolerance of the line of the last kept stick.
    bool slides(const Stick& s) const;
    /// Rules 2, 2c, then place (the rest) for a stick of a new pose.
    bool consider(const Stick& s1, std::vector<Quad>& quads);
    size_t mRestarts = 0;
    uint32_t mPoseCount = 0;
    double mLastTime = 0.0;
    bool mHaveTime = false;
};

/// Convenience: filters a whole stroke; returns its quads (and, if given, its sticks).
std::vector<Quad> filterStroke(const std::vector<Pose>& poses, const IndexFrame& frame,
                               const PathFilterOptions& options = {},
                               std::vector<Stick>* sticks = nullptr);

// ---------------------------------------------------------------------------
// Conservative voxelisation (DESIGN invariant 5)

/// A quad's removed region K_q in index space, ready for exact box tests.
///
/// K_q (see Quad) is mapped to index space by the volume's scale+translate,
/// which keeps it a convex polytope: hull(corners) + [-h, h] with
/// h = (kerf/2) * normal / spacing (anisotropic spacing handled exactly).
/// touchesCell() is the separating-axis test of the closed cell box against
/// K_q with every candidate axis (box normals, K_q's face normals, edge x edge
/// crosses), so it is exact up to a tolerance of about 1e-12 * (|coord| + 1)
/// voxel in the conservative direction: a box that touches K_q (also exactly
/// on a face, edge or vertex: quads on grid planes, through grid vertices) is
/// always reported; one farther than ~1e-9 voxel never is. A degenerate quad
/// (segment or point) cuts the cells its segment/point touches; kerf is not
/// applied to it (it has no plane).
class QuadRegion
{
public:
    /// kerfMm >= 0, world mm (full width; the slab is kerf/2 each side).
    QuadRegion(const Quad& quad, double kerfMm, const IndexFrame& frame);

    /// Does the closed box [c, c+1] (index space) touch K_q? ~50 ns..0.3 us.
    bool touchesCell(const glm::ivec3& cell) const;
    /// Appends every cell a cut can reach (frame.cutCellLo() <= cell <=
    /// frame.cutCellHi(): the volume's cells and the ring around them) that
    /// touches K_q, in lexicographic order of (outer, middle, inner) axes with
    /// the inner axis along the dominant normal. Cost: O(cells near the quad).
    void appendCells(std::vector<glm::ivec3>& cells) const;

    /// Index-space bounding box of K_q (before clipping to the volume).
    glm::dvec3 lower() const { return mLower; }
    glm::dvec3 upper() const { return mUpper; }

private:
    struct Axis
    {
        glm::dvec3 a;
        double lo, hi; ///< projection of K_q, widened by the tolerance and the box radius
    };
    std::vector<Axis> mAxes; ///< the first one is the plane normal when mHasPlane
    bool mHasPlane = false;
    glm::dvec3 mLower{0.0}, mUpper{0.0};
    glm::ivec3 mCellLo{0}, mCellHi{-1}; ///< frame.cutCellLo(), cutCellHi()
};

/// Appends the cells cut by `quad` (QuadRegion(quad, kerf, frame).appendCells).
void voxelizeQuad(const Quad& quad, double kerfMm, const IndexFrame& frame,
                  std::vector<glm::ivec3>& cells);

/// Kerf > 0: consecutive quads of a stroke that bend by less than this (radians,
/// between their world normals) meet on a shared mitre plane in the re-mesher (Remesh.h), so
/// the removed region of a stroke is a smooth thick strip, not prisms with
/// micro-notches at every joint. The mitre reaches past K_q by at most
/// (w/2) tan(bend/2); cutRegion() covers that.
constexpr double kKerfMitreMaxBend = 0.35;
/// Kerf > 0: cutRegion() grows a quad's hull by offsetting its edges, with
/// each corner's reach clamped where 1 - cos(corner angle) is below this (a
/// corner of 2.6 degrees or less: a blade pivoting about its tip makes
/// triangles that sharp); a mitre at such a corner reaches past it by
/// (w/2) tan(bend/2) / sin(angle), so where that reach leaves the clamped
/// growth the re-mesher caps the mitre at the corner, at right angles to
/// the stick (tooSharpForMitre, Remesh.cpp), and cutRegion() adds the strip
/// along each edge of a clamped corner, the edge offset out by the growth
/// (not past its ends), which holds what the capped mitre reaches past it.
constexpr double kKerfMitreMinCornerGap = 1e-3;

/// The region whose cells a quad cuts (what CutMask, the pose stream and the
/// re-mesher voxelise): K_q itself for kerf 0; for kerf w > 0, K_q with its
/// hull grown in its plane by (w/2) tan(kKerfMitreMaxBend/2) (times the
/// spacing anisotropy), with the strips of its sharp corners' edges
/// (kKerfMitreMinCornerGap), so the mitre joints are inside cut cells too.
class CutRegion
{
public:
    CutRegion(const Quad& quad, double kerfMm, const IndexFrame& frame);
    /// Does the closed box [c, c+1] (index space) touch the region?
    bool touchesCell(const glm::ivec3& cell) const;
    /// Appends every cell a cut can reach that touches the region, each
    /// once: QuadRegion::appendCells's order when it is one part (no sharp
    /// corner), else ascending (x, y, z).
    void appendCells(std::vector<glm::ivec3>& cells) const;
    /// The grown hull, then the strips.
    const std::vector<QuadRegion>& parts() const { return mParts; }

private:
    std::vector<QuadRegion> mParts;
};
CutRegion cutRegion(const Quad& quad, double kerfMm, const IndexFrame& frame);

/// Appends the cells cut by `quad` with kerf (cutRegion(...).appendCells).
void voxelizeCut(const Quad& quad, double kerfMm, const IndexFrame& frame, std::vector<glm::ivec3>& cells);

// ---------------------------------------------------------------------------
// Path generators (tests and benchmarks)

/// A LeFort I-like osteotomy: one horizontal stroke in front of the face (-y
/// side), the blade pointing posteriorly (+y), cutting a plane above the
/// teeth. Geometry is a fraction of a box (the scan box, or boxLo..boxHi) so
/// it lands on the head phantom and on a fitted head. Two paths:
/// - HalfEllipse (the default; the phantom's LeFort plane): the base runs a
///   half ellipse centred at x = box centre, in the plane z = zFraction of
///   the box height, from the left to the right side of the face, every
///   blade aiming at one focus behind the front;
/// - Across (leFortOptionsFittedTo): the base runs straight along x across
///   the box's whole width, 10 mm in front of it and 10 mm past each side,
///   the blade's tip reaching reachFraction of the box depth behind its
///   front: on a head scan a plane through the whole face at that height,
///   short of the spine.
struct LeFortOptions
{
    enum class Path
    {
        HalfEllipse,
        Across,
    };
    Path path = Path::HalfEllipse;
    double zFraction = 0.32;   ///< height of the cut in the box, 0 = bottom (Across: at the box's front)
    double halfWidthFraction = 0.16; ///< HalfEllipse: x half-axis of the ellipse / box width
    double depthFraction = 0.16;     ///< HalfEllipse: y half-axis / box depth
    double faceFraction = 0.30;      ///< HalfEllipse: y of the ellipse centre / box depth from -y
    double reachFraction = 0.52;     ///< Across: y of the blade's tip / box depth from -y
    double bladeLength = 30.0;       ///< mm (HalfEllipse; Across: as long as the reach needs)
    double speed = 10.0;             ///< mm/s of the base
    double rate = 1000.0;            ///< poses per second
    double jitter = 0.05;            ///< mm of hand tremor (seeded)
    uint32_t seed = 1;
    double tilt = 0.0;               ///< radians the blade points down from horizontal (a LeFort I cut slopes back)
    /// When set (lo < hi), the fractions above refer to this world box (e.g.
    /// the bone's bounding box) instead of the scan box.
    glm::dvec3 boxLo{0.0}, boxHi{0.0};
};
std::vector<Pose> makeLeFortStroke(const IndexFrame& frame, const LeFortOptions& options = {});
/// LeFortOptions fitted to a head scan from the vertex to the neck through
/// its bone's points (world mm, e.g. the isosurface's vertices): the
/// fractions refer to their bounding box; the path goes Across at 42 % of
/// its height, the tip reaching 52 % of its depth, no tremor, the blade
/// sloping down 0.1 rad. On the VHM head (1, 2 and 4 mm) that frees the
/// lower face: the maxilla with the upper teeth, and the mandible, whose
/// teeth touch them in the scan, its rami cut in the same plane. Reaches of
/// 47-56 % do so on all three; 45 % stops short of the rami's back edges
/// (nothing comes off), 58 % cuts the spine too (the 1 and 4 mm heads lose
/// the neck). The defaults when `bone` is empty.
LeFortOptions leFortOptionsFittedTo(const std::vector<glm::vec3>& bone);

/// Seeded random strokes inside the scan box: smooth random walks of the base
/// with a slowly turning blade. `steps` poses per stroke, base moving about
/// `stepMm` per pose. `turn`: the weight of the random unit vector added to
/// the base's direction of motion at each pose (0.05: a smooth path; about 1:
/// sharp turns and strokes doubling back on themselves).
std::vector<std::vector<Pose>> makeRandomStrokes(const IndexFrame& frame, uint32_t seed,
                                                 int strokes, int steps, double stepMm = 0.3,
                                                 double bladeLength = 20.0, double turn = 0.05);

/// A saw worked back and forth the way a hand does, for sweeps and tests:
/// the blade reciprocates through `centre` (world mm) while it advances,
/// so most of each pass goes back over the cut (the path filter's rule 2b)
/// and the rest deepens it. Two motions, as saws are held:
/// - Across (`slide` false): the blade points along a random direction d,
///   its base swings +-amplitudeMm across it (perpendicular to d) and moves
///   feedMm a pose along d: a keyhole saw pushed deeper each pass; the cut
///   grows at the blade's tip.
/// - Slide (`slide` true): the blade slides +-amplitudeMm along its own
///   line (a reciprocating saw's edge) and moves feedMm a pose across it,
///   in the cut's plane: the cut grows at the blade's side.
/// On top, a hand's tremor: the base wanders by a smoothed random walk of
/// about tremorMm and the direction by about tremorRad (both 0: the poses
/// lie exactly in one plane, a scripted saw). `posesPerCycle` poses make one
/// back-and-forth. Deterministic in `seed`.
struct SawingOptions
{
    int poses = 400;
    double amplitudeMm = 4.0;
    double feedMm = 0.02;
    double posesPerCycle = 24.0;
    double bladeLength = 15.0;
    double tremorMm = 0.05;
    double tremorRad = 0.004;
    bool slide = false;
};
std::vector<Pose> makeSawingStroke(const glm::dvec3& centre, uint32_t seed, const SawingOptions& options = {});
/// Which motion makeSawingStrokes gives its strokes: all Across, all Slide,
/// or Both, stroke by stroke (seed + stroke odd: Slide).
enum class SawMotion { Across, Slide, Both };
/// `strokes` sawing strokes (makeSawingStroke, 400 poses) for the sweeps
/// and tests, each through a vertex of `bone` (world mm, e.g. the uncut
/// isosurface's; not empty) that the seed picks. By seed: amplitude 2, 4 or
/// 6 mm (also by stroke), feed 0.01, 0.03 or 0.05 mm a pose, 16, 24 or 32
/// poses a cycle, blade 10 or 20 mm; tremor `tremorMm` and 0.08 rad a mm of
/// it. Throws std::invalid_argument when `bone` is empty.
std::vector<std::vector<Pose>> makeSawingStrokes(const std::vector<glm::vec3>& bone, uint32_t seed, int strokes,
                                                 SawMotion motion, double tremorMm = 0.05);

} // namespace mtcut::cutter
