// `mtcut cut` end to end: a ball cut straight through by a path file gives two
// closed fragments whose volumes add up to the uncut one, cut.vdb, slices.exr
// and summary.json; a saw of width > 0 removes its slab; a bad path file fails cleanly.
#include "TestStrokes.h"
#include "TestUtil.h"

#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/MeshCheck.h"
#include "cutter/MeshIO.h"
#include "cutter/BladePath.h"
#include "cutter/PathFile.h"
#include "vdb/VolumeIO.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <random>
#include <sstream>

using namespace mtcut;
using mtcut::test::runMtcut;
using mtcut::test::TempDir;
namespace fs = std::filesystem;

namespace {

constexpr double kRadius = 15.0;

/// A dense 40^3 ball at 1 mm: value = radius - distance (mm), iso 0 is the sphere.
std::string writeBall(const TempDir& dir)
{
    vdb::DenseScan scan;
    const openvdb::Coord dims(40);
    scan.geometry.dims = dims;
    scan.geometry.spacing = openvdb::Vec3d(1.0);
    scan.geometry.origin = openvdb::Vec3d(-19.5);
    scan.values.reserve(size_t(dims.x()) * dims.y() * dims.z());
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j)
            for (int i = 0; i < dims.x(); ++i) {
                const openvdb::Vec3d p = scan.geometry.origin + openvdb::Vec3d(i, j, k);
                scan.values.push_back(float(kRadius - p.length()));
            }
    scan.units = "mm";
    vdb::SparseOptions sparse;
    sparse.airThreshold = -25.0f; // nothing pruned
    const vdb::Volume vol = vdb::makeVolume(std::move(scan), "ball", sparse);
    const std::string path = dir.file("ball.vdb");
    vdb::writeVolume(vol, path);
    return path;
}

/// A path file (cutter/PATH_FORMAT.md): one stroke along x at y = 0.37, the
/// blade pointing down (-z) from above the ball to below it: cuts it in two.
std::string writeStraightPath(const TempDir& dir)
{
    const std::string path = dir.file("cut.csv");
    std::ofstream out(path);
    out << "# straight cut through the ball\n";
    out << "t,x,y,z,dx,dy,dz,length\n";
    const int steps = 200;
    for (int i = 0; i <= steps; ++i) {
        const double x = -25.0 + 50.0 * double(i) / steps;
        out << 0.001 * i << "," << x << ",0.37,22,0,0,-1,45\n";
    }
    return path;
}

/// A level stroke along x at z = 14.97 mm, its 45 mm blade along +y from
/// y = -22: it slices the ball's cap above that height off, a crumb of
/// about 0.019 mm^3.
std::string writeCapPath(const TempDir& dir)
{
    const std::string path = dir.file("cap.csv");
    std::ofstream f(path);
    for (int i = 0; i <= 200; ++i) f << 0.001 * i << "," << -25.0 + 50.0 * i / 200 << ",-22,14.97,0,1,0,45\n";
    return path;
}

std::string readText(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    std::ostringstream os;
    os << in.rdbuf();
    return os.str();
}

/// The number after `"key": ` in a JSON text; NaN when absent.
double jsonValue(const std::string& json, const std::string& key)
{
    const size_t at = json.find("\"" + key + "\": ");
    if (at == std::string::npos) return std::nan("");
    return std::strtod(json.c_str() + at + key.size() + 4, nullptr);
}

size_t countOf(const std::string& text, const std::string& what)
{
    size_t n = 0;
    for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + what.size())) ++n;
    return n;
}

std::vector<std::string> filesIn(const std::string& dir)
{
    std::vector<std::string> names;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

} // namespace

TEST(CutCli, StraightCutThroughABallGivesTwoClosedFragmentsAndAllOutputs)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = writeStraightPath(dir);
    const std::string out = dir.file("out");

    const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out + " --check");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    std::printf("%s", r.output.c_str());

    // Exactly two fragment files, each closed and valid.
    std::vector<std::string> fragments;
    for (const std::string& name : filesIn(out)) {
        if (name.rfind("fragment_", 0) == 0) fragments.push_back(name);
    }
    ASSERT_EQ(fragments, (std::vector<std::string>{"fragment_000.stl", "fragment_001.stl"}));
    double sum = 0.0;
    for (const std::string& name : fragments) {
        const cutter::Mesh m = cutter::readMesh(out + "/" + name);
        const cutter::MeshCheck check = cutter::checkMesh(m);
        EXPECT_TRUE(check.ok()) << name << "\n" << check.report();
        EXPECT_EQ(check.shells, 1u) << name;
        sum += cutter::meshVolume(m);
    }
    // The uncut isosurface of the same ball.
    const vdb::Volume vol = vdb::readVolume(ball);
    const double uncut = cutter::meshVolume(cutter::extractIsosurface(vol, 0.0f));
    EXPECT_NEAR(sum, uncut, 1e-3 * uncut);
    const double largest = cutter::meshVolume(cutter::readMesh(out + "/fragment_000.stl"));
    EXPECT_GE(largest, 0.5 * uncut); // largest first

    // summary.json
    const std::string json = readText(out + "/summary.json");
    EXPECT_NE(json.find("\"cut_cells\": "), std::string::npos) << json;
    EXPECT_EQ(json.find("\"cut_cells\": 0,"), std::string::npos) << json;
    EXPECT_EQ(countOf(json, "\"file\": "), 2u) << json;
    EXPECT_NE(json.find("\"fragment_000.stl\""), std::string::npos) << json;
    EXPECT_NE(json.find("\"fragment_001.stl\""), std::string::npos) << json;
    EXPECT_NE(json.find("\"defects\": 0, \"sites\": []}"), std::string::npos) << json;
    for (const char* key : {"\"input\"", "\"isovalue\"", "\"kerf_mm\"", "\"path\"", "\"timings_s\"", "\"read\"",
                            "\"extract\"", "\"mask\"", "\"remesh\"", "\"write\"", "\"write_meshes\"",
                            "\"write_vdb\"", "\"write_slices\"", "\"volume_mm3\"", "\"area_mm2\""}) {
        EXPECT_NE(json.find(key), std::string::npos) << key << "\n" << json;
    }
    // Each fragment's cut faces: the blade's section of the solid, the same
    // caps on both sides (kerf 0), about pi (R^2 - y^2) (the MT surface lies
    // a little inside the sphere).
    {
        const size_t second = json.find("\"fragment_001.stl\"");
        ASSERT_NE(second, std::string::npos) << json;
        const double a0 = jsonValue(json.substr(0, second), "cut_area_mm2");
        const double a1 = jsonValue(json.substr(second), "cut_area_mm2");
        const double section = M_PI * (kRadius * kRadius - 0.37 * 0.37);
        EXPECT_NEAR(a0, a1, 1e-6 * section) << json;
        EXPECT_NEAR(a0, section, 0.01 * section) << json;
        EXPECT_LT(a0, section) << json;
        EXPECT_NE(r.output.find("cut faces:  "), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(" on 2 fragment(s)\n"), std::string::npos) << r.output;
    }
    // The parts of the write (written at once) each take no longer than the write.
    {
        const double write = jsonValue(json, "write"), meshes = jsonValue(json, "write_meshes"),
                     vdbFile = jsonValue(json, "write_vdb"), slices = jsonValue(json, "write_slices");
        EXPECT_GT(meshes, 0.0) << json;
        EXPECT_GT(vdbFile, 0.0) << json;
        EXPECT_GT(slices, 0.0) << json;
        EXPECT_LE(std::max({meshes, vdbFile, slices}), write) << json;
    }

    // cut.vdb: carved, cut_mask, fragment_000, fragment_001.
    {
        openvdb::io::File file(out + "/cut.vdb");
        file.open();
        std::set<std::string> names;
        for (auto it = file.beginName(); it != file.endName(); ++it) names.insert(it.gridName());
        EXPECT_EQ(names, (std::set<std::string>{"carved", "cut_mask", "fragment_000", "fragment_001"}));
        const auto mask = openvdb::gridPtrCast<openvdb::Int32Grid>(file.readGrid("cut_mask"));
        ASSERT_TRUE(mask);
        EXPECT_GT(mask->activeVoxelCount(), 0u);
        const auto carved = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("carved"));
        ASSERT_TRUE(carved);
        // Kerf 0 removes nothing: the carved volume keeps every input value.
        EXPECT_EQ(carved->activeVoxelCount(), vol.grid->activeVoxelCount());
        const auto f0 = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("fragment_000"));
        ASSERT_TRUE(f0);
        EXPECT_EQ(f0->getGridClass(), openvdb::GRID_LEVEL_SET);
        file.close();
    }
    EXPECT_TRUE(fs::is_regular_file(out + "/slices.exr"));
    EXPECT_GT(fs::file_size(out + "/slices.exr"), 0u);
    // No temporaries left behind.
    for (const std::string& name : filesIn(out)) {
        EXPECT_TRUE(name == "cut.vdb" || name == "slices.exr" || name == "summary.json" ||
                    name.rfind("fragment_", 0) == 0)
            << name;
    }

    // --format obj writes .obj fragments; a rerun replaces the earlier .stl ones.
    const test::RunResult r2 = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out + " --format obj");
    ASSERT_EQ(r2.exitCode, 0) << r2.output;
    std::vector<std::string> objs;
    for (const std::string& name : filesIn(out)) {
        if (name.rfind("fragment_", 0) == 0) objs.push_back(name);
    }
    EXPECT_EQ(objs, (std::vector<std::string>{"fragment_000.obj", "fragment_001.obj"}));
}

