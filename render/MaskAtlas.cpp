#include "render/MaskAtlas.h"

#include "render/Shaders.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace mtcut::render {

namespace {

int maxTextureSize()
{
    GLint v = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &v);
    return std::max(v, 1);
}

/// A (width, height) for n texels: width min(n, limit), height ceil(n / width).
void layoutTexels(size_t n, int limit, int& width, int& height, const char* what)
{
    width = int(std::max<size_t>(1, std::min<size_t>(n, size_t(limit))));
    const size_t h = std::max<size_t>(1, (n + size_t(width) - 1) / size_t(width));
    if (h > size_t(limit)) {
        throw std::runtime_error(std::string("mask atlas: ") + what + " needs " + std::to_string(n) +
                                 " texels, more than the largest 2D texture (" + std::to_string(limit) + "^2)");
    }
    height = int(h);
}

} // namespace

std::string maskShaderLibrary()
{
    return shaderSource("mask.glsl");
}

MaskAtlas::MaskAtlas(const MaskTiling& tiling)
    : mSlots(tiling.slotCount()), mLeafMin(tiling.leafMin), mLeafExtent(tiling.leafExtent)
{
    const int limit = maxTextureSize();
    // 2048 keeps rows short for readback and still holds 2048 * limit slots.
    layoutTexels(mSlots, std::min(limit, 2048), mWidth, mHeight, "the tiles");
    layoutTexels(tiling.indirection.size(), std::min(limit, 4096), mIndirectionWidth, mIndirectionHeight, "the indirection");

    glTextureStorage3D(mAtlas.id(), 1, GL_RGBA32UI, mWidth, mHeight, 4);
    glTextureParameteri(mAtlas.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(mAtlas.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    const GLuint zero[4] = {0, 0, 0, 0};
    glClearTexImage(mAtlas.id(), 0, GL_RGBA_INTEGER, GL_UNSIGNED_INT, zero);

    glTextureStorage2D(mIndirection.id(), 1, GL_R32UI, mIndirectionWidth, mIndirectionHeight);
    glTextureParameteri(mIndirection.id(), GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(mIndirection.id(), GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    std::vector<uint32_t> table(size_t(mIndirectionWidth) * size_t(mIndirectionHeight), 0u);
    std::copy(tiling.indirection.begin(), tiling.indirection.end(), table.begin());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTextureSubImage2D(mIndirection.id(), 0, 0, 0, mIndirectionWidth, mIndirectionHeight, GL_RED_INTEGER,
                        GL_UNSIGNED_INT, table.data());
    checkGlError("MaskAtlas: allocating the atlas");
}

void MaskAtlas::uploadTiles(const MaskTiling& tiling)
{
    if (tiling.slotCount() != mSlots) throw std::logic_error("MaskAtlas::uploadTiles: another tiling's tiles");
    // Layer L of texel s holds words 4L..4L+3 of slot s.
    const size_t layerTexels = size_t(mWidth) * size_t(mHeight);
    std::vector<uint32_t> texels(layerTexels * 4 * 4, 0u);
    for (size_t s = 0; s < mSlots; ++s) {
        for (int w = 0; w < kTileWords; ++w) {
            texels[((size_t(w >> 2) * layerTexels) + s) * 4 + size_t(w & 3)] = tiling.words[s * kTileWords + size_t(w)];
        }
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTextureSubImage3D(mAtlas.id(), 0, 0, 0, 0, mWidth, mHeight, 4, GL_RGBA_INTEGER, GL_UNSIGNED_INT, texels.data());
    checkGlError("MaskAtlas::uploadTiles");
}

void MaskAtlas::setLookupUniforms(const Program& program) const
{
    glProgramUniform3i(program.id(), program.uniform("uMaskLeafMin"), mLeafMin.x(), mLeafMin.y(), mLeafMin.z());
    glProgramUniform3i(program.id(), program.uniform("uMaskLeafExtent"), mLeafExtent.x(), mLeafExtent.y(),
                       mLeafExtent.z());
    glProgramUniform1i(program.id(), program.uniform("uMaskIndirectionWidth"), mIndirectionWidth);
    glProgramUniform1i(program.id(), program.uniform("uMaskAtlasWidth"), mWidth);
    glProgramUniform1i(program.id(), program.uniform("uMaskAtlasHeight"), mHeight);
}

void MaskAtlas::bindForSampling(const Program& program) const
{
    glBindTextureUnit(0, mIndirection.id());
    glBindTextureUnit(1, mAtlas.id());
    setLookupUniforms(program);
}

void MaskAtlas::writeCells(const std::vector<openvdb::Coord>& cells)
{
    const GLuint zero[4] = {0, 0, 0, 0};
    glClearTexImage(mAtlas.id(), 0, GL_RGBA_INTEGER, GL_UNSIGNED_INT, zero);
    if (cells.empty() || mSlots == 0) return;

    const Program program = buildProgram({"mask_write.vert", "mask_write.frag"}, maskShaderLibrary());
    Framebuffer fbo;
    GLenum drawBuffers[4];
    for (int layer = 0; layer < 4; ++layer) {
        glNamedFramebufferTextureLayer(fbo.id(), GLenum(GL_COLOR_ATTACHMENT0 + layer), mAtlas.id(), 0, layer);
        drawBuffers[layer] = GLenum(GL_COLOR_ATTACHMENT0 + layer);
    }
    glNamedFramebufferDrawBuffers(fbo.id(), 4, drawBuffers);
    fbo.checkComplete("MaskAtlas::writeCells");

    static_assert(sizeof(openvdb::Coord) == 3 * sizeof(int32_t), "Coord must be three packed int32");
    const Buffer points(cells.size() * sizeof(openvdb::Coord), cells.data());
    VertexArray vao;
    glVertexArrayVertexBuffer(vao.id(), 0, points.id(), 0, GLsizei(sizeof(openvdb::Coord)));
    glEnableVertexArrayAttrib(vao.id(), 0);
    glVertexArrayAttribIFormat(vao.id(), 0, 3, GL_INT, 0);
    glVertexArrayAttribBinding(vao.id(), 0, 0);

    glBindFramebuffer(GL_FRAMEBUFFER, fbo.id());
    glViewport(0, 0, mWidth, mHeight);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_CULL_FACE);
    glDisable(GL_PROGRAM_POINT_SIZE);
    glPointSize(1.0f);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glEnable(GL_COLOR_LOGIC_OP);
    glLogicOp(GL_OR);
    program.use();
    glBindTextureUnit(0, mIndirection.id());
    glBindTextureUnit(1, 0); // the atlas is the render target: never sampled here
    setLookupUniforms(program);
    glBindVertexArray(vao.id());
    glDrawArrays(GL_POINTS, 0, GLsizei(cells.size()));
    glBindVertexArray(0);
    glDisable(GL_COLOR_LOGIC_OP);
    glLogicOp(GL_COPY);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glUseProgram(0);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
    checkGlError("MaskAtlas::writeCells");
}

std::vector<uint32_t> MaskAtlas::readWords() const
{
    const size_t layerTexels = size_t(mWidth) * size_t(mHeight);
    std::vector<uint32_t> texels(layerTexels * 4 * 4);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(mAtlas.id(), 0, GL_RGBA_INTEGER, GL_UNSIGNED_INT, GLsizei(texels.size() * sizeof(uint32_t)),
                      texels.data());
    checkGlError("MaskAtlas::readWords");
    std::vector<uint32_t> words(mSlots * kTileWords);
    for (size_t s = 0; s < mSlots; ++s) {
        for (int w = 0; w < kTileWords; ++w) {
            words[s * kTileWords + size_t(w)] = texels[((size_t(w >> 2) * layerTexels) + s) * 4 + size_t(w & 3)];
        }
    }
    return words;
}

std::vector<uint8_t> MaskAtlas::queryCells(const std::vector<openvdb::Coord>& cells) const
{
    std::vector<uint8_t> out(cells.size(), 0);
    if (cells.empty()) return out;
    const Program program = buildProgram({"mask_query.comp"}, maskShaderLibrary());
    std::vector<int32_t> packed(cells.size() * 4, 0);
    for (size_t i = 0; i < cells.size(); ++i)
        for (int a = 0; a < 3; ++a) packed[4 * i + size_t(a)] = cells[i][a];
    const Buffer in(packed.size() * sizeof(int32_t), packed.data());
    const Buffer answers(cells.size() * sizeof(uint32_t), nullptr, GL_MAP_READ_BIT);
    program.use();
    bindForSampling(program);
    glProgramUniform1ui(program.id(), program.uniform("uCount"), GLuint(cells.size()));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, in.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, answers.id());
    glDispatchCompute(GLuint((cells.size() + 63) / 64), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<uint32_t> result(cells.size());
    glGetNamedBufferSubData(answers.id(), 0, GLsizeiptr(result.size() * sizeof(uint32_t)), result.data());
    glUseProgram(0);
    checkGlError("MaskAtlas::queryCells");
    for (size_t i = 0; i < cells.size(); ++i) out[i] = uint8_t(result[i] != 0);
    return out;
}

} // namespace mtcut::render
