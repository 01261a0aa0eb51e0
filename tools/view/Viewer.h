// mtcut-view: the interactive viewer's window (GLFW, OpenGL 4.5 core, Dear
// ImGui): the scene drawn by render::SurfaceRenderer (discard pass + the CPU
// re-mesher's cut geometry), the blade, the panel and the overlay. The
// document lives in a CutSession on its own thread; the window only draws
// its snapshots and queues commands, so it never waits for a re-mesh.
#pragma once

#include "cutter/BladePath.h"
#include "tools/view/Script.h"
#include "vdb/VolumeIO.h"

#include <limits>
#include <string>
#include <vector>

namespace mtcut::view {

struct ViewerOptions
{
    std::string input;  ///< scan to open; "" = the built-in phantom
    float isovalue = std::numeric_limits<float>::quiet_NaN(); ///< NaN: the suggested bone isovalue
    vdb::ReadOptions readOptions;
    int width = 1280, height = 800; ///< window size, pixels
    /// Script mode: the actions, run one after the other once the one before
    /// has finished; scriptName names the file in messages.
    std::vector<ScriptAction> script;
    std::string scriptName;
    /// Live blade poses in the path format from "stdin" or "udp:PORT"
    /// (cutter/PoseStream.h), read on their own thread; "" = none.
    std::string poseStream;
    /// The path filter's retrace tolerance, voxels (mtcut-view --retrace).
    double retrace = cutter::PathFilterOptions{}.retraceTolerance;
    /// Its slide tolerance, voxels (mtcut-view --slide).
    double slide = cutter::PathFilterOptions{}.slideTolerance;
};

/// Opens the window and runs until the user closes it or a script says
/// `quit`. Returns the exit code (0). Throws std::runtime_error when no
/// window can be made (no display, no GL 4.5).
int runViewer(const ViewerOptions& options);

} // namespace mtcut::view
