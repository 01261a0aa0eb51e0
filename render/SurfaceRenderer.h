// The surface passes (DESIGN "GPU passes"): the uncut isosurface in one
// vertex buffer, uploaded once and never modified, drawn with the discard
// pass (triangles whose cell is in the GPU-coded cut mask are discarded by
// their gl_PrimitiveID's cell, not by position), then the cut geometry as a
// second buffer: the CPU re-mesher's (render/CutGeometry.h), or the GPU cut
// pass's own output drawn indirectly (render/CutKernelGpu.h). Phong shading with the meshes' normals (gradient
// normals on the isosurface, the blade's plane on caps); optional highlight
// colour for the caps. Renders off-screen into a framebuffer object with
// colour, world normal, view depth and fragment-id targets; readFrame()
// brings them back. Needs a current GL 4.5 context for its whole life.
#pragma once

#include "cutter/Mesh.h"
#include "render/Camera.h"
#include "render/Frame.h"
#include "render/GlObjects.h"
#include "render/MaskAtlas.h"
#include "render/MaskTiling.h"

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include <memory>
#include <vector>

namespace mtcut::render {

class GpuCutDraw;

struct RenderStyle
{
    glm::vec3 colour{0.89f, 0.85f, 0.74f};         ///< bone
    /// With highlight on: the cut geometry's caps in this colour, its
    /// isosurface pieces half-way between colour and this.
    glm::vec3 highlightColour{0.85f, 0.20f, 0.16f};
    glm::vec4 background{0.0f, 0.0f, 0.0f, 0.0f};   ///< transparent
    bool highlight = false;
    /// Optional colour per fragment id (index = id; the viewer's fragment
    /// list): rgb replaces `colour`, a = 0 hides the fragment. Ids past the
    /// end keep `colour`. Empty: every fragment in `colour`.
    std::vector<glm::vec4> fragmentColours;
};

class SurfaceRenderer
{
public:
    /// Off-screen targets of width x height pixels. Throws InputError when the
    /// size is not in [1, GL_MAX_RENDERBUFFER_SIZE / viewport limit].
    SurfaceRenderer(int width, int height);
    ~SurfaceRenderer();
    SurfaceRenderer(const SurfaceRenderer&) = delete;
    SurfaceRenderer& operator=(const SurfaceRenderer&) = delete;

    int width() const { return mWidth; }
    int height() const { return mHeight; }

    /// Uploads the uncut isosurface (positions, normals, indices, per-triangle
    /// cells; world mm) once. fragmentIds: one per triangle (empty: all 1).
    /// Clears the cut cells and cut geometry.
    void setSurface(const cutter::Mesh& uncut, const std::vector<uint32_t>& fragmentIds = {});
    /// New fragment ids (one per triangle; empty: all 1) for the surface last
    /// given to setSurface (`uncut` must be that mesh: its cells are written
    /// again). Rewrites only the per-triangle info buffer in place, not the
    /// vertices or indices; keeps the cut cells and cut geometry.
    void setSurfaceFragmentIds(const cutter::Mesh& uncut, const std::vector<uint32_t>& fragmentIds);
    /// The cells whose surface triangles the discard pass drops, coded on the
    /// GPU (one point per cell, OR logic-op) or, with gpuCoding false,
    /// uploaded from the CPU tiles.
    void setCutCells(const MaskTiling& tiling, bool gpuCoding = true);
    /// The cut geometry drawn after the surface (world mm, with normals);
    /// fragmentIds and isCap: one per triangle (empty: all 1 / no caps).
    /// Fragment ids must be < 2^30.
    void setCutGeometry(const cutter::Mesh& mesh, const std::vector<uint32_t>& fragmentIds = {},
                        const std::vector<uint8_t>& isCap = {});
    /// The cut geometry as the GPU cut pass wrote it (pass 3), drawn after
    /// the surface with glDrawArraysIndirect from `draw`'s buffers, which
    /// this renderer shares; instead of setCutGeometry's. Null: none.
    void setGpuCutGeometry(std::shared_ptr<const GpuCutDraw> draw);
    /// Drops the cut cells and the cut geometry (the surface alone again).
    void clearCut();

    /// Bounds of what is drawn (the surface and the cut geometry), world mm.
    Bounds bounds() const;

    /// Draws a frame (surface with discard, then the cut geometry).
    void render(const Camera& camera, const RenderStyle& style);
    /// The last frame's targets.
    Frame readFrame() const;
    /// The last frame's view depth (mm) at pixel (x, y), top-left origin;
    /// +infinity where there is no surface or outside the image. Reads one
    /// texel (waits for the frame): for picking, not per pixel.
    float viewDepthAt(int x, int y) const;
    /// The last frame's fragment id at pixel (x, y), top-left origin (1 =
    /// fragment_000, as Frame::fragments); 0 where there is no surface or
    /// outside the image. Reads one texel: for picking.
    uint32_t fragmentIdAt(int x, int y) const;
    /// The off-screen framebuffer (colour in attachment 0), e.g. to blit
    /// the last frame to a window.
    GLuint framebuffer() const { return mFbo.id(); }
    /// The last frame's depth buffer (GL_DEPTH_COMPONENT32F, window-space
    /// depth, bottom-up), e.g. for BladeOverlay to test against.
    GLuint depthTexture() const { return mDepth.id(); }

    /// The cut mask on the GPU (null before setCutCells).
    const MaskAtlas* maskAtlas() const { return mAtlas.get(); }

private:
    struct DrawMesh;
    std::unique_ptr<DrawMesh> upload(const cutter::Mesh& mesh, const std::vector<uint32_t>& fragmentIds,
                                     const std::vector<uint8_t>& isCap, bool cutGeometry) const;
    void draw(const DrawMesh& mesh, const Program& program) const;

    int mWidth, mHeight;
    Framebuffer mFbo;
    Texture mColour{GL_TEXTURE_2D}, mNormal{GL_TEXTURE_2D}, mDepthOut{GL_TEXTURE_2D}, mFragment{GL_TEXTURE_2D};
    Texture mDepth{GL_TEXTURE_2D};
    Program mDiscardProgram, mPlainProgram;
    std::unique_ptr<DrawMesh> mSurface, mCut;
    std::shared_ptr<const GpuCutDraw> mGpuCut;
    VertexArray mGpuCutVao;
    std::unique_ptr<MaskAtlas> mAtlas;
    Buffer mFragmentColours; ///< RenderStyle::fragmentColours, uploaded per render
};

} // namespace mtcut::render