// A 1 mm saw through the ball: two clean fragments whose volumes add up to
// the ball minus the slab (pi (R^2 y - y^3/3) over |y - 0.37| <= 0.5) within
// one tet per cut cell, and the carved grid has the slab's voxels removed.
TEST(CutCli, KerfCutThroughABallRemovesTheSlab)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = writeStraightPath(dir);
    const std::string out = dir.file("out");
    const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + " --kerf 1 -o " + out + " --check");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    double sum = 0.0;
    size_t count = 0;
    for (const std::string& name : filesIn(out)) {
        if (name.rfind("fragment_", 0) != 0) continue;
        const cutter::Mesh m = cutter::readMesh(out + "/" + name);
        EXPECT_TRUE(cutter::checkMesh(m).ok()) << name;
        sum += cutter::meshVolume(m);
        ++count;
    }
    EXPECT_EQ(count, 2u) << r.output;
    const vdb::Volume vol = vdb::readVolume(ball);
    const double uncut = cutter::meshVolume(cutter::extractIsosurface(vol, 0.0f));
    auto F = [](double y) { return M_PI * (kRadius * kRadius * y - y * y * y / 3.0); };
    const double slab = F(0.37 + 0.5) - F(0.37 - 0.5);
    const std::string json = readText(out + "/summary.json");
    EXPECT_NE(json.find("\"kerf_mm\": 1,"), std::string::npos) << json;
    const size_t at = json.find("\"cut_cells\": ");
    ASSERT_NE(at, std::string::npos);
    const double cells = std::stod(json.substr(at + 13));
    EXPECT_NEAR(uncut - sum, slab, cells / 6.0 + std::abs(uncut - 4.0 / 3.0 * M_PI * std::pow(kRadius, 3)));
    // Carved: the voxels of the plane y = 0.5 (j = 20) inside the ball are gone.
    openvdb::io::File file(out + "/cut.vdb");
    file.open();
    auto carved = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("carved"));
    file.close();
    ASSERT_TRUE(carved);
    const float bg = carved->background();
    EXPECT_EQ(carved->tree().getValue(openvdb::Coord(20, 20, 20)), bg);
    EXPECT_EQ(carved->tree().getValue(openvdb::Coord(20, 22, 20)), vol.grid->tree().getValue(openvdb::Coord(20, 22, 20)));
}

// A blade that passes beside the ball cuts cells but no solid: the outputs
// are the uncut ball (one fragment, clean), and the user is told nothing was
// cut instead of being left to find out from the files.
// A second stroke over the first (a saw put back into its cut: exactly, as a
// script would, and a second pass with 0.05 mm of tremor) adds nothing: the
// fragments are byte for byte those of the single stroke. Before, the exact
// repeat was refused (coplanar overlapping quads, kerf 0), and the tremulous
// one cut a layer of bone crumbs between the two passes.
TEST(CutCli, StrokeGoingBackIntoTheCutAddsNothing)
{
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string once = writeStraightPath(dir);
    const std::string twice = dir.file("twice.csv"), shaky = dir.file("shaky.csv");
    {
        const std::string stroke = readText(once);
        std::ofstream(twice) << stroke << "\n" << stroke;
        std::ofstream out(shaky);
        out << stroke << "\nstroke\n";
        std::mt19937_64 rng(7);
        std::uniform_real_distribution<double> j(-0.05, 0.05);
        for (int i = 0; i <= 200; ++i)
            out << 0.001 * i << "," << -25.0 + 50.0 * i / 200 + j(rng) << "," << 0.37 + j(rng) << "," << 22 + j(rng)
                << "," << j(rng) / 45 << "," << j(rng) / 45 << ",-1,45\n"; // the tip within 0.05 mm too
    }
    for (const double kerf : {0.0, 0.5}) {
        const std::string k = " --kerf " + std::to_string(kerf);
        const auto a = runMtcut("cut " + ball + " --iso 0 --path " + once + k + " -o " + dir.file("a") + " --check");
        ASSERT_EQ(a.exitCode, 0) << a.output;
        for (const std::string& path : {twice, shaky}) {
            const auto b = runMtcut("cut " + ball + " --iso 0 --path " + path + k + " -o " + dir.file("b") + " --check");
            ASSERT_EQ(b.exitCode, 0) << path << k << ": " << b.output;
            EXPECT_EQ(filesIn(dir.file("b")), filesIn(dir.file("a"))) << path << k;
            for (const char* f : {"fragment_000.stl", "fragment_001.stl"})
                EXPECT_EQ(readText(dir.file("b") + "/" + f), readText(dir.file("a") + "/" + f)) << path << k << " " << f;
            fs::remove_all(dir.file("b"));
        }
        fs::remove_all(dir.file("a"));
    }
}

