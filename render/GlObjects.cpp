#include "render/GlObjects.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace mtcut::render {

namespace {

const char* glErrorName(GLenum e)
{
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    case GL_STACK_OVERFLOW: return "GL_STACK_OVERFLOW";
    case GL_STACK_UNDERFLOW: return "GL_STACK_UNDERFLOW";
    default: return "unknown";
    }
}

const char* framebufferStatusName(GLenum s)
{
    switch (s) {
    case GL_FRAMEBUFFER_UNDEFINED: return "GL_FRAMEBUFFER_UNDEFINED";
    case GL_FRAMEBUFFER_INCOMPLETE_ATTACHMENT: return "GL_FRAMEBUFFER_INCOMPLETE_ATTACHMENT";
    case GL_FRAMEBUFFER_INCOMPLETE_MISSING_ATTACHMENT: return "GL_FRAMEBUFFER_INCOMPLETE_MISSING_ATTACHMENT";
    case GL_FRAMEBUFFER_UNSUPPORTED: return "GL_FRAMEBUFFER_UNSUPPORTED";
    case GL_FRAMEBUFFER_INCOMPLETE_MULTISAMPLE: return "GL_FRAMEBUFFER_INCOMPLETE_MULTISAMPLE";
    case GL_FRAMEBUFFER_INCOMPLETE_LAYER_TARGETS: return "GL_FRAMEBUFFER_INCOMPLETE_LAYER_TARGETS";
    default: return "unknown status";
    }
}

} // namespace

void checkGlError(const char* what)
{
    GLenum first = glGetError();
    if (first == GL_NO_ERROR) return;
    for (int i = 0; i < 32 && glGetError() != GL_NO_ERROR; ++i) {
    }
    char buf[160];
    std::snprintf(buf, sizeof buf, "GL error 0x%04x (%s) in %s", unsigned(first), glErrorName(first), what);
    throw std::runtime_error(buf);
}

Buffer::Buffer()
{
    glCreateBuffers(1, &mId);
}

Buffer::Buffer(size_t bytes, const void* data, GLbitfield flags) : Buffer()
{
    // A zero-sized store is an error in GL; keep one byte so the name is usable.
    glNamedBufferStorage(mId, GLsizeiptr(bytes ? bytes : 1), bytes ? data : nullptr, flags);
    mSize = bytes;
}

void Buffer::setData(size_t bytes, const void* data, GLenum usage)
{
    glNamedBufferData(mId, GLsizeiptr(bytes ? bytes : 1), bytes ? data : nullptr, usage);
    mSize = bytes;
}

Texture::Texture(GLenum target) : mTarget(target)
{
    glCreateTextures(target, 1, &mId);
}

Framebuffer::Framebuffer()
{
    glCreateFramebuffers(1, &mId);
}

void Framebuffer::checkComplete(const char* what) const
{
    const GLenum s = glCheckNamedFramebufferStatus(mId, GL_FRAMEBUFFER);
    if (s != GL_FRAMEBUFFER_COMPLETE) {
        throw std::runtime_error(std::string(what) + ": framebuffer incomplete (" + framebufferStatusName(s) + ")");
    }
}

Renderbuffer::Renderbuffer(GLenum internalFormat, int width, int height)
{
    glCreateRenderbuffers(1, &mId);
    glNamedRenderbufferStorage(mId, internalFormat, width, height);
}

VertexArray::VertexArray()
{
    glCreateVertexArrays(1, &mId);
}

Shader::Shader(GLenum stage, const std::string& source, const std::string& name)
{
    mId = glCreateShader(stage);
    if (!mId) throw std::runtime_error(name + ": glCreateShader failed (no current GL context?)");
    const char* text = source.c_str();
    const GLint length = GLint(source.size());
    glShaderSource(mId, 1, &text, &length);
    glCompileShader(mId);
    GLint ok = GL_FALSE;
    glGetShaderiv(mId, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        GLint logLength = 0;
        glGetShaderiv(mId, GL_INFO_LOG_LENGTH, &logLength);
        std::string log(size_t(std::max(logLength, 1)), '\0');
        glGetShaderInfoLog(mId, GLsizei(log.size()), nullptr, log.data());
        log.resize(std::strlen(log.c_str()));
        reset();
        throw std::runtime_error(name + ": compile error:\n" + log);
    }
}

Program Program::linkIds(const std::string& name, const GLuint* shaders, size_t count, bool retrievable)
{
    Program p(glCreateProgram());
    if (retrievable) glProgramParameteri(p.mId, GL_PROGRAM_BINARY_RETRIEVABLE_HINT, GL_TRUE);
    for (size_t i = 0; i < count; ++i) glAttachShader(p.mId, shaders[i]);
    glLinkProgram(p.mId);
    for (size_t i = 0; i < count; ++i) glDetachShader(p.mId, shaders[i]);
    GLint ok = GL_FALSE;
    glGetProgramiv(p.mId, GL_LINK_STATUS, &ok);
    if (!ok) {
        GLint logLength = 0;
        glGetProgramiv(p.mId, GL_INFO_LOG_LENGTH, &logLength);
        std::string log(size_t(std::max(logLength, 1)), '\0');
        glGetProgramInfoLog(p.mId, GLsizei(log.size()), nullptr, log.data());
        log.resize(std::strlen(log.c_str()));
        throw std::runtime_error(name + ": link error:\n" + log);
    }
    return p;
}

Program Program::fromBinary(GLenum format, const void* data, size_t size)
{
    Program p(glCreateProgram());
    glProgramBinary(p.mId, format, data, GLsizei(size));
    GLint ok = GL_FALSE;
    glGetProgramiv(p.mId, GL_LINK_STATUS, &ok);
    if (ok) return p;
    glGetError(); // GL_INVALID_ENUM for a format this driver does not know: refused, not an error
    return Program();
}

std::vector<unsigned char> Program::binary(GLenum& format) const
{
    GLint size = 0;
    glGetProgramiv(mId, GL_PROGRAM_BINARY_LENGTH, &size);
    std::vector<unsigned char> out(size_t(std::max(size, 0)));
    GLsizei written = 0;
    format = 0;
    if (size > 0) glGetProgramBinary(mId, size, &written, &format, out.data());
    out.resize(size_t(std::max(written, 0)));
    return out;
}

Query::Query(GLenum target) : mTarget(target)
{
    glCreateQueries(target, 1, &mId);
}

GLuint64 Query::result() const
{
    GLuint64 v = 0;
    glGetQueryObjectui64v(mId, GL_QUERY_RESULT, &v);
    return v;
}

} // namespace mtcut::render
