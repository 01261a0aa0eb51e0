#include "render/SurfaceRenderer.h"

#include "render/CutKernelGpu.h"
#include "render/Shaders.h"
#include "vdb/Error.h"

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace mtcut::render {

/// One mesh on the GPU: interleaved position + normal, indices, and the
/// per-triangle TriangleInfo (cell, fragment id | cap bit) storage buffer
/// that the fragment shader reads by gl_PrimitiveID.
struct SurfaceRenderer::DrawMesh
{
    Buffer vertices, indices, triangles;
    VertexArray vao;
    GLsizei indexCount = 0;
    size_t triangleCount = 0;
    Bounds bounds;
    bool empty = true;
};

namespace {

struct TriangleInfo
{
    int32_t cell[3];
    uint32_t info; ///< fragment id (bits 0..29) | cap (bit 30) | cut geometry (bit 31)
};
static_assert(sizeof(TriangleInfo) == 16, "std430 layout of shaders/surface.frag's TriangleInfo");

/// The per-triangle TriangleInfo array of `mesh` (sizes checked by the caller).
std::vector<TriangleInfo> triangleInfos(const cutter::Mesh& mesh, const std::vector<uint32_t>& fragmentIds,
                                        const std::vector<uint8_t>& isCap, bool cutGeometry)
{
    const size_t nt = mesh.triangleCount();
    std::vector<TriangleInfo> tri(nt);
    for (size_t t = 0; t < nt; ++t) {
        const glm::ivec3 c = mesh.triangleVoxels[t];
        const uint32_t id = fragmentIds.empty() ? 1u : fragmentIds[t];
        if (id >= (1u << 30)) throw InputError("more than 2^30 fragments");
        tri[t] = {{c.x, c.y, c.z},
                  id | (!isCap.empty() && isCap[t] ? 0x40000000u : 0u) | (cutGeometry ? 0x80000000u : 0u)};
    }
    return tri;
}

/// surface.vert's inputs from `vertices` (6 floats a vertex: position, normal) in `vao`.
void setVertexFormat(const VertexArray& vao, const Buffer& vertices)
{
    const GLuint id = vao.id();
    glVertexArrayVertexBuffer(id, 0, vertices.id(), 0, GLsizei(6 * sizeof(float)));
    for (GLuint a = 0; a < 2; ++a) {
        glEnableVertexArrayAttrib(id, a);
        glVertexArrayAttribFormat(id, a, 3, GL_FLOAT, GL_FALSE, GLuint(3 * a * sizeof(float)));
        glVertexArrayAttribBinding(id, a, 0);
    }
}

void makeTarget(Texture& t, GLenum format, int w, int h)
{
    glTextureStorage2D(t.id(), 1, format, w, h);
    glTextureParameteri(t.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(t.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
}

} // namespace

SurfaceRenderer::SurfaceRenderer(int width, int height) : mWidth(width), mHeight(height)
{
    GLint maxRb = 0, maxTex = 0, maxViewport[2] = {0, 0};
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &maxRb);
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxTex);
    glGetIntegerv(GL_MAX_VIEWPORT_DIMS, maxViewport);
    const int limit = std::min({maxRb, maxTex, maxViewport[0], maxViewport[1]});
    if (width < 1 || height < 1 || width > limit || height > limit) {
        throw InputError("image size " + std::to_string(width) + "x" + std::to_string(height) +
                         ": each side must be in [1, " + std::to_string(limit) + "] on this GL");
    }
    makeTarget(mColour, GL_RGBA8, width, height);
    makeTarget(mNormal, GL_RGBA32F, width, height);
    makeTarget(mDepthOut, GL_R32F, width, height);
    makeTarget(mFragment, GL_R32UI, width, height);
    makeTarget(mDepth, GL_DEPTH_COMPONENT32F, width, height);
    glNamedFramebufferTexture(mFbo.id(), GL_COLOR_ATTACHMENT0, mColour.id(), 0);
    glNamedFramebufferTexture(mFbo.id(), GL_COLOR_ATTACHMENT1, mNormal.id(), 0);
    glNamedFramebufferTexture(mFbo.id(), GL_COLOR_ATTACHMENT2, mDepthOut.id(), 0);
    glNamedFramebufferTexture(mFbo.id(), GL_COLOR_ATTACHMENT3, mFragment.id(), 0);
    glNamedFramebufferTexture(mFbo.id(), GL_DEPTH_ATTACHMENT, mDepth.id(), 0);
    const GLenum buffers[4] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2, GL_COLOR_ATTACHMENT3};
    glNamedFramebufferDrawBuffers(mFbo.id(), 4, buffers);
    mFbo.checkComplete("SurfaceRenderer");

    const std::string library = maskShaderLibrary();
    mDiscardProgram = buildProgram({"surface.vert", "surface.frag"}, "#define DISCARD_CUT 1\n" + library);
    mPlainProgram = buildProgram({"surface.vert", "surface.frag"}, library);
    checkGlError("SurfaceRenderer: targets");
}

