// The GL foundation of render/: a headless GL 4.5 core context (EGL), the
// embedded shaders, compile/link errors with the info log, move-only GL objects.
#include "render/Context.h"
#include "render/CutKernelGpu.h"
#include "render/GlObjects.h"
#include "render/Shaders.h"
#include "tests/TestUtil.h"
#include "tests/test_render_util.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <type_traits>

using namespace mtcut::render;

TEST(RenderGl, HeadlessContextIsGl45Core)
{
    MTCUT_REQUIRE_GL();
    EXPECT_GE(epoxy_gl_version(), 45);
    GLint profile = 0;
    glGetIntegerv(GL_CONTEXT_PROFILE_MASK, &profile);
    EXPECT_TRUE(profile & GL_CONTEXT_CORE_PROFILE_BIT);
    GLint drawBuffers = 0;
    glGetIntegerv(GL_MAX_DRAW_BUFFERS, &drawBuffers);
    EXPECT_GE(drawBuffers, 4); // the mask coding writes 4 integer attachments
    EXPECT_EQ(glGetError(), GLenum(GL_NO_ERROR));
}

TEST(RenderGl, EveryEmbeddedShaderCompiles)
{
    MTCUT_REQUIRE_GL();
    const std::vector<std::string> names = shaderNames();
    ASSERT_FALSE(names.empty());
    EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
    for (const std::string& name : names) {
        if (name.size() > 5 && name.substr(name.size() - 5) == ".glsl") continue; // libraries, prepended to others
        const std::string source = shaderSource(name);
        ASSERT_EQ(source.compare(0, 8, "#version"), 0) << name;
        // Every stage compiles with its libraries in front: the GPU cut
        // pass's (cut_*: cutPassLibrary), poly2_*'s (poly2.glsl), none for
        // doubles_test.comp (its #extension must come first), else the mask
        // lookup.
        const std::string library = name.compare(0, 4, "cut_") == 0     ? cutPassLibrary(name)
                                    : name.compare(0, 6, "poly2_") == 0 ? poly2Library()
                                    : name == "doubles_test.comp"       ? shaderSource("doubles.glsl")
                                                                        : shaderSource("mask.glsl");
        EXPECT_NO_THROW(Shader(shaderStageOf(name), withDefines(source, library), name)) << name;
    }
}

namespace {
/// The cut pass's shader files (programs and libraries), name and source,
/// and their lines' code without the // comment.
std::vector<std::pair<std::string, std::string>> cutPassSources()
{
    std::vector<std::pair<std::string, std::string>> files;
    for (const std::string& name : shaderNames())
        if (name.compare(0, 4, "cut_") == 0 || name == "poly2.glsl" || name == "doubles.glsl")
            files.push_back({name, shaderSource(name)});
    return files;
}
std::string codeOf(const std::string& line) { return line.substr(0, line.find("//")); }
} // namespace

// NVIDIA's driver (580.159.04, H100) keeps a 64-bit value in a private array
// (a function's or a global's, a parameter, a member of a private struct) with
// 32 bits: doubles come back rounded to float, uint64_t changed
// (RenderPoly2.DoublesReachTheShaderUnrounded), and the cut pass's names
// differed from the CPU's there. The GPU pass's shaders keep such arrays as
// uvec2 bits (cut_kernel.glsl's D*GET and u64); this holds them to it on
// every driver, llvmpipe included, where the rounding never shows. Buffers
// are exempt, and so is a struct only buffers hold: one with an array member
// and a 64-bit member must never be copied into a private variable (the H200,
// same driver, changed the double of a private copy of such a query struct:
// the dim 3 vertices of VertexPositionsFromNames... differed, all of them).
TEST(RenderGl, CutPassKeepsNo64BitValueInAPrivateArray)
{
    const std::regex array64(R"(\b(double|dvec[234]|dmat[234](x[234])?|u?int64_t|[iu]64vec[234])\s+\w+\s*\[)");
    const std::regex scalar64(R"(\b(double|dvec[234]|dmat[234](x[234])?|u?int64_t|[iu]64vec[234])\s+\w+)");
    const auto files = cutPassSources();
    // The structs that hold an array and a 64-bit value: buffers' only.
    std::set<std::string> bufferOnly;
    for (const auto& [name, source] : files) {
        std::istringstream text(source);
        std::string line, inStruct;
        bool array = false, wide = false;
        while (std::getline(text, line)) {
            std::smatch m;
            if (std::regex_search(line, m, std::regex(R"(^struct (\w+))"))) inStruct = m[1], array = wide = false;
            if (inStruct.empty()) continue;
            array = array || codeOf(line).find('[') != std::string::npos;
            wide = wide || std::regex_search(codeOf(line), scalar64);
            if (line.compare(0, 2, "};") != 0) continue;
            if (array && wide) bufferOnly.insert(inStruct);
            inStruct.clear();
        }
    }
    EXPECT_EQ(bufferOnly, (std::set<std::string>{"KernelSide", "NameQuery", "VertexQuery"})); // the rule reads them
    for (const auto& [name, source] : files) {
        std::istringstream text(source);
        std::string line, inStruct;
        for (int n = 1; std::getline(text, line); ++n) {
            std::smatch m;
            if (std::regex_search(line, m, std::regex(R"(^struct (\w+))"))) inStruct = m[1];
            if (line.compare(0, 2, "};") == 0) inStruct.clear();
            for (const std::string& s : bufferOnly) // a private copy of one would be a private array
                EXPECT_FALSE(std::regex_search(codeOf(line), std::regex("\\b" + s + R"(\s+\w+\s*[=;])")))
                    << name << ":" << n << ": a private " << s << ": " << line;
            if (line.find("buffer ") != std::string::npos || bufferOnly.count(inStruct)) continue;
            EXPECT_FALSE(std::regex_search(codeOf(line), array64)) << name << ":" << n << ": " << line;
        }
    }
    EXPECT_GE(files.size(), 10u); // the libraries and programs of the cut pass were read
}

