// The viewer's script mode (`mtcut-view INPUT --script FILE`): one action per
// line, so tests and demos drive the real window. No GL here.
//
//   iso V                 isovalue (re-extracts the surface; the cut is kept)
//   view front|side|top|iso|CAMERA   camera as `mtcut render --view`
//   kerf MM               saw width for the cut (re-cuts every stroke at it)
//   retrace VOXELS        the path filter's retrace tolerance for the strokes to come
//   slide VOXELS          the path filter's slide tolerance for the strokes to come
//   path FILE             replays a path file (cutter/PATH_FORMAT.md), one
//                         stroke of the cut per stroke of the file
//   drag X0 Y0 X1 Y1      a mouse stroke from pixel (X0, Y0) to (X1, Y1) (top-left origin),
//                         with the blade of the panel (length, tilt), as the left button does
//   undo | redo           the last stroke (as Ctrl+Z / Ctrl+Shift+Z)
//   pick X Y              selects or unselects the fragment seen at pixel (X, Y), as Ctrl+click
//   screenshot FILE       the 3D view (no panel) as .png or .exr, as `mtcut render` writes it
//   window FILE           the whole window, panel and overlay included, as .png
//   export DIR            fragments, cut.vdb, slices.exr, summary.json (as `mtcut cut -o DIR`)
//   export-selected DIR   the same with the selected fragments only (as "Save selected")
//   wait S                waits S seconds, drawing
//   wait poses            waits until the --poses stream has ended (its `end`
//                         line, or the end of stdin) and its strokes are cut
//   quit                  closes the viewer (exit 0)
//   # ...                 comment; blank lines are skipped
//
// Each action starts when the one before it has finished (the surface and the
// cut are up to date on screen).
#pragma once

#include <string>
#include <vector>

namespace mtcut::view {

struct ScriptAction
{
    enum class Kind { Iso, View, Kerf, Retrace, Slide, Path, Drag, Pick, Undo, Redo, Screenshot, Window, Export, ExportSelected, Wait, WaitPoses, Quit };
    Kind kind = Kind::Quit;
    std::string argument; ///< the rest of the line, trimmed (file names may hold spaces)
    double number = 0.0;  ///< iso, kerf, retrace, slide, wait's seconds
    size_t line = 0;      ///< 1-based line in the script
};

/// Parses a script. Throws InputError "SOURCE:LINE: unknown action 'x' ..."
/// or "SOURCE:LINE: iso: expected a number" on the first bad line, before any
/// action runs.
std::vector<ScriptAction> parseScript(const std::string& text, const std::string& source);

/// parseScript on a file; InputError when it cannot be read.
std::vector<ScriptAction> readScript(const std::string& path);

} // namespace mtcut::view
