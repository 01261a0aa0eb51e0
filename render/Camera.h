// Cameras for rendering a volume's surfaces (world mm, LPS: +x patient's
// left, +y posterior, +z superior). No GL here: matrices for the passes.
#pragma once

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <string>

namespace mtcut::render {

/// An axis-aligned box, world mm.
struct Bounds
{
    glm::dvec3 lo{0.0}, hi{0.0};
    glm::dvec3 centre() const { return 0.5 * (lo + hi); }
    double radius() const; ///< half the diagonal (> 0: at least 1e-6 mm)
};

/// A perspective camera, world mm.
struct Camera
{
    glm::dvec3 eye{0.0, -1.0, 0.0};
    glm::dvec3 target{0.0};
    glm::dvec3 up{0.0, 0.0, 1.0};
    double fovYDegrees = 30.0; ///< vertical field of view
    double nearMm = 0.1, farMm = 1000.0;
    /// Where the view direction meets the image, in normalised device
    /// coordinates (x right, y up; 0 = the image centre): an off-centre
    /// frustum, so the viewer can centre the scene right of its panel while
    /// orbiting about the scene's centre. 0 for `mtcut render`.
    glm::dvec2 lensShift{0.0};

    glm::mat4 view() const;
    glm::mat4 projection(double aspect) const; ///< aspect = width / height

    /// The world point (mm) seen at pixel (x, y) of a width x height image
    /// (top-left origin, pixel centres at +0.5) at `viewDepth` mm along the
    /// view direction (the depth SurfaceRenderer writes): unprojection for
    /// picking. Cost O(1).
    glm::dvec3 worldPointAt(double x, double y, int width, int height, double viewDepth) const;
};

/// Sets the near and far planes of `camera` to hold the bounds' sphere seen
/// from its eye (as cameraFor does; near stays > 0 when the eye is inside).
void fitDepth(Camera& camera, const Bounds& bounds);

/// The camera of a --view argument for a scene with the given bounds:
///   front  looks along +y at the face (the face points to -y), z up;
///   side   looks along -x at the patient's left side (from +x), z up;
///   top    looks down along -z, the face (-y) at the top of the image;
///   iso    from the front-right-above corner (-x, -y, +z), z up;
///   EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ[:FOV]]  eye and target points (world mm),
///          up vector (default 0,0,1) and vertical field of view in degrees
///          (default 30), e.g. "0,-400,0:0,0,0:0,0,1:25".
/// Preset views frame the bounds' sphere at a 30 degree field of view. Near
/// and far planes are set from the bounds (scene depth only, for precision).
/// Throws InputError with a one-line message on a bad argument (unknown
/// view, non-finite numbers, eye == target, up parallel to the view, fov
/// outside (0, 180)).
Camera cameraFor(const std::string& view, const Bounds& bounds, double aspect);

} // namespace mtcut::render
