// Cap detection of the cut geometry (render/CutGeometry.h triangleIsCap, used
// by --highlight and by the caps' shading normals) for kerf > 0, where the
// caps lie on the faces of each quad's prism (offset planes at +-w/2, the
// side through the blade's tip, mitres) rather than on the quad's own plane,
// and for kerf 0 as before.
//
// Oracle 1 (exact, geometric): on a sphere cut by one straight stroke (all
// quads in one plane with normal n through point o; blade direction d
// perpendicular to the sweep), a cut-geometry triangle is a cap exactly when
// its three vertices lie (within 1e-4 mm) on one prism face: n.(p - o) = +-w/2
// with w > 0, n.(p - o) = 0 with w = 0, or, where the blade stops inside, the
// tip plane d.(p - o) = B. An isosurface triangle never has all three
// vertices on one plane of these (it would be degenerate).
// Oracle 2 (pixels): the cut geometry alone, seen from the side the blade's
// normal points to, with caps highlighted in pure red on a green surface:
// the red pixels cover the projected area of the caps facing the camera
// (back faces culled, so the far fragment's cap hides nothing), less what
// the thin band of near-side isosurface pieces hides.
#include "cutter/CutMask.h"
#include "cutter/Isosurface.h"
#include "cutter/Remesh.h"
#include "render/CutGeometry.h"
#include "render/SurfaceRenderer.h"
#include "tests/test_render_util.h"

#include <glm/geometric.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

using namespace mtcut;
using namespace mtcut::render;

