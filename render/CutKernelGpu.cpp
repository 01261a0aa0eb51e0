// See CutKernelGpu.h.
#include "render/CutKernelGpu.h"

#include "cutter/RemeshKernel.h"
#include "render/CutGeometry.h"
#include "render/Shaders.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>
#include <unordered_map>
#include <utility>

namespace mtcut::render {

namespace {

constexpr size_t kStrideU = 48, kStrideD = 32; // per tet, as cut_phase_one.comp

// The arrangement's capacities (cut_arrange.glsl's ARR_MAX_*, defined from
// these): vertices, planes, surfaces of a tet; pieces and corners per
// region of its piece pool. 256 vertices: 128 held 9 of 7,520 tets of the
// kerf 0.5 test back.
constexpr size_t kArrVerts = 256, kArrPlanes = 96, kArrSurfaces = 24, kArrPieces = 64, kArrPool = 640;
// The regions' (cut_regions.glsl): nodes (corners with their side tags),
// regions, loops and loop corners of a tet.
constexpr size_t kArrNodes = 256, kArrRegions = 48, kArrLoops = 64, kArrLoopCorners = 768;
// Scratch words per tet: cut_arrange.glsl's kScratchI/L/D, which it checks
// against these (ARR_SCRATCH_*) when it compiles, as cut_regions.glsl
// checks its layout against them.
constexpr size_t kScratchI = kArrVerts + 3 * kArrPool + 6 * kArrPieces + 2 * kArrPlanes + 16 + 12 * kArrSurfaces +
                             4 * kArrPieces + 8 + 5 * kArrNodes + 2 * kArrVerts + 5 * kArrRegions + 2 * kArrLoops +
                             kArrLoopCorners + 11 * kArrPool;
constexpr size_t kScratchL = 11 * kArrVerts + 3 * kArrPool + kArrPlanes + 5 * kArrSurfaces + 4 * kArrNodes +
                             kArrLoopCorners + kArrPool;
constexpr size_t kScratchD = 3 * kArrVerts + 3 * kArrSurfaces + 3 * kArrRegions;

std::string arrangeDefines()
{
    std::string d;
    const std::pair<const char*, size_t> defines[] = {
        {"ARR_MAX_VERTS", kArrVerts},     {"ARR_MAX_PLANES", kArrPlanes},   {"ARR_MAX_SURFACES", kArrSurfaces},
        {"ARR_MAX_PIECES", kArrPieces},   {"ARR_MAX_POOL", kArrPool},       {"ARR_MAX_NODES", kArrNodes},
        {"ARR_MAX_REGIONS", kArrRegions}, {"ARR_MAX_LOOPS", kArrLoops},     {"ARR_MAX_LOOP_CORNERS", kArrLoopCorners},
        {"ARR_SCRATCH_I", kScratchI},     {"ARR_SCRATCH_L", kScratchL},     {"ARR_SCRATCH_D", kScratchD}};
    for (const auto& [name, value] : defines) d += "#define " + std::string(name) + " " + std::to_string(value) + "\n";
    return d;
}

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
    float isovalue;
    bool prism;
    BoundInput(const cutter::PackedKernelInput& input, const Program& program)
        : cells(storage(input.cells.size() * sizeof(cutter::PackedKernelCell), input.cells.data(),
                        sizeof(cutter::PackedKernelCell))),
          quads(storage(input.quads.size() * sizeof(cutter::PackedKernelQuad), input.quads.data(),
                        sizeof(cutter::PackedKernelQuad))),
          sides(storage(input.sides.size() * sizeof(cutter::PackedKernelSide), input.sides.data(),
                        sizeof(cutter::PackedKernelSide))),
          tets(sizeof(input.tets), input.tets.data()), isovalue(input.isovalue), prism(input.prism)
    {
        setUniforms(program);
        const Buffer* bound[] = {&cells, &quads, &sides, &tets};
        for (GLuint b = 0; b < 4; ++b) glBindBufferBase(GL_SHADER_STORAGE_BUFFER, b, bound[b]->id());
    }
    /// The input's uniforms of a further program that reads the bound input.
    void setUniforms(const Program& program) const
    {
        glProgramUniform1f(program.id(), program.uniform("uIsovalue"), isovalue);
        glProgramUniform1i(program.id(), program.uniform("uPrism"), prism ? 1 : 0);
    }
};

/// One tet's record of cut_arrange.vert and cut_regions.vert, at most
/// `size` words at `w`: tet | fail << 32; vertices | surfaces << 32; nodes |
/// triangles << 32; per surface its plane, its piece count, per piece
/// (corners | kept << 32) and (vertex, label) per corner; per triangle its
/// three nodes, 21 bits each; per node (vertex | tags << 32) and its tags;
/// then 15 words per vertex. Throws when the record runs past its slot.
GpuArrangedTet parseArrangedTet(const uint64_t* w, size_t size)
{
    size_t at = 0;
    auto need = [&](size_t words, const char* what) {
        if (at + words > size)
            throw std::runtime_error(std::string("GpuCutKernel::arrangement: ") + what + " in the record of tet " +
                                     std::to_string(uint32_t(w[0])) + " (word " + std::to_string(at) + " of " +
                                     std::to_string(size) + ")");
    };
    GpuArrangedTet t;
    t.tet = uint32_t(w[0]);
    t.fail = uint32_t(w[0] >> 32);
    const size_t verts = uint32_t(w[1]), surfaces = uint32_t(w[1] >> 32);
    const size_t nodes = uint32_t(w[2]), triangles = uint32_t(w[2] >> 32);
    at = 3;
    for (size_t s = 0; s < surfaces; ++s) {
        need(2, "a truncated surface");
        GpuArrangedTet::Surface& surface = t.surfaces.emplace_back();
        surface.plane = w[at];
        const size_t pieces = w[at + 1];
        at += 2;
        for (size_t i = 0; i < pieces; ++i) {
            need(1, "a truncated piece");
            GpuArrangedTet::Piece& piece = surface.pieces.emplace_back();
            const size_t n = uint32_t(w[at]);
            piece.kept = (w[at] >> 32) != 0;
            ++at;
            need(2 * n, "a truncated piece");
            for (size_t k = 0; k < n; ++k) {
                piece.v.push_back(int(w[at + 2 * k]));
                piece.lab.push_back(w[at + 2 * k + 1]);
            }
            at += 2 * n;
        }
    }
    need(triangles, "truncated triangles");
    for (size_t i = 0; i < triangles; ++i, ++at) {
        const uint64_t x = w[at], mask = (uint64_t(1) << 21) - 1;
        t.triangles.push_back({int(x & mask), int(x >> 21 & mask), int(x >> 42 & mask)});
        t.triangleCap.push_back(uint8_t(x >> 63));
    }
    for (size_t i = 0; i < nodes; ++i) {
        need(1, "a truncated node table");
        GpuArrangedTet::Node& node = t.nodes.emplace_back();
        node.vert = int(uint32_t(w[at]));
        const size_t tags = uint32_t(w[at] >> 32);
        ++at;
        need(tags, "a truncated node table");
        node.tags.assign(w + at, w + at + tags);
        at += tags;
    }
    need(15 * verts, "a truncated vertex table");
    for (size_t v = 0; v < verts; ++v, at += 15) {
        GpuArrangedTet::Vertex& x = t.verts.emplace_back();
        const uint32_t meta = uint32_t(w[at]);
        x.dim = meta & 15u;
        x.planeCount = (meta >> 4) & 15u;
        x.support = (meta >> 8) & 15u;
        x.steiner = ((meta >> 12) & 1u) != 0;
        std::copy(w + at + 1, w + at + 4, x.feature);
        std::copy(w + at + 4, w + at + 12, x.planes);
        std::memcpy(x.pos, w + at + 12, sizeof x.pos);
    }
    return t;
}

/// MTCUT_GPU_CUT_TIMES=1: each stage's draws timed (glFinish after each,
/// so slower) and, per arrangement() call, the stages that took 100 ms or
/// more printed to stderr with their first draw's time, to find where a
/// driver's first-use work goes (NVIDIA 580: the first cut of a process
/// took 28-58 s more than the next with the programs from the cache; the
/// driver's own disk cache keeps that work for later processes).
class StageTimes
{
public:
    StageTimes() : mOn(std::getenv("MTCUT_GPU_CUT_TIMES") && *std::getenv("MTCUT_GPU_CUT_TIMES") == '1') {}
    bool on() const { return mOn; }
    void add(const char* program, int stage, double ms)
    {
        Stage& s = mStages[{program, stage}];
        if (s.draws++ == 0) s.firstMs = ms;
        s.ms += ms;
    }
    void read(size_t words, size_t slotWords)
    {
        mReadWords += words;
        mSlotWords += slotWords;
    }
    void print(size_t tets) const
    {
        if (!mOn) return;
        double all = 0.0;
        for (const auto& [key, s] : mStages) all += s.ms;
        std::fprintf(stderr, "gpu cut stages: %zu tets, %.1f ms in draws; records: %.1f MB read back of %.1f MB of slots\n",
                     tets, all, double(mReadWords) * 8e-6, double(mSlotWords) * 8e-6);
        for (const auto& [key, s] : mStages)
            if (s.ms >= 100.0)
                std::fprintf(stderr, "  %s stage %d: %zu draws, %.1f ms, the first %.1f ms\n", key.first.c_str(), key.second,
                             s.draws, s.ms, s.firstMs);
    }

private:
    struct Stage
    {
        size_t draws = 0;
        double ms = 0.0, firstMs = 0.0;
    };
    bool mOn;
    std::map<std::pair<std::string, int>, Stage> mStages;
    size_t mReadWords = 0, mSlotWords = 0;
};

} // namespace

