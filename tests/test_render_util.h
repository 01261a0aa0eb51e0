// Shared by the tests/test_render_*.cpp: one headless GL context per test
// program. GL tests skip only when no context at all can be made (a machine
// without EGL); on Mesa llvmpipe and on NVIDIA they run. Also the sphere and
// the slanted stroke that several of them cut, and the mask setup of a stroke.
#pragma once

#include "cutter/BladePath.h"
#include "cutter/CutMask.h"
#include "render/Context.h"
#include "tests/TestStrokes.h"
#include "tests/TestVolumes.h"

#include <glm/geometric.hpp>

#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace mtcut::test {

/// The test program's headless context, made current; null when none can be
/// made (then *why says why).
inline render::GlContext* glContext(std::string* why)
{
    static std::unique_ptr<render::GlContext> context;
    static std::string error;
    static bool tried = false;
    if (!tried) {
        tried = true;
        try {
            context = render::createHeadlessContext();
            std::printf("GL context: %s\n", context->description().c_str());
        } catch (const std::exception& e) {
            error = e.what();
        }
    }
    if (context) context->makeCurrent();
    if (why) *why = error;
    return context.get();
}

/// A sphere of radius 15 mm about the origin: the field 15 - |p| (surface at
/// 0) on 40^3 voxels of 1 mm, the first voxel centre at (-19.5, -19.5, -19.5).
inline vdb::Volume sphereVolume()
{
    const double R = 15.0;
    return fieldVolume(openvdb::Coord(40), openvdb::Vec3d(1.0), openvdb::Vec3d(-19.5),
                       [&](const openvdb::Vec3d& p) { return R - p.length(); });
}

/// The slanted stroke across sphereVolume(): the base from kSlantFrom to
/// kSlantTo, above the sphere and just off the grid planes, the blade
/// pointing down and tilted towards +y (kSlantDir).
inline const glm::dvec3 kSlantFrom(-25, 0.37, 22), kSlantTo(25, 0.37, 22);
inline const glm::dvec3 kSlantDir = glm::normalize(glm::dvec3(0, 0.4, -1));

/// That stroke in 200 poses with a blade `blade` mm long.
inline std::vector<cutter::Pose> slantedStroke(double blade)
{
    return straightStroke(kSlantFrom, kSlantTo, kSlantDir, blade, 200);
}

/// Adds `poses` to `mask` as one new stroke: filterStroke -> quads ->
/// CutMask::addQuad, as mtcut cut does.
inline void addStroke(cutter::CutMask& mask, const std::vector<cutter::Pose>& poses)
{
    const std::vector<cutter::Quad> quads = cutter::filterStroke(poses, mask.frame());
    mask.beginStroke();
    for (const cutter::Quad& q : quads) mask.addQuad(q);
}

} // namespace mtcut::test

/// In a TEST body: the shared GL context is current, or the test is skipped.
#define MTCUT_REQUIRE_GL()                                                                         \
    do {                                                                                           \
        std::string whyNoGl_;                                                                      \
        if (!::mtcut::test::glContext(&whyNoGl_)) GTEST_SKIP() << "no GL context: " << whyNoGl_;   \
    } while (0)