// Deepening a cut along a scripted path: the straight stroke with a 20 mm
// blade (its tip 2 mm above the ball's centre: the ball stays whole), then
// the same poses with the 45 mm blade. With a 0.5 mm saw that is what the 45
// mm stroke alone cuts: two clean fragments with its volumes (the second
// pass's prisms contain the first's; the triangles may differ where the two
// coincide). With kerf 0 the second pass's quads lie in the first's plane
// over its whole length: refused ("coplanar overlapping quads"), nothing
// written (README, "Cutting").
TEST(CutCli, DeepeningAScriptedCutWithAKerfCutsWhatTheDeeperStrokeCuts)
{
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string deep = readText(writeStraightPath(dir));
    std::string shallow = deep;
    for (size_t at = 0; (at = shallow.find(",-1,45\n", at)) != std::string::npos; at += 7) shallow.replace(at, 7, ",-1,20\n");
    ASSERT_EQ(countOf(shallow, ",-1,20\n"), 201u);
    const std::string deepOnly = dir.file("deep.csv"), deepened = dir.file("deepened.csv"),
                      shallowOnly = dir.file("shallow.csv");
    std::ofstream(deepOnly) << deep;
    std::ofstream(shallowOnly) << shallow;
    std::ofstream(deepened) << shallow << "\nstroke\n" << deep;
    const auto s = runMtcut("cut " + ball + " --iso 0 --path " + shallowOnly + " --kerf 0.5 -o " + dir.file("s") + " --check");
    ASSERT_EQ(s.exitCode, 0) << s.output;
    EXPECT_FALSE(fs::exists(dir.file("s") + "/fragment_001.stl")) << "the 20 mm blade leaves the ball whole";
    const auto a = runMtcut("cut " + ball + " --iso 0 --path " + deepOnly + " --kerf 0.5 -o " + dir.file("a") + " --check");
    ASSERT_EQ(a.exitCode, 0) << a.output;
    const auto b = runMtcut("cut " + ball + " --iso 0 --path " + deepened + " --kerf 0.5 -o " + dir.file("b") + " --check");
    ASSERT_EQ(b.exitCode, 0) << b.output;
    EXPECT_EQ(filesIn(dir.file("b")), filesIn(dir.file("a")));
    EXPECT_TRUE(fs::exists(dir.file("b") + "/fragment_001.stl"));
    EXPECT_FALSE(fs::exists(dir.file("b") + "/fragment_002.stl"));
    const std::string ja = readText(dir.file("a") + "/summary.json"), jb = readText(dir.file("b") + "/summary.json");
    const double va = jsonValue(ja, "volume_mm3"), vb = jsonValue(jb, "volume_mm3");
    EXPECT_NEAR(vb, va, 1e-6 * va) << "the largest fragment's volume";

    const auto z = runMtcut("cut " + ball + " --iso 0 --path " + deepened + " -o " + dir.file("z"));
    EXPECT_EQ(z.exitCode, 1) << z.output;
    EXPECT_EQ(z.output.rfind("mtcut: error: remesh: coplanar overlapping quads in cell (", 0), 0u) << z.output;
    EXPECT_TRUE(filesIn(dir.file("z")).empty());
}

// Two strokes meeting in the middle of the ball, the second coming from the
// other side, cut it in two as the single stroke does. A script's exact meet
// (both end on the stick x = 0.1) and a hand's (0.05 mm of tremor, ending
// 0.6 mm inside the first cut), with a 0.5 mm saw. Before, the filter left
// bone between them and the ball came out whole: rule 2 dropped each
// stroke's last poses (up to a cell short of where the blade stopped), and
// rule 2b dropped the second stroke's step into the first cut. With kerf 0
// the exact meet is refused (two coplanar quads end to end: never silent); a
// hand's meet with a zero-width blade leaves a sheet of bone between two
// parallel cuts micrometres apart, which is what such a blade does.
TEST(CutCli, TwoStrokesMeetingInTheMiddleSeparateTheBall)
{
    TempDir dir;
    const std::string ball = writeBall(dir);
    auto stroke = [](std::ostream& out, double x0, double x1, int n, double jitter, uint64_t seed) {
        std::mt19937_64 rng(seed);
        std::uniform_real_distribution<double> j(-jitter, jitter);
        for (int i = 0; i <= n; ++i)
            out << 0.001 * i << "," << x0 + (x1 - x0) * i / n + j(rng) << "," << 0.37 + j(rng) << "," << 22 + j(rng)
                << "," << j(rng) / 45 << "," << j(rng) / 45 << ",-1,45\n";
    };
    auto fragments = [&](const std::string& out) {
        size_t n = 0;
        while (fs::exists(out + "/fragment_00" + std::to_string(n) + ".stl")) ++n;
        return n;
    };
    const std::string single = writeStraightPath(dir);
    const auto a = runMtcut("cut " + ball + " --iso 0 --path " + single + " --kerf 0.5 -o " + dir.file("a") + " --check");
    ASSERT_EQ(a.exitCode, 0) << a.output;
    ASSERT_EQ(fragments(dir.file("a")), 2u);
    const double whole = jsonValue(readText(dir.file("a") + "/summary.json"), "volume_mm3");
    for (uint64_t seed = 0; seed < 4; ++seed) {
        const std::string path = dir.file("meet.csv");
        {
            std::ofstream out(path);
            stroke(out, -25.0, 0.1, 100, 0.0, 0);
            out << "stroke\n";
            if (seed == 0) stroke(out, 25.0, 0.1, 100, 0.0, 0);
            else stroke(out, 25.0, -0.5, 102, 0.05, seed);
        }
        const std::string out = dir.file("b");
        const auto b = runMtcut("cut " + ball + " --iso 0 --path " + path + " --kerf 0.5 -o " + out + " --check");
        ASSERT_EQ(b.exitCode, 0) << seed << ": " << b.output;
        EXPECT_EQ(fragments(out), 2u) << (seed ? "a hand's meet, seed " + std::to_string(seed) : "the exact meet");
        // The largest fragment is the single stroke's, within the tremor's reach (0.05 mm x 30 mm x 30 mm).
        EXPECT_NEAR(jsonValue(readText(out + "/summary.json"), "volume_mm3"), whole, seed ? 50.0 : 0.5) << seed;
        if (seed == 0) {
            const auto z = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + dir.file("z"));
            EXPECT_EQ(z.exitCode, 1) << z.output;
            EXPECT_NE(z.output.find("the re-mesher refuses"), std::string::npos) << z.output;
            EXPECT_TRUE(filesIn(dir.file("z")).empty());
        }
        fs::remove_all(out);
    }
}