namespace {
constexpr GLbitfield kReadWrite = GL_DYNAMIC_STORAGE_BIT | GL_MAP_READ_BIT;
struct DrawCommand
{
    GLuint count = 0, instances = 1, first = 0, baseInstance = 0, made = 0;
};
} // namespace

GpuCutDraw::GpuCutDraw(size_t capacity)
    : mCapacity(std::max<size_t>(capacity, 1)), mVertices(mCapacity * 18 * sizeof(float), nullptr, kReadWrite),
      mTriangles(mCapacity * 4 * sizeof(int32_t), nullptr, kReadWrite),
      mKeys(mCapacity * 2 * sizeof(uint32_t), nullptr, kReadWrite), mCommand(sizeof(DrawCommand), nullptr, kReadWrite)
{
    if (mCapacity > size_t(std::numeric_limits<GLsizei>::max() / 3))
        throw std::length_error("GpuCutDraw: capacity past what one draw holds");
    clear();
}

void GpuCutDraw::clear()
{
    const DrawCommand c;
    glNamedBufferSubData(mCommand.id(), 0, sizeof c, &c);
}

size_t GpuCutDraw::triangleCount() const
{
    GLuint count = 0;
    glGetNamedBufferSubData(mCommand.id(), 0, sizeof count, &count);
    return count / 3;
}

