// OpenGL 4.5 core contexts behind one interface: a headless EGL context
// (tests, `mtcut render`; draws into framebuffer objects) and a GLFW window
// context (the viewer). GL entry points are loaded by libepoxy.
#pragma once

#include <memory>
#include <string>

namespace mtcut::render {

/// A current-able OpenGL 4.5 core context. Destroying it destroys the
/// context: GL objects made in it must be gone first. Not thread-safe; one
/// thread uses it at a time.
class GlContext
{
public:
    virtual ~GlContext() = default;
    GlContext(const GlContext&) = delete;
    GlContext& operator=(const GlContext&) = delete;

    /// Makes this context current on the calling thread.
    virtual void makeCurrent() = 0;
    /// "EGL surfaceless: llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 (Core Profile) Mesa 22.3.6".
    virtual std::string description() const = 0;
    /// True when the context has an on-screen default framebuffer (a window).
    virtual bool hasWindow() const { return false; }
    /// Presents the default framebuffer (windows only; no-op headless).
    virtual void swapBuffers() {}
    /// Window contexts: true once the user asked to close it.
    virtual bool shouldClose() const { return false; }
    /// Window contexts: the GLFWwindow* (for input callbacks and UI
    /// toolkits); null headless.
    virtual void* nativeWindow() const { return nullptr; }

protected:
    GlContext() = default;
};

/// A headless OpenGL 4.5 core context through EGL, current on return.
///
/// Display choice: EGL_PLATFORM=surfaceless|device|<other> in the environment
/// picks that platform (other values go to eglGetDisplay, which honours it).
/// Otherwise: the first hardware EGL device (EGL_EXT_platform_device; devices
/// marked EGL_MESA_device_software are skipped, so an NVIDIA GPU wins over
/// Mesa's llvmpipe when both are installed), then Mesa's surfaceless platform
/// (EGL_MESA_platform_surfaceless), then the default display. No default
/// framebuffer: render into framebuffer objects. Throws std::runtime_error
/// naming every platform tried and why it failed when none gives GL 4.5 core.
std::unique_ptr<GlContext> createHeadlessContext();

/// A GLFW window with an OpenGL 4.5 core context, current on return.
/// Throws std::runtime_error (e.g. "GLFW: X11: The DISPLAY environment
/// variable is missing") when no window can be made.
std::unique_ptr<GlContext> createWindowContext(int width, int height, const std::string& title, bool visible = true);

/// "llvmpipe (LLVM ...), OpenGL 4.5 (Core Profile) Mesa ..." of the current context.
std::string currentGlDescription();

} // namespace mtcut::render
