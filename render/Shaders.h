// GLSL programs from the real files in shaders/ (STYLE 9), embedded into the
// binary at build time by render/EmbedShaders.cmake. Variants are made by
// inserting #define lines after the #version line; compile and link errors
// throw std::runtime_error with the file name and the driver's info log.
#pragma once

#include "render/GlObjects.h"

#include <cstddef>
#include <string>
#include <vector>

namespace mtcut::render {

namespace detail {
struct EmbeddedShader
{
    const char* name;   ///< file name in shaders/, e.g. "surface.frag"
    const char* source; ///< its text
};
extern const EmbeddedShader kEmbeddedShaders[]; ///< sorted by name, null-terminated
extern const size_t kEmbeddedShaderCount;
} // namespace detail

/// Names of the embedded shader files, sorted.
std::vector<std::string> shaderNames();

/// The text of embedded shader `name` ("surface.frag"). Throws
/// std::runtime_error when there is none.
std::string shaderSource(const std::string& name);

/// The GL stage of a shader file by its extension (.vert .frag .geom .comp).
/// Throws std::runtime_error for another extension.
GLenum shaderStageOf(const std::string& name);

/// `source` with `defines` (e.g. "#define HIGHLIGHT 1\n") inserted after its
/// #version line (the first line), and a #line directive so that the info
/// log's line numbers are the file's.
std::string withDefines(const std::string& source, const std::string& defines);

/// One stage's source, named for error messages.
struct ShaderText
{
    std::string name;
    std::string source;
};

/// Compiles and links the given stages (stage from each name's extension).
/// Throws std::runtime_error("NAME: compile error:\n<log>") or
/// ("PROGRAM: link error:\n<log>"). Needs a current context. A program
/// whose build took at least the cache's minBuildMs is kept on disk as the
/// driver's binary and taken from there the next time (see ProgramCache).
Program buildProgram(const std::vector<ShaderText>& stages);

/// Where buildProgram keeps the binaries of slow programs (the GPU cut
/// pass's on NVIDIA take over a minute each to build; Mesa's a few ms).
/// One file per program, named by a 64-bit hash of the driver (GL_VENDOR,
/// GL_RENDERER, GL_VERSION) and every stage's name and source, holding a
/// second, independent hash of the same that must match; written to a
/// temporary name and renamed, so processes building side by side are safe.
/// A file the driver refuses (a new driver, another GPU, damaged bytes) is
/// built again and replaced; the newest 32 files are kept. Default, from the environment: MTCUT_SHADER_CACHE
/// = a folder, or "off"; unset: $XDG_CACHE_HOME/mtcut/programs, else
/// $HOME/.cache/mtcut/programs, else none.
struct ProgramCache
{
    std::string dir;          ///< empty: no cache
    double minBuildMs = 1000; ///< programs that built faster are not kept
};
ProgramCache programCache();
void setProgramCache(const ProgramCache& cache);

/// What buildProgram did with the cache since the process started.
struct ProgramCacheCounts
{
    size_t loaded = 0;  ///< programs taken from a file
    size_t stored = 0;  ///< files written
    size_t refused = 0; ///< files there that did not match or that the driver refused
};
ProgramCacheCounts programCacheCounts();

/// buildProgram over embedded files, each with `defines` inserted. The
/// environment variable MTCUT_SHADER_PREAMBLE, when set, goes in first (for
/// trying a driver's pragmas, e.g. "#pragma optionNV(fastmath off)", without
/// a rebuild).
Program buildProgram(const std::vector<std::string>& files, const std::string& defines = {});

} // namespace mtcut::render
