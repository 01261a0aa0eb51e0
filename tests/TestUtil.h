// Shared helpers for the tests: where the shared CT data is, temporary
// folders, running the mtcut binary.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace mtcut::test {

/// ../shared/data (or $MTCUT_DATA), or "" when absent.
inline std::string dataDir()
{
    const char* env = std::getenv("MTCUT_DATA");
    const std::string dir = env ? env : MTCUT_SHARED_DATA;
    return std::filesystem::is_directory(dir) ? dir : std::string();
}

/// Path of a shared data file or folder, or "" when absent.
inline std::string dataPath(const std::string& name)
{
    const std::string dir = dataDir();
    if (dir.empty()) return {};
    const std::string p = dir + "/" + name;
    return std::filesystem::exists(p) ? p : std::string();
}

/// In a TEST body: skip cleanly when the shared file is absent.
#define MTCUT_REQUIRE_DATA(var, name)                                                              \
    const std::string var = ::mtcut::test::dataPath(name);                                         \
    if (var.empty()) GTEST_SKIP() << "shared data '" << name << "' not found (set MTCUT_DATA)"

/// A fresh temporary folder, removed with the object.
class TempDir
{
public:
    TempDir()
    {
        std::string tmpl = (std::filesystem::temp_directory_path() / "mtcut-test-XXXXXX").string();
        mPath = ::mkdtemp(tmpl.data());
    }
    ~TempDir()
    {
        std::error_code ec;
        std::filesystem::remove_all(mPath, ec);
    }
    std::string file(const std::string& name) const { return mPath + "/" + name; }
    const std::string& path() const { return mPath; }

private:
    std::string mPath;
};

struct RunResult
{
    int exitCode = -1;
    std::string output; ///< stdout and stderr together
};

/// Runs `mtcut ARGS` (a shell-quoted string) and captures its output.
inline RunResult runMtcut(const std::string& args)
{
    RunResult r;
    const std::string cmd = std::string(MTCUT_BIN) + " " + args + " 2>&1";
    FILE* p = ::popen(cmd.c_str(), "r");
    if (!p) return r;
    std::array<char, 4096> buf;
    size_t n;
    while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
    const int status = ::pclose(p);
    r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
}

} // namespace mtcut::test
