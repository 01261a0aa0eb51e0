#include "tools/CutOutputs.h"

#include "cutter/MeshIO.h"
#include "cutter/PathFile.h"
#include "cutter/Remesh.h"
#include "vdb/AtomicFile.h"
#include "vdb/CutOutputs.h"
#include "vdb/SliceExr.h"

#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <future>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

namespace mtcut::cli {

namespace {

namespace fs = std::filesystem;

// -- summary.json, by hand ----------------------------------------------------

std::string jsonString(const std::string& s)
{
    std::string out = "\"";
    for (const char ch : s) {
        const unsigned char c = static_cast<unsigned char>(ch);
        switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\b': out += "\\b"; break;
        case '\f': out += "\\f"; break;
        case '\n': out += "\\n"; break;
        case '\r': out += "\\r"; break;
        case '\t': out += "\\t"; break;
        default:
            if (c < 0x20 || c == 0x7f) {
                char buf[8];
                std::snprintf(buf, sizeof buf, "\\u%04x", unsigned(c));
                out += buf;
            } else {
                out += ch; // UTF-8 bytes pass through
            }
        }
    }
    return out + "\"";
}

/// Round-trip precision; JSON has no NaN/Inf, so those become null.
std::string jsonNumber(double v)
{
    if (!std::isfinite(v)) return "null";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

/// The fragments not written (not selected): how many, their solid volume,
/// and how many of them the blade touched.
struct NotWritten
{
    size_t fragments = 0, withCutFaces = 0;
    double volume = 0.0;
};

std::string summaryJson(const CutOutputRequest& r, size_t cutCells, const std::vector<FragmentRecord>& fragments,
                        const NotWritten& notWritten, double levelSetVoxelMm, const cutter::MeshCheck& c,
                        const CutTimings& t)
{
    const std::string stroke =
        !r.strokeLabel.empty() ? r.strokeLabel : r.pathFile.empty() ? "built-in LeFort I" : "path file";
    std::ostringstream os;
    os << "{\n";
    os << "  \"input\": " << jsonString(r.input) << ",\n";
    os << "  \"isovalue\": " << jsonNumber(double(r.isovalue)) << ",\n";
    os << "  \"kerf_mm\": " << jsonNumber(r.kerfMm) << ",\n";
    os << "  \"retrace_voxels\": " << jsonNumber(r.retraceVoxels) << ",\n";
    os << "  \"slide_voxels\": " << jsonNumber(r.slideVoxels) << ",\n";
    os << "  \"path\": " << (r.pathFile.empty() ? std::string("null") : jsonString(r.pathFile)) << ",\n";
    os << "  \"stroke\": " << jsonString(stroke) << ",\n";
    os << "  \"stroke_file\": " << (r.strokesWithoutFile.empty() ? "null" : "\"stroke.csv\"") << ",\n";
    os << "  \"cut_cells\": " << cutCells << ",\n";
    os << "  \"refused\": [";
    for (size_t i = 0; i < r.refused.size(); ++i) {
        const RefusedStroke& x = r.refused[i];
        os << (i ? ",\n" : "\n") << "    {\"stroke\": " << x.stroke << ", \"quads_kept\": " << x.quadsKept
           << ", \"quads\": " << x.quads << ", \"refused_at_t\": " << jsonNumber(x.time)
           << ", \"message\": " << jsonString(x.message) << "}";
    }
    os << (r.refused.empty() ? "],\n" : "\n  ],\n");
    os << "  \"stepped_round\": [";
    for (size_t i = 0; i < r.steppedRound.size(); ++i) os << (i ? ", " : "") << r.steppedRound[i];
    os << "],\n";
    os << "  \"fragments\": [";
    for (size_t i = 0; i < fragments.size(); ++i) {
        const FragmentRecord& f = fragments[i];
        os << (i ? ",\n" : "\n") << "    {\"file\": " << jsonString(f.file) << ", \"triangles\": " << f.triangles
           << ", \"volume_mm3\": " << jsonNumber(f.volume) << ", \"area_mm2\": " << jsonNumber(f.area)
           << ", \"cavities\": " << f.cavities << ", \"cut_area_mm2\": " << jsonNumber(f.cutArea)
           << ", \"coincident_vertices\": " << f.coincidentVertices << "}";
    }
    os << (fragments.empty() ? "],\n" : "\n  ],\n");
    os << "  \"min_volume_mm3\": " << jsonNumber(r.minVolumeMm3) << ",\n";
    os << "  \"level_set_voxel_mm\": " << jsonNumber(levelSetVoxelMm) << ",\n";
    os << "  \"not_written\": {\"fragments\": " << notWritten.fragments
       << ", \"volume_mm3\": " << jsonNumber(notWritten.volume) << ", \"with_cut_faces\": " << notWritten.withCutFaces
       << "},\n";
    os << "  \"check\": {\"triangles\": " << c.triangles << ", \"vertices\": " << c.vertices
       << ", \"shells\": " << c.shells << ", \"unused_vertices\": " << c.unusedVertices
       << ", \"bad_index_triangles\": " << c.badIndexTriangles << ", \"boundary_edges\": " << c.boundaryEdges
       << ", \"non_manifold_edges\": " << c.nonManifoldEdges << ", \"inconsistent_edges\": " << c.inconsistentEdges
       << ", \"non_manifold_vertices\": " << c.nonManifoldVertices
       << ", \"degenerate_triangles\": " << c.degenerateTriangles
       << ", \"non_finite_triangles\": " << c.nonFiniteTriangles
       << ", \"negative_volume_shells\": " << c.negativeVolumeShells << ", \"cavities\": " << c.cavities
       << ", \"malformed_arrays\": " << c.malformedArrays << ", \"defects\": " << c.defects() << ", \"sites\": [";
    for (size_t i = 0; i < c.sites.size(); ++i) {
        const cutter::DefectSite& site = c.sites[i];
        os << (i ? ",\n" : "\n") << "    {\"kind\": " << jsonString(cutter::DefectSite::name(site.kind))
           << ", \"what\": " << jsonString(site.what) << ", \"position_mm\": ";
        if (site.hasPosition)
            os << "[" << jsonNumber(site.position.x) << ", " << jsonNumber(site.position.y) << ", "
               << jsonNumber(site.position.z) << "]";
        else
            os << "null";
        os << ", \"voxel\": ";
        if (site.hasVoxel) os << "[" << site.voxel.x << ", " << site.voxel.y << ", " << site.voxel.z << "]";
        else os << "null";
        os << "}";
    }
    os << (c.sites.empty() ? "]},\n" : "\n  ]},\n");
    os << "  \"timings_s\": {\"read\": " << jsonNumber(t.read) << ", \"extract\": " << jsonNumber(t.extract)
       << ", \"mask\": " << jsonNumber(t.mask) << ", \"remesh\": " << jsonNumber(t.remesh)
       << ", \"check\": " << jsonNumber(t.check) << ", \"write\": " << jsonNumber(t.write)
       << ", \"write_meshes\": " << jsonNumber(t.writeMeshes) << ", \"write_vdb\": " << jsonNumber(t.writeVdb)
       << ", \"write_slices\": " << jsonNumber(t.writeSlices) << "}\n";
    os << "}\n";
    return os.str();
}

/// Removes fragment_NNN.{stl,obj,ply,off} files of an earlier run that this
/// run did not write, so the folder holds exactly this cut's fragments.
void removeStaleFragments(const std::string& dir, const std::set<std::string>& written)
{
    static const std::regex pattern("fragment_[0-9]{3,}\\.(stl|obj|ply|off)");
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
        const std::string name = e.path().filename().string();
        if (std::regex_match(name, pattern) && !written.count(name)) fs::remove(e.path(), ec);
    }
}

} // namespace