// A blade that just grazes the ball's top (a horizontal cut 0.03 mm below the
// highest grid-edge crossing at z = 14.98) cuts off a closed crumb of about
// 0.019 mm^3. The fragment list prints it with two significant digits (one
// decimal would print 0.0), summary.json has the full value, and --check
// finds it closed.
TEST(CutCli, CrumbIsListedWithTwoSignificantDigits)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = writeCapPath(dir);
    const std::string out = dir.file("out");
    const auto r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out + " --check");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(filesIn(out), (std::vector<std::string>{"cut.vdb", "fragment_000.stl", "fragment_001.stl", "slices.exr",
                                                      "summary.json"}));
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.output, m, std::regex(R"(fragment_001\.stl +([0-9.e+-]+) mm\^3 +([0-9.e+-]+) mm\^2)")))
        << r.output;
    const std::string printed = m[1];
    EXPECT_EQ(printed, "0.019") << r.output;
    const std::string json = readText(out + "/summary.json");
    const size_t at = json.find("\"fragment_001.stl\"");
    ASSERT_NE(at, std::string::npos) << json;
    const double volume = jsonValue(json.substr(at), "volume_mm3");
    EXPECT_GT(volume, 0.0185) << json;
    EXPECT_LT(volume, 0.0195) << json;
    EXPECT_NEAR(std::stod(printed), volume, 0.0005);
}

// --min-volume: the same crumb (0.019 mm^3) gets no file and no level set;
// the report and summary.json count it; a threshold above every fragment,
// or not a volume, fails at once and writes nothing.
TEST(CutCli, MinVolumeLeavesOutTheCrumbAndCountsIt)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = writeCapPath(dir);
    const std::string out = dir.file("out");
    const auto r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out + " --check --min-volume 0.1");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(filesIn(out), (std::vector<std::string>{"cut.vdb", "fragment_000.stl", "slices.exr", "summary.json"}));
    EXPECT_NE(r.output.find("left out:   1 fragment(s) under 0.1 mm^3 (--min-volume),      0.019 mm^3 in all, 1 with "
                            "cut faces"),
              std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("fragment_000..000.stl"), std::string::npos) << r.output;
    const std::string json = readText(out + "/summary.json");
    EXPECT_EQ(jsonValue(json, "min_volume_mm3"), 0.1) << json;
    const size_t at = json.find("\"not_written\"");
    ASSERT_NE(at, std::string::npos) << json;
    EXPECT_EQ(jsonValue(json.substr(at), "fragments"), 1.0) << json;
    EXPECT_NEAR(jsonValue(json.substr(at), "volume_mm3"), 0.019, 0.0005) << json;
    EXPECT_EQ(jsonValue(json.substr(at), "with_cut_faces"), 1.0) << json;
    EXPECT_EQ(countOf(json, "\"file\""), 1u) << json;
    openvdb::io::File vdbFile(out + "/cut.vdb");
    vdbFile.open();
    std::vector<std::string> grids;
    for (auto it = vdbFile.beginName(); it != vdbFile.endName(); ++it) grids.push_back(it.gridName());
    vdbFile.close();
    EXPECT_EQ(grids, (std::vector<std::string>{"carved", "cut_mask", "fragment_000"}));

    // Without it, the default: both written, none counted out.
    const auto all = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + dir.file("all"));
    ASSERT_EQ(all.exitCode, 0) << all.output;
    EXPECT_EQ(all.output.find("left out"), std::string::npos) << all.output;
    const std::string allJson = readText(dir.file("all/summary.json"));
    EXPECT_EQ(jsonValue(allJson, "min_volume_mm3"), 0.0);
    EXPECT_EQ(jsonValue(allJson.substr(allJson.find("\"not_written\"")), "fragments"), 0.0) << allJson;

    const std::string none = dir.file("none");
    const auto big = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + none + " --min-volume 1e6");
    EXPECT_EQ(big.exitCode, 1) << big.output;
    EXPECT_NE(big.output.find("mtcut: error: --min-volume 1e6: every fragment is smaller (the largest is 1.41e+04 mm^3): "
                              "nothing to write"),
              std::string::npos)
        << big.output;
    EXPECT_TRUE(filesIn(none).empty());
    for (const char* bad : {"-1", "nan", "inf", "abc"}) {
        const auto b = runMtcut("cut " + ball + " --iso 0 -o " + none + " --min-volume " + bad);
        EXPECT_EQ(b.exitCode, 1) << b.output;
        EXPECT_NE(b.output.find(std::string("--min-volume ") + bad + ": expected"), std::string::npos) << b.output;
        EXPECT_TRUE(filesIn(none).empty());
    }
}

TEST(CutCli, BladeMissingTheSolidIsReportedAsNoCut)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    // A 20 mm stroke along x at height y, the blade 20 mm down from z = 10.
    auto writeLine = [&](const std::string& name, double y) {
        const std::string file = dir.file(name);
        std::ofstream f(file);
        f << "t,x,y,z,dx,dy,dz,length\n";
        for (int i = 0; i <= 100; ++i) f << 0.001 * i << "," << -10.0 + 0.2 * i << "," << y << ",10,0,0,-1,20\n";
        return file;
    };
    const std::string path = writeLine("beside.csv", 17.3);
    const std::string out = dir.file("out");
    const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out + " --check");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("mtcut: warning: the blade meets no solid at iso 0"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("(0 meet the solid)"), std::string::npos) << r.output;
    EXPECT_EQ(countOf(r.output, "fragment_"), 2u) << r.output; // the list line and the "wrote:" line
    EXPECT_TRUE(fs::exists(out + "/fragment_000.stl"));
    EXPECT_FALSE(fs::exists(out + "/fragment_001.stl"));

    // The same blade moved into the ball meets it: no warning.
    const std::string inside = writeLine("inside.csv", 7.3);
    const test::RunResult r2 =
        runMtcut("cut " + ball + " --iso 0 --path " + inside + " -o " + dir.file("out2") + " --format obj");
    ASSERT_EQ(r2.exitCode, 0) << r2.output;
    EXPECT_EQ(r2.output.find("warning"), std::string::npos) << r2.output;
}

