// The viewer's overlays on a SurfaceRenderer frame: the blade strip faded
// where the surface is in front of it (render/BladeOverlay, shaders/blade.frag),
// and the off-centre lens the viewer frames preset views with (Camera::lensShift).
#include "cutter/Isosurface.h"
#include "render/BladeOverlay.h"
#include "render/Camera.h"
#include "render/GlObjects.h"
#include "render/SurfaceRenderer.h"
#include "tests/TestVolumes.h"
#include "tests/test_render_util.h"

#include <glm/geometric.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace mtcut;
using namespace mtcut::render;
using openvdb::Coord;
using openvdb::Vec3d;

namespace {

/// Pixel (top-left origin, pixel units) where `camera` sees world point p in a width x height image.
glm::dvec2 pixelOf(const Camera& camera, int width, int height, const glm::dvec3& p)
{
    const glm::dvec4 clip = glm::dmat4(camera.projection(double(width) / height) * camera.view()) * glm::dvec4(p, 1.0);
    const glm::dvec2 ndc(clip.x / clip.w, clip.y / clip.w);
    return {0.5 * (ndc.x + 1.0) * width, 0.5 * (1.0 - ndc.y) * height};
}

} // namespace

// The lens shift moves the image by exactly the shift (NDC), and picking
// (worldPointAt) inverts the shifted projection.
TEST(RenderOverlay, LensShiftMovesTheImageAndPickingFollowsIt)
{
    const Bounds b{glm::dvec3(-20, -30, -10), glm::dvec3(40, 30, 50)};
    const int w = 640, h = 360;
    for (const char* view : {"front", "side", "iso"}) {
        Camera plain = cameraFor(view, b, 0.6 * w / h);
        Camera shifted = plain;
        shifted.lensShift = glm::dvec2(0.4, -0.1);
        // The target (orbit centre) moves from the image centre by shift * size / 2.
        const glm::dvec2 c0 = pixelOf(plain, w, h, plain.target), c1 = pixelOf(shifted, w, h, shifted.target);
        EXPECT_NEAR(c0.x, 0.5 * w, 1e-3) << view;
        EXPECT_NEAR(c1.x, 0.5 * w + 0.2 * w, 1e-3) << view;
        EXPECT_NEAR(c1.y, 0.5 * h + 0.05 * h, 1e-3) << view;
        // Picking: the world point at a pixel and view depth projects back to that pixel.
        const glm::dvec3 forward = glm::normalize(shifted.target - shifted.eye);
        for (const glm::dvec3& p : {b.lo, b.hi, glm::dvec3(10, -5, 30), glm::dvec3(-15, 20, 0)}) {
            const glm::dvec2 px = pixelOf(shifted, w, h, p);
            const double depth = glm::dot(p - shifted.eye, forward);
            const glm::dvec3 back = shifted.worldPointAt(px.x, px.y, w, h, depth);
            EXPECT_LT(glm::length(back - p), 1e-3) << view; // float matrices
        }
    }
}

// A strip through the centre plane of a sphere, facing the viewer: where the
// sphere's front is nearer than the strip the strip's alpha is faded (x 0.25),
// elsewhere full; pixels whose surface lies within 0.5 mm of the strip's
// depth (the silhouette) are not judged.
TEST(RenderOverlay, BladeIsFadedExactlyWhereTheSurfaceIsInFront)
{
    MTCUT_REQUIRE_GL();
    const double R = 15.0;
    const vdb::Volume vol = test::fieldVolume(Coord(40), Vec3d(1.0), Vec3d(-19.5), [&](const Vec3d& p) { return R - p.length(); });
    const cutter::Mesh sphere = cutter::extractIsosurface(vol, 0.0f);
    const int w = 160, h = 120;
    const Camera camera = cameraFor("front", Bounds{glm::dvec3(-16), glm::dvec3(16)}, double(w) / h);
    SurfaceRenderer r(w, h);
    r.setSurface(sphere);
    r.render(camera, RenderStyle{});
    const Frame frame = r.readFrame();

    Texture colour(GL_TEXTURE_2D);
    glTextureStorage2D(colour.id(), 1, GL_RGBA8, w, h);
    Framebuffer fbo;
    glNamedFramebufferTexture(fbo.id(), GL_COLOR_ATTACHMENT0, colour.id(), 0);
    ASSERT_EQ(glCheckNamedFramebufferStatus(fbo.id(), GL_DRAW_FRAMEBUFFER), GLenum(GL_FRAMEBUFFER_COMPLETE));
    const float clear[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(fbo.id(), GL_COLOR, 0, clear);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo.id());
    // The front view looks along +y: the plane y = 0 is the sphere's centre
    // plane. A strip from (0, 0, -200) to (0, 0, 200), 400 mm wide, covers the image.
    BladeOverlay blade;
    blade.draw(camera, w, h, glm::dvec3(0, 0, -200), glm::dvec3(0, 0, 200), 400.0, glm::vec4(1, 0, 0, 1), 0.25f,
               r.depthTexture());
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    std::vector<uint8_t> rgba(size_t(w) * h * 4);
    glGetTextureImage(colour.id(), 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(rgba.size()), rgba.data());
    ASSERT_EQ(glGetError(), GLenum(GL_NO_ERROR));

    const double stripDepth = glm::dot(glm::dvec3(0.0) - camera.eye, glm::normalize(camera.target - camera.eye));
    size_t faded = 0, full = 0, wrong = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float d = frame.depth[size_t(y) * w + x];          // top-down
            const uint8_t a = rgba[(size_t(h - 1 - y) * w + x) * 4]; // red = alpha x 255 over black; GL rows bottom-up
            if (std::isfinite(d) && std::abs(d - stripDepth) < 0.5) continue;
            const bool hidden = std::isfinite(d) && d < stripDepth;
            const int expected = hidden ? 64 : 255; // 0.25 * 255 rounds to 64
            if (std::abs(int(a) - expected) > 1) ++wrong;
            (hidden ? faded : full)++;
        }
    std::printf("faded %zu, full %zu, wrong %zu pixels\n", faded, full, wrong);
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(faded, size_t(w * h / 10)); // the sphere covers a good part of the image
    EXPECT_GT(full, size_t(w * h / 4));
}
