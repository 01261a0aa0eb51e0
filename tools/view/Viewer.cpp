#include "tools/view/Viewer.h"

#include "cutter/PathFile.h"
#include "cutter/PoseStream.h"
#include "render/BladeOverlay.h"
#include "render/Camera.h"
#include "render/Context.h"
#include "render/Frame.h"
#include "render/GlObjects.h"
#include "render/GpuTimer.h"
#include "render/MaskTiling.h"
#include "render/Shaders.h"
#include "render/SurfaceRenderer.h"
#include "tools/Cli.h"
#include "tools/view/CutSession.h"

#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/gtx/rotate_vector.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <iostream>
#include <thread>
#include <utility>

namespace mtcut::view {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string lowerExtension(const std::string& path)
{
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

/// Reads live poses (path format) on its own thread and feeds them to the
/// session as strokes: a blank line / `stroke` ends one, `end` ends the stream.
class PoseStreamReader
{
public:
    PoseStreamReader(const std::string& spec, CutSession& session) : mSession(session)
    {
        if (spec == "stdin") {
            mSource = std::make_unique<cutter::StreamLineSource>(std::cin, "stdin");
        } else if (spec.rfind("udp:", 0) == 0) {
            const long port = std::strtol(spec.c_str() + 4, nullptr, 10);
            if (port <= 0 || port > 65535) throw InputError("--poses " + spec + ": expected udp:PORT (1..65535)");
            mSource = std::make_unique<cutter::UdpLineSource>(uint16_t(port));
        } else {
            throw InputError("--poses " + spec + ": expected stdin or udp:PORT");
        }
        mThread = std::thread([this] { run(); });
    }
    ~PoseStreamReader()
    {
        mStop = true;
        mSource->stop();
        // A blocked read of stdin cannot be interrupted: leave that thread to
        // end with the process (it touches nothing once mStop is set).
        if (mSource->name() == "stdin") {
            mThread.detach();
            mSource.release();
        } else {
            mThread.join();
        }
    }
    /// The stream has ended (`end`, or the end of stdin); every pose of it
    /// is posted to the session.
    bool ended() const { return mEnded; }

private:
    void run()
    {
        std::string line;
        bool inStroke = false;
        for (size_t lineNo = 1; !mStop && mSource->next(line); ++lineNo) {
            if (mStop) return;
            try {
                cutter::PathLine parsed = cutter::parsePathLine(line, lineNo, mSource->name());
                if (parsed.kind == cutter::PathLine::Kind::Pose) {
                    cutter::checkPose(parsed.pose, lineNo, mSource->name());
                    if (!inStroke) mSession.beginStroke();
                    inStroke = true;
                    mSession.addPose(parsed.pose);
                } else if (parsed.kind == cutter::PathLine::Kind::StrokeBreak ||
                           parsed.kind == cutter::PathLine::Kind::End) {
                    if (inStroke) mSession.endStroke();
                    inStroke = false;
                    if (parsed.kind == cutter::PathLine::Kind::End) break;
                }
            } catch (const std::exception& e) {
                std::fprintf(stderr, "mtcut-view: error: %s\n", e.what());
            }
        }
        if (inStroke && !mStop) mSession.endStroke();
        mEnded = true; // after the last command it posts
    }

    CutSession& mSession;
    std::unique_ptr<cutter::LineSource> mSource;
    std::atomic<bool> mStop{false};
    std::atomic<bool> mEnded{false};
    std::thread mThread;
};

bool sameCamera(const render::Camera& a, const render::Camera& b)
{
    static_assert(sizeof(render::Camera) == 3 * sizeof(glm::dvec3) + 3 * sizeof(double) + sizeof(glm::dvec2),
                  "a field added to Camera must be compared here");
    return a.eye == b.eye && a.target == b.target && a.up == b.up && a.fovYDegrees == b.fovYDegrees &&
           a.nearMm == b.nearMm && a.farMm == b.farMm && a.lensShift == b.lensShift;
}

bool sameStyle(const render::RenderStyle& a, const render::RenderStyle& b)
{
    return a.colour == b.colour && a.highlightColour == b.highlightColour && a.background == b.background &&
           a.highlight == b.highlight && a.fragmentColours == b.fragmentColours;
}

/// Per-fragment display state, by fragment index (id - 1).
struct FragmentStyle
{
    bool visible = true;
    bool selected = false;
    bool customColour = false;
    glm::vec3 colour{0.89f, 0.85f, 0.74f};
};

class Viewer
{
public:
    explicit Viewer(const ViewerOptions& options);
    ~Viewer();
    int run();

private:
    // frame steps
    void pollSession();
    void applySnapshot();
    void panel();
    void overlay();
    void handleInput();
    void stepScript();
    void renderFrame();

    // helpers
    void post(bool error, const std::string& text);
    render::Bounds sceneBounds() const;
    void setPreset(const std::string& view);
    void updateCamera();
    /// The preset view `mPreset` as `mtcut render --view` frames it on the whole image.
    render::Camera presetCamera() const;
    /// The blade for the cursor at pixel (x, y), at the stroke's picked depth, at `time` s.
    cutter::Pose bladeAt(double x, double y, double time) const;
    /// Script `drag`: a mouse stroke from pixel a to b, through the same path as the mouse.
    void scriptDrag(const std::string& argument);
    void screenshot(const std::string& path);
    /// Toggles the selection of the fragment seen at window pixel (x, y) (the
    /// last frame's fragment ids) and scrolls the list to it.
    void pick(double x, double y);
    /// Saves the selected fragments (with cut.vdb, slices.exr, summary.json) into `dir`.
    void saveSelected(const std::string& dir, const std::string& format);
    void saveWindow(const std::string& path);
    render::RenderStyle style(bool forScreenshot) const;