size_t GpuCutDraw::made() const
{
    DrawCommand c;
    glGetNamedBufferSubData(mCommand.id(), 0, sizeof c, &c);
    return c.made;
}

std::vector<std::array<uint32_t, 2>> GpuCutDraw::keys() const
{
    std::vector<std::array<uint32_t, 2>> k(triangleCount());
    if (!k.empty()) glGetNamedBufferSubData(mKeys.id(), 0, GLsizeiptr(k.size() * sizeof k[0]), k.data());
    return k;
}

void GpuCutDraw::setFragmentIds(const std::vector<uint32_t>& ids)
{
    const size_t n = triangleCount();
    if (ids.size() != n) throw std::invalid_argument("GpuCutDraw::setFragmentIds: one id per triangle expected");
    if (n == 0) return;
    std::vector<int32_t> info(4 * n);
    glGetNamedBufferSubData(mTriangles.id(), 0, GLsizeiptr(info.size() * sizeof(int32_t)), info.data());
    for (size_t t = 0; t < n; ++t) {
        if (ids[t] >= (1u << 30)) throw std::invalid_argument("GpuCutDraw::setFragmentIds: an id past 2^30");
        info[4 * t + 3] = int32_t((uint32_t(info[4 * t + 3]) & 0xc0000000u) | ids[t]);
    }
    glNamedBufferSubData(mTriangles.id(), 0, GLsizeiptr(info.size() * sizeof(int32_t)), info.data());
}

