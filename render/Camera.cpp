#include "render/Camera.h"

#include "vdb/Error.h"

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <vector>

namespace mtcut::render {

double Bounds::radius() const
{
    return std::max(0.5 * glm::length(hi - lo), 1e-6);
}

glm::mat4 Camera::view() const
{
    return glm::mat4(glm::lookAt(eye, target, up));
}

glm::mat4 Camera::projection(double aspect) const
{
    const glm::dmat4 p = glm::perspective(glm::radians(fovYDegrees), aspect, nearMm, farMm);
    if (lensShift == glm::dvec2(0.0)) return glm::mat4(p);
    // Clip-space translation by shift * w: NDC moves by the shift.
    return glm::mat4(glm::translate(glm::dmat4(1.0), glm::dvec3(lensShift, 0.0)) * p);
}

namespace {

std::vector<std::string> split(const std::string& s, char sep)
{
    std::vector<std::string> out;
    std::string part;
    std::istringstream is(s);
    while (std::getline(is, part, sep)) out.push_back(part);
    if (!s.empty() && s.back() == sep) out.push_back("");
    return out;
}

double number(const std::string& text, const std::string& view)
{
    size_t used = 0;
    double v = 0.0;
    try {
        v = std::stod(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != text.size() || !std::isfinite(v)) {
        throw InputError("--view " + view + ": '" + text + "' is not a finite number");
    }
    return v;
}

glm::dvec3 vec3Of(const std::string& text, const std::string& view)
{
    const std::vector<std::string> parts = split(text, ',');
    if (parts.size() != 3) throw InputError("--view " + view + ": expected X,Y,Z, got '" + text + "'");
    return glm::dvec3(number(parts[0], view), number(parts[1], view), number(parts[2], view));
}

} // namespace

void fitDepth(Camera& c, const Bounds& b)
{
    const double r = b.radius();
    const glm::dvec3 dir = glm::normalize(c.target - c.eye);
    const double d = glm::dot(b.centre() - c.eye, dir);
    c.farMm = std::max(d + 1.01 * r, 1e-3 * r + 1e-6);
    c.nearMm = std::max(d - 1.01 * r, c.farMm * 1e-4);
}

glm::dvec3 Camera::worldPointAt(double x, double y, int width, int height, double viewDepth) const
{
    const glm::dvec3 forward = glm::normalize(target - eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, up));
    const glm::dvec3 trueUp = glm::cross(right, forward);
    const double tanHalf = std::tan(glm::radians(fovYDegrees) / 2.0);
    const double aspect = double(width) / double(std::max(height, 1));
    const double ndcX = 2.0 * x / double(std::max(width, 1)) - 1.0 - lensShift.x;
    const double ndcY = 1.0 - 2.0 * y / double(std::max(height, 1)) - lensShift.y;
    return eye + viewDepth * (forward + ndcX * tanHalf * aspect * right + ndcY * tanHalf * trueUp);
}

Camera cameraFor(const std::string& view, const Bounds& bounds, double aspect)
{
    Camera c;
    const glm::dvec3 centre = bounds.centre();
    glm::dvec3 dir; // view direction
    if (view == "front") {
        dir = {0, 1, 0};
        c.up = {0, 0, 1};
    } else if (view == "side") {
        dir = {-1, 0, 0};
        c.up = {0, 0, 1};
    } else if (view == "top") {
        dir = {0, 0, -1};
        c.up = {0, -1, 0};
    } else if (view == "iso") {
        dir = glm::normalize(glm::dvec3(1, 1, -1));
        c.up = {0, 0, 1};
    } else if (view.find(':') != std::string::npos) {
        const std::vector<std::string> parts = split(view, ':');
        if (parts.size() < 2 || parts.size() > 4) {
            throw InputError("--view " + view + ": expected EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ[:FOV]]");
        }
        c.eye = vec3Of(parts[0], view);
        c.target = vec3Of(parts[1], view);
        if (parts.size() > 2) c.up = vec3Of(parts[2], view);
        if (parts.size() > 3) c.fovYDegrees = number(parts[3], view);
        if (!(c.fovYDegrees > 0.0 && c.fovYDegrees < 180.0)) {
            throw InputError("--view " + view + ": field of view must be in (0, 180) degrees");
        }
        const glm::dvec3 d = c.target - c.eye;
        if (glm::length(d) < 1e-9) throw InputError("--view " + view + ": eye and target are the same point");
        if (glm::length(c.up) < 1e-12 || glm::length(glm::cross(glm::normalize(d), glm::normalize(c.up))) < 1e-6) {
            throw InputError("--view " + view + ": the up vector is zero or parallel to the view direction");
        }
        fitDepth(c, bounds);
        return c;
    } else {
        throw InputError("--view " + view + ": expected front, side, top, iso or EX,EY,EZ:TX,TY,TZ[:UX,UY,UZ[:FOV]]");
    }
    // Fit the bounds' sphere in the narrower field of view.
    const double halfY = glm::radians(c.fovYDegrees) / 2.0;
    const double halfX = std::atan(std::tan(halfY) * std::max(aspect, 1e-6));
    const double distance = bounds.radius() / std::sin(std::min(halfX, halfY)) * 1.02;
    c.target = centre;
    c.eye = centre - dir * distance;
    fitDepth(c, bounds);
    return c;
}

} // namespace mtcut::render
