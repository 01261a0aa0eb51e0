#include "tools/view/CutSession.h"

#include "cutter/CutMask.h"
#include "cutter/Fusion.h"
#include "cutter/Isosurface.h"
#include "cutter/LiveStroke.h"
#include "cutter/MeshCheck.h"
#include "cutter/Remesh.h"
#include "tools/Cli.h"
#include "vdb/Phantom.h"

#include <glm/geometric.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

namespace mtcut::view {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// Volume and area per fragment id (1-based) of the triangles of `mesh`
/// with ids `ids` (0: skipped), added into `out`.
void accumulateFragments(const cutter::Mesh& mesh, const std::vector<uint32_t>& ids,
                         std::vector<FragmentSummary>& out)
{
    for (size_t t = 0; t < ids.size(); ++t) {
        const uint32_t id = ids[t];
        if (id == 0) continue;
        if (id > out.size()) out.resize(id);
        const glm::dvec3 a(mesh.positions[mesh.indices[3 * t]]), b(mesh.positions[mesh.indices[3 * t + 1]]),
            c(mesh.positions[mesh.indices[3 * t + 2]]);
        FragmentSummary& f = out[id - 1];
        f.volumeMm3 += glm::dot(a, glm::cross(b, c)) / 6.0;
        f.areaMm2 += 0.5 * glm::length(glm::cross(b - a, c - a));
        ++f.triangles;
    }
}

} // namespace

/// Progress of the running task, polled by the worker's long calls.
class CutSession::Progress : public Interrupter
{
public:
    explicit Progress(CutSession& session) : mSession(session) {}
    void start(const char* name) override
    {
        if (name) mSession.setTaskName(name);
        mSession.mPercent = 0;
    }
    void end() override { mSession.mPercent = -1; }
    bool wasInterrupted(int percent) override
    {
        if (percent >= 0) mSession.mPercent = percent;
        return mSession.mCancel.load();
    }

private:
    CutSession& mSession;
};

/// The document (worker thread only).
struct CutSession::State
{
    std::shared_ptr<const vdb::Volume> volume;
    std::string input;
    cutter::IndexFrame frame;
    float iso = 0.0f;
    double kerf = 0.0;
    std::shared_ptr<const cutter::Mesh> surface;
    std::unique_ptr<cutter::CutMask> mask;
    std::unique_ptr<cutter::CutRemesher> remesher;

    // The live stroke.
    cutter::PathFilterOptions filterOptions;  ///< setRetrace, setSlide; for the strokes to come
    bool manyQuadsNoted = false;              ///< cli::manyQuadsNote said once this session
    std::unique_ptr<cutter::PathFilter> filter;
    bool live = false;                          ///< between beginStroke and endStroke
    std::unique_ptr<cutter::LiveStroke> stroke; ///< the live stroke's quads and its refusals
    bool haveBlade = false;
    cutter::Pose blade;
    std::string pathFile; ///< the path file the whole cut came from ("" after a mouse stroke)

    /// What summary.json says of a stroke of the cut, by its number in the
    /// mask (1-based): cut only in part (its quads in the mask then, to
    /// tell a later undo of part of it), or stepped round a refusal.
    struct StrokeNote
    {
        bool refused = false;
        cli::RefusedStroke refusal;
        uint32_t maskQuads = 0;
        bool steppedRound = false;
    };
    std::map<uint32_t, StrokeNote> notes;
    /// A stroke entered the mask as `number`: the notes of strokes
    /// undone before it, which it replaces, go.
    void strokeEntered(uint32_t number) { notes.erase(notes.lower_bound(number), notes.end()); }
    /// Stroke `number` of the cut was cut only in part (`refusal` names it so).
    void noteRefused(uint32_t number, const cli::RefusedStroke& refusal)
    {
        StrokeNote& note = notes[number];
        note.refused = true;
        note.refusal = refusal;
        note.refusal.stroke = number;
        note.maskQuads = mask->quadCount(number);
    }

