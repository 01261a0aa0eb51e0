// Shared by the tests/test_render_*.cpp: one headless GL context per test
// program. GL tests skip only when no context at all can be made (a machine
// without EGL); on Mesa llvmpipe and on NVIDIA they run.
#pragma once

#include "render/Context.h"

#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>

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

} // namespace mtcut::test

/// In a TEST body: the shared GL context is current, or the test is skipped.
#define MTCUT_REQUIRE_GL()                                                                         \
    do {                                                                                           \
        std::string whyNoGl_;                                                                      \
        if (!::mtcut::test::glContext(&whyNoGl_)) GTEST_SKIP() << "no GL context: " << whyNoGl_;   \
    } while (0)
