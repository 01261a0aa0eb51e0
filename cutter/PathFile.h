// The blade path text format (documented in cutter/PATH_FORMAT.md):
//
//   # comment lines start with '#'
//   t,x,y,z,dx,dy,dz,length          <- optional column header, ignored
//   0.000,120.5,98.0,1100.0,0,0,-1,30
//
// One pose per line (seconds, world mm LPS); a blank line or a line `stroke`
// starts a new stroke. Used by path files and by the live streams
// (PoseStream.h). GLM + std only.
#pragma once

#include "cutter/BladePath.h"

#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace mtcut::cutter {

/// What one line of the format says.
struct PathLine
{
    enum class Kind
    {
        Pose,        ///< `pose` holds it
        StrokeBreak, ///< blank line or `stroke`
        Skip,        ///< comment or column header
        End,         ///< `end`: the sender is done (streams; in a file, stops reading)
    };
    Kind kind = Kind::Skip;
    Pose pose;
};

/// Parses one line (without its newline; a trailing '\r' is ignored).
/// Throws InputError "SOURCE:LINE: field NAME: ..." on a malformed pose line:
/// not exactly 8 comma-separated fields (a truncated line), a field that is
/// not a number, or not finite (nan, inf), or a position or length beyond
/// kMaxPoseMm. Semantic checks (direction, length, time order) are made by
/// readPath / PathFilter.
PathLine parsePathLine(std::string_view line, size_t lineNumber, const std::string& source);

/// Checks a parsed pose (used by readPath): length > 0, direction non-zero;
/// the direction is normalised in place. Throws InputError naming the field.
void checkPose(Pose& pose, size_t lineNumber, const std::string& source);

/// Reads a whole path: strokes of poses, empty strokes dropped. Every pose is
/// checked (checkPose) and time must not go backwards within a stroke
/// ("field t: time goes backwards"). Throws InputError naming source and line.
std::vector<std::vector<Pose>> readPath(std::istream& in, const std::string& source);
/// readPath on a file; InputError when it cannot be opened.
std::vector<std::vector<Pose>> readPathFile(const std::string& path);

/// Writes strokes in the format (header line, strokes separated by `stroke`),
/// with 17 significant digits so readPath gives the same doubles back.
void writePath(std::ostream& out, const std::vector<std::vector<Pose>>& strokes);
/// One pose as a line of the format (no newline).
std::string formatPoseLine(const Pose& pose);

} // namespace mtcut::cutter