// The cut pass decides as the CPU does on the same doubles, so every sum of
// products is written out under `precise` (dot3, cross3, planeH in
// cut_kernel.glsl): a driver may evaluate the builtins dot, cross, length,
// distance, normalize with fused multiply-adds, which round differently
// (NVIDIA's sqrt already did: dSqrt). Builtins are left to float shading
// only: a line of the cut shaders that calls one must declare a float.
TEST(RenderGl, CutPassCallsNoGeometricBuiltinOnDoubles)
{
    const std::regex builtin(R"((^|[^\w.])(dot|cross|length|distance|normalize|fma|faceforward|reflect)\s*\()");
    const std::regex floatDecl(R"(^\s*(const\s+)?(float|vec[234])\s+\w+\s*=)");
    const auto files = cutPassSources();
    size_t floatCalls = 0;
    for (const auto& [name, source] : files) {
        std::istringstream text(source);
        std::string line;
        for (int n = 1; std::getline(text, line); ++n) {
            const std::string code = codeOf(line);
            if (!std::regex_search(code, builtin)) continue;
            const bool isFloat = std::regex_search(code, floatDecl);
            floatCalls += isFloat;
            EXPECT_TRUE(isFloat) << name << ":" << n << ": " << line;
        }
    }
    EXPECT_GE(files.size(), 10u);
    EXPECT_GE(floatCalls, 2u); // the shading normal's cross and length (cut_regions.glsl): the rule reads calls
}

TEST(RenderGl, BrokenShaderReportsItsInfoLog)
{
    MTCUT_REQUIRE_GL();
    const std::string broken = "#version 450 core\nout vec4 c;\nvoid main() { c = undefinedThing; }\n";
    try {
        buildProgram({ShaderText{"broken.frag", broken}});
        FAIL() << "a broken shader compiled";
    } catch (const std::runtime_error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("broken.frag: compile error"), std::string::npos) << what;
        EXPECT_NE(what.find("undefinedThing"), std::string::npos) << what; // the driver's log itself
    }
    // A link error: a fragment input no vertex shader writes with that type.
    const std::string vert = "#version 450 core\nout float v;\nvoid main() { v = 1.0; gl_Position = vec4(0); }\n";
    const std::string frag = "#version 450 core\nin vec3 v;\nout vec4 c;\nvoid main() { c = vec4(v, 1); }\n";
    try {
        buildProgram({ShaderText{"a.vert", vert}, ShaderText{"b.frag", frag}});
        FAIL() << "mismatched stages linked";
    } catch (const std::runtime_error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("a.vert+b.frag: link error:\n"), std::string::npos) << what;
        EXPECT_GT(what.size(), std::string("a.vert+b.frag: link error:\n").size()) << "empty info log";
    }
    // Unknown files and stages say so.
    EXPECT_THROW(shaderSource("nope.frag"), std::runtime_error);
    EXPECT_THROW(shaderStageOf("x.txt"), std::runtime_error);
}

