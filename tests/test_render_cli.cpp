// mtcut render: PNG and EXR frames of a small phantom, uncut and cut along
// the phantom's LeFort path, and one-line errors (no file left) on bad input.
#include "render/Frame.h"
#include "tests/TestUtil.h"
#include "tests/test_render_util.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <half.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <map>
#include <set>

using namespace mtcut;
namespace fs = std::filesystem;

namespace {

class RenderCli : public ::testing::Test
{
protected:
    static void SetUpTestSuite()
    {
        sDir = std::make_unique<test::TempDir>();
        sPhantom = sDir->file("phantom.vdb");
        const test::RunResult r = test::runMtcut("phantom " + sPhantom + " --size 128,128,64");
        ASSERT_EQ(r.exitCode, 0) << r.output;
    }
    static void TearDownTestSuite() { sDir.reset(); }

    void SetUp() override { MTCUT_REQUIRE_GL(); } // the command needs the same EGL as the tests

    static std::string lefortPath() { return std::string(MTCUT_SOURCE_ROOT) + "/tools/phantom_lefort.csv"; }

    /// Pixels not transparent.
    static size_t coveredPixels(const render::Frame& f)
    {
        size_t n = 0;
        for (size_t p = 0; p < f.pixelCount(); ++p) n += f.rgba[4 * p + 3] != 0;
        return n;
    }
    /// Reddish pixels: the highlight colour (0.85, 0.20, 0.16) shaded, or half-way to it.
    static size_t highlightPixels(const render::Frame& f)
    {
        size_t n = 0;
        for (size_t p = 0; p < f.pixelCount(); ++p) {
            const int r = f.rgba[4 * p], g = f.rgba[4 * p + 1];
            n += f.rgba[4 * p + 3] != 0 && r > g + 40;
        }
        return n;
    }

    /// Runs a command that must fail: exit 1, one line naming `needle`, and
    /// `output` not written.
    static void expectError(const std::string& args, const std::string& needle, const std::string& output)
    {
        const test::RunResult r = test::runMtcut(args);
        EXPECT_EQ(r.exitCode, 1) << args << "\n" << r.output;
        EXPECT_NE(r.output.find("mtcut: error: "), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(needle), std::string::npos) << r.output;
        EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << "one line:\n" << r.output;
        EXPECT_FALSE(fs::exists(output)) << args;
    }

    static std::unique_ptr<test::TempDir> sDir;
    static std::string sPhantom;
};

std::unique_ptr<test::TempDir> RenderCli::sDir;
std::string RenderCli::sPhantom;

} // namespace

TEST_F(RenderCli, PngOfTheUncutSurface)
{
    const std::string out = sDir->file("front.png");
    const test::RunResult r = test::runMtcut("render " + sPhantom + " --iso 400 -o " + out + " --width 160 --height 120");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_NE(r.output.find("wrote:      " + out + " (160x120)"), std::string::npos) << r.output;
    const render::Frame f = render::readPng(out);
    EXPECT_EQ(f.width, 160);
    EXPECT_EQ(f.height, 120);
    // The skull fills a good part of the frame, centred, and nothing is highlighted.
    const size_t covered = coveredPixels(f);
    EXPECT_GT(covered, f.pixelCount() / 10);
    EXPECT_LT(covered, f.pixelCount() * 9 / 10);
    EXPECT_NE(f.rgba[4 * (60 * 160 + 80) + 3], 0) << "centre pixel";
    EXPECT_EQ(f.rgba[3], 0) << "corner pixel";
    EXPECT_EQ(highlightPixels(f), 0u);
}

