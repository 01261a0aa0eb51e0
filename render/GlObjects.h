// GL objects as move-only RAII types (STYLE 10; after magnum's GL/Buffer.h):
// no raw glGen*/glCreate* outside this file. Every constructor needs a
// current GL 4.5 context (render/Context.h); objects are created with the
// direct-state-access glCreate* calls and deleted when they go out of scope,
// so they must die while their context is still current.
#pragma once

#include <epoxy/gl.h>

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace mtcut::render {

/// Throws std::runtime_error("GL error 0x0502 (GL_INVALID_OPERATION) in WHAT")
/// when glGetError reports one (all pending errors are drained). Cheap; call
/// after a pass, not per draw.
void checkGlError(const char* what);

/// A GL name with a deleter: move-only, 0 when empty or moved from.
template <typename Traits>
class GlName
{
public:
    GlName(GlName&& o) noexcept : mId(std::exchange(o.mId, 0u)) {}
    GlName& operator=(GlName&& o) noexcept
    {
        if (this != &o) {
            reset();
            mId = std::exchange(o.mId, 0u);
        }
        return *this;
    }
    GlName(const GlName&) = delete;
    GlName& operator=(const GlName&) = delete;
    ~GlName() { reset(); }

    GLuint id() const { return mId; }
    explicit operator bool() const { return mId != 0; }

protected:
    GlName() = default;
    explicit GlName(GLuint id) : mId(id) {}
    void reset()
    {
        if (mId) Traits::destroy(mId);
        mId = 0;
    }
    GLuint mId = 0;
};

namespace detail {
struct BufferTraits { static void destroy(GLuint id) { glDeleteBuffers(1, &id); } };
struct TextureTraits { static void destroy(GLuint id) { glDeleteTextures(1, &id); } };
struct FramebufferTraits { static void destroy(GLuint id) { glDeleteFramebuffers(1, &id); } };
struct RenderbufferTraits { static void destroy(GLuint id) { glDeleteRenderbuffers(1, &id); } };
struct VertexArrayTraits { static void destroy(GLuint id) { glDeleteVertexArrays(1, &id); } };
struct ShaderTraits { static void destroy(GLuint id) { glDeleteShader(id); } };
struct ProgramTraits { static void destroy(GLuint id) { glDeleteProgram(id); } };
struct QueryTraits { static void destroy(GLuint id) { glDeleteQueries(1, &id); } };
} // namespace detail

/// A buffer object (vertex, index, storage, uniform...).
class Buffer : public GlName<detail::BufferTraits>
{
public:
    Buffer();
    /// Immutable storage of `bytes` bytes (glNamedBufferStorage) from `data`
    /// (may be null); flags as glNamedBufferStorage (0: GPU-only, static).
    Buffer(size_t bytes, const void* data, GLbitfield flags = 0);
    /// (Re)allocates mutable storage (glNamedBufferData).
    void setData(size_t bytes, const void* data, GLenum usage = GL_STATIC_DRAW);
    size_t size() const { return mSize; }

private:
    size_t mSize = 0;
};

/// A texture of one target (GL_TEXTURE_2D, GL_TEXTURE_2D_ARRAY, ...).
class Texture : public GlName<detail::TextureTraits>
{
public:
    explicit Texture(GLenum target);
    GLenum target() const { return mTarget; }

private:
    GLenum mTarget;
};

class Framebuffer : public GlName<detail::FramebufferTraits>
{
public:
    Framebuffer();
    /// Throws std::runtime_error naming the status unless complete.
    void checkComplete(const char* what) const;
};

class Renderbuffer : public GlName<detail::RenderbufferTraits>
{
public:
    /// Storage of the given internal format and size.
    Renderbuffer(GLenum internalFormat, int width, int height);
};

class VertexArray : public GlName<detail::VertexArrayTraits>
{
public:
    VertexArray();
};

/// One compiled shader stage. Throws std::runtime_error("NAME: compile
/// error:\n<info log>") on failure.
class Shader : public GlName<detail::ShaderTraits>
{
public:
    Shader(GLenum stage, const std::string& source, const std::string& name);
};

/// A linked program.
class Program : public GlName<detail::ProgramTraits>
{
public:
    Program() = default;
    /// Links the given stages. Throws std::runtime_error("NAME: link
    /// error:\n<info log>") on failure.
    template <typename... Shaders>
    static Program link(const std::string& name, const Shaders&... shaders)
    {
        const GLuint ids[] = {shaders.id()...};
        return linkIds(name, ids, sizeof...(shaders));
    }
    /// As link; `retrievable`: ask the driver to keep the linked binary for
    /// binary() (GL_PROGRAM_BINARY_RETRIEVABLE_HINT).
    static Program linkIds(const std::string& name, const GLuint* shaders, size_t count, bool retrievable = false);
    /// A program from bytes binary() gave with `format`; empty (id() 0) when
    /// the driver refuses them (another driver or GPU, or damaged bytes).
    static Program fromBinary(GLenum format, const void* data, size_t size);
    /// The linked program's binary (glGetProgramBinary) and its format;
    /// empty when the driver gives none.
    std::vector<unsigned char> binary(GLenum& format) const;

    /// Uniform location; -1 when the uniform is absent or optimised away.
    GLint uniform(const char* name) const { return glGetUniformLocation(mId, name); }
    void use() const { glUseProgram(mId); }

private:
    explicit Program(GLuint id) : GlName(id) {}
};

/// A query object of one target (GL_TIME_ELAPSED, GL_SAMPLES_PASSED, ...).
class Query : public GlName<detail::QueryTraits>
{
public:
    explicit Query(GLenum target);
    GLenum target() const { return mTarget; }
    /// Blocks until the result is available.
    GLuint64 result() const;

private:
    GLenum mTarget;
};

} // namespace mtcut::render
