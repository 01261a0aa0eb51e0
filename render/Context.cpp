#include "render/Context.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace mtcut::render {

std::string currentGlDescription()
{
    auto str = [](GLenum e) {
        const GLubyte* s = glGetString(e);
        return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
    };
    return str(GL_RENDERER) + ", OpenGL " + str(GL_VERSION);
}

namespace {

/// Fails unless the current context is GL >= 4.5 core.
void requireGl45(const std::string& where)
{
    const int version = epoxy_gl_version();
    if (version < 45) {
        throw std::runtime_error(where + ": got OpenGL " + std::to_string(version / 10) + "." +
                                 std::to_string(version % 10) + ", need 4.5 core (" + currentGlDescription() + ")");
    }
}

bool hasExtension(const char* list, const char* name)
{
    if (!list) return false;
    const size_t n = std::strlen(name);
    for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    }
    return false;
}

std::string eglErrorText()
{
    const EGLint e = eglGetError();
    char buf[32];
    std::snprintf(buf, sizeof buf, "EGL error 0x%04x", unsigned(e));
    return buf;
}

/// Contexts alive per EGL display: eglTerminate ends every context of a
/// display, and a platform display is one object per process, so it is
/// terminated only with its last context.
std::mutex gEglMutex;
std::map<EGLDisplay, int> gEglDisplayUsers;

void releaseDisplay(EGLDisplay display)
{
    std::lock_guard<std::mutex> lock(gEglMutex);
    if (gEglDisplayUsers[display] == 0) eglTerminate(display);
}

class EglContext final : public GlContext
{
public:
    EglContext(EGLDisplay display, EGLContext context, std::string platform)
        : mDisplay(display), mContext(context), mPlatform(std::move(platform))
    {
        mDescription = "EGL " + mPlatform + ": " + currentGlDescription();
        std::lock_guard<std::mutex> lock(gEglMutex);
        ++gEglDisplayUsers[mDisplay];
    }
    ~EglContext() override
    {
        if (eglGetCurrentContext() == mContext) eglMakeCurrent(mDisplay, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(mDisplay, mContext);
        {
            std::lock_guard<std::mutex> lock(gEglMutex);
            --gEglDisplayUsers[mDisplay];
        }
        releaseDisplay(mDisplay);
    }
    void makeCurrent() override
    {
        if (!eglMakeCurrent(mDisplay, EGL_NO_SURFACE, EGL_NO_SURFACE, mContext)) {
            throw std::runtime_error("eglMakeCurrent: " + eglErrorText());
        }
    }
    std::string description() const override { return mDescription; }

private:
    EGLDisplay mDisplay;
    EGLContext mContext;
    std::string mPlatform;
    std::string mDescription;
};

/// Initialises `display` and makes a current GL 4.5 core context on it
/// (surfaceless). Returns null and appends the reason to `why` on failure
/// (the display is terminated then).
std::unique_ptr<GlContext> contextOn(EGLDisplay display, const std::string& platform, std::string& why)
{
    auto fail = [&](const std::string& what) -> std::unique_ptr<GlContext> {
        why += "; " + platform + ": " + what;
        if (display != EGL_NO_DISPLAY) releaseDisplay(display);
        return nullptr;
    };
    if (display == EGL_NO_DISPLAY) return fail("no display (" + eglErrorText() + ")");
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor)) {
        why += "; " + platform + ": eglInitialize failed (" + eglErrorText() + ")";
        return nullptr;
    }
    const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
    if (!hasExtension(extensions, "EGL_KHR_surfaceless_context")) return fail("no EGL_KHR_surfaceless_context");
    if (!eglBindAPI(EGL_OPENGL_API)) return fail("no desktop OpenGL API (" + eglErrorText() + ")");
    EGLConfig config = nullptr;
    const EGLint configAttribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint configCount = 0;
    if (!eglChooseConfig(display, configAttribs, &config, 1, &configCount) || configCount < 1) {
        if (!hasExtension(extensions, "EGL_KHR_no_config_context")) return fail("no OpenGL config");
        config = EGL_NO_CONFIG_KHR;
    }
    const EGLint contextAttribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                     EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    const EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, contextAttribs);
    if (context == EGL_NO_CONTEXT) return fail("no OpenGL 4.5 core context (" + eglErrorText() + ")");
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
        eglDestroyContext(display, context);
        return fail("eglMakeCurrent failed (" + eglErrorText() + ")");
    }
    try {
        requireGl45(platform);
    } catch (const std::exception& e) {
        eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT); // leaves no context current
        eglDestroyContext(display, context);
        return fail(e.what());
    }
    return std::make_unique<EglContext>(display, context, platform);
}

/// EGL devices (EGL_EXT_device_enumeration); empty when unsupported.
std::vector<EGLDeviceEXT> eglDevices(const char* clientExtensions)
{
    if (!hasExtension(clientExtensions, "EGL_EXT_device_enumeration") &&
        !hasExtension(clientExtensions, "EGL_EXT_device_base")) {
        return {};
    }
    EGLint count = 0;
    if (!eglQueryDevicesEXT(0, nullptr, &count) || count <= 0) return {};
    std::vector<EGLDeviceEXT> devices(static_cast<size_t>(count));
    if (!eglQueryDevicesEXT(count, devices.data(), &count)) return {};
    devices.resize(size_t(count));
    return devices;
}