    ViewerOptions mOptions;
    std::unique_ptr<render::GlContext> mContext;
    GLFWwindow* mWindow = nullptr;
    CutSession mSession;
    std::unique_ptr<PoseStreamReader> mPoses;

    // GL
    std::unique_ptr<render::SurfaceRenderer> mRenderer;
    std::unique_ptr<render::BladeOverlay> mBlade;
    std::unique_ptr<render::GpuTimer> mTimer;

    // scene
    std::shared_ptr<const SceneSnapshot> mShown; ///< what the renderer holds
    /// The renderer's image is the window's view of mShown with this camera
    /// and style: a frame that changes none of them only presents it again
    /// (an idle or busy viewer does not redraw millions of triangles 4 times
    /// a second; llvmpipe draws on the cores a save or a cut needs).
    bool mSceneDrawn = false;
    render::Camera mDrawnCamera;
    render::RenderStyle mDrawnStyle;
    uint64_t mShownSurfaceSerial = 0;
    std::vector<FragmentStyle> mFragments;

    // camera
    render::Camera mCamera;
    std::string mPreset = "front"; ///< non-empty: the camera follows this preset view
    int mWidth = 0, mHeight = 0;
    double mPanelRight = 0.0; ///< framebuffer x of the panel's right edge (0: no panel); preset views centre right of it

    // panel state
    float mIso = 0.0f;
    float mKerf = 0.0f;
    float mRetrace = 0.25f; ///< the path filter's retrace tolerance, voxels (panel)
    float mSlide = 0.25f;   ///< the path filter's slide tolerance, voxels (panel)
    float mBladeLength = 60.0f;   ///< mm
    double mScriptWaitUntil = 0.0; ///< glfwGetTime() before which the script waits (`wait`)
    bool mScriptWaitPoses = false; ///< the script waits for the --poses stream to end (`wait poses`)
    int mScrollTo = -1;           ///< fragment list row to scroll to (-1: none)
    float mBladeAngle = 0.0f;     ///< degrees, blade tilted from the view direction towards the screen's bottom
    bool mHighlight = false;
    bool mShowOverlay = true;
    char mOpenPath[1024] = "";
    char mSaveDir[1024] = "mtcut-view-out";
    char mShotPath[1024] = "mtcut-view.png";
    int mFormat = 0;
    std::string mBrowseDir;
    std::deque<Message> mLog;

    // mouse
    enum class Drag { None, Cut, Orbit, Pan };
    Drag mDrag = Drag::None;
    double mLastX = 0, mLastY = 0;
    double mStrokeDepth = 0.0, mStrokeStart = 0.0;
    bool mHaveHover = false;
    cutter::Pose mHover;

    // script
    size_t mScriptNext = 0;
    std::string mWindowShot; ///< write the window's next frame here (panel included)
    bool mQuit = false;