// The GPU cut pass checks its storage layouts when it compiles (the host's
// scratch sizes against cut_arrange.glsl's, cut_regions.glsl's layout
// against both) with an array whose size is -1 when they differ: this
// driver must refuse such an array, or those checks check nothing.
TEST(RenderGl, AnArrayOfSizeMinusOneDoesNotCompile)
{
    MTCUT_REQUIRE_GL();
    const std::string source = "#version 450 core\nconst uint kA = 3u, kB = 4u;\nint gCheck[kA == kB ? 1 : -1];\n"
                               "out vec4 c;\nvoid main() { c = vec4(0.0); }\n";
    EXPECT_THROW(Shader(GL_FRAGMENT_SHADER, source, "check.frag"), std::runtime_error);
    const std::string same = "#version 450 core\nconst uint kA = 4u, kB = 4u;\nint gCheck[kA == kB ? 1 : -1];\n"
                             "out vec4 c;\nvoid main() { c = vec4(0.0); }\n";
    EXPECT_NO_THROW(Shader(GL_FRAGMENT_SHADER, same, "check.frag"));
}

TEST(RenderGl, DefinesGoAfterTheVersionLineAndKeepLineNumbers)
{
    MTCUT_REQUIRE_GL();
    const std::string src = "#version 450 core\nout vec4 c;\nvoid main() { c = vec4(VALUE); }\n";
    EXPECT_EQ(withDefines(src, "#define VALUE 1.0"),
              "#version 450 core\n#define VALUE 1.0\n#line 2\nout vec4 c;\nvoid main() { c = vec4(VALUE); }\n");
    EXPECT_NO_THROW(buildProgram({ShaderText{"v.frag", withDefines(src, "#define VALUE 1.0")}}));
    // The error names line 3 of the file, whatever was inserted.
    try {
        buildProgram({ShaderText{"v.frag", withDefines(src, "#define A 1\n#define B 2\n")}});
        FAIL();
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("3"), std::string::npos) << e.what();
    }
}

TEST(RenderGl, ObjectsAreMoveOnlyAndFreeTheirNames)
{
    static_assert(!std::is_copy_constructible_v<Buffer> && !std::is_copy_assignable_v<Buffer>);
    static_assert(std::is_nothrow_move_constructible_v<Buffer> && std::is_nothrow_move_assignable_v<Texture>);
    static_assert(!std::is_copy_constructible_v<Program> && !std::is_copy_constructible_v<Framebuffer>);
    static_assert(!std::is_copy_constructible_v<VertexArray> && !std::is_copy_constructible_v<Query>);
    static_assert(!std::is_copy_constructible_v<Renderbuffer> && !std::is_copy_constructible_v<Shader>);
    MTCUT_REQUIRE_GL();
    GLuint bufferId = 0, textureId = 0;
    {
        Buffer a(16, nullptr);
        bufferId = a.id();
        ASSERT_TRUE(glIsBuffer(bufferId));
        Buffer b = std::move(a);
        EXPECT_EQ(a.id(), 0u);
        EXPECT_EQ(b.id(), bufferId);
        Texture t(GL_TEXTURE_2D);
        textureId = t.id();
        Texture u(GL_TEXTURE_2D);
        u = std::move(t); // u's own name is freed here
        EXPECT_EQ(u.id(), textureId);
        EXPECT_TRUE(glIsTexture(textureId));
        Framebuffer f;
        Renderbuffer r(GL_RGBA8, 4, 4);
        VertexArray v;
        Query q(GL_SAMPLES_PASSED);
        EXPECT_NE(f.id(), 0u);
        EXPECT_NE(r.id(), 0u);
        EXPECT_NE(v.id(), 0u);
        EXPECT_NE(q.id(), 0u);
    }
    EXPECT_FALSE(glIsBuffer(bufferId));
    EXPECT_FALSE(glIsTexture(textureId));
    EXPECT_NO_THROW(checkGlError("objects"));
}


namespace {

/// Sets an environment variable for the scope, restoring it after.
class ScopedEnv
{
public:
    ScopedEnv(const char* name, const char* value) : mName(name)
    {
        const char* old = std::getenv(name);
        mHad = old != nullptr;
        if (old) mOld = old;
        ::setenv(name, value, 1);
    }
    ~ScopedEnv()
    {
        if (mHad) ::setenv(mName.c_str(), mOld.c_str(), 1); else ::unsetenv(mName.c_str());
    }

private:
    std::string mName;
    bool mHad = false;
    std::string mOld;
};

} // namespace

