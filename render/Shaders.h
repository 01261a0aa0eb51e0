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
/// ("PROGRAM: link error:\n<log>"). Needs a current context.
Program buildProgram(const std::vector<ShaderText>& stages);

/// buildProgram over embedded files, each with `defines` inserted. The
/// environment variable MTCUT_SHADER_PREAMBLE, when set, goes in first (for
/// trying a driver's pragmas, e.g. "#pragma optionNV(fastmath off)", without
/// a rebuild).
Program buildProgram(const std::vector<std::string>& files, const std::string& defines = {});

} // namespace mtcut::render