namespace {

struct KerfCase
{
    double kerf;
    double blade;      ///< mm; the tip is inside the sphere when short
    bool tipInside;
};

struct Counts
{
    size_t triangles = 0, caps = 0, onPrismFace = 0, onTipFace = 0, mismatched = 0;
    double frontCapPixels = 0.0; ///< projected area, pixels, of caps facing the camera
};

void runCase(const KerfCase& kc)
{
    const vdb::Volume vol = test::sphereVolume();
    const cutter::Mesh uncut = cutter::extractIsosurface(vol, 0.0f);
    cutter::CutMask mask(cutter::frameOf(vol), kc.kerf);
    const glm::dvec3 from = test::kSlantFrom, to = test::kSlantTo, dir = test::kSlantDir;
    test::addStroke(mask, test::slantedStroke(kc.blade));
    cutter::CutRemesher remesher(vol, 0.0f, uncut);
    try {
        remesher.update(mask);
    } catch (const std::runtime_error& e) {
        FAIL() << "kerf " << kc.kerf << ": the re-mesher refused the stroke: " << e.what();
    }
    const CutGeometry cut = cutGeometryOf(remesher, vol, 0.0f, CutNormals::Shading);
    const cutter::Mesh& m = cut.mesh;
    ASSERT_EQ(cut.triangleIsCap.size(), m.triangleCount());

    // Oracle 1.
    glm::dvec3 n = glm::normalize(glm::cross(to - from, dir));
    const glm::dvec3 o = from;
    const double halfW = 0.5 * kc.kerf, tol = 1e-4;
    Counts c;
    c.triangles = m.triangleCount();
    for (size_t t = 0; t < m.triangleCount(); ++t) {
        const glm::dvec3 p[3] = {glm::dvec3(m.positions[m.indices[3 * t]]), glm::dvec3(m.positions[m.indices[3 * t + 1]]),
                                 glm::dvec3(m.positions[m.indices[3 * t + 2]])};
        auto allOn = [&](const glm::dvec3& normal, double offset) {
            for (const glm::dvec3& q : p)
                if (std::abs(glm::dot(normal, q - o) - offset) > tol) return false;
            return true;
        };
        bool onFace = kc.kerf > 0 ? allOn(n, halfW) || allOn(n, -halfW) : allOn(n, 0.0);
        if (kc.tipInside && allOn(dir, kc.blade)) {
            onFace = true;
            ++c.onTipFace;
        }
        c.caps += cut.triangleIsCap[t];
        c.onPrismFace += onFace;
        if (bool(cut.triangleIsCap[t]) != onFace) {
            if (++c.mismatched <= 5) {
                ADD_FAILURE() << "kerf " << kc.kerf << ": triangle " << t << " flagged " << int(cut.triangleIsCap[t])
                              << " but " << (onFace ? "lies" : "does not lie") << " on a prism face; n.(p-o) = "
                              << glm::dot(n, p[0] - o) << ", " << glm::dot(n, p[1] - o) << ", " << glm::dot(n, p[2] - o);
            }
        }
    }
    EXPECT_EQ(c.mismatched, 0u) << "kerf " << kc.kerf;
    EXPECT_GT(c.caps, 100u) << "kerf " << kc.kerf << ": the cut should make caps";
    if (kc.tipInside) {
        EXPECT_GT(c.onTipFace, 10u) << "the blade should stop inside the sphere";
    }

    // Oracle 2: the cut geometry alone, highlight on, camera on the +n side.
    const int size = 256;
    SurfaceRenderer r(size, size);
    r.setCutGeometry(m, {}, cut.triangleIsCap);
    const Bounds b = r.bounds();
    const glm::dvec3 centre = b.centre();
    const double dist = 4.0 * b.radius();
    // Up: any direction perpendicular to n.
    const glm::dvec3 up = glm::normalize(glm::cross(n, glm::dvec3(1, 0, 0)));
    Camera camera;
    camera.eye = centre + dist * n;
    camera.target = centre;
    camera.up = up;
    camera.fovYDegrees = 30.0;
    camera.nearMm = 0.5 * dist;
    camera.farMm = 2.0 * dist;
    RenderStyle style;
    style.colour = glm::vec3(0, 1, 0);
    style.highlightColour = glm::vec3(1, 0, 0);
    style.highlight = true;
    r.render(camera, style);
    const Frame f = r.readFrame();
    // Caps: base (1,0,0); the cut cells' isosurface pieces: (0.45,0.55,0);
    // shading scales the base and adds the same white specular to r, g, b.
    size_t red = 0, covered = 0;
    for (size_t px = 0; px < f.pixelCount(); ++px) {
        const int R8 = f.rgba[4 * px], G8 = f.rgba[4 * px + 1], B8 = f.rgba[4 * px + 2];
        covered += f.fragments[px] != 0;
        red += f.fragments[px] != 0 && std::abs(G8 - B8) <= 1 && R8 - B8 > 10;
    }
    const glm::mat4 vp = camera.projection(1.0) * camera.view();
    for (size_t t = 0; t < m.triangleCount(); ++t) {
        if (!cut.triangleIsCap[t]) continue;
        glm::dvec2 s[3];
        for (int k = 0; k < 3; ++k) {
            const glm::vec4 clip = vp * glm::vec4(m.positions[m.indices[3 * t + size_t(k)]], 1.0f);
            s[k] = (glm::dvec2(clip.x, clip.y) / double(clip.w) * 0.5 + 0.5) * double(size);
        }
        const double area2 = (s[1].x - s[0].x) * (s[2].y - s[0].y) - (s[2].x - s[0].x) * (s[1].y - s[0].y);
        if (area2 > 0) c.frontCapPixels += 0.5 * area2; // counter-clockwise on screen: front facing
    }
    std::printf("kerf %.2f, blade %.0f mm%s: %zu cut-geometry triangles, %zu caps (%zu on prism faces, %zu on the tip's); "
                "%zu covered pixels, %zu red (cap) pixels, front caps' projected area %.0f pixels (ratio %.3f)\n",
                kc.kerf, kc.blade, kc.tipInside ? " (tip inside)" : "", c.triangles, c.caps, c.onPrismFace, c.onTipFace, covered, red,
                c.frontCapPixels, double(red) / c.frontCapPixels);
    EXPECT_GT(c.frontCapPixels, 2000.0) << "the near side's cap should face the camera";
    EXPECT_GE(double(red), 0.85 * c.frontCapPixels) << "kerf " << kc.kerf;
    EXPECT_LE(double(red), 1.03 * c.frontCapPixels + 50.0) << "kerf " << kc.kerf;
}

} // namespace

TEST(RenderKerf, CapsOfAKerfCutAreFlaggedAndHighlighted)
{
    MTCUT_REQUIRE_GL();
    runCase({0.5, 45.0, false});
}

TEST(RenderKerf, CapsWhereTheBladeStopsInsideIncludeTheTipFace)
{
    MTCUT_REQUIRE_GL();
    runCase({0.5, 27.0, true});
}

TEST(RenderKerf, ZeroKerfCapsStillFlagged)
{
    MTCUT_REQUIRE_GL();
    runCase({0.0, 45.0, false});
}
