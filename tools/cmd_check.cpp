// mtcut check: validates mesh files (ours or any other tool's) with the
// same checkMesh the cut is held to, and says where each defect is.
#include "cutter/MeshCheck.h"
#include "cutter/MeshIO.h"
#include "tools/Cli.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace mtcut::cli {

namespace {

namespace fs = std::filesystem;

/// The files to check: each argument a mesh file, or a folder whose mesh
/// files (by extension) are taken in name order. Everything is looked up
/// before anything is read, so a wrong name fails at once.
std::vector<std::string> meshFiles(const std::vector<std::string>& arguments)
{
    std::vector<std::string> files;
    for (const std::string& a : arguments) {
        std::error_code ec;
        if (fs::is_directory(a, ec)) {
            std::vector<std::string> inFolder;
            for (const fs::directory_entry& e : fs::directory_iterator(a, ec))
                if (e.is_regular_file(ec) && cutter::hasMeshExtension(e.path().string())) inFolder.push_back(e.path().string());
            if (ec) throw InputError(a + ": cannot list the folder: " + ec.message());
            if (inFolder.empty()) throw InputError(a + ": no mesh files (.stl .obj .ply .off) in the folder");
            std::sort(inFolder.begin(), inFolder.end());
            files.insert(files.end(), inFolder.begin(), inFolder.end());
        } else if (!fs::exists(a, ec)) {
            throw InputError(a + ": no such file or folder");
        } else {
            (void)cutter::meshFormatFromPath(a); // names the path when the extension is not a mesh format
            files.push_back(a);
        }
    }
    return files;
}

int runCheck(const Args& args)
{
    const std::vector<std::string> files = meshFiles(args.positional);
    size_t invalid = 0;
    for (const std::string& file : files) {
        const cutter::Mesh mesh = cutter::readMesh(file);
        const cutter::MeshCheck check = cutter::checkMesh(mesh);
        double volume = 0.0, area = 0.0;
        for (const cutter::Shell& s : cutter::findShells(mesh)) {
            volume += s.volume;
            area += s.area;
        }
        std::printf("%s: %zu triangles, %zu shells (%zu cavities), volume %.3f mm^3, area %.3f mm^2: %s\n",
                    file.c_str(), check.triangles, check.shells, check.cavities, volume, area,
                    check.ok() ? "valid" : "INVALID");
        if (!check.ok() || args.has("report")) std::printf("%s", check.report().c_str());
        invalid += !check.ok();
    }
    if (files.size() > 1)
        std::printf("%zu of %zu files valid\n", files.size() - invalid, files.size());
    return invalid ? 1 : 0;
}

const CommandRegistrar check(
    {"check", "check MESH|FOLDER... [--report]",
     "validate mesh files (.stl .obj .ply .off; a folder: every such file in it, e.g. mtcut cut's OUTDIR) with the "
     "checks every cut is held to: closed, manifold, consistently and outward oriented, no degenerate triangles, "
     "cavities nested right; one line per file, and for a file with defects the counts and where the first of "
     "each kind are (world mm); --report: the counts for every file; exit 1 on any defect. STL stores no "
     "connectivity: points at equal positions are read as one, so the two sides of a kerf-0 cut that ends inside "
     "a fragment read back as touching (check OBJ, PLY or OFF there)",
     {}, {"report"}, 1, size_t(-1), runCheck});

} // namespace

} // namespace mtcut::cli