SurfaceRenderer::~SurfaceRenderer() = default;

std::unique_ptr<SurfaceRenderer::DrawMesh> SurfaceRenderer::upload(const cutter::Mesh& mesh,
                                                                   const std::vector<uint32_t>& fragmentIds,
                                                                   const std::vector<uint8_t>& isCap,
                                                                   bool cutGeometry) const
{
    const size_t nv = mesh.positions.size(), nt = mesh.triangleCount();
    if (mesh.indices.size() != 3 * nt || mesh.triangleVoxels.size() != nt || (!fragmentIds.empty() && fragmentIds.size() != nt) ||
        (!isCap.empty() && isCap.size() != nt) || (!mesh.normals.empty() && mesh.normals.size() != nv)) {
        throw std::invalid_argument("SurfaceRenderer: mesh arrays of mismatched sizes");
    }
    if (nt > size_t(std::numeric_limits<GLsizei>::max() / 3)) throw InputError("mesh too large to draw");
    auto m = std::make_unique<DrawMesh>();
    std::vector<float> interleaved(nv * 6);
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (size_t v = 0; v < nv; ++v) {
        const glm::vec3 p = mesh.positions[v];
        const glm::vec3 n = mesh.normals.empty() ? glm::vec3(0, 0, 1) : mesh.normals[v];
        for (int a = 0; a < 3; ++a) {
            interleaved[6 * v + size_t(a)] = p[a];
            interleaved[6 * v + 3 + size_t(a)] = n[a];
        }
    }
    for (uint32_t i : mesh.indices) { // bounds of the used vertices
        lo = glm::min(lo, glm::dvec3(mesh.positions[i]));
        hi = glm::max(hi, glm::dvec3(mesh.positions[i]));
    }
    const std::vector<TriangleInfo> tri = triangleInfos(mesh, fragmentIds, isCap, cutGeometry);
    m->vertices = Buffer(interleaved.size() * sizeof(float), interleaved.data());
    m->indices = Buffer(mesh.indices.size() * sizeof(uint32_t), mesh.indices.data());
    // The surface's triangle infos can be rewritten in place (setSurfaceFragmentIds).
    m->triangles = Buffer(tri.size() * sizeof(TriangleInfo), tri.data(), cutGeometry ? 0 : GL_DYNAMIC_STORAGE_BIT);
    setVertexFormat(m->vao, m->vertices);
    glVertexArrayElementBuffer(m->vao.id(), m->indices.id());
    m->indexCount = GLsizei(mesh.indices.size());
    m->triangleCount = nt;
    m->empty = nt == 0;
    if (!m->empty) m->bounds = {lo, hi};
    checkGlError("SurfaceRenderer: upload");
    return m;
}

void SurfaceRenderer::setSurface(const cutter::Mesh& uncut, const std::vector<uint32_t>& fragmentIds)
{
    mSurface = upload(uncut, fragmentIds, {}, false);
    mCut.reset();
    mAtlas.reset();
}

void SurfaceRenderer::setSurfaceFragmentIds(const cutter::Mesh& uncut, const std::vector<uint32_t>& fragmentIds)
{
    const size_t nt = uncut.triangleCount();
    if (!mSurface || mSurface->triangleCount != nt || uncut.triangleVoxels.size() != nt ||
        (!fragmentIds.empty() && fragmentIds.size() != nt)) {
        throw std::invalid_argument("SurfaceRenderer::setSurfaceFragmentIds: not the surface given to setSurface");
    }
    if (nt == 0) return;
    const std::vector<TriangleInfo> tri = triangleInfos(uncut, fragmentIds, {}, false);
    glNamedBufferSubData(mSurface->triangles.id(), 0, GLsizeiptr(tri.size() * sizeof(TriangleInfo)), tri.data());
    checkGlError("SurfaceRenderer::setSurfaceFragmentIds");
}

