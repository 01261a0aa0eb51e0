// mtcut mesh: the Marching Tetrahedra isosurface of a scan, written as a mesh
// file (or one file per shell), optionally validated.
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/MeshIO.h"
#include "tools/Cli.h"

#include <chrono>
#include <cmath>
#include <cstdio>

namespace mtcut::cli {

namespace {

using Clock = std::chrono::steady_clock;

int runMesh(const Args& args)
{
    const float iso = args.isoValue("mesh");
    if (!args.has("output")) throw InputError("mtcut mesh needs -o OUT.{stl,obj,ply,off}");
    const std::string out = args.get("output");
    (void)cutter::meshFormatFromPath(out); // fail before the long work

    const vdb::Volume vol = readInput(args.positional[0], args);
    const auto t0 = Clock::now();
    const cutter::Mesh mesh = extractSurface(vol, iso);
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();

    const std::vector<cutter::Shell> shells = cutter::findShells(mesh);
    double volume = 0.0, area = 0.0;
    for (const cutter::Shell& s : shells) {
        volume += s.volume;
        area += s.area;
    }
    std::printf("isosurface: %zu triangles, %zu vertices, %zu shells at iso %g in %.2f s\n", mesh.triangleCount(),
                mesh.vertexCount(), shells.size(), double(iso), seconds);
    std::printf("volume:     %.1f mm^3, area %.1f mm^2\n", volume, area);

    int status = 0;
    if (args.has("check")) {
        const cutter::MeshCheck check = cutter::checkMesh(mesh);
        std::printf("%s", check.report().c_str());
        if (!check.ok()) status = 1;
    }
    if (args.has("shells")) {
        const std::vector<std::string> paths = cutter::writeShells(mesh, out);
        std::printf("wrote %zu shell files: %s .. %s\n", paths.size(), paths.empty() ? "-" : paths.front().c_str(),
                    paths.empty() ? "-" : paths.back().c_str());
    } else {
        cutter::writeMesh(mesh, out);
        std::printf("wrote %s\n", out.c_str());
    }
    return status;
}

std::vector<std::string> meshOptions()
{
    std::vector<std::string> o = kInputOptions;
    o.push_back("iso");
    o.push_back("output");
    return o;
}

const CommandRegistrar mesh({"mesh", "mesh INPUT --iso V -o OUT.{stl,obj,ply,off} [--shells] [--check]",
                             "Marching Tetrahedra isosurface to a mesh file (--shells: one file per shell; --check: "
                             "validate, exit 1 on any defect)",
                             meshOptions(), {"shells", "check"}, 1, 1, runMesh});

} // namespace

} // namespace mtcut::cli