TEST_F(RenderCli, ExrHasTheDocumentedChannels)
{
    const std::string out = sDir->file("cut.exr");
    // mtcut cut on the same scan and path: its fragment count, or its refusal.
    const test::RunResult cut = test::runMtcut("cut " + sPhantom + " --iso 400 --path " + lefortPath() + " -o " +
                                               sDir->file("cutdir"));
    const test::RunResult r = test::runMtcut("render " + sPhantom + " --iso 400 --path " + lefortPath() + " -o " + out +
                                             " --width 96 --height 80 --view iso");
    if (cut.exitCode != 0) { // the re-mesher refused the stroke: render says the same, writes nothing
        EXPECT_EQ(r.exitCode, 1) << r.output;
        EXPECT_NE(r.output.find("remesh"), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(out));
        GTEST_SKIP() << "the re-mesher refuses the phantom's LeFort stroke at this size: " << cut.output;
    }
    ASSERT_EQ(r.exitCode, 0) << r.output;
    const size_t at = cut.output.find(" fragment(s)");
    ASSERT_NE(at, std::string::npos) << cut.output;
    const size_t comma = cut.output.rfind(", ", at);
    const unsigned cutFragments = unsigned(std::stoul(cut.output.substr(comma + 2, at - comma - 2)));
    Imf::InputFile in(out.c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    EXPECT_EQ(w, 96);
    EXPECT_EQ(h, 80);
    std::map<std::string, Imf::PixelType> channels;
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
        channels[it.name()] = it.channel().type;
    }
    const std::map<std::string, Imf::PixelType> expected = {
        {"R", Imf::HALF},    {"G", Imf::HALF},    {"B", Imf::HALF},    {"A", Imf::HALF},       {"Z", Imf::FLOAT},
        {"N.X", Imf::FLOAT}, {"N.Y", Imf::FLOAT}, {"N.Z", Imf::FLOAT}, {"fragment", Imf::UINT}};
    EXPECT_EQ(channels, expected);

    const size_t n = size_t(w) * size_t(h);
    std::vector<half> alpha(n);
    std::vector<float> z(n), nx(n), ny(n), nz(n);
    std::vector<uint32_t> fragment(n);
    Imf::FrameBuffer fb;
    auto slice = [&](Imf::PixelType t, void* base, size_t size) {
        return Imf::Slice(t, static_cast<char*>(base) - (dw.min.x + size_t(dw.min.y) * w) * size, size, size * size_t(w));
    };
    fb.insert("A", slice(Imf::HALF, alpha.data(), sizeof(half)));
    fb.insert("Z", slice(Imf::FLOAT, z.data(), sizeof(float)));
    fb.insert("N.X", slice(Imf::FLOAT, nx.data(), sizeof(float)));
    fb.insert("N.Y", slice(Imf::FLOAT, ny.data(), sizeof(float)));
    fb.insert("N.Z", slice(Imf::FLOAT, nz.data(), sizeof(float)));
    fb.insert("fragment", slice(Imf::UINT, fragment.data(), sizeof(uint32_t)));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    size_t covered = 0;
    std::set<uint32_t> ids;
    for (size_t p = 0; p < n; ++p) {
        const bool c = float(alpha[p]) > 0.0f;
        covered += c;
        EXPECT_EQ(c, fragment[p] != 0) << p;
        if (c) {
            ids.insert(fragment[p]);
            EXPECT_TRUE(std::isfinite(z[p]) && z[p] > 0.0f) << p;
            EXPECT_NEAR(std::sqrt(nx[p] * nx[p] + ny[p] * ny[p] + nz[p] * nz[p]), 1.0, 1e-3) << p;
        } else {
            EXPECT_TRUE(std::isinf(z[p])) << p;
            EXPECT_EQ(nx[p], 0.0f);
        }
    }
    EXPECT_GT(covered, n / 10);
    // As many fragments as `mtcut cut` writes (the LeFort cut adds the
    // maxilla: 9 on this phantom today), ids 1..N, the skull (1) seen.
    EXPECT_NE(r.output.find(", " + std::to_string(cutFragments) + " fragment(s)"), std::string::npos)
        << r.output << "\nmtcut cut: " << cut.output;
    EXPECT_TRUE(ids.count(1));
    EXPECT_LE(*ids.rbegin(), cutFragments);
}

TEST_F(RenderCli, HighlightColoursTheCut)
{
    const std::string plain = sDir->file("plain.png"), lit = sDir->file("lit.png");
    // Close to the maxilla, where the LeFort stroke runs.
    const std::string view = " --view=-90,-220,30:0,-60,-25:0,0,1:22 --width 140 --height 100";
    const std::string base = "render " + sPhantom + " --iso 400 --path " + lefortPath();
    const test::RunResult first = test::runMtcut(base + " -o " + plain + view);
    if (first.exitCode != 0 && first.output.find("remesh") != std::string::npos) {
        GTEST_SKIP() << "the re-mesher refuses the phantom's LeFort stroke at this size: " << first.output;
    }
    ASSERT_EQ(first.exitCode, 0) << first.output;
    const test::RunResult r = test::runMtcut(base + " --highlight -o " + lit + view);
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_EQ(highlightPixels(render::readPng(plain)), 0u);
    EXPECT_GT(highlightPixels(render::readPng(lit)), 40u);
}