    // What the next publish must do.
    bool cutDirty = false;       ///< mask changed since the remesher's last update
    bool sceneDirty = false;     ///< publish needed
    bool fragmentsDirty = false; ///< recompute fragment ids (not during a live stroke)

    // Published pieces kept between publishes.
    uint64_t surfaceSerial = 0;
    std::shared_ptr<const std::vector<uint32_t>> surfaceIds;
    std::shared_ptr<const std::vector<uint32_t>> cutIds;
    std::vector<FragmentSummary> fragments;
};

CutSession::CutSession(vdb::ReadOptions readOptions)
    : mReadOptions(std::move(readOptions)), mState(std::make_unique<State>()),
      mProgress(std::make_unique<Progress>(*this)), mSnapshot(std::make_shared<SceneSnapshot>())
{
    mThread = std::thread([this] { run(); });
}

CutSession::~CutSession()
{
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mStop = true;
        mQueue.clear();
    }
    mCancel = true;
    mWake.notify_all();
    mThread.join();
}

void CutSession::setTaskName(const std::string& name)
{
    std::lock_guard<std::mutex> lock(mMutex);
    mTask = name;
}

std::string CutSession::task() const
{
    std::lock_guard<std::mutex> lock(mMutex);
    return mTask;
}

std::shared_ptr<const SceneSnapshot> CutSession::snapshot() const
{
    std::lock_guard<std::mutex> lock(mMutex);
    return mSnapshot;
}

std::vector<Message> CutSession::takeMessages()
{
    std::lock_guard<std::mutex> lock(mMutex);
    return std::exchange(mMessages, {});
}

void CutSession::message(bool error, const std::string& text)
{
    std::lock_guard<std::mutex> lock(mMutex);
    mMessages.push_back({error, text});
}

void CutSession::cancel() { mCancel = true; }

void CutSession::post(Command command)
{
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mQueue.push_back(std::move(command));
        ++mQueued;
    }
    mWake.notify_one();
}

void CutSession::run()
{
    for (;;) {
        std::deque<Command> batch;
        {
            std::unique_lock<std::mutex> lock(mMutex);
            mWake.wait(lock, [this] { return mStop || !mQueue.empty(); });
            if (mStop) return;
            batch.swap(mQueue);
        }
        mCancel = false;
        for (Command& c : batch) {
            // A pose only grows the mask; everything else sees an up-to-date cut first.
            if (!c.isPose) updateCut();
            try {
                c.work();
            } catch (const Cancelled&) {
                message(true, std::string(c.name) + ": cancelled");
            } catch (const std::exception& e) {
                message(true, e.what());
            }
            {
                std::lock_guard<std::mutex> lock(mMutex);
                mTask.clear();
            }
            mPercent = -1;
        }
        updateCut(true); // after a batch of poses a refusal may wait for the next
        if (mState->sceneDirty) {
            try {
                publish();
            } catch (const std::exception& e) {
                message(true, std::string("update: ") + e.what());
            }
        }
        mDone += batch.size();
    }
}

// -- the cut -----------------------------------------------------------------

