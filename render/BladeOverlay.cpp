#include "render/BladeOverlay.h"

#include "render/Shaders.h"

#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <string>
#include <vector>

namespace mtcut::render {

BladeOverlay::BladeOverlay()
{
    mProgram = buildProgram(std::vector<std::string>{"flat.vert", "blade.frag"});
    mBuffer.setData(4 * sizeof(glm::vec3), nullptr, GL_DYNAMIC_DRAW);
    glVertexArrayVertexBuffer(mVao.id(), 0, mBuffer.id(), 0, GLsizei(sizeof(glm::vec3)));
    glEnableVertexArrayAttrib(mVao.id(), 0);
    glVertexArrayAttribFormat(mVao.id(), 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(mVao.id(), 0, 0);
}

void BladeOverlay::draw(const Camera& camera, int width, int height, const glm::dvec3& base, const glm::dvec3& tip,
                        double widthMm, const glm::vec4& colour, float hiddenAlpha, GLuint sceneDepth) const
{
    if (width <= 0 || height <= 0) return;
    const glm::dvec3 toEye = glm::normalize(camera.eye - base);
    glm::dvec3 side = glm::cross(tip - base, toEye);
    side = glm::length(side) > 1e-9 ? glm::normalize(side) : glm::dvec3(1, 0, 0);
    const double w = 0.5 * widthMm;
    const glm::vec3 strip[4] = {glm::vec3(base - w * side), glm::vec3(base + w * side), glm::vec3(tip - w * side),
                                glm::vec3(tip + w * side)};
    glNamedBufferSubData(mBuffer.id(), 0, sizeof strip, strip);
    const glm::mat4 vp = camera.projection(double(width) / height) * camera.view();
    glViewport(0, 0, width, height);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    mProgram.use();
    glProgramUniformMatrix4fv(mProgram.id(), mProgram.uniform("uViewProjection"), 1, GL_FALSE, glm::value_ptr(vp));
    glProgramUniform4fv(mProgram.id(), mProgram.uniform("uColour"), 1, glm::value_ptr(colour));
    glProgramUniform1f(mProgram.id(), mProgram.uniform("uHiddenAlpha"), hiddenAlpha);
    glBindTextureUnit(0, sceneDepth);
    glBindVertexArray(mVao.id());
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
    glBindVertexArray(0);
    glBindTextureUnit(0, 0);
    glUseProgram(0);
    glDisable(GL_BLEND);
}

} // namespace mtcut::render