TEST_F(RenderCli, BadArgumentsFailWithOneLineAndNoFile)
{
    const std::string out = sDir->file("bad.png");
    const std::string base = "render " + sPhantom + " --iso 400 ";
    expectError(base + "-o " + out + " --view diagonal", "--view diagonal", out);
    expectError(base + "-o " + out + " --view 1,2,3:1,2,3", "eye and target", out);
    expectError(base + "-o " + out + " --view 0,-9,0:0,0,0:0,1,0", "parallel", out);
    expectError(base + "-o " + out + " --view 0,-9,0:0,0,x", "not a finite number", out);
    expectError(base + "-o " + out + " --width 0", "--width 0", out);
    expectError(base + "-o " + out + " --height 100000", "--height 100000", out);
    expectError(base + "-o " + out + " --width 12x", "--width 12x", out);
    expectError(base + "-o " + sDir->file("bad.jpg"), "expected a .png or .exr", sDir->file("bad.jpg"));
    expectError(base + "-o " + sDir->file("missing/x.png"), "does not exist", sDir->file("missing/x.png"));
    {
        std::ofstream(sDir->file("afile")) << "x";
        expectError(base + "-o " + sDir->file("afile/x.png"), "does not exist", sDir->file("afile/x.png"));
    }
    expectError(base + "-o " + out + " --kerf 0.5", "--kerf needs --path", out);
    expectError(base + "-o " + out + " --kerf -1 --path " + lefortPath(), "--kerf -1", out);
    expectError(base + "-o " + out + " --kerf 21 --path " + lefortPath(), "--kerf 21: expected a saw width from 0 to 20 mm", out);
    expectError(base + "-o " + out + " --retrace 1", "--retrace needs --path", out);
    expectError(base + "-o " + out + " --retrace 5 --path " + lefortPath(),
                "--retrace 5: expected a tolerance from 0 to 4 voxels (default 0.25)", out);
    expectError(base + "-o " + out + " --slide 1", "--slide needs --path", out);
    expectError(base + "-o " + out + " --slide -0.5 --path " + lefortPath(),
                "--slide -0.5: expected a tolerance from 0 to 4 voxels (default 0.25)", out);
    expectError("render " + sPhantom + " -o " + out, "needs --iso", out);
    expectError("render " + sDir->file("nope.vdb") + " --iso 400 -o " + out, "nope.vdb", out);
    expectError(base + "-o " + out + " --path " + sDir->file("nope.csv"), "nope.csv", out);
    // No temporary files left behind either.
    for (const auto& e : fs::directory_iterator(sDir->path())) {
        EXPECT_EQ(e.path().filename().string().find("tmp"), std::string::npos) << e.path();
    }
}

// --gpu-cut: the cut geometry made by the GPU cut pass and drawn from its
// own output gives the same EXR as the CPU re-mesher's (colour, depth,
// normals, fragment ids, bit for bit: the same triangles and normals), and
// the command says the recovered geometry is the CPU's in every cell, and how
// many of the pass's programs came from the program cache.
TEST_F(RenderCli, GpuCutPassDrawsTheSameFrame)
{
    { // without a cut there is nothing for the pass to make, and it says so
        const test::RunResult r = test::runMtcut("render " + sPhantom + " --iso 400 --width 64 --height 64 -o " +
                                                 sDir->file("uncut.exr") + " --gpu-cut");
        ASSERT_EQ(r.exitCode, 0) << r.output;
        EXPECT_NE(r.output.find("--gpu-cut: no cut (no --path given)"), std::string::npos) << r.output;
    }
    for (const char* kerf : {"", " --kerf 0.5"}) {
        const std::string cpu = sDir->file("cpu.exr"), gpu = sDir->file("gpu.exr");
        const std::string args = " --iso 400 --path " + lefortPath() + kerf + " --width 128 --height 128 --view iso --highlight";
        const test::RunResult a = test::runMtcut("render " + sPhantom + args + " -o " + cpu);
        if (a.exitCode != 0) GTEST_SKIP() << "the re-mesher refuses the phantom's LeFort stroke: " << a.output;
        const test::RunResult b = test::runMtcut("render " + sPhantom + args + " -o " + gpu + " --gpu-cut");
        ASSERT_EQ(b.exitCode, 0) << b.output;
        EXPECT_NE(b.output.find("recovered geometry equal to the CPU's in every cell"), std::string::npos) << b.output;
        EXPECT_NE(b.output.find("the CPU's mesh;"), std::string::npos) << b.output; // the recovered cells fused
        EXPECT_NE(b.output.find(" of 5 from the program cache)"), std::string::npos) << b.output; // where they came from
        std::ifstream fa(cpu, std::ios::binary), fb(gpu, std::ios::binary);
        const std::string da((std::istreambuf_iterator<char>(fa)), {}), db((std::istreambuf_iterator<char>(fb)), {});
        EXPECT_FALSE(da.empty());
        EXPECT_TRUE(da == db) << "the EXRs differ" << kerf;
    }
}
