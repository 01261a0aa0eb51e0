// The GPU cut pass (DESIGN "GPU passes", pass 3): the re-meshing kernel
// ported to GLSL (shaders/cut_kernel.glsl, cut_arrange.glsl,
// cut_regions.glsl), bit for bit the CPU kernel's, run over the tets of a
// batch of cut cells; and pass 4, recovery: its triangles read back into
// each cell's CutCellGeometry and finished as the CPU kernel finishes a
// cell (recoverCutCells). Its triangles are also written into draw
// buffers (GpuCutDraw) that SurfaceRenderer draws indirectly, with no trip
// through the CPU. Its pieces are exposed for the tests that hold each
// phase equal to the CPU's (phaseOne, vertexPositions, names, arrangement).
#pragma once

#include "cutter/KernelInput.h"
#include "cutter/Mesh.h"
#include "cutter/Remesh.h"
#include "render/GlObjects.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace mtcut::render {

/// Phase one of one tet as the shader writes it (cut_phase_one.comp).
struct GpuTetPhaseOne
{
    static constexpr uint32_t kMaxQuads = 35;
    uint32_t flags = 0;     ///< bit 0: some corner inside (else nothing is set); bit 1: more quads than kMaxQuads
    uint32_t quadCount = 0; ///< quads[0 .. quadCount): the reaching quads, indices into the cell's list
    uint32_t triCount = 0;  ///< marching-tetrahedra polygons
    uint32_t corners[2] = {0, 0};
    uint32_t edges[2][4] = {};           ///< tet edge of each corner: a | b << 2
    uint32_t quads[kMaxQuads] = {};
    double points[2][4][3] = {};          ///< each corner, index space
    double planes[2][4] = {};             ///< n.x, n.y, n.z, d per polygon
};

/// A vertex whose position the GPU computes from its name
/// (cut_vertex_positions.comp; 128 bytes, std430).
struct GpuVertexQuery
{
    uint32_t cell = 0; ///< index into PackedKernelInput::cells
    uint32_t tet = 0;
    uint32_t dim = 0;        ///< CutVertexId::dim
    uint32_t planeCount = 0; ///< CutVertexId::planeCount
    uint32_t support = 0;    ///< tet-local vertices of the smallest simplex holding it
    uint32_t pad[3] = {0, 0, 0};
    uint64_t planes[8] = {}; ///< CutVertexId::planes
    double pos0[4] = {0, 0, 0, 0}; ///< where it was made (kept for names that do not fix a point)
};
static_assert(sizeof(GpuVertexQuery) == 128, "std430 layout of VertexQuery");

/// A point the GPU names (cut_names.comp; 128 bytes, std430): makeVertex's
/// call.
struct GpuNameQuery
{
    uint32_t cell = 0; ///< index into PackedKernelInput::cells
    uint32_t tet = 0;
    uint32_t support = 0;       ///< tet-local vertices of the smallest simplex holding it
    uint32_t definingCount = 0; ///< the planes that made it (at most 8)
    uint32_t pad[4] = {0, 0, 0, 0};
    uint64_t defining[8] = {};
    double pos0[4] = {0, 0, 0, 0}; ///< where it was made, index space
};
static_assert(sizeof(GpuNameQuery) == 128, "std430 layout of NameQuery");

/// The GPU's name for a GpuNameQuery.
struct GpuName
{
    bool named = false;    ///< false: more planes than a name holds (the CPU refuses the cell)
    bool overflow = false; ///< a list outgrew the shader's capacity (the CPU would take the cell)
    uint32_t count = 0;
    uint64_t planes[8] = {};
};

/// One tet's arrangement as the GPU computes it (cut_arrange.vert): what
/// remesh_detail::ArrangementProbe holds for the CPU.
struct GpuArrangedTet
{
    uint32_t tet = 0;  ///< 5 c + t for tet t of cell c
    /// 0, or why the GPU stopped (the CPU takes such a tet): a capacity of
    /// the shader (bits 0-7), the CPU's refusal (bit 8), the record past its
    /// slot (bit 9), llvmpipe's loop limit (bit 10), the slit midpoints'
    /// lists full (bit 11)
    uint32_t fail = 0;
    struct Vertex
    {
        uint32_t dim = 0, planeCount = 0, support = 0;
        bool steiner = false;
        uint64_t feature[3] = {};
        uint64_t planes[8] = {};
        double pos[3] = {};
    };
    struct Piece
    {
        std::vector<int> v;
        std::vector<uint64_t> lab;
        bool kept = true;
    };
    struct Surface
    {
        uint64_t plane = 0;
        std::vector<Piece> pieces;
    };
    /// A corner of the tet's regions: a vertex and the sorted side tags of
    /// the slits it lies in (CutVertexId::tags).
    struct Node
    {
        int vert = 0;
        std::vector<uint64_t> tags;
    };
    std::vector<Vertex> verts;       ///< empty when `fail`; the regions' Steiner centres last
    std::vector<Surface> surfaces;   ///< empty when `fail`
    std::vector<Node> nodes;         ///< empty when `fail`
    std::vector<std::array<int, 3>> triangles; ///< nodes, CCW seen from outside the solid; empty when `fail`
    std::vector<uint8_t> triangleCap;          ///< per triangle: 1 on a cap region (bit 63 of its word)
};