void GpuCutDraw::append(const cutter::Mesh& mesh, const std::vector<uint8_t>& isCap)
{
    const size_t nt = mesh.triangleCount();
    if (isCap.size() != nt || mesh.triangleVoxels.size() != nt || mesh.normals.size() != mesh.positions.size())
        throw std::invalid_argument("GpuCutDraw::append: mesh arrays of mismatched sizes");
    if (nt == 0) return;
    DrawCommand c;
    glGetNamedBufferSubData(mCommand.id(), 0, sizeof c, &c);
    const size_t at = c.count / 3;
    if (nt > mCapacity - at) throw std::length_error("GpuCutDraw::append: past the capacity");
    std::vector<float> v(18 * nt);
    std::vector<int32_t> info(4 * nt);
    std::vector<uint32_t> keys(2 * nt, ~0u);
    for (size_t t = 0; t < nt; ++t) {
        for (size_t k = 0; k < 3; ++k) {
            const uint32_t i = mesh.indices[3 * t + k];
            for (int a = 0; a < 3; ++a) {
                v[18 * t + 6 * k + size_t(a)] = mesh.positions[i][a];
                v[18 * t + 6 * k + 3 + size_t(a)] = mesh.normals[i][a];
            }
        }
        const glm::ivec3 cell = mesh.triangleVoxels[t];
        info[4 * t] = cell.x;
        info[4 * t + 1] = cell.y;
        info[4 * t + 2] = cell.z;
        info[4 * t + 3] = int32_t(1u | (isCap[t] ? 0x40000000u : 0u) | 0x80000000u);
    }
    glNamedBufferSubData(mVertices.id(), GLintptr(18 * at * sizeof(float)), GLsizeiptr(v.size() * sizeof(float)), v.data());
    glNamedBufferSubData(mTriangles.id(), GLintptr(4 * at * sizeof(int32_t)), GLsizeiptr(info.size() * sizeof(int32_t)),
                         info.data());
    glNamedBufferSubData(mKeys.id(), GLintptr(2 * at * sizeof(uint32_t)), GLsizeiptr(keys.size() * sizeof(uint32_t)),
                         keys.data());
    c.count += GLuint(3 * nt);
    c.made += GLuint(nt);
    glNamedBufferSubData(mCommand.id(), 0, sizeof c, &c);
    checkGlError("GpuCutDraw::append");
}

PointPass::PointPass()
{
    glNamedFramebufferParameteri(mFbo.id(), GL_FRAMEBUFFER_DEFAULT_WIDTH, 1);
    glNamedFramebufferParameteri(mFbo.id(), GL_FRAMEBUFFER_DEFAULT_HEIGHT, 1);
    glBindFramebuffer(GL_FRAMEBUFFER, mFbo.id());
    glBindVertexArray(mVao.id());
    glEnable(GL_RASTERIZER_DISCARD);
}