void SurfaceRenderer::setGpuCutGeometry(std::shared_ptr<const GpuCutDraw> draw)
{
    mCut.reset();
    mGpuCut = std::move(draw);
    if (!mGpuCut) return;
    setVertexFormat(mGpuCutVao, mGpuCut->vertices());
    checkGlError("SurfaceRenderer::setGpuCutGeometry");
}

void SurfaceRenderer::clearCut()
{
    mCut.reset();
    mGpuCut.reset();
    mAtlas.reset();
}

void SurfaceRenderer::setCutCells(const MaskTiling& tiling, bool gpuCoding)
{
    mAtlas = std::make_unique<MaskAtlas>(tiling);
    if (gpuCoding) {
        mAtlas->writeCells(tiling.cells());
    } else {
        mAtlas->uploadTiles(tiling);
    }
}

void SurfaceRenderer::setCutGeometry(const cutter::Mesh& mesh, const std::vector<uint32_t>& fragmentIds,
                                     const std::vector<uint8_t>& isCap)
{
    mGpuCut.reset();
    mCut = upload(mesh, fragmentIds, isCap, true);
}

Bounds SurfaceRenderer::bounds() const
{
    bool any = false;
    Bounds b;
    for (const DrawMesh* m : {mSurface.get(), mCut.get()}) {
        if (!m || m->empty) continue;
        b = any ? Bounds{glm::min(b.lo, m->bounds.lo), glm::max(b.hi, m->bounds.hi)} : m->bounds;
        any = true;
    }
    return b;
}

void SurfaceRenderer::draw(const DrawMesh& mesh, const Program& program) const
{
    if (mesh.empty) return;
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, mesh.triangles.id());
    program.use();
    glBindVertexArray(mesh.vao.id());
    glDrawElements(GL_TRIANGLES, mesh.indexCount, GL_UNSIGNED_INT, nullptr);
    glBindVertexArray(0);
}

void SurfaceRenderer::render(const Camera& camera, const RenderStyle& style)
{
    glBindFramebuffer(GL_FRAMEBUFFER, mFbo.id());
    glViewport(0, 0, mWidth, mHeight);
    glDisable(GL_BLEND);
    glDisable(GL_COLOR_LOGIC_OP);
    glDisable(GL_SCISSOR_TEST);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDepthMask(GL_TRUE);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    // Closed, outward-oriented surfaces: back faces are never the nearest
    // visible surface, and culling them keeps the coincident opposite caps
    // of a zero-width cut from fighting.
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    glClearNamedFramebufferfv(mFbo.id(), GL_COLOR, 0, glm::value_ptr(style.background));
    const float zero4[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(mFbo.id(), GL_COLOR, 1, zero4);
    const float inf4[4] = {std::numeric_limits<float>::infinity(), 0, 0, 0};
    glClearNamedFramebufferfv(mFbo.id(), GL_COLOR, 2, inf4);
    const GLuint zeroU[4] = {0, 0, 0, 0};
    glClearNamedFramebufferuiv(mFbo.id(), GL_COLOR, 3, zeroU);
    const float one = 1.0f;
    glClearNamedFramebufferfv(mFbo.id(), GL_DEPTH, 0, &one);

    const double aspect = double(mWidth) / double(mHeight);
    const glm::mat4 view = camera.view();
    const glm::mat4 viewProjection = camera.projection(aspect) * view;
    for (const Program* p : {&mDiscardProgram, &mPlainProgram}) {
        const GLuint id = p->id();
        glProgramUniformMatrix4fv(id, p->uniform("uViewProjection"), 1, GL_FALSE, glm::value_ptr(viewProjection));
        glProgramUniformMatrix4fv(id, p->uniform("uView"), 1, GL_FALSE, glm::value_ptr(view));
        glProgramUniform3f(id, p->uniform("uEye"), float(camera.eye.x), float(camera.eye.y), float(camera.eye.z));
        glProgramUniform3fv(id, p->uniform("uColour"), 1, glm::value_ptr(style.colour));
        glProgramUniform3fv(id, p->uniform("uHighlightColour"), 1, glm::value_ptr(style.highlightColour));
        glProgramUniform1i(id, p->uniform("uHighlight"), style.highlight ? 1 : 0);
        glProgramUniform1ui(id, p->uniform("uFragmentColourCount"), GLuint(style.fragmentColours.size()));
    }
    if (!style.fragmentColours.empty()) {
        mFragmentColours.setData(style.fragmentColours.size() * sizeof(glm::vec4), style.fragmentColours.data(),
                                 GL_STREAM_DRAW);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, mFragmentColours.id());
    }
    if (mSurface) {
        if (mAtlas) {
            mAtlas->bindForSampling(mDiscardProgram);
            draw(*mSurface, mDiscardProgram);
        } else {
            draw(*mSurface, mPlainProgram);
        }
    }
    if (mCut) draw(*mCut, mPlainProgram);
    if (mGpuCut) {
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, mGpuCut->triangles().id());
        mPlainProgram.use();
        glBindVertexArray(mGpuCutVao.id());
        glBindBuffer(GL_DRAW_INDIRECT_BUFFER, mGpuCut->command().id());
        glDrawArraysIndirect(GL_TRIANGLES, nullptr);
        glBindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
        glBindVertexArray(0);
    }
    glUseProgram(0);
    glDisable(GL_CULL_FACE);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    checkGlError("SurfaceRenderer::render");
}