// A zero-width cut that ends inside the ball leaves one fragment whose two
// sides of the slit lie on each other, vertices of their own at the same
// positions: OBJ (PLY, OFF) keeps them apart and reads back clean; STL has
// positions only, so a reader that welds it (OpenMesh's, as `mtcut check`
// reads it) makes the slit non-manifold. That is said when it is written,
// and summary.json counts the vertices; a saw of some width has none.
TEST(CutCli, AKerf0CutEndingInsideTouchesItselfWhichStlCannotKeep)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = dir.file("inside.csv");
    {
        std::ofstream f(path);
        f << "t,x,y,z,dx,dy,dz,length\n";
        for (int i = 0; i <= 100; ++i) f << 0.001 * i << "," << -10.0 + 0.2 * i << ",7.3,10,0,0,-1,20\n";
    }
    const std::string obj = dir.file("obj"), stl = dir.file("stl"), kerf = dir.file("kerf");
    const test::RunResult o = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + obj + " --format obj --check");
    ASSERT_EQ(o.exitCode, 0) << o.output;
    EXPECT_EQ(o.output.find("warning"), std::string::npos) << o.output;
    const double touching = jsonValue(readText(obj + "/summary.json"), "coincident_vertices");
    EXPECT_GT(touching, 0.0);
    const test::RunResult oc = runMtcut("check " + obj);
    EXPECT_EQ(oc.exitCode, 0) << oc.output;
    EXPECT_NE(oc.output.find("fragment_000.obj: "), std::string::npos) << oc.output;

    const test::RunResult s = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + stl + " --check");
    ASSERT_EQ(s.exitCode, 0) << s.output; // the mesh cut is clean
    char expected[96];
    std::snprintf(expected, sizeof expected, "mtcut: warning: fragment_000.stl touches itself at %.0f vertices", touching);
    EXPECT_NE(s.output.find(expected), std::string::npos) << s.output;
    EXPECT_EQ(jsonValue(readText(stl + "/summary.json"), "coincident_vertices"), touching);
    const test::RunResult sc = runMtcut("check " + stl);
    EXPECT_EQ(sc.exitCode, 1) << sc.output; // what the warning said a welding reader sees
    EXPECT_NE(sc.output.find("where (the first 5 of each kind):"), std::string::npos) << sc.output;

    const test::RunResult k = runMtcut("cut " + ball + " --iso 0 --path " + path + " --kerf 0.5 -o " + kerf + " --check");
    ASSERT_EQ(k.exitCode, 0) << k.output;
    EXPECT_EQ(k.output.find("warning"), std::string::npos) << k.output;
    EXPECT_EQ(jsonValue(readText(kerf + "/summary.json"), "coincident_vertices"), 0.0);
    EXPECT_EQ(runMtcut("check " + kerf).exitCode, 0);
}

// The straight stroke, then again along the same base line with the blade
// tilted by 0.02 rad (its tip 0.9 mm off the first cut, beyond the path
// filter's retrace tolerance): with a zero-width blade the two strokes'
// quads meet along the base line nearly in one plane, which the re-mesher
// refuses. The error names the cell and where it is in world mm, suggests a
// saw width, and nothing is written; with --kerf 0.5 the same path cuts the
// ball in two. (The same stroke exactly twice adds nothing since the filter
// knows the earlier strokes: StrokeGoingBackIntoTheCutAddsNothing.)
TEST(CutCli, RefusedStrokeNamesTheCellInWorldMmAndWritesNothing)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string once = readText(writeStraightPath(dir));
    const std::string path = dir.file("twice.csv");
    {
        std::ofstream f(path);
        f << once << "\nstroke\n";
        for (int i = 0; i <= 200; ++i) f << 0.001 * i << "," << -25.0 + 50.0 * i / 200 << ",0.37,22,0.02,0,-1,45\n";
    }
    const std::string out = dir.file("out");
    const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out);
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_EQ(r.output.rfind("mtcut: error: remesh: coplanar overlapping quads in cell (", 0), 0u) << r.output;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.output, m, std::regex(R"(cell \((-?\d+), (-?\d+), (-?\d+)\), centred at \(([-.0-9]+), ([-.0-9]+), ([-.0-9]+)\) mm)")))
        << r.output;
    for (int a = 0; a < 3; ++a) // the ball's grid: origin -19.5 mm, 1 mm voxels
        EXPECT_NEAR(std::stod(m[4 + a]), -19.5 + std::stod(m[1 + a]) + 0.5, 1e-9) << r.output;
    EXPECT_NEAR(std::stod(m[5]), 0.0, 1.0) << "the cell holds the blade at y = 0.37: " << r.output;
    EXPECT_NE(r.output.find("--kerf 0.5"), std::string::npos) << r.output;
    EXPECT_TRUE(filesIn(out).empty());

    const test::RunResult k = runMtcut("cut " + ball + " --iso 0 --path " + path + " --kerf 0.5 -o " + out + " --check");
    ASSERT_EQ(k.exitCode, 0) << k.output;
    EXPECT_TRUE(fs::exists(out + "/fragment_001.stl"));
    EXPECT_FALSE(fs::exists(out + "/fragment_002.stl"));
}

// --keep-going on the refused path above (kerf 0): the first stroke is cut
// whole and the second up to the quad before the one the re-mesher refuses,
// the rest of it dropped; stdout, stderr and summary.json ("refused") say so,
// and the files check clean. On a path that goes through whole the flag
// changes nothing but an empty "refused" list.
TEST(CutCli, KeepGoingCutsARefusedStrokeUpToWhereItIsRefused)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string single = writeStraightPath(dir);
    const std::string path = dir.file("twice.csv");
    {
        std::ofstream f(path);
        f << readText(single) << "\nstroke\n";
        for (int i = 0; i <= 200; ++i) f << 0.001 * i << "," << -25.0 + 50.0 * i / 200 << ",0.37,22,0.02,0,-1,45\n";
    }
    const std::string out = dir.file("out");
    const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out + " --keep-going --check");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    const std::string json = readText(out + "/summary.json");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(json, m, std::regex(R"re("refused": \[\n    \{"stroke": 2, "quads_kept": (\d+), "quads": (\d+), "refused_at_t": ([-.e0-9]+), "message": "([^"]*)"\}\n  \])re")))
        << json;
    const int kept = std::stoi(m[1]), quads = std::stoi(m[2]);
    EXPECT_LT(kept, quads);
    EXPECT_GT(quads, 40);
    EXPECT_EQ(std::string(m[4]).rfind("remesh: coplanar overlapping quads in cell (", 0), 0u) << m[4];
    // The pose that made the refused quad: the second stroke's poses are 1 ms
    // and 0.25 mm apart from x = -25 mm, and the refused cell holds that x.
    const double t = std::stod(m[3]);
    EXPECT_GT(t, 0.0);
    EXPECT_LE(t, 0.2);
    const std::string message = m[4];
    std::smatch c;
    ASSERT_TRUE(std::regex_search(message, c, std::regex(R"(centred at \(([-.0-9]+), )"))) << message;
    EXPECT_NEAR(std::stod(c[1]), -25.0 + 250.0 * t, 1.5) << "t " << t << ": " << message;
    EXPECT_NE(r.output.find("refused:    stroke 2 at quad " + std::to_string(kept + 1) + " of " + std::to_string(quads)),
              std::string::npos) << r.output;
    EXPECT_NE(r.output.find("warning: 1 stroke(s) cut only in part"), std::string::npos) << r.output;
    // Cutting the same plane twice is the kernel's own refusal, not one below a float step: not stepped round.
    EXPECT_NE(json.find("\"stepped_round\": [],\n"), std::string::npos) << json;
    EXPECT_NE(r.output.find("defects:                0 (valid)"), std::string::npos) << r.output;
    EXPECT_TRUE(fs::exists(out + "/fragment_001.stl")) << "the first stroke cuts the ball in two";

    // mtcut render: the same refusal (named in world mm, nothing written), and
    // with --keep-going the same partial cut, reported alike.
#ifdef MTCUT_HAVE_RENDER
    const std::string png = dir.file("cut.png");
    const test::RunResult refusedRender = runMtcut("render " + ball + " --iso 0 --path " + path + " -o " + png + " --width 64 --height 48");
    EXPECT_EQ(refusedRender.exitCode, 1) << refusedRender.output;
    EXPECT_NE(refusedRender.output.find("coplanar overlapping quads in cell ("), std::string::npos) << refusedRender.output;
    EXPECT_NE(refusedRender.output.find("mm; the re-mesher refuses"), std::string::npos) << refusedRender.output;
    EXPECT_FALSE(fs::exists(png));
    const test::RunResult partialRender =
        runMtcut("render " + ball + " --iso 0 --path " + path + " -o " + png + " --width 64 --height 48 --keep-going");
    EXPECT_EQ(partialRender.exitCode, 0) << partialRender.output;
    EXPECT_NE(partialRender.output.find("refused:    stroke 2 at quad " + std::to_string(kept + 1) + " of " +
                                        std::to_string(quads)),
              std::string::npos) << partialRender.output;
    EXPECT_TRUE(fs::exists(png));
#else
    std::puts("mtcut render not built (-DMTCUT_BUILD_RENDER=OFF): its part of this test is left out");
#endif

    const std::string a = dir.file("a"), b = dir.file("b");
    ASSERT_EQ(runMtcut("cut " + ball + " --iso 0 --path " + single + " -o " + a + " --keep-going").exitCode, 0);
    ASSERT_EQ(runMtcut("cut " + ball + " --iso 0 --path " + single + " -o " + b).exitCode, 0);
    EXPECT_NE(readText(a + "/summary.json").find("\"refused\": [],\n"), std::string::npos);
    for (const std::string file : {"fragment_000.stl", "fragment_001.stl"})
        EXPECT_EQ(readText(a + "/" + file), readText(b + "/" + file)) << file;
}

