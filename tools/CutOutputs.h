// The outputs of a cut, as `mtcut cut -o OUTDIR` writes them and the viewer
// saves them: fragment_NNN.{stl,obj,ply,off} (one closed mesh per fragment,
// largest first), cut.vdb (vdb/CutOutputs.h), slices.exr (vdb/SliceExr.h),
// stroke.csv (a built-in stroke's poses) and summary.json (written last). Every file is atomic; nothing is written before
// the caller has the whole cut.
#pragma once

#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "cutter/Fusion.h"
#include "cutter/MeshCheck.h"
#include "tools/Cli.h"
#include "vdb/Progress.h"
#include "vdb/Volume.h"

#include <string>
#include <vector>

namespace mtcut::cli {

/// Seconds per stage, for summary.json's "timings_s" (write and its parts
/// are measured by writeCutOutputs itself).
struct CutTimings
{
    double read = 0, extract = 0, mask = 0, remesh = 0, check = 0, write = 0;
    /// Parts of write, each its own time: the fragment mesh files; cut.vdb
    /// (mostly the fragments' level sets); slices.exr. The three are written
    /// at once (writeCutOutputs), so they overlap; the rest of write is the
    /// carving.
    double writeMeshes = 0, writeVdb = 0, writeSlices = 0;
};

/// One fragment file written.
struct FragmentRecord
{
    std::string file; ///< "fragment_000.stl"
    size_t triangles = 0;
    double volume = 0.0, area = 0.0; ///< mm^3 of solid (cavities taken out), mm^2
    size_t cavities = 0;             ///< cavity shells inside the outer one
    double cutArea = 0.0;            ///< mm^2 of its surface on the blade (0: the cut did not touch it)
    /// Vertices at a position another vertex of the fragment has
    /// (cutter::coincidentVertices): where it touches itself. 0 for a
    /// fragment an STL reader reads back as it is.
    size_t coincidentVertices = 0;
};

/// What to write and what summary.json says about it.
struct CutOutputRequest
{
    std::string outDir;          ///< created when missing; must not be a file
    std::string format = "stl";  ///< stl, obj, ply or off
    std::string input;           ///< the scan, as the user named it
    std::string pathFile;        ///< the blade path file; "" when none
    std::string strokeLabel;     ///< summary's "stroke"; "" = "path file" / "built-in LeFort I"
    float isovalue = 0.0f;
    double kerfMm = 0.0;
    /// The path filter's retrace tolerance the strokes were filtered with
    /// (voxels; mtcut cut --retrace): summary's "retrace_voxels".
    double retraceVoxels = cutter::PathFilterOptions{}.retraceTolerance;
    /// Its slide tolerance (voxels; mtcut cut --slide): summary's "slide_voxels".
    double slideVoxels = cutter::PathFilterOptions{}.slideTolerance;
    /// Which fragments (by index in the fragment list) to write as mesh files
    /// and level sets; empty = all. Files keep their index in the full list
    /// (fragment_003.stl stays fragment 3), so a partial save is unambiguous.
    std::vector<bool> selected;
    /// summary's "min_volume_mm3" (mtcut cut --min-volume: the fragments
    /// below it are the ones not selected); 0 when every one is asked for.
    double minVolumeMm3 = 0.0;
    /// The fragments' level sets' voxel size in cut.vdb, mm (mtcut cut
    /// --level-set-voxel); 0: the scan's smallest spacing. summary's
    /// "level_set_voxel_mm" gives the size used.
    double levelSetVoxelMm = 0.0;
    /// Strokes cut only in part (summary's "refused"; empty: every stroke whole).
    std::vector<RefusedStroke> refused;
    /// Strokes (1-based) whose live cut stepped round a refusal (summary's "stepped_round").
    std::vector<size_t> steppedRound;
    /// The poses cut when no path file holds them (mtcut cut's built-in
    /// stroke): written to stroke.csv in the path file format
    /// (cutter/PATH_FORMAT.md), so the cut can be rendered (`mtcut render
    /// --path`), replayed or edited; summary's "stroke_file" names it. Empty:
    /// no stroke.csv (one an earlier run left is removed) and "stroke_file"
    /// is null.
    std::vector<std::vector<cutter::Pose>> strokesWithoutFile;
};

/// For fragments written as STL that touch themselves (FragmentRecord::
/// coincidentVertices), a sentence that says which and what a reader will
/// make of them; "" when there are none or the format keeps vertices apart.
std::string touchingStlNote(const std::vector<FragmentRecord>& records, const std::string& format);

/// Throws InputError unless `format` is stl, obj, ply or off.
void checkMeshFormat(const std::string& format);

/// Writes the outputs of a cut of `volume` by `mask` into request.outDir:
/// the (selected) fragments' meshes, removing fragment files of an earlier
/// run that this one did not write, cut.vdb (carved volume, mask, one level
/// set per written fragment), slices.exr and summary.json (with `check`, the
/// report of the whole fused mesh, and `timings`, whose write time is set
/// here). Returns the fragment files written. Throws InputError (bad format,
/// an unwritable folder, nothing selected) or Cancelled (interrupter).
/// Cost: the level sets and the slice stack dominate (seconds on a 1 mm head);
/// the fragment files and the slice stack are written on threads of their own
/// while the level sets are made. The interrupter sees the level sets' start,
/// end and percentages, and is polled for cancellation from all three (it
/// must be thread-safe, as Interrupter says).
std::vector<FragmentRecord> writeCutOutputs(const CutOutputRequest& request, const vdb::Volume& volume,
                                            const cutter::CutMask& mask,
                                            const std::vector<cutter::Fragment>& fragments,
                                            const cutter::MeshCheck& check, CutTimings& timings,
                                            Interrupter* interrupter = nullptr);

} // namespace mtcut::cli