    // timing
    double mFrameMs = 0.0;
    Clock::time_point mLastFrame = Clock::now();
};

Viewer::Viewer(const ViewerOptions& options)
    : mOptions(options), mContext(render::createWindowContext(options.width, options.height, "mtcut-view")),
      mSession(options.readOptions)
{
    mWindow = static_cast<GLFWwindow*>(mContext->nativeWindow());
    glfwSwapInterval(options.script.empty() ? 1 : 0);

    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(mWindow, true);
    ImGui_ImplOpenGL3_Init("#version 450 core");

    // A file or DICOM folder dropped on the window is opened.
    glfwSetWindowUserPointer(mWindow, this);
    glfwSetDropCallback(mWindow, [](GLFWwindow* window, int count, const char** paths) {
        auto* viewer = static_cast<Viewer*>(glfwGetWindowUserPointer(window));
        if (count > 0 && viewer) {
            std::snprintf(viewer->mOpenPath, sizeof viewer->mOpenPath, "%s", paths[0]);
            viewer->mSession.open(paths[0], std::numeric_limits<float>::quiet_NaN());
        }
    });
    mBlade = std::make_unique<render::BladeOverlay>();
    mTimer = std::make_unique<render::GpuTimer>();

    std::snprintf(mOpenPath, sizeof mOpenPath, "%s", options.input.c_str());
    mBrowseDir = fs::current_path().string();
    if (!options.input.empty()) {
        std::error_code ec;
        const fs::path p = fs::absolute(options.input, ec);
        if (!ec) mBrowseDir = (fs::is_directory(p, ec) ? p.parent_path() : p.parent_path()).string();
    }
    mSession.open(options.input, options.isovalue);
    mRetrace = float(options.retrace);
    if (options.retrace != cutter::PathFilterOptions{}.retraceTolerance) mSession.setRetrace(options.retrace);
    mSlide = float(options.slide);
    if (options.slide != cutter::PathFilterOptions{}.slideTolerance) mSession.setSlide(options.slide);
    if (!options.poseStream.empty()) {
        try {
            mPoses = std::make_unique<PoseStreamReader>(options.poseStream, mSession);
        } catch (const std::exception& e) {
            post(true, e.what());
        }
    }
}

Viewer::~Viewer()
{
    mPoses.reset();
    mRenderer.reset();
    mTimer.reset();
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
}

void Viewer::post(bool error, const std::string& text)
{
    std::fprintf(stderr, "mtcut-view: %s%s\n", error ? "error: " : "", text.c_str());
    mLog.push_back({error, text});
    while (mLog.size() > 12) mLog.pop_front();
}

void Viewer::pollSession()
{
    for (const Message& m : mSession.takeMessages()) post(m.error, m.text);
}

render::Bounds Viewer::sceneBounds() const
{
    if (mRenderer) {
        const render::Bounds b = mRenderer->bounds();
        if (b.hi != b.lo) return b;
    }
    return render::Bounds{glm::dvec3(-100.0), glm::dvec3(100.0)};
}

void Viewer::setPreset(const std::string& view)
{
    // Checks the syntax (throws InputError) before the camera changes.
    (void)render::cameraFor(view, sceneBounds(), 1.0);
    mPreset = view;
    updateCamera();
}

render::Camera Viewer::presetCamera() const
{
    return render::cameraFor(mPreset, sceneBounds(), double(mWidth) / mHeight);
}

void Viewer::updateCamera()
{
    if (mWidth <= 0 || mHeight <= 0) return;
    const double free = double(mWidth) - mPanelRight;
    if (!mPreset.empty() && mOptions.script.empty() && mPanelRight > 0.0 && free >= 0.3 * mWidth) {
        // Interactive window: frame the preset in the area right of the panel
        // (its aspect), with the lens shifted so the scene's centre, still the
        // target an orbit turns about, is seen at that area's centre.
        // Screenshots use presetCamera() (the whole image, as `mtcut
        // render`); a script never gets here.
        mCamera = render::cameraFor(mPreset, sceneBounds(), free / mHeight);
        mCamera.lensShift = glm::dvec2(mPanelRight / mWidth, 0.0);
    } else if (!mPreset.empty()) {
        mCamera = presetCamera();
    } else {
        render::fitDepth(mCamera, sceneBounds());
    }
}

void Viewer::applySnapshot()
{
    const std::shared_ptr<const SceneSnapshot> snap = mSession.snapshot();
    if (snap == mShown || !mRenderer) return;
    mSceneDrawn = false;
    const bool firstSurface = !mShown || !mShown->surface || mShown->input != snap->input;
    if (snap->surface) {
        const std::vector<uint32_t> noIds;
        const std::vector<uint32_t>& ids = snap->surfaceIds ? *snap->surfaceIds : noIds;
        if (!mShown || snap->surface != mShown->surface) {
            mRenderer->setSurface(*snap->surface, ids);
            mShownSurfaceSerial = snap->surfaceSerial;
        } else {
            mRenderer->clearCut();
            if (snap->surfaceSerial != mShownSurfaceSerial) {
                // Same surface, new fragment ids (a stroke ended): rewrite only
                // the per-triangle buffer, not the whole surface.
                mRenderer->setSurfaceFragmentIds(*snap->surface, ids);
                mShownSurfaceSerial = snap->surfaceSerial;
            }
        }
        if (snap->cut && snap->cells) {
            mRenderer->setCutCells(*snap->cells);
            mRenderer->setCutGeometry(snap->cut->mesh, *snap->cutIds, snap->cut->triangleIsCap);
        }
    }
    if (firstSurface && snap->surface) { // a new scan: front view, fresh fragment styles
        mPreset = "front";
        mFragments.clear();
    }
    mIso = snap->isovalue;
    mKerf = float(snap->kerfMm);
    if (mFragments.size() != snap->fragments.size() && !snap->liveStroke) {
        mFragments.resize(snap->fragments.size());
    }
    mShown = snap;
    updateCamera();
}

render::RenderStyle Viewer::style(bool forScreenshot) const
{
    render::RenderStyle s;
    s.highlight = mHighlight;
    if (!forScreenshot) s.background = glm::vec4(0.16f, 0.17f, 0.19f, 1.0f);
    const bool styled = std::any_of(mFragments.begin(), mFragments.end(), [](const FragmentStyle& f) {
        return !f.visible || f.selected || f.customColour;
    });
    if (styled) { // index = fragment id; 0 = cut geometry of a live stroke
        s.fragmentColours.assign(mFragments.size() + 1, glm::vec4(s.colour, 1.0f));
        for (size_t i = 0; i < mFragments.size(); ++i) {
            const FragmentStyle& f = mFragments[i];
            glm::vec3 c = f.customColour ? f.colour : s.colour;
            if (f.selected) c = glm::mix(c, glm::vec3(0.25f, 0.55f, 1.0f), 0.55f);
            s.fragmentColours[i + 1] = glm::vec4(c, f.visible ? 1.0f : 0.0f);
        }
    }
    return s;
}

cutter::Pose Viewer::bladeAt(double x, double y, double time) const
{
    // The blade points into the screen, tilted by the panel's angle towards
    // the bottom of the screen; it starts a little in front of the picked depth.
    const glm::dvec3 forward = glm::normalize(mCamera.target - mCamera.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, mCamera.up));
    const glm::dvec3 up = glm::cross(right, forward);
    const double a = glm::radians(double(mBladeAngle));
    cutter::Pose p;
    p.direction = glm::normalize(std::cos(a) * forward - std::sin(a) * up);
    p.length = mBladeLength;
    const double inset = std::min(5.0, 0.1 * p.length);
    p.base = mCamera.worldPointAt(x, y, mWidth, mHeight, mStrokeDepth) - inset * p.direction;
    p.time = time;
    return p;
}

void Viewer::handleInput()
{
    ImGuiIO& io = ImGui::GetIO();
    double x = 0, y = 0;
    glfwGetCursorPos(mWindow, &x, &y);
    // Window to framebuffer pixels (HiDPI).
    int ww = 1, wh = 1;
    glfwGetWindowSize(mWindow, &ww, &wh);
    x *= double(mWidth) / std::max(ww, 1);
    y *= double(mHeight) / std::max(wh, 1);
    const double dx = x - mLastX, dy = y - mLastY;
    mLastX = x;
    mLastY = y;

    if (!io.WantCaptureKeyboard) {
        const bool ctrl = io.KeyCtrl, shift = io.KeyShift;
        if (ctrl && ImGui::IsKeyPressed(GLFW_KEY_Z, false)) {
            if (shift) {
                mSession.redo();
            } else if (mDrag == Drag::Cut && mShown && mShown->liveStroke) {
                // Within the current stroke: back 10 quads; dragging on starts a new stroke.
                const uint32_t q = mShown->lastStrokeQuads;
                mSession.undoToQuad(q > 10 ? q - 10 : 0);
                mDrag = Drag::None;
            } else {
                mSession.undo();
            }
        }
        if (ctrl && ImGui::IsKeyPressed(GLFW_KEY_Y, false)) mSession.redo();
        if (!ctrl) {
            const char* presets[] = {"front", "side", "top", "iso"};
            for (int k = 0; k < 4; ++k) {
                if (ImGui::IsKeyPressed(GLFW_KEY_1 + k, false)) setPreset(presets[k]);
            }
            if (ImGui::IsKeyPressed(GLFW_KEY_R, false)) setPreset("front");
            if (ImGui::IsKeyPressed(GLFW_KEY_H, false)) mHighlight = !mHighlight;
            if (ImGui::IsKeyPressed(GLFW_KEY_F1, false)) mShowOverlay = !mShowOverlay;
        }
    }

    const bool overUi = io.WantCaptureMouse && mDrag == Drag::None;
    mHaveHover = false;
    if (!mRenderer || overUi) return;

    // Zoom: the wheel moves the eye towards the target.
    if (io.MouseWheel != 0.0f) {
        const glm::dvec3 offset = mCamera.eye - mCamera.target;
        mCamera.eye = mCamera.target + offset * std::pow(0.88, double(io.MouseWheel));
        mPreset.clear();
        updateCamera();
    }

    if (mDrag == Drag::None && ImGui::IsMouseClicked(0) && io.KeyCtrl) {
        pick(x, y); // Ctrl+click: select a fragment, no drag
    } else if (mDrag == Drag::None && (ImGui::IsMouseClicked(0) || ImGui::IsMouseClicked(1) || ImGui::IsMouseClicked(2))) {
        const float depth = mRenderer->viewDepthAt(int(x), int(y));
        if (ImGui::IsMouseClicked(0) && !io.KeyShift && !io.KeyAlt && std::isfinite(depth) && mShown &&
            mShown->surface) {
            mDrag = Drag::Cut;
            mStrokeDepth = depth;
            mStrokeStart = glfwGetTime();
            mSession.beginStroke();
            mSession.addPose(bladeAt(x, y, glfwGetTime() - mStrokeStart));
        } else if (ImGui::IsMouseClicked(2) || (ImGui::IsMouseClicked(0) && io.KeyShift)) {
            mDrag = Drag::Pan;
        } else {
            mDrag = Drag::Orbit;
        }
    } else if (mDrag != Drag::None && !ImGui::IsMouseDown(0) && !ImGui::IsMouseDown(1) && !ImGui::IsMouseDown(2)) {
        if (mDrag == Drag::Cut) mSession.endStroke();
        mDrag = Drag::None;
    } else if (mDrag == Drag::Cut && (dx != 0.0 || dy != 0.0)) {
        mSession.addPose(bladeAt(x, y, glfwGetTime() - mStrokeStart));
    } else if (mDrag == Drag::Orbit && (dx != 0.0 || dy != 0.0)) {
        const glm::dvec3 forward = glm::normalize(mCamera.target - mCamera.eye);
        const glm::dvec3 right = glm::normalize(glm::cross(forward, mCamera.up));
        glm::dvec3 offset = mCamera.eye - mCamera.target;
        glm::dvec3 up = glm::normalize(glm::cross(right, forward));
        const double yaw = -dx * 0.008, pitch = -dy * 0.008;
        offset = glm::rotate(offset, yaw, up);
        const glm::dvec3 right2 = glm::rotate(right, yaw, up);
        offset = glm::rotate(offset, pitch, right2);
        up = glm::rotate(up, pitch, right2);
        mCamera.eye = mCamera.target + offset;
        mCamera.up = up;
        mPreset.clear();
        updateCamera();
    } else if (mDrag == Drag::Pan && (dx != 0.0 || dy != 0.0)) {
        const glm::dvec3 forward = glm::normalize(mCamera.target - mCamera.eye);
        const glm::dvec3 right = glm::normalize(glm::cross(forward, mCamera.up));
        const glm::dvec3 up = glm::cross(right, forward);
        const double distance = glm::length(mCamera.target - mCamera.eye);
        const double mmPerPixel = 2.0 * distance * std::tan(glm::radians(mCamera.fovYDegrees) / 2.0) / mHeight;
        const glm::dvec3 shift = (-dx * right + dy * up) * mmPerPixel;
        mCamera.eye += shift;
        mCamera.target += shift;
        mPreset.clear();
        updateCamera();
    }
    if (mDrag == Drag::None && !io.WantCaptureMouse) {
        // Where the blade would go: shown while hovering over the bone.
        const float depth = mRenderer->viewDepthAt(int(x), int(y));
        if (std::isfinite(depth)) {
            const double saved = mStrokeDepth;
            mStrokeDepth = depth;
            mHover = bladeAt(x, y, 0.0);
            mStrokeDepth = saved;
            mHaveHover = true;
        }
    }
}

void Viewer::pick(double x, double y)
{
    if (!mRenderer || !mShown) return;
    const uint32_t id = mRenderer->fragmentIdAt(int(x), int(y));
    if (id == 0 || id > mFragments.size() || id > mShown->fragments.size()) {
        post(false, "pick: no fragment at pixel (" + std::to_string(int(x)) + ", " + std::to_string(int(y)) + ")");
        return;
    }
    FragmentStyle& f = mFragments[id - 1];
    f.selected = !f.selected;
    mScrollTo = int(id - 1);
    char text[160];
    std::snprintf(text, sizeof text, "fragment %03u %s (%.0f mm^3, %.0f mm^2)", id - 1,
                  f.selected ? "selected" : "unselected", mShown->fragments[id - 1].volumeMm3,
                  mShown->fragments[id - 1].areaMm2);
    post(false, text);
}

void Viewer::saveSelected(const std::string& dir, const std::string& format)
{
    if (!mShown) return;
    std::vector<bool> selected(mShown->fragments.size(), false);
    for (size_t i = 0; i < selected.size() && i < mFragments.size(); ++i) selected[i] = mFragments[i].selected;
    mSession.save({dir, format, selected});
}

void Viewer::screenshot(const std::string& path)
{
    const std::string ext = lowerExtension(path);
    if (ext != ".png" && ext != ".exr") throw InputError("screenshot " + path + ": expected a .png or .exr file name");
    if (!mRenderer) throw InputError("screenshot " + path + ": nothing on screen yet");
    // A preset view as `mtcut render` frames it (the window's may sit right of the panel).
    mRenderer->render(mPreset.empty() ? mCamera : presetCamera(), style(true));
    mSceneDrawn = false;
    const render::Frame frame = mRenderer->readFrame();
    if (ext == ".png") {
        render::writePng(frame, path);
    } else {
        render::writeExr(frame, path);
    }
    post(false, "screenshot " + path + " (" + std::to_string(frame.width) + "x" + std::to_string(frame.height) + ")");
}

void Viewer::saveWindow(const std::string& path)
{
    render::Frame frame;
    frame.width = mWidth;
    frame.height = mHeight;
    std::vector<uint8_t> rows(frame.pixelCount() * 4);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    glReadBuffer(GL_BACK);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, mWidth, mHeight, GL_RGBA, GL_UNSIGNED_BYTE, rows.data());
    render::checkGlError("mtcut-view window capture");
    frame.rgba.resize(rows.size());
    const size_t row = size_t(mWidth) * 4;
    for (int y = 0; y < mHeight; ++y) {
        std::copy_n(rows.begin() + long(size_t(mHeight - 1 - y) * row), row, frame.rgba.begin() + long(size_t(y) * row));
    }
    for (size_t p = 0; p < frame.pixelCount(); ++p) frame.rgba[4 * p + 3] = 255;
    render::writePng(frame, path);
    post(false, "window " + path + " (" + std::to_string(mWidth) + "x" + std::to_string(mHeight) + ")");
}

