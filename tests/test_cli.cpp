// The mtcut command line as a user meets it: exit codes, one-line errors that
// name the file, and no half-written output.
#include "TestUtil.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <vector>

using mtcut::test::runMtcut;
using mtcut::test::TempDir;
namespace fs = std::filesystem;

namespace {

int lineCount(const std::string& s)
{
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

bool folderHasOnly(const std::string& dir, const std::vector<std::string>& names)
{
    std::vector<std::string> found;
    for (const auto& e : fs::directory_iterator(dir)) found.push_back(e.path().filename().string());
    std::sort(found.begin(), found.end());
    std::vector<std::string> want = names;
    std::sort(want.begin(), want.end());
    return found == want;
}

} // namespace

TEST(Cli, PhantomThenInfo)
{
    TempDir dir;
    const auto made = runMtcut("phantom " + dir.file("p.vdb") + " --size 40,36,30 --seed 3");
    ASSERT_EQ(made.exitCode, 0) << made.output;
    EXPECT_TRUE(folderHasOnly(dir.path(), {"p.vdb"}));
    const auto info = runMtcut("info " + dir.file("p.vdb"));
    ASSERT_EQ(info.exitCode, 0) << info.output;
    EXPECT_NE(info.output.find("grid:      40 x 36 x 30 voxels"), std::string::npos) << info.output;
    EXPECT_NE(info.output.find("(OpenVDB)"), std::string::npos) << info.output;
    EXPECT_NE(info.output.find("bone iso:"), std::string::npos) << info.output;
}

TEST(Cli, ConvertRoundTripsThroughVdb)
{
    TempDir dir;
    ASSERT_EQ(runMtcut("phantom " + dir.file("p.vdb") + " --size 24,20,16").exitCode, 0);
    const auto conv = runMtcut("convert " + dir.file("p.vdb") + " " + dir.file("q.vdb"));
    ASSERT_EQ(conv.exitCode, 0) << conv.output;
    const auto a = runMtcut("info " + dir.file("p.vdb"));
    const auto b = runMtcut("info " + dir.file("q.vdb"));
    // Same numbers apart from the file name and the read time.
    auto strip = [](const std::string& s) {
        std::string out;
        size_t pos = 0;
        while (pos < s.size()) {
            size_t end = s.find('\n', pos);
            if (end == std::string::npos) end = s.size();
            const std::string line = s.substr(pos, end - pos);
            if (line.rfind("input:", 0) != 0 && line.rfind("read in:", 0) != 0) out += line + "\n";
            pos = end + 1;
        }
        return out;
    };
    EXPECT_EQ(strip(a.output), strip(b.output));
}

TEST(Cli, ErrorsAreOneLineNamingTheFileWithNonZeroExit)
{
    TempDir dir;
    const auto missing = runMtcut("info " + dir.file("nothere.nrrd"));
    EXPECT_EQ(missing.exitCode, 1);
    EXPECT_EQ(lineCount(missing.output), 1) << missing.output;
    EXPECT_EQ(missing.output, "mtcut: error: " + dir.file("nothere.nrrd") + ": no such file or folder\n");

    {
        std::ofstream(dir.file("junk.bin")) << "this is not a scan";
    }
    const auto junk = runMtcut("info " + dir.file("junk.bin"));
    EXPECT_EQ(junk.exitCode, 1);
    EXPECT_EQ(lineCount(junk.output), 1) << junk.output;
    EXPECT_NE(junk.output.find(dir.file("junk.bin")), std::string::npos);

    const auto unknownCommand = runMtcut("frobnicate");
    EXPECT_EQ(unknownCommand.exitCode, 2);
    const auto badOption = runMtcut("info x --bogus 3");
    EXPECT_EQ(badOption.exitCode, 1);
    EXPECT_NE(badOption.output.find("unknown option --bogus"), std::string::npos) << badOption.output;
    const auto badSize = runMtcut("phantom " + dir.file("p.vdb") + " --size 10,0,4");
    EXPECT_EQ(badSize.exitCode, 1);
    EXPECT_FALSE(fs::exists(dir.file("p.vdb")));
    const auto hugeSize = runMtcut("phantom " + dir.file("p.vdb") + " --size 100000,100000,100000");
    EXPECT_EQ(hugeSize.exitCode, 1) << hugeSize.output;
    EXPECT_NE(hugeSize.output.find("more than the limit"), std::string::npos) << hugeSize.output;
}

// `mtcut COMMAND --help` (or -h, anywhere an option may stand) and `mtcut
// help COMMAND` print that command's usage on stdout and exit 0, reading
// nothing; a "-h" that is an option's value is that value, not a request.
TEST(Cli, CommandHelpPrintsItsUsageAndExitsZero)
{
    for (const std::string args : {"cut --help", "cut ../nothere -h --iso 400", "help cut"}) {
        const auto help = runMtcut(args);
        EXPECT_EQ(help.exitCode, 0) << args << ": " << help.output;
        EXPECT_EQ(help.output.rfind("usage: mtcut cut INPUT --iso V", 0), 0u) << args << ": " << help.output;
        EXPECT_NE(help.output.find("--kerf"), std::string::npos) << args;
        EXPECT_NE(help.output.find("input options"), std::string::npos) << args << ": cut reads an INPUT";
        EXPECT_EQ(help.output.find("mesh INPUT"), std::string::npos) << args << ": only the one command";
    }
    const auto phantom = runMtcut("phantom --help");
    EXPECT_EQ(phantom.exitCode, 0);
    EXPECT_EQ(phantom.output.rfind("usage: mtcut phantom OUT.vdb", 0), 0u) << phantom.output;
    EXPECT_EQ(phantom.output.find("input options"), std::string::npos) << "phantom reads no INPUT";
    // As a value: --path -h names a path file "-h"; the command then fails on --iso, not with help.
    const auto value = runMtcut("cut x --path -h");
    EXPECT_EQ(value.exitCode, 1) << value.output;
    EXPECT_EQ(value.output.find("usage: mtcut cut"), std::string::npos) << value.output;
    const auto unknown = runMtcut("help frobnicate");
    EXPECT_EQ(unknown.exitCode, 2);
    EXPECT_NE(unknown.output.find("unknown command 'frobnicate'"), std::string::npos) << unknown.output;
    // The overview names every command and how to get one command's help.
    const auto all = runMtcut("--help");
    EXPECT_EQ(all.exitCode, 0);
    EXPECT_NE(all.output.find("mtcut COMMAND --help"), std::string::npos) << all.output;
}

TEST(Cli, FailedWriteLeavesNothingBehind)
{
    TempDir dir;
    ASSERT_EQ(runMtcut("phantom " + dir.file("p.vdb") + " --size 16,16,16").exitCode, 0);
    const auto bad = runMtcut("convert " + dir.file("p.vdb") + " " + dir.file("out.xyz"));
    EXPECT_EQ(bad.exitCode, 1);
    EXPECT_NE(bad.output.find("unknown output format"), std::string::npos) << bad.output;
    // Writing into a folder that does not exist fails cleanly, no temp files anywhere.
    const auto noDir = runMtcut("convert " + dir.file("p.vdb") + " " + dir.file("sub/out.vdb"));
    EXPECT_EQ(noDir.exitCode, 1) << noDir.output;
    EXPECT_TRUE(folderHasOnly(dir.path(), {"p.vdb"}));
}