// The 2 mm head at 400, kerf 0.5, random strokes seed 12052 as a path file:
// the cut of both strokes is refused below a float step (five vertices of
// three quads' planes and the isosurface within 2e-5 mm of face y = 210 mm),
// and the error says --keep-going steps round such a refusal; with it the
// second stroke, cut live, steps round it and is cut whole, and stdout and
// summary.json ("stepped_round") say so, the files clean.
TEST(CutCli, KeepGoingStepsRoundARefusalBelowAFloatStep)
{
    MTCUT_REQUIRE_DATA(head, "vhm_head_2mm.nhdr");
    openvdb::initialize();
    TempDir dir;
    const uint32_t seed = 12052;
    const auto strokes = cutter::makeRandomStrokes(cutter::frameOf(vdb::readVolume(head)), seed, 2, 150 + 50 * int(seed % 5),
                                                   0.4 + 0.2 * (seed % 4), 20.0 + 10.0 * (seed % 4));
    const std::string path = dir.file("strokes.csv");
    {
        std::ofstream f(path);
        cutter::writePath(f, strokes);
    }
    const std::string out = dir.file("out");
    const test::RunResult refused = runMtcut("cut " + head + " --iso 400 --kerf 0.5 --path " + path + " -o " + out);
    ASSERT_EQ(refused.exitCode, 1) << refused.output;
    EXPECT_NE(refused.output.find("crosses or touches itself"), std::string::npos) << refused.output;
    EXPECT_NE(refused.output.find("--keep-going"), std::string::npos) << refused.output;
    EXPECT_FALSE(fs::exists(out + "/summary.json"));
    const test::RunResult r = runMtcut("cut " + head + " --iso 400 --kerf 0.5 --path " + path + " -o " + out + " --keep-going --check");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("stepped:    stroke 2 stepped round"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("refused:"), std::string::npos) << r.output;
    const std::string json = readText(out + "/summary.json");
    EXPECT_NE(json.find("\"refused\": [],\n  \"stepped_round\": [2],\n"), std::string::npos) << json;
    EXPECT_NE(r.output.find("defects:                0 (valid)"), std::string::npos) << r.output;

    // mtcut render alike: the hint without --keep-going, nothing written; the stepped stroke reported with it.
#ifdef MTCUT_HAVE_RENDER
    const std::string png = dir.file("cut.png");
    const std::string render = "render " + head + " --iso 400 --kerf 0.5 --path " + path + " -o " + png + " --width 64 --height 48";
    const test::RunResult refusedRender = runMtcut(render);
    EXPECT_EQ(refusedRender.exitCode, 1) << refusedRender.output;
    EXPECT_NE(refusedRender.output.find("--keep-going cuts the strokes one by one"), std::string::npos) << refusedRender.output;
    EXPECT_FALSE(fs::exists(png));
    const test::RunResult rendered = runMtcut(render + " --keep-going");
    EXPECT_EQ(rendered.exitCode, 0) << rendered.output;
    EXPECT_NE(rendered.output.find("stepped:    stroke 2 stepped round"), std::string::npos) << rendered.output;
    EXPECT_EQ(rendered.output.find("refused:"), std::string::npos) << rendered.output;
    EXPECT_TRUE(fs::exists(png));
#endif
}

TEST(CutCli, BadPathFileFailsNamingTheLine)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = dir.file("bad.csv");
    {
        std::ofstream f(path);
        f << "t,x,y,z,dx,dy,dz,length\n";
        f << "0,-25,0.37,22,0,0,-1,45\n";
        f << "0.001,-24,0.37,22,0,0,-1\n"; // line 3: 7 fields
    }
    const std::string out = dir.file("out");
    const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out);
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_EQ(r.output.rfind("mtcut: error: ", 0), 0u) << r.output;
    EXPECT_NE(r.output.find("bad.csv:3:"), std::string::npos) << r.output;
    EXPECT_EQ(countOf(r.output, "\n"), 1u) << r.output;
    EXPECT_TRUE(filesIn(out).empty());
}

// The fragment files, cut.vdb and slices.exr are written at once; when one
// of them cannot be written (a folder of that name in the way), the others
// stop, and the error names that file: it is not reported as a cancel.
TEST(CutCli, AnOutputThatCannotBeWrittenIsNamedAndStopsTheOthers)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = writeStraightPath(dir);
    for (const char* blocked : {"fragment_000.stl", "cut.vdb", "slices.exr"}) {
        const std::string out = dir.file(std::string("out_") + blocked);
        fs::create_directories(out + "/" + blocked);
        std::ofstream(out + "/" + blocked + "/keep") << "x";
        const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + " -o " + out);
        EXPECT_EQ(r.exitCode, 1) << blocked << ": " << r.output;
        EXPECT_NE(r.output.find(std::string("mtcut: error: ") + out + "/" + blocked + ": cannot write"),
                  std::string::npos)
            << r.output;
        EXPECT_EQ(r.output.find("cancelled"), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(out + "/summary.json")) << blocked;
    }
}