PointPass::~PointPass()
{
    glDisable(GL_RASTERIZER_DISCARD);
    glBindVertexArray(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

void PointPass::draw(size_t count) const { glDrawArrays(GL_POINTS, 0, GLsizei(count)); }

std::string cutPassLibrary(const std::string& name)
{
    const bool big = name == "cut_arrange.vert" || name == "cut_regions.vert";
    const char* vendor = reinterpret_cast<const char*>(glGetString(GL_VENDOR));
    std::string library = big && vendor && std::strstr(vendor, "NVIDIA") ? "#pragma optionNV(unroll none)\n" : "";
    library += shaderSource("doubles.glsl") + shaderSource("cut_kernel.glsl");
    if (big) library += arrangeDefines() + shaderSource("cut_arrange.glsl");
    if (name == "cut_regions.vert") library += shaderSource("poly2.glsl") + shaderSource("cut_regions.glsl");
    return library;
}

std::string poly2Library() { return shaderSource("doubles.glsl") + shaderSource("poly2.glsl"); }

GpuCutKernel::GpuCutKernel()
    : mPhaseOne(buildProgram({"cut_phase_one.comp"}, cutPassLibrary("cut_phase_one.comp"))),
      mVertexPositions(buildProgram({"cut_vertex_positions.comp"}, cutPassLibrary("cut_vertex_positions.comp"))),
      mNames(buildProgram({"cut_names.comp"}, cutPassLibrary("cut_names.comp"))),
      mArrange(buildProgram({"cut_arrange.vert"}, cutPassLibrary("cut_arrange.vert"))),
      mRegions(buildProgram({"cut_regions.vert"}, cutPassLibrary("cut_regions.vert")))
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

std::vector<GpuArrangedTet> GpuCutKernel::arrangement(const cutter::PackedKernelInput& input, size_t firstTet,
                                                      size_t tetCount, size_t lanesPerTet, GpuCutDraw* target) const
{
    if (lanesPerTet == 0) throw std::invalid_argument("GpuCutKernel::arrangement: lanesPerTet 0");
    if (firstTet > 5 * input.cells.size() || tetCount > 5 * input.cells.size() - firstTet)
        throw std::out_of_range("GpuCutKernel::arrangement: tets " + std::to_string(firstTet) + " + " +
                                std::to_string(tetCount) + " past the input's " +
                                std::to_string(5 * input.cells.size()));
    std::vector<GpuArrangedTet> out;
    if (tetCount == 0) return out;
    const BoundInput bound(input, mArrange);
    bound.setUniforms(mRegions);
    // Scratch per invocation (kScratchI/L/D), for a batch of invocations at a time.
    constexpr size_t kBatch = 1020; // whole cells (the draw's kStageEmit looks at a tet's cell)
    constexpr int kStageEnd = 1 + 2 * int(kArrSurfaces);                            // cut_arrange.vert
    constexpr int kStageCorners = int(kArrSurfaces), kStageClose = 2 * int(kArrSurfaces) + 1, // cut_regions.vert
        kStageEmit = kStageClose + 1;
    const size_t batch = std::min(tetCount, kBatch);
    const Buffer scratchI(batch * kScratchI * sizeof(int32_t), nullptr);
    const Buffer scratchL(batch * kScratchL * sizeof(uint64_t), nullptr);
    const Buffer scratchD(batch * kScratchD * sizeof(double), nullptr);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, scratchI.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, scratchL.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 8, scratchD.id());
    constexpr size_t kSlot = 8192; // words per tet's record
    const Buffer records(batch * kSlot * sizeof(uint64_t), nullptr, GL_MAP_READ_BIT);
    // The records' used words, packed on the GPU (glCopyNamedBufferSubData)
    // and read back in one call: a tet's record is a few thousand words of
    // its 8,192 and most tets hold no solid (bench_render's 425-cell crop
    // cut: 1.4 MB read back of the slots' 139 MB, 67 MB a batch of 1,020).
    const Buffer packed(batch * kSlot * sizeof(uint64_t), nullptr, GL_MAP_READ_BIT);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, records.id());
    const Buffer tetList(batch * sizeof(GLuint), nullptr, GL_DYNAMIC_STORAGE_BIT);
    const Buffer tetStatus(batch * sizeof(GLint), nullptr, GL_MAP_READ_BIT);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, tetList.id());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 9, tetStatus.id());
    std::vector<GLint> status(batch), words(batch);
    for (const Program* p : {&mArrange, &mRegions}) {
        glProgramUniform1ui(p->id(), p->uniform("uSlotWords"), GLuint(kSlot));
        glProgramUniform1ui(p->id(), p->uniform("uLaneStride"), GLuint(lanesPerTet));
        glProgramUniform1i(p->id(), p->uniform("uProbeTrips"), 2);
    }
    // Pass 3's draw: the triangles into `target`, shaded from the value blocks.
    Buffer blocks;
    if (target) {
        if (firstTet % 5 != 0 || tetCount % 5 != 0)
            throw std::invalid_argument("GpuCutKernel::arrangement: a draw takes whole cells");
        if (input.blocks.size() != 64 * input.cells.size())
            throw std::invalid_argument("GpuCutKernel::arrangement: the input has no value blocks to draw with");
        blocks = storage(input.blocks.size() * sizeof(float), input.blocks.data(), sizeof(float));
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 10, blocks.id());
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 11, target->vertices().id());
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 12, target->triangles().id());
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 13, target->keysBuffer().id());
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 14, target->command().id());
        const GLuint id = mRegions.id();
        glProgramUniform3d(id, mRegions.uniform("uOrigin"), input.origin[0], input.origin[1], input.origin[2]);
        glProgramUniform3d(id, mRegions.uniform("uSpacing"), input.spacing[0], input.spacing[1], input.spacing[2]);
        glProgramUniform1ui(id, mRegions.uniform("uDrawCapacity"), GLuint(target->capacity()));
    }
    const PointPass pass;
    StageTimes times;
    std::vector<uint64_t> slots(batch * kSlot);
    for (size_t from = 0; from < tetCount; from += batch) {
        const size_t count = std::min(batch, tetCount - from);
        for (const Program* p : {&mArrange, &mRegions})
            glProgramUniform1ui(p->id(), p->uniform("uFirstTet"), GLuint(firstTet + from));
        // The stages (cut_arrange.vert, cut_regions.vert), each over the
        // slots that have it: the tet; per surface its split, finish and
        // regions; the corners; per surface its triangles; the node table;
        // the vertex table.
        std::vector<GLuint> list(count);
        for (size_t i = 0; i < count; ++i) list[i] = GLuint(i);
        auto draw = [&](const Program& program, int stage) {
            program.use();
            glNamedBufferSubData(tetList.id(), 0, GLsizeiptr(list.size() * sizeof(GLuint)), list.data());
            glProgramUniform1ui(program.id(), program.uniform("uListCount"), GLuint(list.size()));
            glProgramUniform1i(program.id(), program.uniform("uStage"), stage);
            if (times.on()) glFinish();
            const auto start = std::chrono::steady_clock::now();
            pass.draw(list.size() * lanesPerTet);
            glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
            if (!times.on()) return;
            glFinish();
            times.add(&program == &mArrange ? "cut_arrange.vert" : "cut_regions.vert", stage,
                      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
        };
        auto listSlots = [&](int minStatus) {
            list.clear();
            for (size_t i = 0; i < count; ++i)
                if (status[i] >= minStatus) list.push_back(GLuint(i));
            return !list.empty();
        };
        draw(mArrange, 0);
        glGetNamedBufferSubData(tetStatus.id(), 0, GLsizeiptr(count * sizeof(GLint)), status.data());
        for (int surface = 0; surface < int(kArrSurfaces) && listSlots(surface + 1); ++surface) {
            draw(mArrange, 1 + 2 * surface); // split
            draw(mArrange, 2 + 2 * surface); // conform, classify, write
            draw(mRegions, surface);         // regions
        }
        if (listSlots(1)) {
            draw(mRegions, kStageCorners);
            for (int surface = 0; surface < int(kArrSurfaces) && listSlots(surface + 1); ++surface)
                draw(mRegions, kStageCorners + 1 + surface);
            listSlots(1);
            draw(mRegions, kStageClose);
        }
        if (listSlots(-1)) draw(mArrange, kStageEnd);
        if (target && listSlots(1)) draw(mRegions, kStageEmit);
        glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT | GL_VERTEX_ATTRIB_ARRAY_BARRIER_BIT);
        // Each record's length (tetStatus after the end; a tet without
        // solid, status -2, has none), then the records packed, in slot
        // order (ascending tets).
        glGetNamedBufferSubData(tetStatus.id(), 0, GLsizeiptr(count * sizeof(GLint)), words.data());
        std::vector<std::pair<size_t, size_t>> at; // each record's first word in `packed`, its words
        size_t total = 0;
        for (size_t i = 0; i < count; ++i) {
            if (status[i] == -2) continue;
            if (words[i] < 3 || size_t(words[i]) > kSlot)
                throw std::runtime_error("GpuCutKernel::arrangement: a record of " + std::to_string(words[i]) +
                                         " words for tet " + std::to_string(firstTet + from + i));
            glCopyNamedBufferSubData(records.id(), packed.id(), GLintptr(i * kSlot * sizeof(uint64_t)),
                                     GLintptr(total * sizeof(uint64_t)), GLsizeiptr(size_t(words[i]) * sizeof(uint64_t)));
            at.emplace_back(total, size_t(words[i]));
            total += size_t(words[i]);
        }
        if (total > 0) glGetNamedBufferSubData(packed.id(), 0, GLsizeiptr(total * sizeof(uint64_t)), slots.data());
        times.read(total, count * kSlot);
        for (const auto& [first, n] : at) out.push_back(parseArrangedTet(&slots[first], n));
    }
    glUseProgram(0);
    checkGlError("GpuCutKernel::arrangement");
    times.print(tetCount);
    return out;
}