void Viewer::scriptDrag(const std::string& argument)
{
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    char tail = 0;
    if (std::sscanf(argument.c_str(), "%lf %lf %lf %lf %c", &x0, &y0, &x1, &y1, &tail) != 4) {
        throw InputError("drag " + argument + ": expected X0 Y0 X1 Y1 (pixels)");
    }
    mRenderer->render(mCamera, style(false)); // pick on what the current camera sees
    mSceneDrawn = false;
    const float depth = mRenderer->viewDepthAt(int(x0), int(y0));
    if (!std::isfinite(depth)) throw InputError("drag " + argument + ": no bone under the start pixel");
    mStrokeDepth = depth;
    mSession.beginStroke();
    // One pose per pixel of the way, 2 ms apart, as a steady hand would give.
    const int steps = std::max(1, int(std::ceil(std::hypot(x1 - x0, y1 - y0))));
    for (int i = 0; i <= steps; ++i) {
        const double t = double(i) / steps;
        mSession.addPose(bladeAt(x0 + t * (x1 - x0), y0 + t * (y1 - y0), 0.002 * i));
    }
    mSession.endStroke();
}

void Viewer::stepScript()
{
    if (mScriptNext >= mOptions.script.size()) return;
    // `wait poses`: the stream's commands are all posted once it has ended,
    // so the session's being idle below means they are done.
    if (mScriptWaitPoses) {
        if (mPoses && !mPoses->ended()) return;
        mScriptWaitPoses = false;
    }
    // The action before has finished and its result is on screen.
    if (!mSession.idle() || mSession.snapshot() != mShown || !mRenderer) return;
    if (glfwGetTime() < mScriptWaitUntil) return;
    const ScriptAction& a = mOptions.script[mScriptNext++];
    const std::string where = mOptions.scriptName + ":" + std::to_string(a.line) + ": ";
    try {
        switch (a.kind) {
        case ScriptAction::Kind::Iso: mSession.setIsovalue(float(a.number)); break;
        case ScriptAction::Kind::View: setPreset(a.argument); break;
        case ScriptAction::Kind::Kerf: mSession.setKerf(a.number); break;
        case ScriptAction::Kind::Retrace:
            mSession.setRetrace(a.number);
            mRetrace = float(a.number);
            break;
        case ScriptAction::Kind::Slide:
            mSession.setSlide(a.number);
            mSlide = float(a.number);
            break;
        case ScriptAction::Kind::Path: mSession.addStrokes(cli::readStrokes(a.argument), a.argument); break;
        case ScriptAction::Kind::Drag: scriptDrag(a.argument); break;
        case ScriptAction::Kind::Undo: mSession.undo(); break;
        case ScriptAction::Kind::Redo: mSession.redo(); break;
        case ScriptAction::Kind::Screenshot: screenshot(a.argument); break;
        case ScriptAction::Kind::Window:
            if (lowerExtension(a.argument) != ".png") throw InputError("window " + a.argument + ": expected a .png file name");
            mWindowShot = a.argument;
            break;
        case ScriptAction::Kind::Export: mSession.save({a.argument, "stl", {}}); break;
        case ScriptAction::Kind::ExportSelected: saveSelected(a.argument, "stl"); break;
        case ScriptAction::Kind::Pick: {
            std::istringstream words(a.argument);
            double x = 0, y = 0;
            words >> x >> y;
            pick(x, y);
            break;
        }
        case ScriptAction::Kind::Wait: mScriptWaitUntil = glfwGetTime() + a.number; break;
        case ScriptAction::Kind::WaitPoses:
            if (!mPoses) throw InputError("wait poses: no pose stream (start with --poses stdin or --poses udp:PORT)");
            mScriptWaitPoses = true;
            break;
        case ScriptAction::Kind::Quit: mQuit = true; break;
        }
    } catch (const std::exception& e) {
        post(true, where + e.what());
    }
}

