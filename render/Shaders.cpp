#include "render/Shaders.h"

#include <cstdlib>
#include <cstring>
#include <memory>
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

Program buildProgram(const std::vector<ShaderText>& stages)
{
    std::vector<Shader> shaders;
    std::vector<GLuint> ids;
    std::string name;
    for (const ShaderText& s : stages) {
        shaders.emplace_back(shaderStageOf(s.name), s.source, s.name);
        ids.push_back(shaders.back().id());
        name += (name.empty() ? "" : "+") + s.name;
    }
    return Program::linkIds(name, ids.data(), ids.size());
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