void CutSession::updateCut(bool mayDefer)
{
    State& s = *mState;
    if (!s.remesher) return;
    // A live stroke's update refused for where the blade is now is tried
    // again with the next poses (LiveStroke); any other command settles it.
    const bool waiting = s.live && s.stroke && s.stroke->quads() != s.stroke->acceptedQuads();
    if (!s.cutDirty && (mayDefer || !waiting)) return;
    s.cutDirty = false;
    const auto t0 = Clock::now();
    if (s.live && s.stroke && s.stroke->inMask()) {
        const uint32_t given = s.stroke->quads(); // a stop cuts them back
        const cutter::LiveStroke::Result r = mayDefer ? s.stroke->update() : s.stroke->finish();
        const uint32_t stroke = s.stroke->inMask() ? s.mask->strokeCount() : 0; // 0: nothing of it kept
        if (r.outcome == cutter::LiveStroke::Outcome::Stopped) {
            const std::string why = cli::describeRefusal(r.refusal, s.mask->frame(), s.mask->kerf());
            message(true, "cut refused, the stroke stops here: " + why);
            // (A mouse stroke's poses carry no time of their own.)
            if (stroke)
                s.noteRefused(stroke, {stroke, s.stroke->acceptedQuads(), given, std::numeric_limits<double>::quiet_NaN(), why});
        }
        if (r.steppedRound) {
            message(false, "the blade stepped round a refusal below a float step, moving by a hundredth of a voxel "
                           "at most: " + r.refusal);
            if (stroke) s.notes[stroke].steppedRound = true;
        }
        if (r.outcome == cutter::LiveStroke::Outcome::Deferred) mLastUpdate = secondsSince(t0); // it took its time too
        if (r.outcome == cutter::LiveStroke::Outcome::Unchanged ||
            r.outcome == cutter::LiveStroke::Outcome::Deferred)
            return;
    } else {
        s.remesher->update(*s.mask);
    }
    mLastUpdate = secondsSince(t0);
    s.sceneDirty = true;
}

void CutSession::publish()
{
    State& s = *mState;
    s.sceneDirty = false;
    auto snap = std::make_shared<SceneSnapshot>();
    {
        std::lock_guard<std::mutex> lock(mMutex);
        snap->serial = mSnapshot->serial + 1;
    }
    snap->input = s.input;
    snap->isovalue = s.iso;
    snap->kerfMm = s.kerf;
    snap->frame = s.frame;
    if (s.volume) {
        snap->minValue = s.volume->minValue;
        snap->maxValue = s.volume->maxValue;
        snap->units = s.volume->units;
    }
    snap->surface = s.surface;
    if (s.surface && s.remesher) {
        std::shared_ptr<render::CutGeometry> geometry;
        if (s.remesher->cutCellCount() > 0) {
            geometry = std::make_shared<render::CutGeometry>(render::cutGeometryOf(*s.remesher, *s.volume, s.iso));
        }
        if (s.fragmentsDirty && !s.live) {
            s.fragmentsDirty = false;
            std::vector<uint32_t> uncutIds, cutIds;
            if (geometry) {
                std::vector<uint32_t> source;
                const cutter::Mesh fused = s.remesher->fusedMesh(&source);
                render::discardFragmentIds(*s.remesher, fused, source, uncutIds, cutIds);
            } else {
                uncutIds = render::fragmentIdsOf(*s.surface);
            }
            s.fragments.clear();
            accumulateFragments(*s.surface, uncutIds, s.fragments);
            if (geometry) accumulateFragments(geometry->mesh, cutIds, s.fragments);
            s.surfaceIds = std::make_shared<const std::vector<uint32_t>>(std::move(uncutIds));
            s.cutIds = std::make_shared<const std::vector<uint32_t>>(std::move(cutIds));
            ++s.surfaceSerial;
        }
        if (geometry) {
            if (!s.cutIds || s.cutIds->size() != geometry->mesh.triangleCount()) {
                // A live stroke: its fragments are found when it ends.
                s.cutIds = std::make_shared<const std::vector<uint32_t>>(geometry->mesh.triangleCount(), 0u);
                s.fragmentsDirty = true;
            }
            snap->cut = std::move(geometry);
            snap->cutIds = s.cutIds;
            snap->cells = std::make_shared<const render::MaskTiling>(
                render::tileMask(render::remeshedCellGrid(*s.remesher)->tree()));
        }
        snap->surfaceIds = s.surfaceIds;
        snap->fragments = s.fragments;
        snap->cutCells = s.mask->cutCellCount();
        snap->strokes = s.mask->strokeCount();
        snap->lastStrokeQuads = snap->strokes ? s.mask->quadCount(snap->strokes) : 0;
    }
    snap->surfaceSerial = s.surfaceSerial;
    snap->liveStroke = s.live;
    snap->haveBlade = s.live && s.haveBlade;
    snap->blade = s.blade;
    std::lock_guard<std::mutex> lock(mMutex);
    mSnapshot = std::move(snap);
}