void Viewer::panel()
{
    const std::shared_ptr<const SceneSnapshot>& s = mShown;
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
    // At most 40 % of a small window's width (the view stays usable at 640x480).
    ImGui::SetNextWindowSize(ImVec2(std::clamp(0.4f * float(mWidth), 240.0f, 360.0f), float(std::max(mHeight - 16, 200))),
                             ImGuiCond_FirstUseEver);
    ImGui::Begin("MTCut");
    mPanelRight = ImGui::IsWindowCollapsed()
                      ? 0.0
                      : double(ImGui::GetWindowPos().x + ImGui::GetWindowSize().x) * ImGui::GetIO().DisplayFramebufferScale.x;
    ImGui::TextWrapped("LMB on bone: cut | Ctrl+LMB: select fragment | LMB elsewhere / RMB: orbit | MMB or Shift+LMB: pan | wheel: zoom | "
                       "1-4: front/side/top/iso, R: reset | Ctrl+Z / Ctrl+Shift+Z: undo/redo | H: highlight | "
                       "drop a file or folder to open it");
    ImGui::Separator();

    // -- file -------------------------------------------------------------------
    if (ImGui::CollapsingHeader("Scan", ImGuiTreeNodeFlags_DefaultOpen)) {
        ImGui::TextWrapped("%s", s && !s->input.empty() ? s->input.c_str() : "(loading)");
        ImGui::InputText("##path", mOpenPath, sizeof mOpenPath);
        ImGui::SameLine();
        if (ImGui::Button("Open")) mSession.open(mOpenPath, std::numeric_limits<float>::quiet_NaN());
        ImGui::SameLine();
        if (ImGui::Button("Phantom")) mSession.open("", std::numeric_limits<float>::quiet_NaN());
        if (ImGui::TreeNode("Browse")) {
            ImGui::TextWrapped("%s", mBrowseDir.c_str());
            ImGui::BeginChild("files", ImVec2(0, 140), true);
            if (ImGui::Selectable("..")) mBrowseDir = fs::path(mBrowseDir).parent_path().string();
            std::error_code ec;
            std::vector<fs::directory_entry> entries;
            for (const fs::directory_entry& e : fs::directory_iterator(mBrowseDir, ec)) entries.push_back(e);
            std::sort(entries.begin(), entries.end());
            for (const fs::directory_entry& e : entries) {
                const bool dir = e.is_directory(ec);
                const std::string label = e.path().filename().string() + (dir ? "/" : "");
                if (ImGui::Selectable(label.c_str(), e.path().string() == mOpenPath,
                                      ImGuiSelectableFlags_AllowDoubleClick)) {
                    std::snprintf(mOpenPath, sizeof mOpenPath, "%s", e.path().string().c_str());
                    if (dir && ImGui::IsMouseDoubleClicked(0)) mBrowseDir = e.path().string();
                }
            }
            ImGui::EndChild();
            ImGui::TextDisabled("click: pick (a DICOM folder too), double-click: enter folder");
            ImGui::TreePop();
        }
        if (!mSession.idle()) {
            const std::string task = mSession.task();
            const int pct = mSession.percent();
            ImGui::ProgressBar(pct >= 0 ? pct / 100.0f : 0.0f, ImVec2(-70, 0),
                               task.empty() ? "working" : task.c_str());
            ImGui::SameLine();
            if (ImGui::Button("Cancel")) mSession.cancel();
        }
    }

    // -- surface ------------------------------------------------------------------
    if (s && s->surface && ImGui::CollapsingHeader("Surface", ImGuiTreeNodeFlags_DefaultOpen)) {
        ImGui::SliderFloat(s->units == "HU" ? "iso (HU)" : "iso", &mIso, s->minValue, s->maxValue, "%.0f");
        if (ImGui::IsItemDeactivatedAfterEdit()) mSession.setIsovalue(mIso);
        ImGui::Text("%zu triangles, %zu fragment(s)", s->surface->triangleCount(), s->fragments.size());
        for (const char* v : {"front", "side", "top", "iso"}) {
            if (ImGui::Button(v)) setPreset(v);
            ImGui::SameLine();
        }
        ImGui::Checkbox("highlight cut", &mHighlight);
    }

    // -- blade ----------------------------------------------------------------------
    if (s && s->surface && ImGui::CollapsingHeader("Blade", ImGuiTreeNodeFlags_DefaultOpen)) {
        ImGui::SliderFloat("length (mm)", &mBladeLength, 2.0f, 200.0f, "%.0f");
        ImGui::SliderFloat("tilt (deg)", &mBladeAngle, -80.0f, 80.0f, "%.0f");
        ImGui::SliderFloat("kerf (mm)", &mKerf, 0.0f, 2.0f, "%.2f");
        if (ImGui::IsItemDeactivatedAfterEdit()) mSession.setKerf(mKerf);
        ImGui::SliderFloat("retrace (vox)", &mRetrace, 0.0f, float(cutter::kMaxRetraceTolerance), "%.2f");
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip("A pose this close to the cut is taken as going back over it. 1: a saw worked back and\n"
                              "forth cuts many times faster, and the cut may lag the blade by up to that much.");
        if (ImGui::IsItemDeactivatedAfterEdit()) mSession.setRetrace(mRetrace);
        ImGui::SliderFloat("slide (vox)", &mSlide, 0.0f, float(cutter::kMaxRetraceTolerance), "%.2f");
        if (ImGui::IsItemHovered())
            ImGui::SetTooltip("A pose whose blade lies this close to the line of the last one kept is held back as\n"
                              "sliding along itself (it sweeps no area) until the blade leaves that line.");
        if (ImGui::IsItemDeactivatedAfterEdit()) mSession.setSlide(mSlide);
        ImGui::Text("%u stroke(s), %zu cut voxels", s->strokes, s->cutCells);
        if (ImGui::Button("Undo")) mSession.undo();
        ImGui::SameLine();
        if (ImGui::Button("Redo")) mSession.redo();
        if (s->strokes > 0 && s->lastStrokeQuads > 0) {
            int keep = int(s->lastStrokeQuads);
            if (ImGui::SliderInt("last stroke", &keep, 0, int(s->lastStrokeQuads), "%d quads") &&
                keep < int(s->lastStrokeQuads)) {
                mSession.undoToQuad(uint32_t(keep));
            }
        }
    }

    // -- fragments ------------------------------------------------------------------
    if (s && s->surface && ImGui::CollapsingHeader("Fragments", ImGuiTreeNodeFlags_DefaultOpen)) {
        if (s->liveStroke) ImGui::TextDisabled("(updated when the stroke ends)");
        const ImGuiTableFlags flags = ImGuiTableFlags_ScrollY | ImGuiTableFlags_RowBg | ImGuiTableFlags_BordersOuter;
        if (ImGui::BeginTable("fragments", 6, flags, ImVec2(0, 180))) {
            ImGui::TableSetupScrollFreeze(0, 1);
            ImGui::TableSetupColumn("#");
            ImGui::TableSetupColumn("show");
            ImGui::TableSetupColumn("sel");
            ImGui::TableSetupColumn("colour");
            ImGui::TableSetupColumn("mm^3");
            ImGui::TableSetupColumn("mm^2");
            ImGui::TableHeadersRow();
            ImGuiListClipper clipper;
            const int count = int(std::min(s->fragments.size(), mFragments.size()));
            clipper.Begin(count);
            if (mScrollTo >= 0 && mScrollTo < count) clipper.ForceDisplayRangeByIndices(mScrollTo, mScrollTo + 1);
            while (clipper.Step()) {
                for (int i = clipper.DisplayStart; i < clipper.DisplayEnd; ++i) {
                    FragmentStyle& f = mFragments[size_t(i)];
                    ImGui::PushID(i);
                    ImGui::TableNextRow();
                    ImGui::TableNextColumn();
                    ImGui::Text("%03d", i);
                    ImGui::TableNextColumn();
                    ImGui::Checkbox("##show", &f.visible);
                    ImGui::TableNextColumn();
                    ImGui::Checkbox("##sel", &f.selected);
                    if (i == mScrollTo) {
                        ImGui::SetScrollHereY();
                        mScrollTo = -1;
                    }
                    ImGui::TableNextColumn();
                    if (ImGui::ColorEdit3("##colour", glm::value_ptr(f.colour), ImGuiColorEditFlags_NoInputs)) {
                        f.customColour = true;
                    }
                    ImGui::TableNextColumn();
                    ImGui::Text("%.0f", s->fragments[size_t(i)].volumeMm3);
                    ImGui::TableNextColumn();
                    ImGui::Text("%.0f", s->fragments[size_t(i)].areaMm2);
                    ImGui::PopID();
                }
            }
            ImGui::EndTable();
        }
        if (ImGui::Button("show all")) {
            for (FragmentStyle& f : mFragments) f.visible = true;
        }
        ImGui::SameLine();
        if (ImGui::Button("select none")) {
            for (FragmentStyle& f : mFragments) f.selected = false;
        }
    }

    // -- save -------------------------------------------------------------------------
    if (s && s->surface && ImGui::CollapsingHeader("Save", ImGuiTreeNodeFlags_DefaultOpen)) {
        ImGui::InputText("folder", mSaveDir, sizeof mSaveDir);
        const char* formats[] = {"stl", "obj", "ply", "off"};
        ImGui::Combo("format", &mFormat, formats, 4);
        if (ImGui::Button("Save all")) mSession.save({mSaveDir, formats[mFormat], {}});
        ImGui::SameLine();
        if (ImGui::Button("Save selected")) {
            saveSelected(mSaveDir, formats[mFormat]);
        }
        ImGui::InputText("image", mShotPath, sizeof mShotPath);
        if (ImGui::Button("Screenshot (.png / .exr)")) {
            try {
                screenshot(mShotPath);
            } catch (const std::exception& e) {
                post(true, e.what());
            }
        }
    }

    // -- messages -----------------------------------------------------------------------
    if (!mLog.empty() && ImGui::CollapsingHeader("Messages", ImGuiTreeNodeFlags_DefaultOpen)) {
        for (auto it = mLog.rbegin(); it != mLog.rend(); ++it) {
            if (it->error) {
                ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.45f, 0.4f, 1.0f));
                ImGui::TextWrapped("%s", it->text.c_str());
                ImGui::PopStyleColor();
            } else {
                ImGui::TextWrapped("%s", it->text.c_str());
            }
        }
        if (ImGui::Button("clear")) mLog.clear();
    }
    ImGui::End();
}

