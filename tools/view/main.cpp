// mtcut-view: the interactive viewer. See tools/view/Viewer.h and README
// ("The viewer").
#include "tools/Cli.h"
#include "tools/view/Script.h"
#include "tools/view/Viewer.h"
#include "vdb/SliceExr.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <thread>

using namespace mtcut;

namespace {

const char* const kUsage =
    "usage: mtcut-view [INPUT] [--iso V] [--script FILE] [--size WxH] [--poses stdin|udp:PORT] [--retrace VOXELS]\n"
    "                  [--slide VOXELS]\n"
    "                  [input options]\n"
    "  INPUT            a scan (DICOM folder, .nrrd/.nhdr, .nii, .mha, .vdb, raw); none: the built-in phantom\n"
    "  --iso V          isovalue (default: the suggested bone isovalue, as `mtcut info` prints it)\n"
    "  --script FILE    run the actions in FILE, one per line (iso V, view NAME, kerf MM, path FILE,\n"
    "                   undo, redo, screenshot FILE.png|.exr, export DIR, quit); see README\n"
    "  --size WxH       window size in pixels (default 1280x800)\n"
"  --poses SOURCE   drive the blade from a pose stream in the path format (stdin or udp:PORT)\n"
    "  --retrace V      the path filter's retrace tolerance in voxels, 0 to 4 (default 0.25; 1: sawing back\n"
    "                   and forth cuts many times faster, the cut lagging the blade by up to 1 voxel)\n"
    "  --slide V        the path filter's slide tolerance in voxels, 0 to 4 (default 0.25): a pose whose blade\n"
    "                   lies this close to the last kept one's line is held back as sliding along itself\n"
    "  input options    as mtcut's: --series --grid --air --dims --type --endian --spacing --origin --offset\n";

view::ViewerOptions parseArgs(int argc, char** argv, std::string& scriptPath)
{
    cli::Args args;
    std::vector<std::string> valueOptions = cli::kInputOptions;
    for (const char* name : {"iso", "script", "size", "poses", "retrace", "slide"}) valueOptions.push_back(name);
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a.rfind("--", 0) != 0 || a.size() <= 2) {
            args.positional.push_back(a);
            continue;
        }
        std::string name = a.substr(2), value;
        const size_t eq = name.find('=');
        if (eq != std::string::npos) {
            value = name.substr(eq + 1);
            name.resize(eq);
        } else if (i + 1 < argc) {
            value = argv[++i];
        } else {
            throw InputError("option --" + name + " needs a value");
        }
        if (std::find(valueOptions.begin(), valueOptions.end(), name) == valueOptions.end()) {
            throw InputError("unknown option --" + name + "\n" + kUsage);
        }
        args.options[name] = value;
    }
    if (args.positional.size() > 1) throw InputError(std::string("one INPUT at most\n") + kUsage);

    view::ViewerOptions o;
    if (!args.positional.empty()) o.input = args.positional[0];
    o.readOptions = cli::readOptions(args);
    if (args.has("iso")) {
        o.isovalue = float(args.getDouble("iso", 0.0));
        if (!std::isfinite(o.isovalue)) throw InputError("--iso " + args.get("iso") + ": expected a finite number");
    }
    if (args.has("size")) {
        int w = 0, h = 0;
        char tail = 0;
        if (std::sscanf(args.get("size").c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 64 || h < 64 || w > 8192 ||
            h > 8192) {
            throw InputError("--size " + args.get("size") + ": expected WxH, each in [64, 8192]");
        }
        o.width = w;
        o.height = h;
    }
    o.poseStream = args.get("poses");
    const cutter::PathFilterOptions filter = args.pathFilterOptions(); // --retrace, --slide, checked as mtcut's
    o.retrace = filter.retraceTolerance;
    o.slide = filter.slideTolerance;
    scriptPath = args.get("script");
    return o;
}

} // namespace

int main(int argc, char** argv)
{
    if (argc > 1 && (!std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h"))) {
        std::printf("%s", kUsage);
        return 0;
    }
    try {
        openvdb::initialize();
        vdb::setExrThreadCount(std::thread::hardware_concurrency()); // EXR compression on every core
        std::string scriptPath;
        view::ViewerOptions options = parseArgs(argc, argv, scriptPath);
        if (!scriptPath.empty()) {
            options.script = view::readScript(scriptPath); // a bad line stops here, before the window opens
            options.scriptName = scriptPath;
        }
        return view::runViewer(options);
    } catch (const InputError& e) {
        std::fprintf(stderr, "mtcut-view: error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "mtcut-view: error: %s\n", e.what());
        return 1;
    }
}