TEST(RenderGl, ShaderPreambleFromTheEnvironmentGoesInFrontOfEveryEmbeddedShader)
{
    MTCUT_REQUIRE_GL();
    const std::vector<std::string> files{"surface.vert", "surface.frag"};
    EXPECT_NO_THROW(buildProgram(files));
    {
        // Not GLSL: the build must fail, naming the first stage, so the
        // text did reach the compiler.
        ScopedEnv env("MTCUT_SHADER_PREAMBLE", "this is not glsl");
        try {
            buildProgram(files);
            FAIL() << "the preamble was not inserted";
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find("surface.vert: compile error"), std::string::npos) << e.what();
        }
    }
    {
        // A pragma the driver ignores, then the program's own defines: builds.
        ScopedEnv env("MTCUT_SHADER_PREAMBLE", "#pragma optionNV(fastmath off)");
        EXPECT_NO_THROW(buildProgram(files));
    }
    {
        ScopedEnv env("MTCUT_SHADER_PREAMBLE", ""); // empty: nothing inserted
        EXPECT_NO_THROW(buildProgram(files));
    }
}

namespace {

/// A compute program writing `value` to binding 0, built with buildProgram.
Program valueProgram(unsigned value)
{
    const std::string source = "#version 450 core\nlayout(local_size_x = 1) in;\n"
                               "layout(std430, binding = 0) writeonly buffer Out { uint uOut; };\n"
                               "void main() { uOut = " + std::to_string(value) + "u; }\n";
    return buildProgram({ShaderText{"value.comp", source}});
}

/// What `p` writes.
unsigned run(const Program& p)
{
    const unsigned zero = 0;
    Buffer out(sizeof zero, &zero, GL_MAP_READ_BIT);
    p.use();
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, out.id());
    glDispatchCompute(1, 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    unsigned v = 0;
    glGetNamedBufferSubData(out.id(), 0, sizeof v, &v);
    glUseProgram(0);
    return v;
}

} // namespace

// buildProgram's binary cache: a slow program is kept (here every program:
// minBuildMs 0) and taken from its file the next time, and it runs as built;
// another source is another file; a damaged file or one of another driver is
// refused, built again and replaced; with no folder nothing is written.
TEST(RenderGl, SlowProgramsAreKeptOnDiskAndTakenFromThereNextTime)
{
    MTCUT_REQUIRE_GL();
    GLint formats = 0;
    glGetIntegerv(GL_NUM_PROGRAM_BINARY_FORMATS, &formats);
    if (formats == 0) GTEST_SKIP() << "this driver gives no program binaries (GL_NUM_PROGRAM_BINARY_FORMATS 0)";
    const mtcut::test::TempDir dir;
    const ProgramCache before = programCache();
    struct Restore
    {
        ProgramCache c;
        ~Restore() { setProgramCache(c); }
    } restore{before};
    setProgramCache({dir.path() + "/programs", 0.0});
    const auto files = [&] {
        std::vector<std::filesystem::path> out;
        for (const auto& e : std::filesystem::directory_iterator(dir.path() + "/programs")) out.push_back(e.path());
        return out;
    };
    const ProgramCacheCounts c0 = programCacheCounts();
    EXPECT_EQ(run(valueProgram(17)), 17u);
    ProgramCacheCounts c = programCacheCounts();
    EXPECT_EQ(c.stored - c0.stored, 1u);
    EXPECT_EQ(c.loaded - c0.loaded, 0u);
    ASSERT_EQ(files().size(), 1u);
    const std::filesystem::path file = files()[0];
    EXPECT_EQ(file.extension(), ".bin");

    EXPECT_EQ(run(valueProgram(17)), 17u); // from the file
    c = programCacheCounts();
    EXPECT_EQ(c.loaded - c0.loaded, 1u);
    EXPECT_EQ(c.stored - c0.stored, 1u);

    EXPECT_EQ(run(valueProgram(18)), 18u); // another source: another file
    c = programCacheCounts();
    EXPECT_EQ(c.stored - c0.stored, 2u);
    EXPECT_EQ(files().size(), 2u);

    { // the check hash damaged (as a file of another source with the same name would be)
        std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(8);
        f.put('\x55');
    }
    EXPECT_EQ(run(valueProgram(17)), 17u);
    c = programCacheCounts();
    EXPECT_EQ(c.refused - c0.refused, 1u);
    EXPECT_EQ(c.stored - c0.stored, 3u); // replaced
    EXPECT_EQ(run(valueProgram(17)), 17u);
    EXPECT_EQ(programCacheCounts().loaded - c0.loaded, 2u);

    { // the driver's bytes damaged: the driver must refuse them, or they must still run as built
        std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(28);
        for (int i = 0; i < 64; ++i) f.put('\xff');
    }
    EXPECT_EQ(run(valueProgram(17)), 17u);
    { // cut short: refused without asking the driver
        std::filesystem::resize_file(file, 30);
    }
    const size_t refusedBefore = programCacheCounts().refused;
    EXPECT_EQ(run(valueProgram(17)), 17u);
    EXPECT_EQ(programCacheCounts().refused, refusedBefore + 1);
    EXPECT_GT(std::filesystem::file_size(file), 30u); // replaced
    EXPECT_EQ(glGetError(), GLenum(GL_NO_ERROR));

    setProgramCache({"", 0.0}); // no folder: nothing read or written
    const ProgramCacheCounts c1 = programCacheCounts();
    EXPECT_EQ(run(valueProgram(17)), 17u);
    EXPECT_EQ(programCacheCounts().loaded, c1.loaded);
    EXPECT_EQ(programCacheCounts().stored, c1.stored);
    setProgramCache({dir.path() + "/slow", 60000.0}); // faster than minBuildMs: not kept
    EXPECT_EQ(run(valueProgram(19)), 19u);
    EXPECT_FALSE(std::filesystem::exists(dir.path() + "/slow"));

    setProgramCache({dir.path() + "/many", 0.0}); // the newest 32 files are kept
    for (unsigned v = 100; v < 136; ++v) EXPECT_EQ(run(valueProgram(v)), v);
    size_t kept = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir.path() + "/many")) kept += e.path().extension() == ".bin";
    EXPECT_EQ(kept, 32u);
    const size_t loaded = programCacheCounts().loaded;
    EXPECT_EQ(run(valueProgram(135)), 135u); // the newest is there
    EXPECT_EQ(programCacheCounts().loaded, loaded + 1);
}