std::string touchingStlNote(const std::vector<FragmentRecord>& records, const std::string& format)
{
    if (format != "stl") return {};
    const FragmentRecord* first = nullptr;
    size_t files = 0, vertices = 0;
    for (const FragmentRecord& r : records) {
        if (r.coincidentVertices == 0) continue;
        if (!first) first = &r;
        ++files;
        vertices += r.coincidentVertices;
    }
    if (!first) return {};
    return first->file +
           (files > 1 ? " and " + std::to_string(files - 1) + " other file(s) touch themselves"
                      : std::string(" touches itself")) +
           " at " + std::to_string(vertices) +
           " vertices (where the two sides of a kerf-0 cut that ends inside a fragment lie on each other, or at a "
           "pinch): STL "
           "keeps no vertex identity, so a reader that welds it by position (most do) sees a non-manifold surface "
           "there; OBJ, PLY and OFF keep the sides apart (summary.json \"coincident_vertices\")";
}

void checkMeshFormat(const std::string& format)
{
    if (format != "stl" && format != "obj" && format != "ply" && format != "off") {
        throw InputError("--format " + format + ": expected stl, obj, ply or off");
    }
}

std::vector<FragmentRecord> writeCutOutputs(const CutOutputRequest& request, const vdb::Volume& volume,
                                            const cutter::CutMask& mask,
                                            const std::vector<cutter::Fragment>& fragments,
                                            const cutter::MeshCheck& check, CutTimings& timings,
                                            Interrupter* interrupter)
{
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    checkMeshFormat(request.format);
    const std::string& outDir = request.outDir;
    if (outDir.empty()) throw InputError("-o: empty output folder name");
    {
        std::error_code ec;
        if (fs::exists(outDir, ec) && !fs::is_directory(outDir, ec)) {
            throw InputError(outDir + ": exists and is not a folder");
        }
    }
    if (!request.selected.empty() && request.selected.size() != fragments.size()) {
        throw std::invalid_argument("writeCutOutputs: one selection flag per fragment");
    }
    auto isSelected = [&](size_t i) { return request.selected.empty() || request.selected[i]; };
    size_t selectedCount = 0;
    for (size_t i = 0; i < fragments.size(); ++i) selectedCount += isSelected(i);
    if (selectedCount == 0) throw InputError("no fragment selected: nothing to save");

    std::error_code ec;
    fs::create_directories(outDir, ec);
    if (ec) throw InputError(outDir + ": cannot create the folder (" + ec.message() + ")");
    std::vector<FragmentRecord> records;
    std::set<std::string> written;
    std::vector<vdb::FragmentMesh> fragmentMeshes;
    NotWritten notWritten;
    for (size_t i = 0; i < fragments.size(); ++i) {
        if (isSelected(i)) continue;
        ++notWritten.fragments;
        notWritten.volume += fragments[i].volume;
        notWritten.withCutFaces += fragments[i].cutArea > 0.0;
    }
    static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "glm::vec3 must be three packed floats");
    std::vector<std::string> names(fragments.size());
    for (size_t i = 0; i < fragments.size(); ++i) {
        if (!isSelected(i)) continue;
        const cutter::Fragment& f = fragments[i];
        char name[64];
        std::snprintf(name, sizeof name, "fragment_%03zu.%s", i, request.format.c_str());
        names[i] = name;
        written.insert(name);
        records.push_back({name, f.mesh.triangleCount(), f.volume, f.area, f.cavities, f.cutArea, 0});
        vdb::FragmentMesh fm;
        fm.worldPositions = f.mesh.positions.empty() ? nullptr : &f.mesh.positions[0].x;
        fm.vertexCount = f.mesh.positions.size();
        fm.triangleIndices = f.mesh.indices.data();
        fm.triangleCount = f.mesh.triangleCount();
        fm.index = i; // its level set is named as its file, also when only some are written
        fragmentMeshes.push_back(fm);
    }
    const auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };

    // Carved volume: voxels whose centre lies in the removed region (the
    // kerf's prisms). With kerf 0 the blade removes nothing.
    const openvdb::MaskGrid::Ptr removed = cutter::removedVoxels(mask);
    vdb::Volume carved = volume;
    carved.grid = vdb::carveVolume(volume, *removed);
    const openvdb::Int32Grid& cutMaskGrid = *mask.grid();
    vdb::CutInfo info;
    info.isovalue = request.isovalue;
    info.kerfMm = float(request.kerfMm);
    info.pathFile = request.pathFile;
    vdb::CutVdbOptions vdbOptions;
    vdbOptions.levelSetVoxelMm = request.levelSetVoxelMm;
    const double levelSetVoxelMm = vdbOptions.voxelMmFor(volume);
    const std::string vdbPath = (fs::path(outDir) / "cut.vdb").string();
    const std::string exrPath = (fs::path(outDir) / "slices.exr").string();
    const std::string jsonPath = (fs::path(outDir) / "summary.json").string();

    // The fragment files, cut.vdb and slices.exr are independent: the files
    // and the slice stack are written on threads of their own while this
    // one makes the level sets (most of the write), so where cores are free
    // the write takes about as long as its longest part. The progress bar
    // follows the level sets; every part stops at its next poll when the
    // user cancels or another part has failed, and the first error that is
    // not such a stop is the one reported.
    std::atomic<bool> failed{false};
    struct Shared : Interrupter
    {
        Interrupter* outer = nullptr;
        const std::atomic<bool>* failed = nullptr;
        bool forwardProgress = false; ///< the level sets': start, end and percentages reach the bar
        void start(const char* name) override
        {
            if (forwardProgress && outer) outer->start(name);
        }
        void end() override
        {
            if (forwardProgress && outer) outer->end();
        }
        bool wasInterrupted(int percent) override
        {
            return failed->load() || (outer && outer->wasInterrupted(forwardProgress ? percent : -1));
        }
    };
    Shared levelSets, sideJobs;
    levelSets.outer = sideJobs.outer = interrupter;
    levelSets.failed = sideJobs.failed = &failed;
    levelSets.forwardProgress = true;
    auto timed = [&](double& seconds, const std::function<void()>& work) {
        const auto t = Clock::now();
        try {
            work();
        } catch (...) {
            failed = true;
            seconds = since(t);
            throw;
        }
        seconds = since(t);
    };
    std::vector<size_t> coincident(fragments.size(), 0);
    std::future<void> meshesDone = std::async(std::launch::async, [&] {
        timed(timings.writeMeshes, [&] {
            for (size_t i = 0; i < fragments.size(); ++i) {
                if (names[i].empty()) continue;
                pollInterrupter(&sideJobs);
                cutter::writeMesh(fragments[i].mesh, (fs::path(outDir) / names[i]).string());
                coincident[i] = cutter::coincidentVertices(fragments[i].mesh);
            }
        });
    });
    std::future<void> slicesDone = std::async(std::launch::async, [&] {
        timed(timings.writeSlices,
              [&] { vdb::writeSliceStack(exrPath, carved, cutMaskGrid, request.isovalue, &sideJobs); });
    });
    std::exception_ptr error, stopped;
    auto keep = [&](std::exception_ptr e) {
        try {
            std::rethrow_exception(e);
        } catch (const Cancelled&) {
            if (!stopped) stopped = e;
        } catch (...) {
            if (!error) error = e;
        }
    };
    try {
        timed(timings.writeVdb, [&] {
            vdb::writeCutVdb(vdbPath, volume, *carved.grid, cutMaskGrid, fragmentMeshes, info, vdbOptions, &levelSets);
        });
    } catch (...) {
        keep(std::current_exception());
    }
    for (std::future<void>* done : {&meshesDone, &slicesDone}) {
        try {
            done->get();
        } catch (...) {
            keep(std::current_exception());
        }
    }
    if (error) std::rethrow_exception(error);
    if (stopped) std::rethrow_exception(stopped);
    for (size_t i = 0, r = 0; i < fragments.size(); ++i)
        if (!names[i].empty()) records[r++].coincidentVertices = coincident[i];
    removeStaleFragments(outDir, written);
    const std::string strokePath = (fs::path(outDir) / "stroke.csv").string();
    if (!request.strokesWithoutFile.empty()) {
        writeFileAtomically(strokePath, [&](const std::string& tmp) {
            std::ofstream out(tmp, std::ios::binary);
            cutter::writePath(out, request.strokesWithoutFile);
            out.close();
            if (!out) throw InputError(strokePath + ": cannot write");
        });
    } else {
        fs::remove(strokePath, ec); // an earlier run's built-in stroke: not this cut's
    }
    timings.write = since(t0);
    const std::string json = summaryJson(request, mask.cutCellCount(), records, notWritten, levelSetVoxelMm, check, timings);
    writeFileAtomically(jsonPath, [&](const std::string& tmp) {
        std::ofstream out(tmp, std::ios::binary);
        out << json;
        out.close();
        if (!out) throw InputError(jsonPath + ": cannot write");
    });
    return records;
}

} // namespace mtcut::cli