// -- commands ------------------------------------------------------------------

namespace {

std::shared_ptr<const cutter::Mesh> extract(const vdb::Volume& volume, float iso, Interrupter* progress)
{
    cutter::IsosurfaceOptions options;
    options.interrupter = progress;
    progress->start("isosurface");
    auto mesh = std::make_shared<const cutter::Mesh>(cutter::extractIsosurface(volume, iso, options));
    progress->end();
    return mesh;
}

std::string isoText(float iso)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", double(iso));
    return buf;
}

} // namespace

void CutSession::resetCut()
{
    State& s = *mState;
    s.mask = std::make_unique<cutter::CutMask>(s.frame, s.kerf);
    s.remesher = std::make_unique<cutter::CutRemesher>(*s.volume, s.iso, *s.surface);
    s.filter = std::make_unique<cutter::PathFilter>(s.frame, s.filterOptions);
    s.live = s.haveBlade = false;
    s.stroke.reset();
    s.cutDirty = false;
    s.cutIds.reset();
    s.pathFile.clear();
    s.notes.clear();
    s.sceneDirty = s.fragmentsDirty = true;
}

void CutSession::recut(float iso, std::shared_ptr<const cutter::Mesh> surface, std::unique_ptr<cutter::CutMask> mask,
                       const std::string& refusal)
{
    State& s = *mState;
    const cutter::CutMask& cutMask = mask ? *mask : *s.mask;
    auto remesher = std::make_unique<cutter::CutRemesher>(*s.volume, iso, *surface);
    try {
        remesher->update(cutMask);
    } catch (const std::runtime_error& e) {
        throw InputError(refusal + ": " + cli::describeRefusal(e.what(), cutMask.frame(), cutMask.kerf()));
    }
    s.iso = iso;
    s.surface = std::move(surface);
    if (mask) s.mask = std::move(mask);
    s.remesher = std::move(remesher);
    s.cutIds.reset();
    s.sceneDirty = s.fragmentsDirty = true;
}

void CutSession::endLiveStroke()
{
    State& s = *mState;
    if (!s.live) return;
    if (s.filter) {
        // The cut reaches the stroke's last pose (PathFilter::finishStroke).
        const std::vector<cutter::Quad> last = s.filter->endStroke();
        if (s.stroke && !s.stroke->stopped()) {
            addLiveQuads(last);
            updateCut(); // while the stroke is live: a refusal cuts it back to its last accepted update
        }
    }
    s.live = s.haveBlade = false;
    s.stroke.reset();
    s.sceneDirty = s.fragmentsDirty = true;
    noteManyQuads();
}

void CutSession::open(const std::string& path, float isovalue)
{
    post({"open", false, [this, path, isovalue] {
              State& s = *mState;
              const auto t0 = Clock::now();
              std::shared_ptr<const vdb::Volume> volume;
              if (path.empty()) {
                  setTaskName("making the phantom");
                  vdb::PhantomOptions options;
                  options.dims = openvdb::Coord(256, 256, 128);
                  volume = std::make_shared<const vdb::Volume>(vdb::makePhantom(options, mProgress.get()));
              } else {
                  setTaskName("reading " + path);
                  volume = std::make_shared<const vdb::Volume>(vdb::readVolume(path, mReadOptions, mProgress.get()));
              }
              float iso = isovalue;
              if (std::isnan(iso)) iso = std::round(vdb::computeStats(*volume).suggestedBoneIso);
              const std::string warning = cutter::isosurfaceWarning(*volume, iso);
              if (!warning.empty()) message(true, "warning: " + warning);
              setTaskName("isosurface");
              std::shared_ptr<const cutter::Mesh> surface = extract(*volume, iso, mProgress.get());
              const std::string name = path.empty() ? std::string("phantom") : path;
              if (surface->empty()) throw InputError(name + ": no surface at iso " + isoText(iso));
              s.volume = std::move(volume);
              s.input = name;
              s.frame = cutter::frameOf(*s.volume);
              s.iso = iso;
              s.surface = std::move(surface);
              resetCut();
              char buf[256];
              std::snprintf(buf, sizeof buf, "opened %s: %d x %d x %d voxels, %zu triangles at iso %s in %.2f s",
                            name.c_str(), s.frame.dims.x, s.frame.dims.y, s.frame.dims.z,
                            s.surface->triangleCount(), isoText(iso).c_str(), secondsSince(t0));
              message(false, buf);
          }});
}

