#include "render/Shaders.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <stdexcept>

namespace mtcut::render {

std::vector<std::string> shaderNames()
{
    std::vector<std::string> out;
    for (size_t i = 0; i < detail::kEmbeddedShaderCount; ++i) out.push_back(detail::kEmbeddedShaders[i].name);
    return out;
}

std::string shaderSource(const std::string& name)
{
    for (size_t i = 0; i < detail::kEmbeddedShaderCount; ++i) {
        if (name == detail::kEmbeddedShaders[i].name) return detail::kEmbeddedShaders[i].source;
    }
    throw std::runtime_error("shader '" + name + "' is not embedded (no such file in shaders/)");
}

GLenum shaderStageOf(const std::string& name)
{
    const size_t dot = name.rfind('.');
    const std::string ext = dot == std::string::npos ? std::string() : name.substr(dot);
    if (ext == ".vert") return GL_VERTEX_SHADER;
    if (ext == ".frag") return GL_FRAGMENT_SHADER;
    if (ext == ".geom") return GL_GEOMETRY_SHADER;
    if (ext == ".comp") return GL_COMPUTE_SHADER;
    throw std::runtime_error(name + ": unknown shader stage (expected .vert, .frag, .geom or .comp)");
}

std::string withDefines(const std::string& source, const std::string& defines)
{
    if (defines.empty()) return source;
    const size_t eol = source.find('\n');
    if (eol == std::string::npos || source.compare(0, 8, "#version") != 0) {
        throw std::runtime_error("shader source must start with a #version line to take defines");
    }
    std::string d = defines;
    if (d.back() != '\n') d += '\n';
    return source.substr(0, eol + 1) + d + "#line 2\n" + source.substr(eol + 1);
}

namespace {

ProgramCache defaultProgramCache()
{
    ProgramCache c;
    const char* env = std::getenv("MTCUT_SHADER_CACHE");
    if (env && *env) {
        if (std::strcmp(env, "off") != 0) c.dir = env;
    } else if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) {
        c.dir = std::string(xdg) + "/mtcut/programs";
    } else if (const char* home = std::getenv("HOME"); home && *home) {
        c.dir = std::string(home) + "/.cache/mtcut/programs";
    }
    return c;
}

std::mutex gCacheMutex;
ProgramCache gCache = defaultProgramCache();
ProgramCacheCounts gCounts;

/// FNV-1a, 64 bits, continued from `h`.
uint64_t fnv1a(uint64_t h, const std::string& s)
{
    for (unsigned char c : s) h = (h ^ c) * 0x100000001b3ull;
    return (h ^ 0xffu) * 0x100000001b3ull; // a separator: ("ab","c") and ("a","bc") differ
}

std::string glString(GLenum e)
{
    const char* s = reinterpret_cast<const char*>(glGetString(e));
    return s ? s : "";
}

constexpr size_t kMaxCacheFiles = 32;
constexpr char kMagic[8] = {'M', 'T', 'C', 'P', 'R', 'G', '0', '1'};

struct CacheFile
{
    std::filesystem::path path;
    uint64_t check = 0; ///< the second hash, stored in the file
};

CacheFile cacheFileOf(const std::string& dir, const std::vector<ShaderText>& stages)
{
    uint64_t name = 0xcbf29ce484222325ull, check = 0x84222325cbf29ce4ull;
    for (const std::string& s : {glString(GL_VENDOR), glString(GL_RENDERER), glString(GL_VERSION)}) {
        name = fnv1a(name, s);
        check = fnv1a(check, s);
    }
    for (const ShaderText& s : stages) {
        name = fnv1a(fnv1a(name, s.name), s.source);
        check = fnv1a(fnv1a(check, s.source), s.name);
    }
    char file[32];
    std::snprintf(file, sizeof file, "%016llx.bin", static_cast<unsigned long long>(name));
    return {std::filesystem::path(dir) / file, check};
}

/// The program in `f`; empty when there is none or it does not serve.
Program loadCached(const CacheFile& f, bool& refused)
{
    refused = false;
    std::ifstream in(f.path, std::ios::binary);
    if (!in) return {};
    char magic[8];
    uint64_t check = 0, size = 0;
    uint32_t format = 0;
    in.read(magic, 8);
    in.read(reinterpret_cast<char*>(&check), 8);
    in.read(reinterpret_cast<char*>(&format), 4);
    in.read(reinterpret_cast<char*>(&size), 8);
    refused = true;
    if (!in || std::memcmp(magic, kMagic, 8) != 0 || check != f.check || size == 0 || size > (1ull << 31)) return {};
    std::vector<char> bytes(size);
    in.read(bytes.data(), std::streamsize(size));
    if (!in || in.peek() != std::char_traits<char>::eof()) return {};
    Program p = Program::fromBinary(GLenum(format), bytes.data(), bytes.size());
    refused = p.id() == 0;
    return p;
}

void storeCached(const CacheFile& f, const Program& p)
{
    GLenum format = 0;
    const std::vector<unsigned char> bytes = p.binary(format);
    if (bytes.empty()) return;
    std::error_code ec;
    std::filesystem::create_directories(f.path.parent_path(), ec);
    const std::filesystem::path tmp = f.path.string() + ".tmp" + std::to_string(::getpid());
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        const uint32_t format32 = format;
        const uint64_t size = bytes.size();
        out.write(kMagic, 8);
        out.write(reinterpret_cast<const char*>(&f.check), 8);
        out.write(reinterpret_cast<const char*>(&format32), 4);
        out.write(reinterpret_cast<const char*>(&size), 8);
        out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
        if (!out.flush()) {
            out.close();
            std::filesystem::remove(tmp, ec);
            return; // a cache that cannot be written is no error: the program is built
        }
    }
    std::filesystem::rename(tmp, f.path, ec);
    if (ec) {
        std::filesystem::remove(tmp, ec);
        return;
    }
    // Keep the newest kMaxCacheFiles: each source change leaves a file behind.
    std::vector<std::pair<std::filesystem::file_time_type, std::filesystem::path>> files;
    for (const auto& e : std::filesystem::directory_iterator(f.path.parent_path(), ec))
        if (e.path().extension() == ".bin") files.emplace_back(e.last_write_time(ec), e.path());
    if (files.size() > kMaxCacheFiles) {
        std::sort(files.begin(), files.end());
        for (size_t i = 0; i + kMaxCacheFiles < files.size(); ++i) std::filesystem::remove(files[i].second, ec);
    }
    const std::lock_guard<std::mutex> lock(gCacheMutex);
    ++gCounts.stored;
}

} // namespace

