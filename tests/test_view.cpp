// mtcut-view, driven by scripts in a real window under Xvfb (xvfb-run): the
// 4 mm head is opened, cut along a path file (two strokes, kerf 0.5 mm),
// undone stroke by stroke, redone, screenshotted and exported. The oracle is
// `mtcut render` / `mtcut cut` of the same state: screenshots must match
// renders pixel for pixel within the tolerance below, exports must equal
// `mtcut cut`'s files and pass checkMesh. Bad scripts: an unknown action
// stops with its line number and a non-zero exit before the window opens; a
// missing file is a message and the session goes on. A scripted mouse drag
// cuts through the mouse's code path and undoes exactly. A path file loaded
// twice cuts what it cut once. A path stroke the re-mesher refuses is cut up
// to where it is refused, as `mtcut cut --keep-going` cuts it.
#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "cutter/MeshCheck.h"
#include "cutter/MeshIO.h"
#include "cutter/PathFile.h"
#include "render/Frame.h"
#include "tests/TestStrokes.h"
#include "tests/TestUtil.h"
#include "tests/TestVolumes.h"
#include "vdb/VolumeIO.h"

#include <gtest/gtest.h>

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

#include <glm/geometric.hpp>
#include <openvdb/io/File.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

using namespace mtcut;
namespace fs = std::filesystem;