void CutSession::setIsovalue(float isovalue)
{
    post({"iso", false, [this, isovalue] {
              State& s = *mState;
              if (!s.volume) throw InputError("iso: no scan is open");
              endLiveStroke();
              setTaskName("isosurface");
              std::shared_ptr<const cutter::Mesh> surface = extract(*s.volume, isovalue, mProgress.get());
              if (surface->empty()) throw InputError("iso " + isoText(isovalue) + ": no surface (the old one stays)");
              recut(isovalue, std::move(surface), nullptr,
                    "iso " + isoText(isovalue) + ": the cut cannot be re-meshed there (the old surface stays)");
          }});
}

void CutSession::setKerf(double kerfMm)
{
    post({"kerf", false, [this, kerfMm] {
              State& s = *mState;
              if (!(kerfMm >= 0.0 && kerfMm <= cutter::kMaxKerfMm))
                  throw InputError("kerf: expected a width from 0 to " + std::to_string(int(cutter::kMaxKerfMm)) + " mm");
              if (kerfMm == s.kerf) return;
              if (!s.volume) {
                  s.kerf = kerfMm;
                  return;
              }
              endLiveStroke();
              // The same strokes, voxelised and re-meshed at the new width.
              auto mask = std::make_unique<cutter::CutMask>(s.frame, kerfMm);
              for (uint32_t stroke = 1; stroke <= s.mask->strokeCount(); ++stroke) {
                  mask->beginStroke();
                  for (uint32_t q = 0; q < s.mask->quadCount(stroke); ++q) mask->addQuad(s.mask->quad({stroke, q}));
              }
              char what[96];
              std::snprintf(what, sizeof what, "kerf %g mm: the cut cannot be re-meshed at this width (kept the old one)",
                            kerfMm);
              recut(s.iso, s.surface, std::move(mask), what);
              s.kerf = kerfMm;
          }});
}

void CutSession::setRetrace(double voxels)
{
    setFilterTolerance("retrace", &cutter::PathFilterOptions::retraceTolerance, voxels);
}

void CutSession::setSlide(double voxels)
{
    setFilterTolerance("slide", &cutter::PathFilterOptions::slideTolerance, voxels);
}

void CutSession::setFilterTolerance(const char* name, double cutter::PathFilterOptions::*tolerance, double voxels)
{
    post({name, false, [this, name, tolerance, voxels] {
              char text[48];
              std::snprintf(text, sizeof text, "%s %g", name, voxels);
              // The next stroke's filter takes it.
              mState->filterOptions.*tolerance =
                  cli::filterToleranceWith(voxels, text, cutter::PathFilterOptions{}.*tolerance);
          }});
}

void CutSession::beginStroke()
{
    post({"stroke", false, [this] {
              State& s = *mState;
              if (!s.remesher) return;
              endLiveStroke();
              // A filter for the stroke (with the retrace tolerance set now)
              // that knows the cut as it is (after any undo).
              s.filter = std::make_unique<cutter::PathFilter>(s.frame, s.filterOptions);
              cutter::setEarlierQuads(*s.mask, *s.filter);
              s.live = true;
              s.haveBlade = false;
              s.stroke = std::make_unique<cutter::LiveStroke>(*s.mask, *s.remesher);
              s.sceneDirty = true;
          }});
}