// --level-set-voxel sets the voxel size of cut.vdb's level sets (default:
// the scan's smallest spacing, 1 mm for the ball), and summary.json gives the
// size used. A size that is no size, past 100 mm or finer than a quarter of
// the scan's spacing fails at once, writing nothing.
TEST(CutCli, LevelSetVoxelSizeIsChosenAndChecked)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = writeStraightPath(dir);
    auto levelSetVoxel = [](const std::string& out) {
        openvdb::io::File file(out + "/cut.vdb");
        file.open();
        const openvdb::GridBase::Ptr grid = file.readGridMetadata("fragment_000");
        file.close();
        return grid->voxelSize();
    };
    for (const char* size : {"", "0.5", "2.5"}) {
        const std::string out = dir.file(std::string("out_") + size);
        const std::string option = *size ? std::string(" --level-set-voxel ") + size : std::string();
        const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + path + option + " -o " + out);
        ASSERT_EQ(r.exitCode, 0) << r.output;
        const double want = *size ? std::stod(size) : 1.0;
        EXPECT_EQ(levelSetVoxel(out), openvdb::Vec3d(want)) << size;
        EXPECT_EQ(jsonValue(readText(out + "/summary.json"), "level_set_voxel_mm"), want) << size;
    }
    const std::string out = dir.file("bad");
    for (const char* size : {"0", "-1", "nan", "100.5", "0.2"}) {
        const test::RunResult r =
            runMtcut("cut " + ball + " --iso 0 --path " + path + " --level-set-voxel " + size + " -o " + out);
        EXPECT_EQ(r.exitCode, 1) << r.output;
        EXPECT_EQ(r.output.rfind(std::string("mtcut: error: --level-set-voxel ") + size + ": expected ", 0), 0u)
            << r.output;
        EXPECT_TRUE(filesIn(out).empty()) << size;
    }
}

// A saw width that is not a width (negative, not a number) or wider than any
// saw (past cutter::kMaxKerfMm, 20 mm: a 1e9 mm kerf made every cell a cut
// cell and ran for minutes without a word) fails at once, writing nothing.
TEST(CutCli, AKerfOutOfRangeFailsAtOnce)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string out = dir.file("out");
    for (const char* kerf : {"-1", "nan", "20.5", "1e9"}) {
        const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --kerf " + kerf + " -o " + out);
        EXPECT_EQ(r.exitCode, 1) << r.output;
        EXPECT_EQ(r.output, std::string("mtcut: error: --kerf ") + kerf + ": expected a saw width from 0 to 20 mm\n");
        EXPECT_TRUE(filesIn(out).empty());
    }
    cutter::IndexFrame frame;
    frame.dims = glm::ivec3(8);
    EXPECT_THROW(cutter::CutMask(frame, 20.5), InputError);
    EXPECT_NO_THROW(cutter::CutMask(frame, 20.0));
}

// --retrace sets the path filter's retrace tolerance: out of range it fails
// at once, nothing written; in range summary.json records it, and a saw
// worked back and forth through the ball (each pass deepening the cut a
// little) makes fewer quads with a wider one, and both cuts come out clean.
// At the default, the quads the passes pile in a cell get a note saying so.
TEST(CutCli, ARetraceToleranceIsCheckedUsedAndRecorded)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string out = dir.file("out");
    for (const char* retrace : {"-1", "nan", "4.5"}) {
        const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --retrace " + retrace + " -o " + out);
        EXPECT_EQ(r.exitCode, 1) << r.output;
        EXPECT_EQ(r.output, std::string("mtcut: error: --retrace ") + retrace +
                                ": expected a tolerance from 0 to 4 voxels (default 0.25)\n");
        EXPECT_TRUE(filesIn(out).empty());
    }
    const test::RunResult word = runMtcut("cut " + ball + " --iso 0 --retrace wide -o " + out);
    EXPECT_EQ(word.output, "mtcut: error: --retrace wide: expected a number\n");

    const std::string saw = dir.file("saw.csv");
    {
        std::ofstream file(saw);
        cutter::writePath(file, {test::sawThroughTheBall()});
    }
    size_t quads[2] = {0, 0};
    for (int wide = 0; wide < 2; ++wide) {
        const std::string outDir = dir.file(wide ? "wide" : "fine");
        const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --kerf 0.5 --path " + saw +
                                           (wide ? " --retrace 1" : "") + " -o " + outDir + " --check");
        ASSERT_EQ(r.exitCode, 0) << r.output;
        std::smatch m;
        ASSERT_TRUE(std::regex_search(r.output, m, std::regex(R"(1 stroke\(s\), (\d+) quads, kerf 0.5 mm, retrace ([0-9.]+) voxels)")))
            << r.output;
        quads[wide] = std::stoul(m[1]);
        EXPECT_EQ(m[2], wide ? "1" : "0.25");
        // At the default the passes pile quads in the cells, and the note says what to do.
        std::smatch note;
        const bool noted = std::regex_search(
            r.output, note, std::regex(R"(mtcut: note: up to (\d+) quads cross one cut cell .*; --retrace 1 lays one only)"));
        EXPECT_EQ(noted, !wide) << r.output;
        if (noted) {
            EXPECT_GE(std::stoul(note[1]), 12u); // cli::kManyQuadsPerCell
        }
        const std::string json = readText(outDir + "/summary.json");
        EXPECT_NE(json.find(wide ? "\"retrace_voxels\": 1,\n" : "\"retrace_voxels\": 0.25,\n"), std::string::npos) << json;
    }
    EXPECT_LT(2 * quads[1], quads[0]) << quads[1] << " quads with --retrace 1, " << quads[0] << " without";
}

// --slide sets the path filter's slide tolerance (rule 2c): out of range it
// fails at once, nothing written; in range summary.json records it, and a
// saw slid along its blade through the ball makes fewer quads at the default
// than at 0 (where only poses exactly on the line would be held back), both
// cuts clean.
TEST(CutCli, ASlideToleranceIsCheckedUsedAndRecorded)
{
    openvdb::initialize();
    TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string out = dir.file("out");
    for (const char* slide : {"-1", "nan", "4.5"}) {
        const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --slide " + slide + " -o " + out);
        EXPECT_EQ(r.exitCode, 1) << r.output;
        EXPECT_EQ(r.output, std::string("mtcut: error: --slide ") + slide +
                                ": expected a tolerance from 0 to 4 voxels (default 0.25)\n");
        EXPECT_TRUE(filesIn(out).empty());
    }
    EXPECT_EQ(runMtcut("cut " + ball + " --iso 0 --slide far -o " + out).output,
              "mtcut: error: --slide far: expected a number\n");

    const std::string saw = dir.file("slide.csv");
    {
        cutter::SawingOptions o;
        o.poses = 160;
        o.amplitudeMm = 5.0;
        o.feedMm = 0.05;
        o.posesPerCycle = 16.0;
        o.bladeLength = 20.0;
        o.slide = true;
        std::ofstream file(saw);
        cutter::writePath(file, {cutter::makeSawingStroke(glm::dvec3(0.0, 0.37, 0.0), 5, o)});
    }
    size_t quads[2] = {0, 0};
    for (int held = 0; held < 2; ++held) {
        const std::string outDir = dir.file(held ? "held" : "each");
        const test::RunResult r = runMtcut("cut " + ball + " --iso 0 --path " + saw + (held ? "" : " --slide 0") +
                                           " -o " + outDir + " --check");
        ASSERT_EQ(r.exitCode, 0) << r.output;
        std::smatch m;
        ASSERT_TRUE(std::regex_search(r.output, m,
                                      std::regex(R"(1 stroke\(s\), (\d+) quads, .*, slide ([0-9.]+) voxels)")))
            << r.output;
        quads[held] = std::stoul(m[1]);
        EXPECT_EQ(m[2], held ? "0.25" : "0");
        const std::string json = readText(outDir + "/summary.json");
        EXPECT_NE(json.find(held ? "\"slide_voxels\": 0.25,\n" : "\"slide_voxels\": 0,\n"), std::string::npos) << json;
    }
    EXPECT_LT(2 * quads[1], quads[0]) << quads[1] << " quads at the default, " << quads[0] << " with --slide 0";
}

