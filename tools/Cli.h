// The `mtcut` command line: argument parsing, the command registry, the
// progress bar. Each command lives in its own cmd_*.cpp and registers itself.
#pragma once

#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "cutter/Mesh.h"
#include "cutter/Remesh.h"
#include "vdb/Progress.h"
#include "vdb/VolumeIO.h"

#include <atomic>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <vector>

namespace mtcut::cli {

/// Parsed arguments of one command. Options are "--name value" or "--name=value";
/// flags are "--name" alone. Which is which is declared by the command.
struct Args
{
    std::vector<std::string> positional;
    std::map<std::string, std::string> options;
    std::set<std::string> flags;

    bool has(const std::string& name) const { return options.count(name) || flags.count(name); }
    std::string get(const std::string& name, const std::string& fallback = {}) const;
    double getDouble(const std::string& name, double fallback) const;
    /// --kerf in mm (default 0); InputError outside 0..cutter::kMaxKerfMm.
    double kerfMm() const;
    /// The path filter's options: --retrace VOXELS and --slide VOXELS (the
    /// retrace and slide tolerances, default PathFilterOptions' 0.25 each),
    /// checked by filterToleranceWith.
    cutter::PathFilterOptions pathFilterOptions() const;
    /// --iso, which `command` (mesh, cut, render) needs; InputError when it
    /// is missing or not a finite number.
    float isoValue(const std::string& command) const;
    long long getInt(const std::string& name, long long fallback) const;
};

struct Command
{
    std::string name;
    std::string usage;   ///< one line: "info INPUT [input options]"
    std::string summary; ///< one line: what it does
    std::vector<std::string> valueOptions; ///< names without "--"
    std::vector<std::string> flagOptions;
    size_t minPositional = 0, maxPositional = 0;
    std::function<int(const Args&)> run;
};

/// Registers a command at static-initialisation time (one per cmd_*.cpp).
struct CommandRegistrar
{
    explicit CommandRegistrar(Command command);
};
const std::map<std::string, Command>& commands();

/// Options every command that reads an INPUT accepts.
extern const std::vector<std::string> kInputOptions;
/// Builds ReadOptions from --series, --grid, --air and the raw layout options
/// (--dims --type --endian --spacing --origin --offset).
vdb::ReadOptions readOptions(const Args& args);

/// Reads INPUT with a progress bar; prints nothing else.
vdb::Volume readInput(const std::string& path, const Args& args);

/// Draws "name [#####     ]  42%" on stderr when it is a terminal; Ctrl+C
/// cancels the running operation (which throws Cancelled).
class ProgressBar : public Interrupter
{
public:
    ProgressBar();
    ~ProgressBar() override;
    void start(const char* name = nullptr) override;
    void end() override;
    bool wasInterrupted(int percent = -1) override;

private:
    bool mTty;
    std::string mName;
    std::atomic<int> mLast{-1};
    std::mutex mMutex;
};

/// The re-mesher's refusal ("remesh: ... in cell (i, j, k)", `what`) for a
/// user: the cell's centre in world mm, that nothing broken was written, and
/// with a zero-width blade (`kerf` 0) that a saw width may go through. Other
/// messages are returned as they are.
std::string describeRefusal(const std::string& what, const cutter::IndexFrame& frame, double kerf);

/// "1.23 GiB", "45.6 MiB", ...
std::string humanBytes(double bytes);

/// The isosurface of `vol` at `iso`, with a progress bar (Ctrl+C cancels);
/// first prints isosurfaceWarning() to stderr when there is one.
cutter::Mesh extractSurface(const vdb::Volume& vol, float iso);

/// The strokes of a path file (InputError "FILE:LINE: field ..." when bad, or
/// naming the file when it holds no poses).
std::vector<std::vector<cutter::Pose>> readStrokes(const std::string& pathFile);

/// Adds each stroke's filtered quads to `mask` as a stroke of its own (a stroke
/// that never leaves its first cell, or only retraces the cut so far, adds
/// nothing). One path filter runs over all strokes and knows the cut (the
/// mask's quads, then each stroke's), so a stroke going back into the cut
/// adds nothing there (PathFilter rule 2b, within filterOptions'
/// retraceTolerance). Returns the quads added.
size_t addStrokes(cutter::CutMask& mask, const std::vector<std::vector<cutter::Pose>>& strokes,
                  const cutter::PathFilterOptions& filterOptions);

/// A stroke the re-mesher refused part of (mtcut cut --keep-going): it was
/// cut up to the quad before the refused one, and the rest of it dropped.
struct RefusedStroke
{
    size_t stroke = 0;     ///< 1-based, in the path file's order
    size_t quadsKept = 0;  ///< of its quads (after the path filter), the first ones kept
    size_t quads = 0;      ///< all its quads
    double time = 0.0;     ///< t (s) of the pose that made the refused quad
    std::string message;   ///< the re-mesher's reason, with the cell in world mm
};

using cutter::refusalOf; // the re-mesher's refusal of an update, or ""

/// --keep-going, once the re-mesher refused the whole cut, and the viewer's
/// path files: the strokes cut one after another into `mask` and `remesher`
/// (holding the mask's cut, as a refused update leaves it; a stroke going
/// back into that cut adds nothing there, PathFilter rule 2b). A
/// stroke the re-mesher refuses is cut again quad by quad, as the viewer
/// cuts a live stroke (cutter::LiveStroke: a refusal of where the blade
/// stops at one quad waits for the next), to its last accepted update, and
/// the rest of it dropped; it is listed in `refused` (the first quad
/// dropped, and the refusal of the update that added it). A stroke whose
/// live cut stepped round a refusal (LiveStroke: its blade moved by a
/// hundredth of a voxel at most) is listed (1-based) in `steppedRound`
/// when given. `maskStrokes`, when given, gets per stroke the mask's
/// number of it (1-based; 0: nothing of it kept). The path filter sees only
/// the quads kept (with `filterOptions`). Returns the quads kept. Throws
/// what update() throws other than a refusal (InputError, Cancelled).
size_t cutStrokeByStroke(cutter::CutRemesher& remesher, cutter::CutMask& mask,
                         const std::vector<std::vector<cutter::Pose>>& strokes,
                         const cutter::PathFilterOptions& filterOptions, std::vector<RefusedStroke>& refused,
                         std::vector<size_t>* steppedRound = nullptr, std::vector<uint32_t>* maskStrokes = nullptr);

/// The report lines of a cut made stroke by stroke (--keep-going): one
/// "refused:" line per stroke cut only in part, one "stepped:" line per
/// stroke that stepped round a refusal below a float step; on stdout.
void printStrokeByStroke(const std::vector<RefusedStroke>& refused, const std::vector<size_t>& steppedRound);

/// A tolerance of the path filter in voxels (mtcut --retrace and --slide,
/// the viewer's sliders and script), returned when it is from 0 to
/// cutter::kMaxRetraceTolerance; otherwise InputError "`what`: expected a
/// tolerance from 0 to 4 voxels (default `fallback`)".
double filterToleranceWith(double voxels, const std::string& what, double fallback);

/// Quads crossing one cut cell from which manyQuadsNote speaks.
constexpr size_t kManyQuadsPerCell = 12;
/// The most quads of `mask` that cross one of `cells` (cut cells).
size_t mostQuadsInACell(const cutter::CutMask& mask, const std::vector<openvdb::Coord>& cells);
/// A note for the user when up to `most` quads cross one cut cell
/// (at least kManyQuadsPerCell) and the retrace tolerance is below a voxel:
/// such cells are slow to re-mesh, and a wider tolerance (`how`: the option
/// or control that sets it) keeps a saw worked back and forth from piling
/// quads there. "" otherwise.
std::string manyQuadsNote(size_t most, double retraceVoxels, const std::string& how);

/// describeRefusal, and when the refusal is one a live stroke steps round
/// (below a float step) and --keep-going was not given, how to get past it.
std::string describeRefusalWithHint(const std::string& what, const cutter::IndexFrame& frame, double kerf,
                                    bool keepGoing);

} // namespace mtcut::cli