void CutSession::addPose(const cutter::Pose& pose)
{
    post({"pose", true, [this, pose] {
              State& s = *mState;
              if (!s.live || !s.remesher) return;
              s.blade = pose;
              s.haveBlade = true;
              s.sceneDirty = true;
              if (s.stroke->stopped()) return;
              std::vector<cutter::Quad> quads;
              s.filter->push(pose, quads);
              addLiveQuads(quads);
          }});
}

void CutSession::addLiveQuads(const std::vector<cutter::Quad>& quads)
{
    State& s = *mState;
    for (const cutter::Quad& q : quads) {
        const bool entering = !s.stroke->inMask();
        if (entering) s.pathFile.clear(); // the cut is no longer just a path file's
        if (!s.stroke->add(q)) continue;
        s.cutDirty = true;
        if (entering) s.strokeEntered(s.mask->strokeCount());
    }
}

void CutSession::endStroke()
{
    post({"stroke end", false, [this] { endLiveStroke(); }});
}

void CutSession::addStrokes(std::vector<std::vector<cutter::Pose>> strokes, std::string pathName)
{
    post({"path", false, [this, strokes = std::move(strokes), pathName] {
              State& s = *mState;
              if (!s.remesher) throw InputError("path " + pathName + ": no scan is open");
              endLiveStroke();
              const auto t0 = Clock::now();
              // As mtcut cut --keep-going: a stroke the re-mesher refuses is
              // cut again as a live stroke, up to where it is refused.
              const uint32_t before = s.mask->strokeCount();
              std::vector<cli::RefusedStroke> refused;
              std::vector<size_t> stepped;
              std::vector<uint32_t> maskStroke; // per stroke of the file: its number in the mask, 0 if none
              const size_t quads = cli::cutStrokeByStroke(*s.remesher, *s.mask, strokes, s.filterOptions, refused, &stepped,
                                                            &maskStroke);
              const size_t added = s.mask->strokeCount() - before;
              if (added) s.strokeEntered(before + 1);
              for (const cli::RefusedStroke& r : refused) {
                  message(true, pathName + ": stroke " + std::to_string(r.stroke) + " refused at quad " +
                                    std::to_string(r.quadsKept + 1) + " of " + std::to_string(r.quads) + ", cut to quad " +
                                    std::to_string(r.quadsKept) + ": " + r.message);
                  if (const uint32_t m = maskStroke[r.stroke - 1]) s.noteRefused(m, r); // numbered as the cut's
              }
              for (const size_t i : stepped) {
                  message(false, pathName + ": stroke " + std::to_string(i) +
                                     " stepped round a refusal below a float step, its blade moved by a hundredth of a "
                                     "voxel at most");
                  if (const uint32_t m = maskStroke[i - 1]) s.notes[m].steppedRound = true;
              }
              if (added) s.pathFile = pathName;
              mLastUpdate = secondsSince(t0);
              s.sceneDirty = s.fragmentsDirty = true;
              char buf[160];
              std::snprintf(buf, sizeof buf, ": %zu stroke(s), %zu quads, %zu cut cells in %.2f s", added, quads,
                            s.mask->cutCellCount(), secondsSince(t0));
              message(false, pathName + buf);
              noteManyQuads();
          }});
}

void CutSession::noteManyQuads()
{
    State& s = *mState;
    if (s.manyQuadsNoted || !s.remesher) return;
    std::vector<openvdb::Coord> withSurface;
    for (const auto& [cell, geometry] : s.remesher->cells())
        if (!geometry.indices.empty()) withSurface.push_back(cell);
    const std::string note = cli::manyQuadsNote(cli::mostQuadsInACell(*s.mask, withSurface),
                                                s.filterOptions.retraceTolerance, "the retrace slider at 1 (--retrace 1)");
    if (note.empty()) return;
    s.manyQuadsNoted = true;
    message(false, "note: " + note);
}