/// The text buildProgram puts in front of the cut pass's shader `name`
/// (cut_*.comp, cut_*.vert): its GLSL libraries with the host's capacities,
/// and for the two big programs on NVIDIA's driver `#pragma optionNV(unroll
/// none)` (580.159.04 on an H100 built cut_arrange.vert in 114 s so, and not
/// in 270 s without). Reads the current context's GL_VENDOR.
std::string cutPassLibrary(const std::string& name);

/// poly2.glsl with doubles.glsl in front, for a program of poly2's own
/// (poly2_test.comp).
std::string poly2Library();

/// One cut cell's geometry as the GPU cut pass makes it (the triangles of
/// its five tets, before the CPU's float repairs: CellKernel::finish).
struct GpuCutCell
{
    /// false: a tet of the cell was flagged (a capacity of the shader,
    /// llvmpipe's loop limit, a configuration the CPU refuses), and
    /// `geometry` is empty; the CPU kernel takes such a cell.
    bool complete = false;
    cutter::CutCellGeometry geometry;
    std::array<uint32_t, 5> tetTriangles{}; ///< triangles of each tet (in `geometry`, tet after tet)
};

/// Pass 3's draw buffers: the cut geometry's triangles as the GPU cut pass
/// writes them (shaders/cut_regions.glsl, emitTriangles), each at a slot an
/// atomic counter gives it, drawn with glDrawArraysIndirect (three vertices
/// a triangle, surface.vert's layout) without a trip through the CPU
/// (SurfaceRenderer::setGpuCutGeometry). Needs a current GL 4.5 context.
class GpuCutDraw
{
public:
    /// Room for `capacity` triangles (at least 1).
    explicit GpuCutDraw(size_t capacity);
    size_t capacity() const { return mCapacity; }
    /// No triangles (the command's count 0).
    void clear();
    /// The triangles in the buffers, and those the GPU made (more when the
    /// capacity was short: the rest were dropped). Each reads back 4 bytes.
    size_t triangleCount() const;
    size_t made() const;
    /// Per triangle in the buffers, the tet (5 c + t of the input's cell c)
    /// that made it and its index among that tet's triangles. Reads back.
    std::vector<std::array<uint32_t, 2>> keys() const;
    /// Rewrites the fragment ids (one per triangle in the buffers; ids <
    /// 2^30), keeping the cap and cut-geometry bits.
    void setFragmentIds(const std::vector<uint32_t>& ids);
    /// Appends triangles made elsewhere (the cells the GPU left to the
    /// CPU): world mm with normals, one cell and cap flag per triangle,
    /// fragment id 1. Throws std::length_error past the capacity.
    void append(const cutter::Mesh& mesh, const std::vector<uint8_t>& isCap);

    const Buffer& vertices() const { return mVertices; }   ///< 6 floats a vertex: world mm, unit normal
    const Buffer& triangles() const { return mTriangles; } ///< surface.frag's TriangleInfo per triangle
    const Buffer& keysBuffer() const { return mKeys; }     ///< (tet, triangle of the tet) per triangle
    const Buffer& command() const { return mCommand; }     ///< DrawArraysIndirectCommand, then made()

private:
    size_t mCapacity;
    Buffer mVertices, mTriangles, mKeys, mCommand;
};

/// The GL state of a pass drawn as points by a vertex shader that writes
/// storage buffers (cut_arrange.vert): an empty vertex array, a framebuffer
/// without attachments, the rasterizer off; put back when it goes. Needs a
/// current OpenGL 4.5 context.
class PointPass
{
public:
    PointPass();
    ~PointPass();
    PointPass(const PointPass&) = delete;
    PointPass& operator=(const PointPass&) = delete;
    /// Draws vertices [0, count) with the program in use.
    void draw(size_t count) const;

private:
    VertexArray mVao;
    Framebuffer mFbo;
};

/// The ported kernel's programs. Needs a current OpenGL 4.5 context with
/// GL_ARB_gpu_shader_fp64 (core in 4.0) and GL_ARB_gpu_shader_int64; the
/// constructor throws std::runtime_error when the shaders do not build.
class GpuCutKernel
{
public:
    GpuCutKernel();