// The README demo's cut: the phantom's LeFort I plane, cut by tools/phantom_lefort.csv, must
// come out clean and split off exactly one more piece (the maxilla with the upper teeth).
TEST(CutCli, DemoLeFortStrokeSeparatesThePhantomMaxilla)
{
    TempDir dir;
    const std::string phantom = dir.file("p.vdb");
    ASSERT_EQ(runMtcut("phantom " + phantom + " --size 128,128,64").exitCode, 0);
    const auto mesh = runMtcut("mesh " + phantom + " --iso 400 -o " + dir.file("bone.stl") + " --check");
    ASSERT_EQ(mesh.exitCode, 0) << mesh.output;
    const size_t shellsAt = mesh.output.find(" shells at iso");
    ASSERT_NE(shellsAt, std::string::npos) << mesh.output;
    // A fragment is an outer shell with its cavities.
    const size_t cavitiesAt = mesh.output.find(" cavities face inward");
    ASSERT_NE(cavitiesAt, std::string::npos) << mesh.output;
    const int uncutShells = std::stoi(mesh.output.substr(mesh.output.rfind(' ', shellsAt - 1) + 1)) -
                            std::stoi(mesh.output.substr(mesh.output.rfind(' ', cavitiesAt - 1) + 1));

    const std::string path = std::string(MTCUT_SOURCE_ROOT) + "/tools/phantom_lefort.csv";
    const auto cut = runMtcut("cut " + phantom + " --iso 400 --path " + path + " -o " + dir.file("out") + " --check");
    ASSERT_EQ(cut.exitCode, 0) << cut.output;
    EXPECT_NE(cut.output.find("defects:                0 (valid)"), std::string::npos) << cut.output;
    const std::string tag = " fragment(s)";
    const size_t at = cut.output.find(tag);
    ASSERT_NE(at, std::string::npos) << cut.output;
    const int fragments = std::stoi(cut.output.substr(cut.output.rfind(' ', at - 1) + 1));
    EXPECT_EQ(fragments, uncutShells + 1) << cut.output;
    // The maxilla and the skull both have cut faces, the same caps on both
    // sides of the zero-width blade, bar the specks the cut also touched.
    const std::string json = readText(dir.file("out") + "/summary.json");
    std::vector<double> cutAreas;
    for (size_t p = json.find("\"cut_area_mm2\": "); p != std::string::npos; p = json.find("\"cut_area_mm2\": ", p + 1)) {
        const double a = std::strtod(json.c_str() + p + 16, nullptr);
        if (a > 0.0) cutAreas.push_back(a);
    }
    std::sort(cutAreas.rbegin(), cutAreas.rend());
    ASSERT_GE(cutAreas.size(), 2u) << json;
    EXPECT_GT(cutAreas[1], 0.9 * cutAreas[0]) << json;
    double rest = 0.0;
    for (size_t i = 2; i < cutAreas.size(); ++i) rest += cutAreas[i];
    EXPECT_NEAR(cutAreas[0], cutAreas[1], rest + 1e-6 * cutAreas[0]) << json;
}

// The built-in stroke fitted to a small bone box (the 103 x 94 x 161 mm tooth
// scan). When it was a half ellipse whose blades all aimed at one focus, a
// 30 mm blade passed through it from every pose, so one cell held all 78
// quads and the re-mesher ran for minutes; the cut must finish clean, both
// kerfs. The built-in stroke's poses are written to stroke.csv, and cutting
// along that file gives the same cut; a cut along a path file writes none
// and removes the one an earlier run left.
TEST(CutCli, BuiltInStrokeOnTheToothScanIsClean)
{
    MTCUT_REQUIRE_DATA(tooth, "tooth.nhdr");
    TempDir dir;
    const std::string out = dir.file("out"), replay = dir.file("replay");
    // summary.json from the cut cells to the timings: what was cut and written.
    auto cutPart = [](const std::string& json) {
        const size_t a = json.find("\"cut_cells\""), b = json.find("\"timings_s\"");
        return a == std::string::npos || b == std::string::npos ? std::string() : json.substr(a, b - a);
    };
    for (const char* kerf : {"0", "0.5"}) {
        const auto cut = runMtcut("cut " + tooth + " --iso 656 --kerf " + kerf + " -o " + out + " --check");
        ASSERT_EQ(cut.exitCode, 0) << cut.output;
        EXPECT_NE(cut.output.find("defects:                0 (valid)"), std::string::npos) << cut.output;
        EXPECT_NE(cut.output.find("built-in LeFort I"), std::string::npos) << cut.output;
        EXPECT_NE(cut.output.find("stroke.csv, summary.json}"), std::string::npos) << cut.output;
        const std::string json = readText(out + "/summary.json");
        EXPECT_NE(json.find("\"stroke_file\": \"stroke.csv\","), std::string::npos) << json;
        ASSERT_TRUE(fs::exists(out + "/stroke.csv"));
        EXPECT_EQ(cutter::readPathFile(out + "/stroke.csv").size(), 1u);

        const auto again = runMtcut("cut " + tooth + " --iso 656 --kerf " + kerf + " --path " + out +
                                    "/stroke.csv -o " + replay + " --check");
        ASSERT_EQ(again.exitCode, 0) << again.output;
        const std::string replayed = readText(replay + "/summary.json");
        EXPECT_NE(replayed.find("\"stroke_file\": null,"), std::string::npos) << replayed;
        EXPECT_FALSE(fs::exists(replay + "/stroke.csv"));
        EXPECT_FALSE(cutPart(json).empty()) << json;
        EXPECT_EQ(cutPart(replayed), cutPart(json));
    }
    fs::copy_file(out + "/stroke.csv", dir.file("path.csv"));
    ASSERT_EQ(runMtcut("cut " + tooth + " --iso 656 --path " + dir.file("path.csv") + " -o " + out).exitCode, 0);
    EXPECT_FALSE(fs::exists(out + "/stroke.csv")) << "an earlier run's stroke.csv is not this cut's";
}
