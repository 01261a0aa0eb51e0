// See CutKernelGpu.h.
#include "render/CutKernelGpu.h"

#include "render/Shaders.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace mtcut::render {

namespace {

constexpr size_t kStrideU = 48, kStrideD = 32; // per tet, as cut_phase_one.comp

/// A storage buffer of `bytes` (at least one element, GL wants a size) from `data`.
Buffer storage(size_t bytes, const void* data, size_t minimum)
{
    if (bytes == 0) return Buffer(minimum, nullptr);
    return Buffer(bytes, data);
}

/// The kernel's input buffers bound at 0-3 (KernelCells, KernelQuads,
/// KernelSides, KernelTets) and the uniforms of `program` set.
struct BoundInput
{
    Buffer cells, quads, sides, tets;
    BoundInput(const cutter::PackedKernelInput& input, const Program& program)
        : cells(storage(input.cells.size() * sizeof(cutter::PackedKernelCell), input.cells.data(),
                        sizeof(cutter::PackedKernelCell))),
          quads(storage(input.quads.size() * sizeof(cutter::PackedKernelQuad), input.quads.data(),
                        sizeof(cutter::PackedKernelQuad))),
          sides(storage(input.sides.size() * sizeof(cutter::PackedKernelSide), input.sides.data(),
                        sizeof(cutter::PackedKernelSide))),
          tets(sizeof(input.tets), input.tets.data())
    {
        glProgramUniform1f(program.id(), program.uniform("uIsovalue"), input.isovalue);
        glProgramUniform1i(program.id(), program.uniform("uPrism"), input.prism ? 1 : 0);
        const Buffer* bound[] = {&cells, &quads, &sides, &tets};
        for (GLuint b = 0; b < 4; ++b) glBindBufferBase(GL_SHADER_STORAGE_BUFFER, b, bound[b]->id());
    }
};

} // namespace

GpuCutKernel::GpuCutKernel()
    : mPhaseOne(buildProgram({"cut_phase_one.comp"}, shaderSource("cut_kernel.glsl"))),
      mVertexPositions(buildProgram({"cut_vertex_positions.comp"}, shaderSource("cut_kernel.glsl"))),
      mNames(buildProgram({"cut_names.comp"}, shaderSource("cut_kernel.glsl")))
{
}

std::vector<double> GpuCutKernel::vertexPositions(const cutter::PackedKernelInput& input,
                                                  const std::vector<GpuVertexQuery>& queries) const
{
    std::vector<double> out(3 * queries.size());
    if (queries.empty()) return out;
    mVertexPositions.use();
    const BoundInput bound(input, mVertexPositions);
    const Buffer in(queries.size() * sizeof(GpuVertexQuery), queries.data());
    const Buffer positions(out.size() * sizeof(double), nullptr, GL_MAP_READ_BIT);
    glProgramUniform1ui(mVertexPositions.id(), mVertexPositions.uniform("uQueryCount"), GLuint(queries.size()));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, in.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, positions.id());
    glDispatchCompute(GLuint((queries.size() + 63) / 64), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    glGetNamedBufferSubData(positions.id(), 0, GLsizeiptr(out.size() * sizeof(double)), out.data());
    glUseProgram(0);
    checkGlError("GpuCutKernel::vertexPositions");
    return out;
}

std::vector<GpuTetPhaseOne> GpuCutKernel::phaseOne(const cutter::PackedKernelInput& input) const
{
    const size_t tets = 5 * input.cells.size();
    std::vector<GpuTetPhaseOne> out(tets);
    if (tets == 0) return out;
    mPhaseOne.use();
    const BoundInput bound(input, mPhaseOne);
    const Buffer outU(tets * kStrideU * sizeof(uint32_t), nullptr, GL_MAP_READ_BIT);
    const Buffer outD(tets * kStrideD * sizeof(double), nullptr, GL_MAP_READ_BIT);
    glProgramUniform1ui(mPhaseOne.id(), mPhaseOne.uniform("uTetCount"), GLuint(tets));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, outU.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, outD.id());
    glDispatchCompute(GLuint((tets + 63) / 64), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<uint32_t> u(tets * kStrideU);
    std::vector<double> d(tets * kStrideD);
    glGetNamedBufferSubData(outU.id(), 0, GLsizeiptr(u.size() * sizeof(uint32_t)), u.data());
    glGetNamedBufferSubData(outD.id(), 0, GLsizeiptr(d.size() * sizeof(double)), d.data());
    glUseProgram(0);
    checkGlError("GpuCutKernel::phaseOne");
    for (size_t t = 0; t < tets; ++t) {
        const uint32_t* w = &u[t * kStrideU];
        GpuTetPhaseOne& r = out[t];
        r.flags = w[0];
        r.quadCount = w[1];
        r.triCount = w[2];
        r.corners[0] = w[3];
        r.corners[1] = w[4];
        std::memcpy(r.edges, w + 5, sizeof(r.edges));
        std::memcpy(r.quads, w + 13, sizeof(r.quads));
        std::memcpy(r.points, &d[t * kStrideD], sizeof(r.points));
        std::memcpy(r.planes, &d[t * kStrideD + 24], sizeof(r.planes));
    }
    return out;
}

std::vector<GpuName> GpuCutKernel::names(const cutter::PackedKernelInput& input,
                                         const std::vector<GpuNameQuery>& queries) const
{
    std::vector<GpuName> out(queries.size());
    if (queries.empty()) return out;
    mNames.use();
    const BoundInput bound(input, mNames);
    const Buffer in(queries.size() * sizeof(GpuNameQuery), queries.data());
    const Buffer names(10 * queries.size() * sizeof(uint64_t), nullptr, GL_MAP_READ_BIT);
    glProgramUniform1ui(mNames.id(), mNames.uniform("uQueryCount"), GLuint(queries.size()));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, in.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, names.id());
    glDispatchCompute(GLuint((queries.size() + 63) / 64), 1, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<uint64_t> words(10 * queries.size());
    glGetNamedBufferSubData(names.id(), 0, GLsizeiptr(words.size() * sizeof(uint64_t)), words.data());
    glUseProgram(0);
    checkGlError("GpuCutKernel::names");
    for (size_t i = 0; i < queries.size(); ++i) {
        const uint64_t* w = &words[10 * i];
        out[i].named = (w[0] & 1u) != 0;
        out[i].overflow = (w[0] & 2u) != 0;
        out[i].count = uint32_t(w[1]);
        std::copy(w + 2, w + 10, out[i].planes);
    }
    return out;
}

} // namespace mtcut::render