std::vector<GpuCutCell> GpuCutKernel::cutCells(const cutter::PackedKernelInput& input, size_t lanesPerTet,
                                               GpuCutDraw* draw) const
{
    const size_t cellCount = input.cells.size();
    std::vector<GpuCutCell> out(cellCount);
    for (GpuCutCell& c : out) c.complete = true;
    const std::vector<GpuArrangedTet> tets = arrangement(input, 0, 5 * cellCount, lanesPerTet, draw);
    std::unordered_map<cutter::CutVertexId, uint32_t, cutter::CutVertexIdHash> index;
    size_t indexCell = cellCount;
    for (const GpuArrangedTet& t : tets) {
        GpuCutCell& cell = out[t.tet / 5];
        if (!cell.complete) continue;
        if (t.fail != 0) {
            cell.complete = false;
            cell.geometry.clear();
            cell.tetTriangles = {};
            continue;
        }
        if (indexCell != t.tet / 5) { // the tets come ascending: a new cell
            index.clear();
            indexCell = t.tet / 5;
        }
        cutter::CutCellGeometry& g = cell.geometry;
        cell.tetTriangles[t.tet % 5] = uint32_t(t.triangles.size());
        g.cap.insert(g.cap.end(), t.triangleCap.begin(), t.triangleCap.end());
        for (const std::array<int, 3>& tri : t.triangles)
            for (int n : tri) {
                if (n < 0 || size_t(n) >= t.nodes.size() || size_t(t.nodes[size_t(n)].vert) >= t.verts.size())
                    throw std::runtime_error("GpuCutKernel::cutCells: a triangle past the node or vertex table of tet " +
                                             std::to_string(t.tet));
                const GpuArrangedTet::Node& node = t.nodes[size_t(n)];
                const GpuArrangedTet::Vertex& v = t.verts[size_t(node.vert)];
                cutter::CutVertexId id;
                id.dim = uint8_t(v.dim);
                id.planeCount = uint8_t(v.planeCount);
                std::copy(v.feature, v.feature + 3, id.feature.begin());
                std::copy(v.planes, v.planes + 8, id.planes.begin());
                if (node.tags.size() > id.tags.size())
                    throw std::runtime_error("GpuCutKernel::cutCells: more than 4 tags in tet " + std::to_string(t.tet));
                id.tagCount = uint8_t(node.tags.size());
                std::copy(node.tags.begin(), node.tags.end(), id.tags.begin());
                auto it = index.find(id);
                if (it == index.end()) {
                    it = index.emplace(id, uint32_t(g.vertexIds.size())).first;
                    g.vertexIds.push_back(id);
                    g.indexPositions.emplace_back(v.pos[0], v.pos[1], v.pos[2]);
                }
                g.indices.push_back(it->second);
            }
    }
    return out;
}