ProgramCache programCache()
{
    const std::lock_guard<std::mutex> lock(gCacheMutex);
    return gCache;
}

void setProgramCache(const ProgramCache& cache)
{
    const std::lock_guard<std::mutex> lock(gCacheMutex);
    gCache = cache;
}

ProgramCacheCounts programCacheCounts()
{
    const std::lock_guard<std::mutex> lock(gCacheMutex);
    return gCounts;
}

Program buildProgram(const std::vector<ShaderText>& stages)
{
    const ProgramCache cache = programCache();
    CacheFile file;
    if (!cache.dir.empty()) {
        file = cacheFileOf(cache.dir, stages);
        bool refused = false;
        Program p = loadCached(file, refused);
        const std::lock_guard<std::mutex> lock(gCacheMutex);
        if (p.id()) {
            ++gCounts.loaded;
            return p;
        }
        if (refused) ++gCounts.refused;
    }
    const auto start = std::chrono::steady_clock::now();
    std::vector<Shader> shaders;
    std::vector<GLuint> ids;
    std::string name;
    for (const ShaderText& s : stages) {
        shaders.emplace_back(shaderStageOf(s.name), s.source, s.name);
        ids.push_back(shaders.back().id());
        name += (name.empty() ? "" : "+") + s.name;
    }
    const bool keep = !cache.dir.empty();
    Program p = Program::linkIds(name, ids.data(), ids.size(), keep);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (keep && ms >= cache.minBuildMs) storeCached(file, p);
    return p;
}

Program buildProgram(const std::vector<std::string>& files, const std::string& defines)
{
    std::string all = defines;
    if (const char* preamble = std::getenv("MTCUT_SHADER_PREAMBLE"); preamble && *preamble)
        all = std::string(preamble) + "\n" + defines;
    std::vector<ShaderText> stages;
    for (const std::string& f : files) stages.push_back({f, withDefines(shaderSource(f), all)});
    return buildProgram(stages);
}

} // namespace mtcut::render