void CutSession::undo()
{
    post({"undo", false, [this] {
              State& s = *mState;
              if (!s.remesher) return;
              endLiveStroke();
              if (!s.mask->undoStroke()) {
                  message(false, "nothing to undo");
                  return;
              }
              s.cutDirty = true;
              s.fragmentsDirty = true;
          }});
}

void CutSession::redo()
{
    post({"redo", false, [this] {
              State& s = *mState;
              if (!s.remesher) return;
              endLiveStroke();
              const uint32_t strokes = s.mask->strokeCount(), quads = s.mask->quadCount(strokes);
              if (!s.mask->redoStroke()) {
                  message(false, "nothing to redo");
                  return;
              }
              try {
                  s.remesher->update(*s.mask);
              } catch (const std::runtime_error& e) {
                  if (s.mask->strokeCount() == strokes) {
                      s.mask->undoToQuad(quads);
                  } else {
                      s.mask->undoStroke();
                  }
                  s.remesher->update(*s.mask);
                  throw InputError("redo refused: " + cli::describeRefusal(e.what(), s.mask->frame(), s.mask->kerf()));
              }
              s.sceneDirty = s.fragmentsDirty = true;
          }});
}

void CutSession::undoToQuad(uint32_t quads)
{
    post({"undo", false, [this, quads] {
              State& s = *mState;
              if (!s.remesher) return;
              endLiveStroke();
              s.mask->undoToQuad(quads);
              s.cutDirty = true;
              s.fragmentsDirty = true;
          }});
}

void CutSession::save(SaveRequest request)
{
    post({"save", false, [this, request = std::move(request)] {
              State& s = *mState;
              if (!s.remesher) throw InputError("save: no scan is open");
              endLiveStroke();
              const auto t0 = Clock::now();
              setTaskName("saving to " + request.outDir);
              cli::CutTimings timings;
              std::vector<uint32_t> source;
              const cutter::Mesh fused = s.remesher->fusedMesh(&source);
              const std::vector<cutter::Fragment> fragments =
                  cutter::fragmentsOf(fused, s.remesher->bladeTriangles(source));
              timings.remesh = secondsSince(t0);
              const auto t1 = Clock::now();
              const cutter::MeshCheck check = cutter::checkMesh(fused);
              timings.check = secondsSince(t1);
              cli::CutOutputRequest r;
              r.outDir = request.outDir;
              r.format = request.format;
              r.input = s.input;
              r.pathFile = s.pathFile;
              r.strokeLabel = "mtcut-view, " + std::to_string(s.mask->strokeCount()) + " stroke(s)";
              r.isovalue = s.iso;
              r.kerfMm = s.kerf;
              r.retraceVoxels = s.filterOptions.retraceTolerance; // as set now
              r.slideVoxels = s.filterOptions.slideTolerance;
              r.selected = request.selected;
              // The strokes of the cut now (after any undo) that were cut
              // only in part, as they still are, or stepped round a refusal.
              for (const auto& [stroke, note] : s.notes) {
                  if (stroke > s.mask->strokeCount()) break;
                  if (note.refused && s.mask->quadCount(stroke) == note.maskQuads) r.refused.push_back(note.refusal);
                  if (note.steppedRound) r.steppedRound.push_back(stroke);
              }
              const std::vector<cli::FragmentRecord> written =
                  cli::writeCutOutputs(r, *s.volume, *s.mask, fragments, check, timings, mProgress.get());
              char buf[160];
              std::snprintf(buf, sizeof buf, "saved %zu of %zu fragment(s) as %s, cut.vdb, slices.exr, summary.json in %.2f s",
                            written.size(), fragments.size(), request.format.c_str(), secondsSince(t0));
              message(false, buf + std::string(" to ") + request.outDir);
              if (const std::string note = cli::touchingStlNote(written, request.format); !note.empty())
                  message(false, "warning: " + note);
              if (!check.ok()) {
                  message(true, "warning: the cut mesh has " + std::to_string(check.defects()) + " defect(s):\n" +
                                    check.report());
              }
          }});
}

} // namespace mtcut::view