RecoveredCells recoverCutCells(const GpuCutKernel& gpu, const vdb::Volume& volume, float isovalue,
                               const cutter::CutMask& mask, const std::vector<openvdb::Coord>& cells,
                               size_t lanesPerTet, GpuCutDraw* draw)
{
    const cutter::PackedKernelInput input = cutter::packKernelInput(volume, isovalue, mask, cells);
    if (draw) draw->clear();
    std::vector<GpuCutCell> gpuCells = gpu.cutCells(input, lanesPerTet, draw);
    if (draw && draw->made() > draw->triangleCount())
        throw std::length_error("recoverCutCells: the GPU made " + std::to_string(draw->made()) +
                                " triangles, the draw buffers hold " + std::to_string(draw->capacity()));
    RecoveredCells r;
    r.cells.resize(cells.size());
    r.madeByGpu.resize(cells.size());
    r.tetTriangles.resize(cells.size());
    cutter::remesh_detail::CellKernel cpu(volume, isovalue);
    cutter::remesh_detail::KernelQuads kernelQuads(mask, volume, isovalue);
    const bool prism = mask.kerf() > 0;
    for (size_t i = 0; i < cells.size(); ++i) {
        const std::vector<cutter::remesh_detail::QuadGeom> quads = kernelQuads.of(cells[i]);
        r.madeByGpu[i] = gpuCells[i].complete;
        r.tetTriangles[i] = gpuCells[i].tetTriangles;
        if (gpuCells[i].complete) {
            r.cells[i] = std::move(gpuCells[i].geometry);
            cpu.finish(cells[i], quads, prism, r.cells[i]);
            r.byGpu += !r.cells[i].indices.empty();
        } else {
            cpu.remesh(cells[i], quads, prism, r.cells[i]);
            ++r.byCpu;
        }
    }
    if (draw) { // the cells the CPU took join the GPU's triangles
        std::vector<std::pair<openvdb::Coord, const cutter::CutCellGeometry*>> byCpu;
        for (size_t i = 0; i < cells.size(); ++i)
            if (!gpuCells[i].complete) byCpu.emplace_back(cells[i], &r.cells[i]);
        const CutGeometry g = cutGeometryOfCells(byCpu, volume, isovalue, CutNormals::Shading);
        draw->append(g.mesh, g.triangleIsCap);
    }
    return r;
}