TEST(RenderGl, EglPlatformIsHonoured)
{
    MTCUT_REQUIRE_GL();
    const std::string shared = mtcut::test::glContext(nullptr)->description();
    {
        ScopedEnv env("EGL_PLATFORM", "surfaceless");
        try {
            auto ctx = createHeadlessContext();
            EXPECT_EQ(ctx->description().rfind("EGL surfaceless: ", 0), 0u) << ctx->description();
            EXPECT_GE(epoxy_gl_version(), 45);
        } catch (const std::runtime_error& e) { // an EGL without Mesa's surfaceless platform (NVIDIA only)
            EXPECT_NE(std::string(e.what()).find("surfaceless"), std::string::npos) << e.what();
        }
    }
    {
        ScopedEnv env("EGL_PLATFORM", "device"); // any EGL device, Mesa's software one included
        try {
            auto ctx = createHeadlessContext();
            EXPECT_EQ(ctx->description().rfind("EGL device ", 0), 0u) << ctx->description();
            EXPECT_GE(epoxy_gl_version(), 45);
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find("device"), std::string::npos) << e.what();
        }
    }
    // The shared context survives the others (its display is not terminated under it).
    MTCUT_REQUIRE_GL();
    EXPECT_EQ(mtcut::test::glContext(nullptr)->description(), shared);
    Buffer b(64, nullptr);
    EXPECT_TRUE(glIsBuffer(b.id()));
    EXPECT_NO_THROW(checkGlError("after other contexts"));
}

TEST(RenderGl, UnknownEglPlatformFailsWithAMessage)
{
    // A platform no EGL knows: either a clear error naming it, or (some
    // drivers ignore the variable) a working context.
    MTCUT_REQUIRE_GL();
    {
        ScopedEnv env("EGL_PLATFORM", "no-such-platform");
        try {
            auto ctx = createHeadlessContext();
            EXPECT_GE(epoxy_gl_version(), 45);
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find("no headless OpenGL 4.5 core context"), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("EGL_PLATFORM=no-such-platform"), std::string::npos) << e.what();
        }
    }
    MTCUT_REQUIRE_GL(); // the shared context again
    EXPECT_GE(epoxy_gl_version(), 45);
}

TEST(RenderGl, WindowContextWorksOrSaysWhy)
{
    // No display on a CI machine: a one-line reason, not a crash.
    try {
        auto ctx = createWindowContext(64, 64, "test", false);
        EXPECT_TRUE(ctx->hasWindow());
        EXPECT_GE(epoxy_gl_version(), 45);
        std::printf("window context: %s\n", ctx->description().c_str());
    } catch (const std::runtime_error& e) {
        EXPECT_EQ(std::string(e.what()).rfind("GLFW", 0), 0u) << e.what();
        std::printf("no window context: %s\n", e.what());
    }
}