Frame SurfaceRenderer::readFrame() const
{
    Frame f;
    f.width = mWidth;
    f.height = mHeight;
    const size_t n = f.pixelCount();
    std::vector<uint8_t> rgba(n * 4);
    std::vector<float> normal(n * 4), depth(n);
    std::vector<uint32_t> fragment(n);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glGetTextureImage(mColour.id(), 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(rgba.size()), rgba.data());
    glGetTextureImage(mNormal.id(), 0, GL_RGBA, GL_FLOAT, GLsizei(normal.size() * sizeof(float)), normal.data());
    glGetTextureImage(mDepthOut.id(), 0, GL_RED, GL_FLOAT, GLsizei(depth.size() * sizeof(float)), depth.data());
    glGetTextureImage(mFragment.id(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT, GLsizei(fragment.size() * sizeof(uint32_t)),
                      fragment.data());
    checkGlError("SurfaceRenderer::readFrame");
    // GL rows go bottom-up; frames top-down.
    f.rgba.resize(n * 4);
    f.depth.resize(n);
    f.normals.resize(n);
    f.fragments.resize(n);
    for (int y = 0; y < mHeight; ++y) {
        const size_t src = size_t(mHeight - 1 - y) * size_t(mWidth), dst = size_t(y) * size_t(mWidth);
        std::copy_n(rgba.begin() + long(4 * src), 4 * size_t(mWidth), f.rgba.begin() + long(4 * dst));
        std::copy_n(depth.begin() + long(src), size_t(mWidth), f.depth.begin() + long(dst));
        std::copy_n(fragment.begin() + long(src), size_t(mWidth), f.fragments.begin() + long(dst));
        for (int x = 0; x < mWidth; ++x) {
            const float* nv = &normal[4 * (src + size_t(x))];
            f.normals[dst + size_t(x)] = glm::vec3(nv[0], nv[1], nv[2]);
        }
    }
    return f;
}

float SurfaceRenderer::viewDepthAt(int x, int y) const
{
    if (x < 0 || y < 0 || x >= mWidth || y >= mHeight) return std::numeric_limits<float>::infinity();
    float depth = std::numeric_limits<float>::infinity();
    glGetTextureSubImage(mDepthOut.id(), 0, x, mHeight - 1 - y, 0, 1, 1, 1, GL_RED, GL_FLOAT, sizeof depth, &depth);
    checkGlError("SurfaceRenderer::viewDepthAt");
    return depth;
}

uint32_t SurfaceRenderer::fragmentIdAt(int x, int y) const
{
    if (x < 0 || y < 0 || x >= mWidth || y >= mHeight) return 0;
    uint32_t id = 0;
    glGetTextureSubImage(mFragment.id(), 0, x, mHeight - 1 - y, 0, 1, 1, 1, GL_RED_INTEGER, GL_UNSIGNED_INT, sizeof id, &id);
    checkGlError("SurfaceRenderer::fragmentIdAt");
    return id;
}

} // namespace mtcut::render