std::vector<uint32_t> gpuCutFragmentIds(const GpuCutDraw& draw, const RecoveredCells& rec,
                                        const std::vector<openvdb::Coord>& cells, const cutter::CutRemesher& remesher,
                                        const std::vector<uint32_t>& cutIds, size_t* approximate)
{
    std::map<openvdb::Coord, size_t> first;
    size_t n = 0;
    for (const auto& [c, g] : remesher.cells()) {
        first[c] = n;
        n += g.indices.size() / 3;
    }
    std::vector<std::pair<size_t, size_t>> byCpu; // (cell, triangle) in the order recoverCutCells appends them
    for (size_t i = 0; i < cells.size(); ++i)
        if (!rec.madeByGpu[i])
            for (size_t j = 0; j < rec.cells[i].indices.size() / 3; ++j) byCpu.emplace_back(i, j);
    const std::vector<std::array<uint32_t, 2>> keys = draw.keys();
    std::vector<uint32_t> ids(keys.size(), 0);
    size_t nextCpu = 0;
    size_t approx = 0;
    for (size_t s = 0; s < keys.size(); ++s) {
        size_t cell = 0, k = 0;
        if (keys[s][0] == ~0u) {
            std::tie(cell, k) = byCpu.at(nextCpu++);
        } else {
            cell = keys[s][0] / 5;
            size_t made = 0;
            for (uint32_t t = 0; t < 5; ++t) {
                if (t < keys[s][0] % 5) k += rec.tetTriangles[cell][t];
                made += rec.tetTriangles[cell][t];
            }
            k += keys[s][1];
            const size_t now = rec.cells[cell].indices.size() / 3;
            if (made != now) {
                ++approx;
                k = std::min(k, now - 1);
            }
        }
        ids[s] = cutIds.at(first.at(cells.at(cell)) + k);
    }
    if (approximate) *approximate = approx;
    return ids;
}


} // namespace mtcut::render
