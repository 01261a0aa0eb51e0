// The viewer's blade, drawn over a SurfaceRenderer frame: a thin strip from
// the blade's base to its tip, turned to face the viewer, depth-tested
// against the frame's surface by hand (shaders/blade.frag) so the part inside
// the bone shows faded instead of over it. The strip goes to whatever
// framebuffer is bound (the window's has no depth buffer of the frame's
// format, so the frame's depth is read as a texture).
#pragma once

#include "render/Camera.h"
#include "render/GlObjects.h"

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace mtcut::render {

class BladeOverlay
{
public:
    BladeOverlay(); ///< needs a current GL 4.5 context
    BladeOverlay(const BladeOverlay&) = delete;
    BladeOverlay& operator=(const BladeOverlay&) = delete;

    /// Draws the blade base -> tip (world mm) as a strip `widthMm` wide into
    /// the bound draw framebuffer's (0, 0, width, height) viewport, blended
    /// over it (straight alpha). `sceneDepth`: SurfaceRenderer::depthTexture()
    /// of a frame rendered with the same camera and size. Where the surface is
    /// nearer than the strip the alpha is colour.a * hiddenAlpha.
    void draw(const Camera& camera, int width, int height, const glm::dvec3& base, const glm::dvec3& tip,
              double widthMm, const glm::vec4& colour, float hiddenAlpha, GLuint sceneDepth) const;

private:
    Program mProgram;
    VertexArray mVao;
    Buffer mBuffer;
};

} // namespace mtcut::render