void Viewer::overlay()
{
    if (!mShowOverlay) return;
    ImGui::SetNextWindowPos(ImVec2(float(mWidth) - 10.0f, 10.0f), ImGuiCond_Always, ImVec2(1.0f, 0.0f));
    ImGui::SetNextWindowBgAlpha(0.45f);
    const ImGuiWindowFlags flags = ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                                   ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav |
                                   ImGuiWindowFlags_NoMove;
    ImGui::Begin("overlay", nullptr, flags);
    ImGui::Text("frame %.1f ms (%.0f fps)", mFrameMs, mFrameMs > 0 ? 1000.0 / mFrameMs : 0.0);
    const render::FrameTimes& t = mTimer->latest();
    for (const render::PassTime& p : t.passes) {
        ImGui::Text("%*s%-10s %6.2f ms %s", 2 * p.depth, "", p.name.c_str(), p.gpuMs, t.gpuTimed ? "GPU" : "CPU");
    }
    if (mShown && mShown->surface) {
        const size_t cutTriangles = mShown->cut ? mShown->cut->mesh.triangleCount() : 0;
        ImGui::Text("triangles %zu + %zu cut", mShown->surface->triangleCount(), cutTriangles);
        ImGui::Text("cut voxels %zu", mShown->cutCells);
        ImGui::Text("cut update %.1f ms", 1000.0 * mSession.lastUpdateSeconds());
    }
    ImGui::End();
}