namespace {

/// The first 4 mm head and xvfb-run, or a reason to skip.
std::string whyNotRunnable()
{
    if (test::dataPath("vhm_head_4mm.nhdr").empty()) return "shared data 'vhm_head_4mm.nhdr' not found (set MTCUT_DATA)";
    if (std::system("command -v xvfb-run > /dev/null 2>&1") != 0) return "xvfb-run not found (apt-get install xvfb)";
    return {};
}

/// Runs mtcut-view under a fresh Xvfb with a 640x480 window; output = stdout + stderr.
/// Runs mtcut-view under Xvfb; `stdinFrom` (a shell command), when given,
/// feeds its standard input.
test::RunResult runView(const std::string& args, const std::string& stdinFrom = "")
{
    test::RunResult r;
    const std::string cmd = (stdinFrom.empty() ? std::string() : "(" + stdinFrom + ") | ") +
                            "timeout 300 xvfb-run -a -s '-screen 0 1024x768x24' " + std::string(MTCUT_VIEW_BIN) + " " +
                            args + " 2>&1";
    FILE* p = ::popen(cmd.c_str(), "r");
    if (!p) return r;
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
    const int status = ::pclose(p);
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

void writeText(const std::string& path, const std::string& text)
{
    std::ofstream out(path, std::ios::binary);
    out << text;
}

std::string readBytes(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

struct FrameDiff
{
    size_t covered = 0;   ///< pixels with a surface in either image
    size_t different = 0; ///< pixels where some channel differs by more than 2/255
};

FrameDiff compare(const render::Frame& a, const render::Frame& b)
{
    FrameDiff d;
    for (size_t p = 0; p < a.pixelCount(); ++p) {
        const uint8_t* x = &a.rgba[4 * p];
        const uint8_t* y = &b.rgba[4 * p];
        d.covered += x[3] != 0 || y[3] != 0;
        bool differs = false;
        for (int c = 0; c < 4; ++c) differs |= std::abs(int(x[c]) - int(y[c])) > 2;
        d.different += differs;
    }
    return d;
}

/// The screenshot and the render show the same state: the same size, and at
/// most 0.1 % of the covered pixels differ by more than 2/255. Both come from
/// render::SurfaceRenderer with the same camera (the preset framed on the same
/// bounds), the same uncut surface and the same cut geometry (the viewer's
/// incremental re-mesh equals the batch one exactly), so only float rounding
/// of a camera computed in another process could move a pixel centre lying
/// on a triangle edge; the measured difference is 0 pixels.
void expectSameImage(const std::string& shot, const std::string& render, const std::string& what)
{
    ASSERT_TRUE(fs::exists(shot)) << what << ": no " << shot;
    ASSERT_TRUE(fs::exists(render)) << what << ": no " << render;
    const render::Frame a = render::readPng(shot), b = render::readPng(render);
    ASSERT_EQ(a.width, 640) << what;
    ASSERT_EQ(a.height, 480) << what;
    ASSERT_EQ(b.width, a.width);
    ASSERT_EQ(b.height, a.height);
    const FrameDiff d = compare(a, b);
    EXPECT_GT(d.covered, a.pixelCount() / 20) << what << ": the head should fill part of the frame";
    EXPECT_LE(d.different, d.covered / 1000) << what << ": " << d.different << " of " << d.covered
                                             << " covered pixels differ";
    std::printf("%-28s %zu of %zu covered pixels differ\n", what.c_str(), d.different, d.covered);
}

class ViewScript : public ::testing::Test
{
protected:
    void SetUp() override
    {
        const std::string why = whyNotRunnable();
        if (!why.empty()) GTEST_SKIP() << why;
        mHead = test::dataPath("vhm_head_4mm.nhdr");
    }

    /// Two strokes on the head: a horizontal cut 40 % up (right to left, the
    /// blade pointing posterior, as test_render_frame's) and a vertical one
    /// down the middle of the face. Writes stroke 1 alone and both.
    void writePaths(const std::string& first, const std::string& both) const
    {
        const vdb::Volume vol = vdb::readVolume(mHead);
        const cutter::IndexFrame frame = cutter::frameOf(vol);
        const glm::dvec3 lo = frame.toWorld(glm::dvec3(0.0));
        const glm::dvec3 hi = frame.toWorld(glm::dvec3(frame.dims - glm::ivec3(1)));
        const double z = lo.z + 0.4 * (hi.z - lo.z) + 0.37;
        const double x = 0.5 * (lo.x + hi.x) + 0.41;
        const auto horizontal = test::straightStroke({lo.x - 10, lo.y - 10, z}, {hi.x + 10, lo.y - 10, z},
                                                     glm::normalize(glm::dvec3(0, 1, 0.05)), hi.y - lo.y + 20, 300);
        const auto vertical = test::straightStroke({x, lo.y - 10, z + 30.3}, {x, lo.y - 10, z - 60.7},
                                                   glm::normalize(glm::dvec3(0.04, 1, 0)), 0.45 * (hi.y - lo.y), 200);
        std::ofstream a(first), b(both);
        cutter::writePath(a, {horizontal});
        cutter::writePath(b, {horizontal, vertical});
    }

    std::string mHead;
};

} // namespace

TEST_F(ViewScript, CutUndoRedoScreenshotsAndExportMatchTheCommandLine)
{
    const auto t0 = std::chrono::steady_clock::now();
    test::TempDir dir;
    const std::string one = dir.file("one.csv"), two = dir.file("two.csv");
    writePaths(one, two);
    auto shot = [&](const std::string& name) { return dir.file(name + ".png"); };
    writeText(dir.file("session.txt"), "# a cutting session\n"
                                       "iso 400\n"
                                       "view front\n"
                                       "screenshot " + shot("uncut_front") + "\n"
                                       "kerf 0.5\n"
                                       "path " + two + "\n"
                                       "screenshot " + shot("cut_front") + "\n"
                                       "view iso\n"
                                       "screenshot " + shot("cut_iso") + "\n"
                                       "undo\n"
                                       "screenshot " + shot("undo1_iso") + "\n"
                                       "undo\n"
                                       "screenshot " + shot("undo2_iso") + "\n"
                                       "redo\n"
                                       "redo\n"
                                       "screenshot " + shot("redo_iso") + "\n"
                                       "export " + dir.file("out") + "\n"
                                       "quit\n");
    const test::RunResult r = runView(mHead + " --size 640x480 --script " + dir.file("session.txt"));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(r.output.find("error"), std::string::npos) << "the session must leave no error:\n" << r.output;
    EXPECT_NE(r.output.find("saved 1"), std::string::npos) << r.output;
    std::printf("%s", r.output.c_str());
    const double viewSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    // The same states from the command line.
    const std::string common = "render " + mHead + " --iso 400 --width 640 --height 480 ";
    struct Expect
    {
        const char* name;
        std::string args;
    };
    const std::vector<Expect> expected = {
        {"uncut_front", "--view front"},
        {"cut_front", "--view front --kerf 0.5 --path " + two},
        {"cut_iso", "--view iso --kerf 0.5 --path " + two},
        {"undo1_iso", "--view iso --kerf 0.5 --path " + one},
        {"undo2_iso", "--view iso"},
        {"redo_iso", "--view iso --kerf 0.5 --path " + two},
    };
    for (const Expect& e : expected) {
        const test::RunResult rr = test::runMtcut(common + e.args + " -o " + dir.file(std::string("render_") + e.name + ".png"));
        ASSERT_EQ(rr.exitCode, 0) << rr.output;
        expectSameImage(shot(e.name), dir.file(std::string("render_") + e.name + ".png"), e.name);
    }
    // The cut shows: each stroke changes the picture a lot.
    const render::Frame uncut = render::readPng(shot("undo2_iso")), one_ = render::readPng(shot("undo1_iso")),
                        cut = render::readPng(shot("cut_iso"));
    EXPECT_GT(compare(uncut, one_).different, 100u) << "the first stroke should be visible";
    EXPECT_GT(compare(one_, cut).different, 100u) << "the second stroke should be visible";

    // The export equals `mtcut cut`'s output and is clean: all fragments
    // together pass checkMesh, and each alone too (a cavity, e.g. an air
    // pocket inside bone, is written with the fragment that encloses it).
    const test::RunResult cutRun =
        test::runMtcut("cut " + mHead + " --iso 400 --kerf 0.5 --path " + two + " -o " + dir.file("cut"));
    ASSERT_EQ(cutRun.exitCode, 0) << cutRun.output;
    size_t fragments = 0;
    cutter::Mesh all;
    for (const fs::directory_entry& e : fs::directory_iterator(dir.file("cut"))) {
        const std::string name = e.path().filename().string();
        if (name.rfind("fragment_", 0) != 0) continue;
        ++fragments;
        const std::string mine = dir.file("out/" + name);
        ASSERT_TRUE(fs::exists(mine)) << name << " not exported";
        EXPECT_EQ(readBytes(mine), readBytes(e.path().string())) << name << " differs from mtcut cut's";
        const cutter::Mesh mesh = cutter::readMesh(mine);
        const cutter::MeshCheck check = cutter::checkMesh(mesh);
        EXPECT_TRUE(check.ok()) << name << ":\n" << check.report();
        const uint32_t offset = uint32_t(all.positions.size());
        all.positions.insert(all.positions.end(), mesh.positions.begin(), mesh.positions.end());
        for (uint32_t i : mesh.indices) all.indices.push_back(offset + i);
    }
    EXPECT_GT(fragments, 1u);
    const cutter::MeshCheck allCheck = cutter::checkMesh(all);
    EXPECT_TRUE(allCheck.ok()) << "all fragments:\n" << allCheck.report();
    EXPECT_EQ(allCheck.shells, fragments + allCheck.cavities); // cavities go with their fragment
    for (const char* name : {"cut.vdb", "slices.exr", "summary.json"}) {
        EXPECT_TRUE(fs::exists(dir.file(std::string("out/") + name))) << name;
    }
    const std::string summary = readBytes(dir.file("out/summary.json"));
    EXPECT_NE(summary.find("\"defects\": 0"), std::string::npos) << summary;
    EXPECT_NE(summary.find("\"kerf_mm\": 0.5"), std::string::npos) << summary;
    std::printf("viewer session %.1f s, whole test %.1f s\n", viewSeconds,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

// The window shows each change of the scene: a frame that changes nothing
// presents the image drawn before (the viewer does not draw the head again
// 4 times a second), so a change it missed would leave the old image on
// screen. `window` shots of the cut head, after undoing its strokes (the
// camera stays: only the uploaded geometry changes), after redoing them,
// and from the side; compared where only the 3D view is (right of the
// panel, below the overlay: 8 lines at most, ~150 of the 480 rows).
TEST_F(ViewScript, TheWindowShowsEachChangeOfTheScene)
{
    test::TempDir dir;
    const std::string first = dir.file("first.csv"), both = dir.file("both.csv");
    writePaths(first, both);
    auto shot = [&](const std::string& name) { return "window " + dir.file(name) + "\n"; };
    writeText(dir.file("s.txt"), "iso 400\nkerf 2\npath " + both + "\n" + shot("cut.png") + "undo\nundo\n" +
                                     shot("uncut.png") + "redo\nredo\n" + shot("again.png") + "view side\n" +
                                     shot("side.png") + "quit\n");
    const test::RunResult r = runView(mHead + " --size 640x480 --script " + dir.file("s.txt"));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(r.output.find("error"), std::string::npos) << r.output;
    auto differing = [&](const std::string& x, const std::string& y) {
        const render::Frame a = render::readPng(dir.file(x)), b = render::readPng(dir.file(y));
        EXPECT_EQ(a.width, b.width);
        EXPECT_EQ(a.height, b.height);
        size_t n = 0;
        for (int row = a.height * 4 / 10; row < a.height; ++row)
            for (int col = a.width * 45 / 100; col < a.width; ++col) {
                const size_t p = 4 * (size_t(row) * size_t(a.width) + size_t(col));
                bool differs = false;
                for (int c = 0; c < 3; ++c) differs |= std::abs(int(a.rgba[p + size_t(c)]) - int(b.rgba[p + size_t(c)])) > 2;
                n += differs;
            }
        std::printf("%s vs %s: %zu pixels differ\n", x.c_str(), y.c_str(), n);
        return n;
    };
    EXPECT_EQ(differing("cut.png", "again.png"), 0u) << "the same scene twice";
    EXPECT_GT(differing("cut.png", "uncut.png"), 100u) << "the undone cut is still on screen";
    EXPECT_GT(differing("again.png", "side.png"), 5000u) << "the new view is not on screen";
}

TEST_F(ViewScript, AMouseStrokeCutsAndUndoes)
{
    // `drag` goes through the mouse's path: the blade picked on the bone at the
    // start pixel, moved across the screen at that depth, pointing into it.
    test::TempDir dir;
    auto shot = [&](const std::string& name) { return dir.file(name + ".png"); };
    writeText(dir.file("s.txt"), "iso 400\nview front\nscreenshot " + shot("uncut") +
                                     "\ndrag 262 292 160 292\nscreenshot " + shot("cut") + "\nexport " +
                                     dir.file("out") + "\nundo\nscreenshot " + shot("undone") + "\nquit\n");
    const test::RunResult r = runView(mHead + " --size 640x480 --script " + dir.file("s.txt"));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(r.output.find("error"), std::string::npos) << r.output;
    // The mouse's zero-width stroke ends inside the bone: the saved STL's slit sides lie on each other.
    EXPECT_NE(r.output.find("mtcut-view: warning: fragment_000.stl touches itself at "), std::string::npos) << r.output;
    const render::Frame uncut = render::readPng(shot("uncut")), cut = render::readPng(shot("cut")),
                        undone = render::readPng(shot("undone"));
    EXPECT_GT(compare(uncut, cut).different, 100u) << "the stroke should show";
    EXPECT_EQ(compare(uncut, undone).different, 0u) << "undo gives the uncut surface back exactly";
    const std::string summary = readBytes(dir.file("out/summary.json"));
    const size_t at = summary.find("\"cut_cells\": ");
    ASSERT_NE(at, std::string::npos) << summary;
    EXPECT_GT(std::stoul(summary.substr(at + 13)), 100u) << summary;
    EXPECT_NE(summary.find("\"defects\": 0"), std::string::npos) << summary;
}

// A path file loaded a second time goes back into the cut: the viewer's
// path filter knows the cut, so the second load adds nothing and the
// exported fragments are byte for byte those of one load. With kerf 0 the
// repeat used to be refused (coplanar overlapping quads).
TEST_F(ViewScript, ThePathLoadedTwiceCutsWhatItCutOnce)
{
    test::TempDir dir;
    const std::string one = dir.file("one.csv"), two = dir.file("two.csv");
    writePaths(one, two);
    auto session = [&](const std::string& name, int loads) {
        std::string script = "iso 400\n";
        for (int i = 0; i < loads; ++i) script += "path " + one + "\n";
        script += "export " + dir.file(name) + "\nquit\n";
        writeText(dir.file(name + ".txt"), script);
        const test::RunResult r = runView(mHead + " --size 640x480 --script " + dir.file(name + ".txt"));
        EXPECT_EQ(r.exitCode, 0) << r.output;
        EXPECT_EQ(r.output.find("error"), std::string::npos) << r.output;
        EXPECT_EQ(r.output.find("refused"), std::string::npos) << r.output;
    };
    session("once", 1);
    session("twice", 2);
    auto fragmentFiles = [&](const std::string& name) {
        std::set<std::string> files;
        for (const fs::directory_entry& e : fs::directory_iterator(dir.file(name)))
            if (e.path().filename().string().rfind("fragment_", 0) == 0) files.insert(e.path().filename().string());
        return files;
    };
    const std::set<std::string> files = fragmentFiles("once");
    EXPECT_GT(files.size(), 1u);
    EXPECT_EQ(fragmentFiles("twice"), files);
    for (const std::string& f : files) EXPECT_EQ(readBytes(dir.file("twice/" + f)), readBytes(dir.file("once/" + f))) << f;
}

namespace {

/// A ball of radius 15 mm (the field 15 - |p|, iso 0) in a 40^3 grid of 1 mm
/// voxels centred on the origin, written into `dir`: no shared data needed.
std::string writeBall(const test::TempDir& dir)
{
    openvdb::initialize();
    const std::string ball = dir.file("ball.vdb");
    vdb::writeVolume(test::fieldVolume(openvdb::Coord(40), openvdb::Vec3d(1.0), openvdb::Vec3d(-19.5),
                                       [](const openvdb::Vec3d& p) { return 15.0 - p.length(); }),
                     ball);
    return ball;
}

/// Expects every fragment file `mtcut cut` wrote into `cutDir` in `exported`
/// too, byte for byte; returns how many there are.
size_t sameFragments(const std::string& exported, const std::string& cutDir)
{
    size_t fragments = 0;
    for (const fs::directory_entry& e : fs::directory_iterator(cutDir)) {
        const std::string name = e.path().filename().string();
        if (name.rfind("fragment_", 0) != 0) continue;
        ++fragments;
        EXPECT_EQ(readBytes(exported + "/" + name), readBytes(e.path().string())) << name << " differs from mtcut cut's";
    }
    return fragments;
}

} // namespace

// A path whose second stroke the re-mesher refuses part way: the ball cut
// at kerf 0 by a stroke in the plane y = 0.37, then by one in the same plane
// with its blade tilted, whose quads overlap the first's (the kernel refuses
// coplanar overlapping quads). The viewer cuts the refused stroke again as a
// live stroke, up to where it is refused, and says so; the result is what
// `mtcut cut --keep-going` makes of the same path, file for file. (The ball
// is made here: no shared data needed.)
TEST(ViewPath, ARefusedStrokeIsCutUpToWhereItIsRefusedAsTheCommandLineDoes)
{
    if (std::system("command -v xvfb-run > /dev/null 2>&1") != 0) GTEST_SKIP() << "xvfb-run not found (apt-get install xvfb)";
    test::TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = dir.file("twice.csv");
    std::vector<std::vector<cutter::Pose>> strokes;
    for (const glm::dvec3 blade : {glm::dvec3(0, 0, -1), glm::normalize(glm::dvec3(0.02, 0, -1))})
        strokes.push_back(test::straightStroke({-25, 0.37, 22}, {25, 0.37, 22}, blade, 45, 200));
    {
        std::ofstream f(path);
        cutter::writePath(f, strokes);
    }
    writeText(dir.file("s.txt"), "iso 0\nkerf 0\npath " + path + "\nexport " + dir.file("out") + "\nquit\n");
    const test::RunResult r = runView(ball + " --size 320x240 --script " + dir.file("s.txt"));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.output, m, std::regex(R"(error: \S*twice\.csv: stroke 2 refused at quad (\d+) of (\d+), cut to quad (\d+): remesh: coplanar overlapping quads in cell \()")))
        << r.output;
    const int at = std::stoi(m[1]), quads = std::stoi(m[2]), kept = std::stoi(m[3]);
    EXPECT_EQ(kept + 1, at);
    EXPECT_GT(kept, 0) << "the stroke is cut up to where it is refused, not dropped";
    EXPECT_LT(kept, quads);
    EXPECT_NE(r.output.find("twice.csv: 2 stroke(s), " ), std::string::npos) << r.output;

    const test::RunResult cut = test::runMtcut("cut " + ball + " --iso 0 --kerf 0 --path " + path + " -o " +
                                               dir.file("cut") + " --keep-going --check");
    ASSERT_EQ(cut.exitCode, 0) << cut.output;
    EXPECT_NE(cut.output.find("refused:    stroke 2 at quad " + std::to_string(at) + " of " + std::to_string(quads)),
              std::string::npos) << cut.output;
    EXPECT_EQ(sameFragments(dir.file("out"), dir.file("cut")), 2u) << "the first stroke cuts the ball in two";
    // Its summary.json lists the stroke cut in part as the command line's
    // does (the cut's stroke numbers are the file's here: none is dropped).
    auto refusedOf = [&](const std::string& summary) {
        const std::string json = readBytes(summary);
        std::smatch s;
        EXPECT_TRUE(std::regex_search(json, s, std::regex(R"("refused": \[[^\]]*\],\n  "stepped_round": \[[^\]]*\])")))
            << json;
        return s.empty() ? std::string() : s.str();
    };
    const std::string listed = refusedOf(dir.file("cut/summary.json"));
    EXPECT_NE(listed.find("{\"stroke\": 2, \"quads_kept\": " + std::to_string(kept) + ", \"quads\": " +
                          std::to_string(quads) + ", \"refused_at_t\": "),
              std::string::npos)
        << listed;
    EXPECT_EQ(refusedOf(dir.file("out/summary.json")), listed);
}

// The retrace and slide tolerances in the viewer: a script sets them (out of
// range, the script stops at that line before anything opens), and a saw
// worked back and forth through the ball is then cut as `mtcut cut --retrace
// --slide` cuts it, file for file, summary.json recording them; out of range
// on the command line, the viewer does not start. At the default a note says the cells gather quads.
TEST(ViewPath, ASawPathWithAWiderRetraceIsCutAsTheCommandLineCutsIt)
{
    if (std::system("command -v xvfb-run > /dev/null 2>&1") != 0) GTEST_SKIP() << "xvfb-run not found (apt-get install xvfb)";
    test::TempDir dir;
    const std::string ball = writeBall(dir);
    const std::string path = dir.file("saw.csv");
    {
        std::ofstream f(path);
        cutter::writePath(f, {test::sawThroughTheBall()});
    }
    writeText(dir.file("s.txt"),
              "iso 0\nkerf 0.5\nretrace 1\nslide 0.5\npath " + path + "\nexport " + dir.file("out") + "\nquit\n");
    const test::RunResult r = runView(ball + " --size 320x240 --script " + dir.file("s.txt"));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("saw.csv: 1 stroke(s), "), std::string::npos) << r.output;
    const test::RunResult cut = test::runMtcut("cut " + ball + " --iso 0 --kerf 0.5 --retrace 1 --slide 0.5 --path " + path +
                                               " -o " + dir.file("cut") + " --check");
    ASSERT_EQ(cut.exitCode, 0) << cut.output;
    EXPECT_GE(sameFragments(dir.file("out"), dir.file("cut")), 1u);
    EXPECT_NE(readBytes(dir.file("out/summary.json")).find("\"retrace_voxels\": 1,\n"), std::string::npos);
    EXPECT_NE(readBytes(dir.file("out/summary.json")).find("\"slide_voxels\": 0.5,\n"), std::string::npos);
    EXPECT_EQ(r.output.find("note: up to"), std::string::npos) << r.output;
    // At the default tolerance the passes pile quads in the cells: a note
    // says so, and what the slider does.
    writeText(dir.file("fine.txt"), "iso 0\nkerf 0.5\npath " + path + "\nquit\n");
    const test::RunResult fine = runView(ball + " --size 320x240 --script " + dir.file("fine.txt"));
    ASSERT_EQ(fine.exitCode, 0) << fine.output;
    EXPECT_TRUE(std::regex_search(fine.output, std::regex(R"(note: up to \d+ quads cross one cut cell .*; the retrace slider at 1 \(--retrace 1\) lays one only)")))
        << fine.output;

    const test::RunResult bad = runView(ball + " --retrace 9");
    EXPECT_EQ(bad.exitCode, 2) << bad.output;
    EXPECT_NE(bad.output.find("mtcut-view: error: --retrace 9: expected a tolerance from 0 to 4 voxels"), std::string::npos)
        << bad.output;
    writeText(dir.file("bad.txt"), "iso 0\nretrace 9\nquit\n");
    const test::RunResult badLine = runView(ball + " --script " + dir.file("bad.txt"));
    EXPECT_EQ(badLine.exitCode, 2) << badLine.output;
    EXPECT_NE(badLine.output.find("bad.txt:2: retrace 9: expected a tolerance from 0 to 4 voxels"), std::string::npos)
        << badLine.output;
    EXPECT_EQ(badLine.output.find("opened"), std::string::npos) << "stops before opening anything:\n" << badLine.output;
    const test::RunResult badSlide = runView(ball + " --slide 9");
    EXPECT_EQ(badSlide.exitCode, 2) << badSlide.output;
    EXPECT_NE(badSlide.output.find("mtcut-view: error: --slide 9: expected a tolerance from 0 to 4 voxels"),
              std::string::npos)
        << badSlide.output;
    writeText(dir.file("badslide.txt"), "iso 0\nslide 4.5\nquit\n");
    const test::RunResult badSlideLine = runView(ball + " --script " + dir.file("badslide.txt"));
    EXPECT_EQ(badSlideLine.exitCode, 2) << badSlideLine.output;
    EXPECT_NE(badSlideLine.output.find("badslide.txt:2: slide 4.5: expected a tolerance from 0 to 4 voxels"),
              std::string::npos)
        << badSlideLine.output;
}

// A haptic device's stream (--poses stdin), its strokes cut live: the ball
// cut in two by a stroke at kerf 0, then by the tilted-blade stroke above,
// whose quads overlap the first's inside the ball. Its first poses (in air,
// x < -18 mm; the ball's radius is 15) come; the rest only once the viewer
// has cut them (its script writes a window shot a second after it started,
// which the feeder waits for, so how long the viewer takes to start does
// not matter): the live stroke keeps what it had and stops at the refusal,
// with a message. `wait poses` lets the script export only once the stream has
// ended and is cut. The second stroke's kept quads are in air, so the
// fragments are those of `mtcut cut` of the first stroke alone, file for
// file, and summary.json lists the second as cut in part.
TEST(ViewPoses, AStreamedStrokeThatIsRefusedStopsThereAndTheSummarySaysSo)
{
    if (std::system("command -v xvfb-run > /dev/null 2>&1") != 0) GTEST_SKIP() << "xvfb-run not found (apt-get install xvfb)";
    test::TempDir dir;
    const std::string ball = writeBall(dir);
    const std::vector<cutter::Pose> first = test::straightStroke({-25, 0.37, 22}, {25, 0.37, 22}, {0, 0, -1}, 45, 200);
    const std::vector<cutter::Pose> second =
        test::straightStroke({-25, 0.37, 22}, {25, 0.37, 22}, glm::normalize(glm::dvec3(0.02, 0, -1)), 45, 200);
    constexpr size_t kInAir = 25; // poses of the second stroke sent first: x up to -19 mm
    {
        std::ofstream f(dir.file("part1.csv"));
        cutter::writePath(f, {first, std::vector<cutter::Pose>(second.begin(), second.begin() + kInAir)});
        std::ofstream g(dir.file("part2.csv"));
        for (size_t i = kInAir; i < second.size(); ++i) g << cutter::formatPoseLine(second[i]) << '\n';
        g << "end\n";
        std::ofstream h(dir.file("first.csv"));
        cutter::writePath(h, {first});
    }
    const std::string ready = dir.file("ready.png"); // written atomically (renamed into place)
    writeText(dir.file("s.txt"), "wait 1\nwindow " + ready + "\nwait poses\nexport " + dir.file("out") + "\nquit\n");
    const test::RunResult r = runView(ball + " --iso 0 --size 320x240 --poses stdin --script " + dir.file("s.txt"),
                                      "cat " + dir.file("part1.csv") + "; i=0; while [ ! -f " + ready +
                                          " ] && [ $i -lt 1200 ]; do sleep 0.1; i=$((i+1)); done; cat " +
                                          dir.file("part2.csv"));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("cut refused, the stroke stops here: remesh: coplanar overlapping quads in cell ("),
              std::string::npos)
        << r.output;
    EXPECT_EQ(r.output.find("wait poses:"), std::string::npos) << r.output;