    /// Phase one of the 5 tets of every cell of `input` (5 c + t for tet t
    /// of cell c). Cost: one dispatch, O(cells' quads) on the GPU.
    std::vector<GpuTetPhaseOne> phaseOne(const cutter::PackedKernelInput& input) const;
    /// The position (index space) of each queried vertex from its name, as
    /// the CPU kernel's canonicalPosition gives it. 3 doubles per query.
    std::vector<double> vertexPositions(const cutter::PackedKernelInput& input,
                                        const std::vector<GpuVertexQuery>& queries) const;
    /// The name (its planes, ascending) of each queried point, as the CPU
    /// kernel's makeVertex gives it before looking the name up.
    std::vector<GpuName> names(const cutter::PackedKernelInput& input, const std::vector<GpuNameQuery>& queries) const;
    /// The arrangement of tets [firstTet, firstTet + tetCount) of `input`
    /// (5 per cell), those with solid only, ascending by tet; one tet per
    /// `lanesPerTet` vertex-shader invocations (1 on a GPU; on llvmpipe its
    /// SIMD width, 8, so that no tet shares the loop limit with another:
    /// cut_arrange.vert). Throws std::invalid_argument for lanesPerTet 0,
    /// std::out_of_range for tets past the input's.
    /// With `draw`, the triangles of the tets it arranges (and did not
    /// flag) also go into it, appended to what it holds (pass 3).
    std::vector<GpuArrangedTet> arrangement(const cutter::PackedKernelInput& input, size_t firstTet, size_t tetCount,
                                            size_t lanesPerTet = 1, GpuCutDraw* draw = nullptr) const;
    /// The geometry of every cell of `input` (arrangement() of its tets,
    /// their triangles in tet order, vertices welded by CutVertexId within
    /// the cell, as the CPU kernel's remesh() before its finish).
    std::vector<GpuCutCell> cutCells(const cutter::PackedKernelInput& input, size_t lanesPerTet = 1,
                                     GpuCutDraw* draw = nullptr) const;

private:
    Program mPhaseOne;
    Program mVertexPositions;
    Program mNames;
    Program mArrange;
    Program mRegions;
};

/// Pass 4, recovery: the geometry of `cells` (cut cells of `mask`) made by
/// the GPU cut pass and finished on the CPU (CellKernel::finish); the cells
/// the GPU flagged are re-meshed by the CPU kernel. Each cell's geometry is
/// then what the CPU kernel's remesh() gives (tests/test_render_cut_kernel
/// holds them equal). Throws std::runtime_error for a cell the CPU kernel
/// refuses, as CutRemesher::update does.
struct RecoveredCells
{
    std::vector<cutter::CutCellGeometry> cells; ///< one per cell, in order
    size_t byGpu = 0; ///< cells with triangles the GPU made
    size_t byCpu = 0; ///< cells the GPU flagged, re-meshed by the CPU
    /// Per cell: whether the GPU made it, and then its tets' triangle
    /// counts as the GPU made them (before the CPU's finish).
    std::vector<uint8_t> madeByGpu;
    std::vector<std::array<uint32_t, 5>> tetTriangles;
};
/// With `draw` (cleared first), the GPU's triangles also go into it (pass
/// 3), and then those of the cells the CPU took (its shading normals:
/// CutGeometry.h); std::length_error when they do not fit.
RecoveredCells recoverCutCells(const GpuCutKernel& gpu, const vdb::Volume& volume, float isovalue,
                               const cutter::CutMask& mask, const std::vector<openvdb::Coord>& cells,
                               size_t lanesPerTet = 1, GpuCutDraw* draw = nullptr);

/// The fragment id of each triangle in `draw` (as recoverCutCells filled
/// it for `cells`, giving `rec`), from `remesher` (the same cut re-meshed by
/// the CPU, e.g. its CutRemesher) and `cutIds`, the fragment id of each
/// triangle of cutGeometryOf(remesher) (discardFragmentIds). A GPU triangle
/// is the k-th of its cell before the CPU's finish; where the finish
/// changed the cell's triangle count (float repairs), the k-th after it
/// stands in (counted in `approximate` when given). For
/// GpuCutDraw::setFragmentIds. Throws std::out_of_range when the remesher's
/// cells are not those recovered.
std::vector<uint32_t> gpuCutFragmentIds(const GpuCutDraw& draw, const RecoveredCells& rec,
                                        const std::vector<openvdb::Coord>& cells, const cutter::CutRemesher& remesher,
                                        const std::vector<uint32_t>& cutIds, size_t* approximate = nullptr);

} // namespace mtcut::render