std::unique_ptr<GlContext> tryDevices(const char* clientExtensions, bool includeSoftware, std::string& why)
{
    if (!hasExtension(clientExtensions, "EGL_EXT_platform_device")) {
        why += "; device: no EGL_EXT_platform_device";
        return nullptr;
    }
    const std::vector<EGLDeviceEXT> devices = eglDevices(clientExtensions);
    if (devices.empty()) why += "; device: no EGL devices";
    for (size_t i = 0; i < devices.size(); ++i) {
        const char* devExt = eglQueryDeviceStringEXT(devices[i], EGL_EXTENSIONS);
        const bool software = hasExtension(devExt, "EGL_MESA_device_software");
        if (software && !includeSoftware) continue;
        const EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
        auto ctx = contextOn(display, "device " + std::to_string(i) + (software ? " (software)" : ""), why);
        if (ctx) return ctx;
    }
    return nullptr;
}

std::unique_ptr<GlContext> trySurfaceless(const char* clientExtensions, std::string& why)
{
    if (!hasExtension(clientExtensions, "EGL_MESA_platform_surfaceless")) {
        why += "; surfaceless: no EGL_MESA_platform_surfaceless";
        return nullptr;
    }
    const EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    return contextOn(display, "surfaceless", why);
}

} // namespace

std::unique_ptr<GlContext> createHeadlessContext()
{
    // Client extensions (EGL 1.5 / EGL_EXT_client_extensions); null when unsupported.
    const char* clientExtensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!clientExtensions) eglGetError(); // clear EGL_BAD_DISPLAY
    std::string why;
    std::unique_ptr<GlContext> ctx;
    const char* env = std::getenv("EGL_PLATFORM");
    const std::string platform = env ? env : "";
    if (platform == "surfaceless") {
        ctx = trySurfaceless(clientExtensions, why);
    } else if (platform == "device") {
        ctx = tryDevices(clientExtensions, true, why);
    } else if (!platform.empty()) {
        ctx = contextOn(eglGetDisplay(EGL_DEFAULT_DISPLAY), "default display (EGL_PLATFORM=" + platform + ")", why);
    } else {
        ctx = tryDevices(clientExtensions, false, why);
        if (!ctx) ctx = trySurfaceless(clientExtensions, why);
        if (!ctx) ctx = contextOn(eglGetDisplay(EGL_DEFAULT_DISPLAY), "default display", why);
    }
    if (!ctx) {
        throw std::runtime_error("no headless OpenGL 4.5 core context: " + (why.size() > 2 ? why.substr(2) : why) +
                                 " (needs EGL with Mesa >= 20 or an NVIDIA driver; try EGL_PLATFORM=surfaceless)");
    }
    return ctx;
}

// ------------------------------------------------------------------ GLFW --

namespace {

std::mutex gGlfwMutex;
std::string gGlfwError;

void glfwErrorCallback(int, const char* description)
{
    gGlfwError = description ? description : "unknown error";
}

class GlfwContext final : public GlContext
{
public:
    explicit GlfwContext(GLFWwindow* window) : mWindow(window)
    {
        mDescription = "GLFW window: " + currentGlDescription();
    }
    ~GlfwContext() override
    {
        std::lock_guard<std::mutex> lock(gGlfwMutex);
        glfwDestroyWindow(mWindow);
        if (--sWindows == 0) glfwTerminate();
    }
    void makeCurrent() override { glfwMakeContextCurrent(mWindow); }
    std::string description() const override { return mDescription; }
    bool hasWindow() const override { return true; }
    void swapBuffers() override { glfwSwapBuffers(mWindow); }
    bool shouldClose() const override { return glfwWindowShouldClose(mWindow) != 0; }
    void* nativeWindow() const override { return mWindow; }
    GLFWwindow* window() const { return mWindow; }

    static int sWindows;

private:
    GLFWwindow* mWindow;
    std::string mDescription;
};

int GlfwContext::sWindows = 0;

} // namespace

std::unique_ptr<GlContext> createWindowContext(int width, int height, const std::string& title, bool visible)
{
    GLFWwindow* window = nullptr;
    {
        std::lock_guard<std::mutex> lock(gGlfwMutex);
        glfwSetErrorCallback(glfwErrorCallback);
        gGlfwError.clear();
        if (GlfwContext::sWindows == 0 && !glfwInit()) {
            throw std::runtime_error("GLFW: " + (gGlfwError.empty() ? std::string("glfwInit failed") : gGlfwError));
        }
        glfwDefaultWindowHints();
        glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
        glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
        glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
        glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
        glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
        window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
        if (!window) {
            const std::string why = gGlfwError.empty() ? std::string("glfwCreateWindow failed") : gGlfwError;
            if (GlfwContext::sWindows == 0) glfwTerminate();
            throw std::runtime_error("GLFW: no OpenGL 4.5 core window: " + why);
        }
        glfwMakeContextCurrent(window);
        ++GlfwContext::sWindows;
    }
    std::unique_ptr<GlContext> ctx = std::make_unique<GlfwContext>(window);
    requireGl45("GLFW window"); // the window goes with ctx on a throw
    return ctx;
}

} // namespace mtcut::render
