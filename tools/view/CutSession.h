// The viewer's document and its worker thread: the scan, the isosurface, the
// cut mask with its stroke history and the incremental re-mesher, all owned by
// one geometry thread so the window never waits for them (STYLE 4: long work
// reports progress and can be cancelled). The window queues commands and
// draws the newest SceneSnapshot. No GL here.
#pragma once

#include "cutter/BladePath.h"
#include "cutter/Mesh.h"
#include "render/CutGeometry.h"
#include "render/MaskTiling.h"
#include "tools/CutOutputs.h"
#include "vdb/VolumeIO.h"

namespace mtcut::cutter {
class CutMask;
}

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace mtcut::view {

/// One fragment (shell) of the current cut, in cutter::fragmentsOf order
/// (largest volume first): fragment id = index + 1.
struct FragmentSummary
{
    double volumeMm3 = 0.0;
    double areaMm2 = 0.0;
    size_t triangles = 0;
};

/// Everything the window draws and lists, as the worker last published it.
/// Immutable once published; big arrays are shared between snapshots.
struct SceneSnapshot
{
    uint64_t serial = 0;        ///< grows with every publish
    uint64_t surfaceSerial = 0; ///< changes when the uncut surface or its fragment ids change
    std::string input;          ///< the scan as named ("phantom" for the built-in one); "" before any
    float isovalue = 0.0f;
    float minValue = 0.0f, maxValue = 0.0f; ///< the scan's value range
    std::string units;                      ///< "HU" or ""
    double kerfMm = 0.0;
    cutter::IndexFrame frame;
    /// The uncut isosurface (world mm) and one fragment id per triangle (0
    /// where its cell is re-meshed). Null before the first load.
    std::shared_ptr<const cutter::Mesh> surface;
    std::shared_ptr<const std::vector<uint32_t>> surfaceIds;
    /// The cut cells' geometry and its fragment ids (0 during a live stroke,
    /// until the stroke ends), and the re-meshed cells. Null without a cut.
    std::shared_ptr<const render::CutGeometry> cut;
    std::shared_ptr<const std::vector<uint32_t>> cutIds;
    std::shared_ptr<const render::MaskTiling> cells;
    std::vector<FragmentSummary> fragments;
    size_t cutCells = 0;
    uint32_t strokes = 0;          ///< strokes in the mask
    uint32_t lastStrokeQuads = 0;  ///< quads of the last stroke
    bool canRedo = false;
    bool liveStroke = false;       ///< a mouse / stream stroke is in progress
    /// The blade's last position of the live stroke (world mm), for drawing.
    bool haveBlade = false;
    cutter::Pose blade;
};

struct Message
{
    bool error = false;
    std::string text;
};

/// What to save: CutOutputRequest without the fields the session knows.
struct SaveRequest
{
    std::string outDir;
    std::string format = "stl";
    std::vector<bool> selected; ///< empty: all fragments
};

class CutSession
{
public:
    /// Starts the worker thread. `readOptions` apply to every open().
    explicit CutSession(vdb::ReadOptions readOptions = {});
    /// Cancels running work and joins the worker.
    ~CutSession();
    CutSession(const CutSession&) = delete;
    CutSession& operator=(const CutSession&) = delete;

    // -- commands: queued, run in order on the worker (any thread) ----------
    /// Reads a scan (path "" = the built-in phantom at 256 x 256 x 128) and
    /// extracts its surface at `isovalue` (NaN: the suggested bone isovalue,
    /// as `mtcut info` prints it). On failure the old scene stays and an
    /// error message is posted.
    void open(const std::string& path, float isovalue);
    /// Re-extracts the surface at a new isovalue and re-meshes the cut on it.
    void setIsovalue(float isovalue);
    /// Saw width (mm, >= 0); re-cuts every stroke of the mask at it.
    void setKerf(double kerfMm);
    /// The path filter's retrace tolerance (voxels, 0 to
    /// cutter::kMaxRetraceTolerance) for the strokes to come (live and path
    /// files); the cut so far stays as it is.
    void setRetrace(double voxels);
    /// The path filter's slide tolerance (voxels, 0 to
    /// cutter::kMaxRetraceTolerance: a pose whose blade lies this close to
    /// the line of the last kept one is held back as sliding along itself)
    /// for the strokes to come; the cut so far stays as it is.
    void setSlide(double voxels);
    /// A live stroke: begin, poses (world mm, seconds; filtered by the path
    /// filter, re-meshed as they come), end (then the fragments are updated).
    void beginStroke();
    void addPose(const cutter::Pose& pose);
    void endStroke();
    /// Adds whole strokes (a path file), each a stroke of its own.
    void addStrokes(std::vector<std::vector<cutter::Pose>> strokes, std::string pathName);
    void undo();
    void redo();
    /// Cuts the last stroke back to its first `quads` quads (redo brings them back).
    void undoToQuad(uint32_t quads);
    /// Writes the cut's outputs, as `mtcut cut -o DIR` does.
    void save(SaveRequest request);
    /// Asks the running load / extraction / save to stop (Cancelled).
    void cancel();

    // -- state (any thread) --------------------------------------------------
    std::shared_ptr<const SceneSnapshot> snapshot() const;
    /// True when every command queued so far has finished and been published.
    bool idle() const { return mDone.load() == mQueued.load(); }
    /// The running task ("reading", "isosurface", ...) and its percent (-1: none).
    std::string task() const;
    int percent() const { return mPercent.load(); }
    /// Messages posted since the last call, oldest first.
    std::vector<Message> takeMessages();
    /// Seconds the last cut update took (mask + re-mesh + geometry; also one
    /// a live stroke deferred, refused where the blade was), for the overlay.
    double lastUpdateSeconds() const { return mLastUpdate.load(); }

private:
    struct State;
    class Progress;
    struct Command
    {
        const char* name;
        bool isPose; ///< poses only grow the mask; the re-mesh runs once per batch
        std::function<void()> work;
    };
    void post(Command command);
    /// setRetrace and setSlide: `name` (a string literal) and the option they set.
    void setFilterTolerance(const char* name, double cutter::PathFilterOptions::*tolerance, double voxels);
    void run();
    /// Worker: re-meshes what changed. mayDefer: a live stroke's refused
    /// update waits for its next poses (cutter::LiveStroke); else it is
    /// settled (the stroke stops at its last accepted update).
    void updateCut(bool mayDefer = false);
    void publish();
    void message(bool error, const std::string& text);
    /// Worker: once a session, cli::manyQuadsNote when the cut's cells
    /// with surface gather that many quads (after a stroke or a path file).
    void noteManyQuads();
    void setTaskName(const std::string& name);
    void resetCut();      ///< worker: a new mask (kerf kept) and remesher on the current surface
    void endLiveStroke(); ///< worker: ends the live stroke, if any
    void addLiveQuads(const std::vector<cutter::Quad>& quads); ///< worker: appends quads to the live stroke in the mask
    /// Worker: a new remesher for `surface` at `iso` brought up to `mask`
    /// (null: the current mask) becomes current with them; when the
    /// re-mesher refuses, throws InputError(refusal + ": why") and keeps the old state.
    void recut(float iso, std::shared_ptr<const cutter::Mesh> surface, std::unique_ptr<cutter::CutMask> mask,
               const std::string& refusal);

    vdb::ReadOptions mReadOptions;
    std::unique_ptr<State> mState; // worker thread only
    std::unique_ptr<Progress> mProgress;

    mutable std::mutex mMutex; // guards the members below
    std::condition_variable mWake;
    std::deque<Command> mQueue;
    std::shared_ptr<const SceneSnapshot> mSnapshot;
    std::vector<Message> mMessages;
    std::string mTask;
    bool mStop = false;

    std::atomic<uint64_t> mQueued{0}, mDone{0};
    std::atomic<int> mPercent{-1};
    std::atomic<bool> mCancel{false};
    std::atomic<double> mLastUpdate{0.0};
    std::thread mThread;
};

} // namespace mtcut::view