void Viewer::renderFrame()
{
    glfwGetFramebufferSize(mWindow, &mWidth, &mHeight);
    if (mWidth <= 0 || mHeight <= 0) return;
    if (!mRenderer || mRenderer->width() != mWidth || mRenderer->height() != mHeight) {
        mRenderer = std::make_unique<render::SurfaceRenderer>(mWidth, mHeight);
        mSceneDrawn = false;
        mShown.reset(); // upload again
        mShownSurfaceSerial = 0;
        applySnapshot();
    }
    updateCamera();
    mTimer->beginFrame();
    const render::RenderStyle now = style(false);
    if (!mSceneDrawn || !sameCamera(mCamera, mDrawnCamera) || !sameStyle(now, mDrawnStyle)) {
        auto pass = mTimer->scope("scene");
        mRenderer->render(mCamera, now);
        mSceneDrawn = true;
        mDrawnCamera = mCamera;
        mDrawnStyle = now;
    }
    {
        auto pass = mTimer->scope("present");
        glBlitNamedFramebuffer(mRenderer->framebuffer(), 0, 0, 0, mWidth, mHeight, 0, 0, mWidth, mHeight,
                               GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    const bool cutting = mDrag == Drag::Cut;
    const bool streamed = mShown && mShown->haveBlade && !cutting;
    if (cutting || streamed || mHaveHover) {
        auto pass = mTimer->scope("blade");
        cutter::Pose p = streamed ? mShown->blade : cutting ? bladeAt(mLastX, mLastY, 0.0) : mHover;
        // Faded where the bone is in front of it (BladeOverlay).
        const glm::dvec3 tip = p.base + p.length * glm::normalize(p.direction);
        const double w = 0.008 * glm::length(mCamera.eye - mCamera.target);
        const glm::vec4 colour = cutting || streamed ? glm::vec4(0.30f, 0.75f, 1.0f, 0.85f) : glm::vec4(0.30f, 0.75f, 1.0f, 0.35f);
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        mBlade->draw(mCamera, mWidth, mHeight, p.base, tip, w, colour, 0.3f, mRenderer->depthTexture());
    }
    {
        auto pass = mTimer->scope("ui");
        ImGui::Render();
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    }
    mTimer->endFrame();
    mTimer->takeResults();
    render::checkGlError("mtcut-view frame");
}

int Viewer::run()
{
    while (!mQuit) {
        // A long task (open, save, a new isovalue: it has a name) changes
        // nothing on screen but its progress: drawn 4 times a second, so
        // drawing (llvmpipe: on the same cores) does not slow it down.
        const bool longTask = !mSession.task().empty() && mDrag == Drag::None;
        const bool busy = !mSession.idle() || mScriptNext < mOptions.script.size() || mDrag != Drag::None;
        if (busy && !longTask) {
            glfwPollEvents();
        } else {
            glfwWaitEventsTimeout(0.25); // idle: draw on input, else 4 times a second (llvmpipe is busy enough)
        }
        if (glfwWindowShouldClose(mWindow)) break;
        pollSession();
        applySnapshot();

        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
        glfwGetFramebufferSize(mWindow, &mWidth, &mHeight);
        handleInput();
        panel();
        overlay();
        stepScript();
        if (mQuit) {
            ImGui::EndFrame();
            break;
        }
        renderFrame();
        if (!mWindowShot.empty()) {
            try {
                saveWindow(std::exchange(mWindowShot, {}));
            } catch (const std::exception& e) {
                post(true, e.what());
            }
        }
        mContext->swapBuffers();

        const auto now = Clock::now();
        const double ms = std::chrono::duration<double, std::milli>(now - mLastFrame).count();
        mLastFrame = now;
        mFrameMs = mFrameMs == 0.0 ? ms : 0.9 * mFrameMs + 0.1 * ms;
    }
    pollSession();
    return 0;
}

} // namespace

int runViewer(const ViewerOptions& options)
{
    Viewer viewer(options);
    return viewer.run();
}

} // namespace mtcut::view