    const std::string json = readBytes(dir.file("out/summary.json"));
    std::smatch m;
    ASSERT_TRUE(std::regex_search(json, m, std::regex(R"("refused": \[\n    \{"stroke": 2, "quads_kept": (\d+), "quads": (\d+), "refused_at_t": null, "message": "remesh: coplanar overlapping quads in cell)")))
        << json;
    const int kept = std::stoi(m[1]), quads = std::stoi(m[2]);
    EXPECT_GT(kept, 0) << "the quads in air were cut before the rest came";
    EXPECT_LT(kept, quads);
    EXPECT_NE(json.find("\"stepped_round\": []"), std::string::npos) << json;

    const test::RunResult cut = test::runMtcut("cut " + ball + " --iso 0 --kerf 0 --path " + dir.file("first.csv") +
                                               " -o " + dir.file("cut") + " --check");
    ASSERT_EQ(cut.exitCode, 0) << cut.output;
    EXPECT_EQ(sameFragments(dir.file("out"), dir.file("cut")), 2u);

    // Without a stream, `wait poses` is an error message and the script goes
    // on; a wait for neither seconds nor poses stops it before it starts.
    writeText(dir.file("nostream.txt"), "wait poses\nquit\n");
    const test::RunResult none = runView(ball + " --iso 0 --size 320x240 --script " + dir.file("nostream.txt"));
    EXPECT_EQ(none.exitCode, 0) << none.output;
    EXPECT_NE(none.output.find("nostream.txt:1: wait poses: no pose stream (start with --poses stdin or --poses udp:PORT)"),
              std::string::npos)
        << none.output;
    writeText(dir.file("soon.txt"), "wait soon\n");
    const test::RunResult soon = runView(ball + " --script " + dir.file("soon.txt"));
    EXPECT_NE(soon.exitCode, 0);
    EXPECT_NE(soon.output.find("soon.txt:1: wait (seconds, or 'poses'): expected a number >= 0, got 'soon'"),
              std::string::npos)
        << soon.output;
}

// Ctrl+click (`pick`) selects the fragment under the cursor: the one whose
// id `mtcut render`'s EXR has at that pixel. "Save selected" (`export-selected`)
// then writes that fragment alone; a pick on the background selects nothing.
TEST_F(ViewScript, PickSelectsTheFragmentUnderTheCursorAndSavesIt)
{
    test::TempDir dir;
    // The fragment ids of the front view, from the command line's EXR.
    const std::string exr = dir.file("front.exr");
    const test::RunResult rr = test::runMtcut("render " + mHead + " --iso 400 --width 640 --height 480 --view front -o " + exr);
    ASSERT_EQ(rr.exitCode, 0) << rr.output;
    Imf::InputFile in(exr.c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    ASSERT_EQ(w, 640);
    ASSERT_EQ(h, 480);
    std::vector<uint32_t> ids(size_t(w) * size_t(h));
    Imf::FrameBuffer fb;
    fb.insert("fragment", Imf::Slice(Imf::UINT, reinterpret_cast<char*>(ids.data()), sizeof(uint32_t), sizeof(uint32_t) * size_t(w)));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    auto idAt = [&](int x, int y) { return ids[size_t(y) * size_t(w) + size_t(x)]; };
    // A pixel of a fragment other than the largest, inside it (its 4
    // neighbours agree), whose mirror images in x and y show something else:
    // a pick that reads the wrong pixel selects another fragment or none.
    int px = -1, py = -1;
    for (int y = 1; y + 1 < h && px < 0; ++y)
        for (int x = 1; x + 1 < w && px < 0; ++x) {
            const uint32_t id = idAt(x, y);
            if (id <= 1 || idAt(x - 1, y) != id || idAt(x + 1, y) != id || idAt(x, y - 1) != id || idAt(x, y + 1) != id) continue;
            if (idAt(x, h - 1 - y) == id || idAt(w - 1 - x, y) == id) continue;
            px = x;
            py = y;
        }
    ASSERT_GE(px, 0) << "no small fragment in the front view";
    const uint32_t id = idAt(px, py);

    writeText(dir.file("s.txt"), "iso 400\nview front\npick 3 3\npick " + std::to_string(px) + " " +
                                     std::to_string(py) + "\nexport-selected " + dir.file("out") + "\nquit\n");
    const test::RunResult r = runView(mHead + " --size 640x480 --script " + dir.file("s.txt"));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(r.output.find("error"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("pick: no fragment at pixel (3, 3)"), std::string::npos) << r.output;
    char name[32], said[48];
    std::snprintf(name, sizeof name, "fragment_%03u.stl", id - 1);
    std::snprintf(said, sizeof said, "fragment %03u selected", id - 1);
    EXPECT_NE(r.output.find(said), std::string::npos) << "picked at (" << px << ", " << py << ")\n" << r.output;
    size_t files = 0;
    for (const fs::directory_entry& e : fs::directory_iterator(dir.file("out"))) {
        const std::string f = e.path().filename().string();
        if (f.rfind("fragment_", 0) != 0) continue;
        ++files;
        EXPECT_EQ(f, name);
    }
    EXPECT_EQ(files, 1u) << r.output;
    EXPECT_TRUE(cutter::checkMesh(cutter::readMesh(dir.file(std::string("out/") + name))).ok());
    // Its level set in cut.vdb has its number too (it was fragment_000, by
    // its place among the saved ones).
    std::vector<std::string> grids;
    {
        openvdb::initialize();
        openvdb::io::File vdbFile(dir.file("out/cut.vdb"));
        vdbFile.open();
        for (auto it = vdbFile.beginName(); it != vdbFile.endName(); ++it) grids.push_back(it.gridName());
    }
    const std::string levelSet = std::string(name).substr(0, std::string(name).size() - 4);
    EXPECT_EQ(grids, (std::vector<std::string>{"carved", "cut_mask", levelSet}));

    writeText(dir.file("bad.txt"), "pick 3\n");
    const test::RunResult bad = runView(mHead + " --script " + dir.file("bad.txt"));
    EXPECT_NE(bad.exitCode, 0);
    EXPECT_NE(bad.output.find(":1: pick: expected X Y (pixels), got '3'"), std::string::npos) << bad.output;
    writeText(dir.file("bad2.txt"), "wait 0.1\nwait -2\n");
    const test::RunResult bad2 = runView(mHead + " --script " + dir.file("bad2.txt"));
    EXPECT_NE(bad2.exitCode, 0);
    EXPECT_NE(bad2.output.find(":2: wait"), std::string::npos) << bad2.output;
}

TEST_F(ViewScript, UnknownActionStopsWithItsLineNumber)
{
    test::TempDir dir;
    writeText(dir.file("bad.txt"), "view front\n\n# comment\nfrobnicate 3\nquit\n");
    const test::RunResult r = runView(mHead + " --script " + dir.file("bad.txt"));
    EXPECT_NE(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find(dir.file("bad.txt") + ":4: unknown action 'frobnicate'"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("opened"), std::string::npos) << "stops before opening anything:\n" << r.output;

    writeText(dir.file("badiso.txt"), "iso\n");
    const test::RunResult r2 = runView(mHead + " --script " + dir.file("badiso.txt"));
    EXPECT_NE(r2.exitCode, 0) << r2.output;
    EXPECT_NE(r2.output.find(dir.file("badiso.txt") + ":1: iso needs an argument"), std::string::npos) << r2.output;
}

TEST_F(ViewScript, MissingFilesAreMessagesAndTheViewerGoesOn)
{
    test::TempDir dir;
    // A path file that does not exist, then a screenshot: the session goes on.
    writeText(dir.file("s.txt"), "path " + dir.file("nowhere.csv") + "\nundo\nscreenshot " + dir.file("after.png") +
                                     "\nscreenshot " + dir.file("x.bmp") + "\nquit\n");
    const test::RunResult r = runView(mHead + " --size 640x480 --script " + dir.file("s.txt"));
    EXPECT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("error: " + dir.file("s.txt") + ":1: "), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("nowhere.csv"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("nothing to undo"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(":4: screenshot " + dir.file("x.bmp") + ": expected a .png or .exr"), std::string::npos)
        << r.output;
    EXPECT_TRUE(fs::exists(dir.file("after.png"))) << r.output;

    // A scan that does not load: a message, the window stays (the script runs to its end).
    const test::RunResult r2 = runView(dir.file("missing.nrrd") + " --size 640x480 --script " + dir.file("s.txt"));
    EXPECT_EQ(r2.exitCode, 0) << r2.output;
    EXPECT_NE(r2.output.find("error: " + dir.file("missing.nrrd")), std::string::npos) << r2.output;
    EXPECT_NE(r2.output.find("screenshot " + dir.file("x.bmp")), std::string::npos) << r2.output;
}
