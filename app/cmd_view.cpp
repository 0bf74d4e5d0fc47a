// `cutsim view SCENE`: the scene running live in a window, with an orbit camera and a panel.
// Same scene loading and step as `cutsim run` (run.hpp), same frame content (frames.hpp).
#include "commands.hpp"
#include "exit_code.hpp"
#include "run.hpp"
#include "util/stopwatch.hpp"
#include "frames.hpp"
#include "fem/forces.hpp"
#include "mesh/mesh.hpp"
#include "sim/simulation.hpp"
#include "sim/take.hpp"
#include "util/atomic_file.hpp"

#ifdef CUTSIM_HAVE_RENDER
#include "png_writer.hpp"
#include "renderer.hpp"
#include "window.hpp"
#include "util/json_text.hpp"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#endif

#include <CLI/CLI.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace cutsim::app {
namespace {

struct ViewArgs {
    std::string scene;
    std::vector<std::string> sets;
    int width = 0, height = 0;  // 0: the scene's capture size
    int frames = 0;             // > 0: draw this many frames, save the screenshot, exit
    std::string screenshot;     // where p (and the end of --frames) writes
    int threads = 0;
    std::vector<double> toolAt;        // x y z: the first tool held there from the start, as a mouse drag leaves it [m]
    std::string report;                // report.json of the session, written at exit
    std::string record;                // the take written as a scene at exit
    bool recordCamera = false;         // the take's camera moves as camera keyframes
    bool sceneCamera = false;          // follow the scene's camera keyframes until a drag takes over
    std::vector<std::string> drags;    // "F,DX,DY": a shift-drag of the first tool at frame F [px]
    std::vector<std::string> presses;  // "F,KEY": a key pressed at frame F
    std::vector<std::string> orbits;   // "F,DX,DY": a drag of the camera at frame F [px]
};

#ifdef CUTSIM_HAVE_RENDER

// A camera orbiting a target: drag rotates about the up axis and the screen's horizontal axis,
// scroll changes the distance, right-drag moves the target in the view plane.
struct Orbit {
    Eigen::Vector3d target, dir, up;  // dir: unit vector from target to eye
    double distance = 1, fovY = 40;

    explicit Orbit(const Camera& c)
        : target(c.target), dir((c.eye - c.target).normalized()), up(c.up.normalized()),
          distance((c.eye - c.target).norm()), fovY(c.fovY) {}
    Camera camera() const {
        Camera c;
        c.eye = target + distance * dir;
        c.target = target;
        c.up = up;
        c.fovY = fovY;
        return c;
    }
    void rotate(double dx, double dy) {  // pixels
        const Eigen::Vector3d right = up.cross(dir).normalized();
        Eigen::Vector3d d = Eigen::AngleAxisd(-0.008 * dx, up) * dir;
        const Eigen::Vector3d tilted = Eigen::AngleAxisd(-0.008 * dy, right) * d;
        // Stay off the poles, where the up vector and the view direction would align.
        if (std::abs(tilted.normalized().dot(up)) < 0.995) d = tilted;
        dir = d.normalized();
    }
    void zoom(double clicks) { distance *= std::pow(0.88, clicks); }
    // p moved with the mouse by (dx, dy) pixels in the plane facing the camera at p's depth, so it
    // stays under the cursor.
    Eigen::Vector3d dragged(const Eigen::Vector3d& p, double dx, double dy, int heightPx) const {
        const Eigen::Vector3d right = up.cross(dir).normalized(), screenUp = dir.cross(right);
        const Eigen::Vector3d eye = target + distance * dir;
        const double depth = std::max(1e-6, (eye - p).dot(dir));
        const double perPx = 2 * depth * std::tan(0.5 * fovY * M_PI / 180.0) / std::max(1, heightPx);
        return p + perPx * (dx * right - dy * screenUp);
    }
    void pan(double dx, double dy, int heightPx) {
        const Eigen::Vector3d right = up.cross(dir).normalized(), screenUp = dir.cross(right);
        const double perPx = 2 * distance * std::tan(0.5 * fovY * M_PI / 180.0) / std::max(1, heightPx);
        target += perPx * (-dx * right + dy * screenUp);
    }
};

// A free file name view_NNN.png in the current folder.
std::string nextShotName() {
    for (int i = 1;; ++i) {
        char name[32];
        std::snprintf(name, sizeof name, "view_%03d.png", i);
        if (!std::filesystem::exists(name)) return name;
    }
}

// Scripted input for --drag and --press: "F,A,B" -> frame F and the numbers after it.
std::vector<std::pair<int, std::vector<std::string>>> parseScript(const std::vector<std::string>& items,
                                                                  const char* flag, size_t fields) {
    std::vector<std::pair<int, std::vector<std::string>>> out;
    for (const auto& item : items) {
        std::vector<std::string> parts;
        std::string cur;
        for (char c : item + ",") {
            if (c == ',') {
                parts.push_back(cur);
                cur.clear();
            } else {
                cur += c;
            }
        }
        char* end = nullptr;
        const long f = parts.empty() ? -1 : std::strtol(parts[0].c_str(), &end, 10);
        if (parts.size() != fields + 1 || f < 0 || *end || parts[0].empty())
            throw InputError(std::string(flag) + ": expected FRAME," + (fields == 2 ? "DX,DY" : "KEY") + ", got \"" +
                             item + "\"");
        out.emplace_back(static_cast<int>(f), std::vector<std::string>(parts.begin() + 1, parts.end()));
    }
    return out;
}

// A key name of --press as GLFW's key code: a letter, or space/escape.
int keyCode(const std::string& k) {
    if (k.size() == 1 && k[0] >= 'a' && k[0] <= 'z') return GLFW_KEY_A + (k[0] - 'a');
    if (k == "space") return GLFW_KEY_SPACE;
    if (k == "escape") return GLFW_KEY_ESCAPE;
    throw InputError("--press: unknown key \"" + k + "\" (a letter, space or escape)");
}

constexpr const char* kColormaps[] = {"timestep", "displacement", "stress", "none"};
constexpr Integrator kIntegrators[] = {Integrator::SymplecticEuler, Integrator::CentralDifference, Integrator::Newmark,
                                       Integrator::BackwardEuler};

// The panel's combo entries: an integrator's and a colour map's index.
int integratorIndex(Integrator integ) {
    return static_cast<int>(std::find(std::begin(kIntegrators), std::end(kIntegrators), integ) -
                            std::begin(kIntegrators));
}
int colormapIndex(const std::string& name) {
    return static_cast<int>(
        std::find_if(std::begin(kColormaps), std::end(kColormaps), [&](const char* c) { return name == c; }) -
        std::begin(kColormaps));
}

// --press: "F,KEY" -> frame F and GLFW's key code.
std::vector<std::pair<int, int>> parseKeys(const std::vector<std::string>& items) {
    std::vector<std::pair<int, int>> out;
    for (const auto& [f, k] : parseScript(items, "--press", 1)) out.emplace_back(f, keyCode(k[0]));
    return out;
}

// --drag and --orbit: "F,DX,DY" -> frame F and a move of (DX, DY) pixels.
std::vector<std::tuple<int, double, double>> parseMoves(const std::vector<std::string>& items, const char* flag) {
    std::vector<std::tuple<int, double, double>> out;
    for (const auto& [f, d] : parseScript(items, flag, 2)) {
        char* e1 = nullptr;
        char* e2 = nullptr;
        const double dx = std::strtod(d[0].c_str(), &e1), dy = std::strtod(d[1].c_str(), &e2);
        if (*e1 || *e2 || d[0].empty() || d[1].empty())
            throw InputError(std::string(flag) + ": expected FRAME,DX,DY in pixels, got \"" + d[0] + "," + d[1] + "\"");
        out.emplace_back(f, dx, dy);
    }
    return out;
}

// The view's Simulation: its warnings printed, the first tool held at --tool-at.
std::unique_ptr<Simulation> startSimulation(const SceneDef& sc, const Simulation::Options& opt, const ViewArgs& a) {
    auto sim = std::make_unique<Simulation>(sc, opt);
    printWarnings(*sim);
    if (a.toolAt.size() == 3) {
        if (!sim->contact()) throw InputError(sc.file + ": --tool-at: the scene has no tools");
        sim->holdTool(0, Eigen::Vector3d(a.toolAt[0], a.toolAt[1], a.toolAt[2]));
    }
    return sim;
}

// The renderer draws the scene's capture settings into the window's framebuffer.
render::RenderOptions viewRenderOptions(const SceneDef& sc, const render::Window& win) {
    render::RenderOptions ro;
    ro.width = win.framebufferWidth();
    ro.height = win.framebufferHeight();
    ro.xray = sc.capture.xray;
    ro.floor = sc.capture.floor;
    ro.samples = sc.capture.samples;
    ro.wireframe = true;  // the snapshot has edges only when wireframe is on
    ro.hud = false;       // the panel shows the HUD values
    return ro;
}

// One view session: what the frame loop, the input handlers and the panel share.
struct ViewSession {
    const ViewArgs& args;
    SceneDef sc;
    std::vector<std::pair<int, int>> pressKeys;                          // --press
    std::vector<std::tuple<int, double, double>> dragMoves, orbitMoves;  // --drag, --orbit
    Simulation::Options simOpt;
    std::unique_ptr<Simulation> sim;
    bool headless;  // --frames: a fixed number of frames, then exit
    render::Window win;
    render::Renderer renderer;
    SceneSnapshot scene;
    int drawnVersion;  // the topology the snapshot shows
    Orbit orbit;
    double frameDt;  // one capture frame [s]
    bool paused = false, stepOnce = false, shot = false, panel = true;
    bool follow;  // the scene's camera keyframes, until the mouse moves the camera
    std::string message;
    // Rates over the last half second of wall time.
    double rateSteps = 0, rateSim = 0, rateWall = 0, stepsPerSecond = 0, realTime = 0;
    WallClock::time_point last, start;
    float fraction;
    int integrator, colormap;
    double maxToolForce = 0;
    std::vector<float> forceHistory;
    std::vector<CameraKey> cameraKeys;  // the take's camera: a key whenever the orbit moves (record-camera)
    CameraKey lastCamera;

    explicit ViewSession(const ViewArgs& a);
    int run();
    void handleKeys(int frame);
    void handleMouse();
    void applyScript(int frame);
    void simulate(int frame);
    void drawPanel(const Eigen::Vector3d& toolForce);
    void drawScene();
    bool endFrame(int frame);
    int finish();
    void takeCamera();
    std::string statusLine() const;
    void reset();
    void applyPolicy(Integrator integ, double frac);
    void cutNext();
    CameraKey cameraKey();
    double justAfterNow() const;
    void dragTool(double dx, double dy, double wheel);
};

ViewSession::ViewSession(const ViewArgs& a)
    : args(a), sc(loadScene(a.scene, a.sets)), pressKeys(parseKeys(a.presses)),
      dragMoves(parseMoves(a.drags, "--drag")),
      orbitMoves(parseMoves(a.orbits, "--orbit")), simOpt{.threads = a.threads, .renderSurface = true},
      sim(startSimulation(sc, simOpt, a)), headless(a.frames > 0),
      win("cutsim view: " + sc.name, a.width > 0 ? a.width : sc.capture.width,
          a.height > 0 ? a.height : sc.capture.height, !headless),
      renderer(viewRenderOptions(sc, win), render::RenderTarget::CurrentContext),
      scene(sc, sim->model(), sim->analyzer().estimates().r1r, sim->dt(), sim->surface()),
      drawnVersion(sim->topologyVersion()), orbit(scene.defaultCamera(sim->model(), 0)), frameDt(1.0 / sc.capture.fps),
      follow(a.sceneCamera), last(WallClock::now()), start(WallClock::now()),
      fraction(static_cast<float>(sc.dt.fraction)), integrator(integratorIndex(sc.integrator)),
      colormap(colormapIndex(scene.colormap())), lastCamera(cameraKey()) {}

// The frame loop: input, simulation, panel, drawing, until the window closes or --frames ends.
int ViewSession::run() {
    for (int frame = 0; !win.shouldClose(); ++frame) {
        win.beginFrame();
        handleKeys(frame);
        handleMouse();
        applyScript(frame);
        simulate(frame);
        drawPanel(sim->record().tool.force);
        drawScene();
        if (endFrame(frame)) break;
    }
    return finish();
}

// Keys typed and those --press scripts for this frame.
void ViewSession::handleKeys(int frame) {
    std::vector<int> keys = win.takeKeys();
    for (const auto& [f, k] : pressKeys)
        if (f == frame) keys.push_back(k);
    for (int key : keys) {
        switch (key) {
        case GLFW_KEY_SPACE: paused = !paused; break;
        case GLFW_KEY_S:
            stepOnce = true;
            paused = true;
            break;
        case GLFW_KEY_R:
            reset();
            cameraKeys.clear();  // the take starts again
            lastCamera = cameraKey();
            break;
        case GLFW_KEY_C: renderer.options().xray = !renderer.options().xray; break;
        case GLFW_KEY_W: scene.setWireframe(!scene.wireframe()); break;
        case GLFW_KEY_P: shot = true; break;
        case GLFW_KEY_H: panel = !panel; break;
        case GLFW_KEY_K:
            if (follow)
                takeCamera();
            else
                follow = true;
            break;
        case GLFW_KEY_X: cutNext(); break;
        case GLFW_KEY_Q:
        case GLFW_KEY_ESCAPE: win.close(); break;
        default: break;
        }
    }
}

// The mouse, unless over the panel: with shift it moves the first tool, else the camera.
void ViewSession::handleMouse() {
    ImGuiIO& io = ImGui::GetIO();
    const bool toolDrag = io.KeyShift && sim->contact() && !sim->contact()->tools().empty();
    if (!io.WantCaptureMouse && toolDrag) {
        const bool down = ImGui::IsMouseDown(ImGuiMouseButton_Left);
        dragTool(down ? io.MouseDelta.x : 0.0, down ? io.MouseDelta.y : 0.0, io.MouseWheel);
    } else if (!io.WantCaptureMouse) {
        const bool moved = io.MouseDelta.x != 0 || io.MouseDelta.y != 0;
        if ((moved && (ImGui::IsMouseDown(ImGuiMouseButton_Left) || ImGui::IsMouseDown(ImGuiMouseButton_Right))) ||
            io.MouseWheel != 0)
            takeCamera();
        if (ImGui::IsMouseDown(ImGuiMouseButton_Left)) orbit.rotate(io.MouseDelta.x, io.MouseDelta.y);
        if (ImGui::IsMouseDown(ImGuiMouseButton_Right)) orbit.pan(io.MouseDelta.x, io.MouseDelta.y, renderer.height());
        if (io.MouseWheel != 0) orbit.zoom(io.MouseWheel);
    }
}

// The drags of --drag and --orbit scripted for this frame.
void ViewSession::applyScript(int frame) {
    if (sim->contact() && !sim->contact()->tools().empty())
        for (const auto& [f, dx, dy] : dragMoves)
            if (f == frame) dragTool(dx, dy, 0);
    for (const auto& [f, dx, dy] : orbitMoves)
        if (f == frame) {
            takeCamera();
            orbit.rotate(dx, dy);
        }
}

// Simulate: up to the next capture frame's time when headless (the same steps as `cutsim run`),
// else the wall time since the last frame, stopping early to keep the window responsive. Then the
// snapshot follows a cut, and the rates are updated.
void ViewSession::simulate(int frame) {
    const double wallFrame = std::min(secondsSince(last), 0.1);
    last = WallClock::now();
    const auto simStart = WallClock::now();
    const long steps0 = sim->state().steps;
    const double t0 = sim->state().time;
    if (sim->status() == RunStatus::Running && (!paused || stepOnce)) {
        if (headless) {
            sim->advance((frame + 1) * frameDt);
        } else if (stepOnce) {
            sim->step();
        } else {
            const double target = sim->state().time + wallFrame;
            while (sim->status() == RunStatus::Running && sim->state().time < target - 1e-12 &&
                   secondsSince(simStart) < 0.05)
                sim->step();
        }
        stepOnce = false;
        if (sim->status() == RunStatus::Running && sim->finished()) sim->finish();
    }
    if (sim->topologyVersion() != drawnVersion) {
        drawnVersion = sim->topologyVersion();
        scene.topologyChanged(sim->model(), *sim->surface(), sim->analyzer().estimates().r1r, sim->dt());
        if (!sim->record().cuts.empty()) {  // the last cut, scripted, x or blade
            const auto& c = sim->record().cuts.back();
            char msg[200];
            std::snprintf(msg, sizeof msg, "%s: %d elements split, dt %.3e s (%s)", c["key"].get<std::string>().c_str(),
                          c["split"].get<int>(), sim->dt(), c["limit_action"].get<std::string>().c_str());
            message = msg;
        }
    }
    maxToolForce = std::max(maxToolForce, sim->record().tool.maxForce);
    rateSteps += static_cast<double>(sim->state().steps - steps0);
    rateSim += sim->state().time - t0;
    rateWall += wallFrame;
    if (rateWall >= 0.5) {
        stepsPerSecond = rateSteps / rateWall;
        realTime = rateSim / rateWall;
        rateSteps = rateSim = rateWall = 0;
    }
}

// Panel: HUD values and controls. h hides it; narrow widgets keep it to a corner of a 960x540
// window.
void ViewSession::drawPanel(const Eigen::Vector3d& toolForce) {
    if (!panel) return;
    const Model& model = sim->model();
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowBgAlpha(0.75f);
    ImGui::Begin("cutsim", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::PushItemWidth(110);
    ImGui::Text("%s: %d tets, %d nodes", sc.name.c_str(), model.elements(), model.nodes());
    ImGui::Text("%s%s", statusLine().c_str(), paused && sim->status() == RunStatus::Running ? " (paused)" : "");
    ImGui::Separator();
    ImGui::Text("t          %.4f s", sim->state().time);
    ImGui::Text("dt used    %.3e s", sim->dt());
    ImGui::Text("dt cert    %.3e s", sim->limits().certified);
    ImGui::Text("dt exact   %.3e s", sim->limits().exact);
    // Until the first half second is over, the rates so far.
    const bool early = stepsPerSecond == 0 && rateWall > 0;
    ImGui::Text("steps/s    %.0f", early ? rateSteps / rateWall : stepsPerSecond);
    ImGui::Text("real time  %.3f x", early ? rateSim / rateWall : realTime);
    ImGui::Text("critical   %d elements", sim->criticalElements());
    if (sim->contact()) {
        forceHistory.push_back(static_cast<float>(toolForce.norm()));
        if (forceHistory.size() > 200) forceHistory.erase(forceHistory.begin());
        ImGui::Text("tool F     %.3f N (max %.3f N)", toolForce.norm(), maxToolForce);
        ImGui::PlotLines("##force", forceHistory.data(), static_cast<int>(forceHistory.size()), 0, nullptr, 0.0f,
                         FLT_MAX, ImVec2(0, 40));
    }
    if (!sc.cutting.cuts.empty()) {
        ImGui::Text("cuts       %d of %d", static_cast<int>(sim->scriptedCutsDone()),
                    static_cast<int>(sc.cutting.cuts.size()));
        ImGui::SameLine();
        if (ImGui::Button("cut next (x)")) cutNext();
    }
    if (sim->record().bladeCutSteps > 0 || sim->cutter())
        ImGui::Text("cuts made  %d (a blade stroke counts once)", sim->record().cutsMade);
    ImGui::Separator();
    const char* integNames[] = {integratorName(kIntegrators[0]), integratorName(kIntegrators[1]),
                                integratorName(kIntegrators[2]), integratorName(kIntegrators[3])};
    const bool integChanged = ImGui::Combo("integrator", &integrator, integNames, 4);
    ImGui::SliderFloat("dt fraction", &fraction, 0.05f, 1.2f, "%.2f");
    if (integChanged || ImGui::IsItemDeactivatedAfterEdit())  // the slider applies on release
        applyPolicy(kIntegrators[integrator], fraction);
    ImGui::SameLine();
    ImGui::TextDisabled("of %s", limitOfName(sc.dt.of));
    if (ImGui::Combo("colour map", &colormap, kColormaps, 4)) scene.setColormap(kColormaps[colormap]);
    if (!message.empty()) ImGui::TextWrapped("%s", message.c_str());
    if (ImGui::CollapsingHeader("keys and mouse")) {
        ImGui::TextUnformatted("space pause/resume   s single step   r reset\n"
                               "c critical elements  w wireframe     p screenshot\n"
                               "x next scripted cut  h hide panel     k scene camera\n"
                               "q, Esc quit\n"
                               "drag rotate   scroll zoom   right-drag pan\n"
                               "shift-drag move tool   shift-scroll tool depth");
    }
    ImGui::PopItemWidth();
    ImGui::End();
}

// Scene, then the panel over it; the camera's move is a key of the take.
void ViewSession::drawScene() {
    const Model& model = sim->model();
    renderer.resize(win.framebufferWidth(), win.framebufferHeight());
    const FrameInfo fi = frameInfoOf(*sim, secondsSince(start));
    RenderSnapshot& snap = scene.update(model, sim->state(), fi);
    snap.camera = follow ? scene.defaultCamera(model, sim->state().time) : orbit.camera();
    if (args.recordCamera) {
        const CameraKey now = cameraKey();
        addCameraKey(cameraKeys, lastCamera, now);
        lastCamera = now;
    }
    snap.tools.clear();
    if (sim->contact())
        for (const auto& t : sim->contact()->tools()) appendToolShapes(t, justAfterNow(), snap.tools);
    renderer.draw(snap);
    renderer.present(0);
    win.endFrame();
}

// The screenshot p asked for (or the last --frames frame's), then the swap; true after the last
// --frames frame.
bool ViewSession::endFrame(int frame) {
    const bool lastFrame = headless && frame + 1 >= args.frames;
    if (shot || (lastFrame && !args.screenshot.empty())) {
        const std::string path = args.screenshot.empty() ? nextShotName() : args.screenshot;
        render::writePng(path, win.readBackBuffer());
        std::fprintf(stderr, "screenshot: %s\n", path.c_str());
        shot = false;
    }
    win.swap();
    return lastFrame;
}

// At exit: the take (--record), the report (--report), a summary line when headless.
int ViewSession::finish() {
    if (!args.record.empty()) {
        writeFileAtomic(args.record, jsonText(takeScene(*sim, args.record, args.recordCamera ? &cameraKeys : nullptr)));
        std::fprintf(stderr, "recorded: %s (replay: cutsim run %s --out DIR)\n", args.record.c_str(),
                     args.record.c_str());
    }
    if (!args.report.empty()) {
        const nlohmann::json report = sim->report({{"wall_time", secondsSince(start)}, {"frames", 0}, {"video", ""}});
        writeFileAtomic(args.report, jsonText(report));
    }
    if (headless) {
        std::printf("view: t = %.4f s, %ld steps, %d cuts", sim->state().time, sim->state().steps,
                    sim->record().cutsMade);
        if (sim->contact())
            std::printf(", tool force %.4g N (max %.4g N)", sim->record().tool.force.norm(), maxToolForce);
        std::printf("\n");
        if (sim->status() == RunStatus::Diverged || sim->status() == RunStatus::Refused)
            std::fprintf(stderr, "%s\n", sim->message().c_str());
    }
    return static_cast<int>(exitCodeOf(sim->status()));
}

// The orbit takes over from wherever the followed camera is now.
void ViewSession::takeCamera() {
    if (follow) orbit = Orbit(scene.defaultCamera(sim->model(), sim->state().time));
    follow = false;
}

// The run's state as the panel's first line says it.
std::string ViewSession::statusLine() const {
    switch (sim->status()) {
    case RunStatus::Running: return "running";
    case RunStatus::Finished: return "end of scene (r resets)";
    default: return sim->message() + " (r resets)";
    }
}

// The scene from the start: the cuts undone, tools back on their keyframes (a new Simulation).
void ViewSession::reset() {
    sim = std::make_unique<Simulation>(sc, simOpt);
    scene.topologyChanged(sim->model(),
                          sim->surface() ? *sim->surface() : boundarySurface(sim->model().tets, sim->model().X),
                          sim->analyzer().estimates().r1r, sim->dt());
    drawnVersion = sim->topologyVersion();
    maxToolForce = 0;
    paused = false;
}

// New integrator or step fraction: the policy chooses again; a refused step keeps the old one.
void ViewSession::applyPolicy(Integrator integ, double frac) {
    StepPolicy p = sc.dt;
    p.fixed = false;
    p.fraction = frac;
    message = sim->setPolicy(integ, p);
    if (!message.empty()) {
        fraction = static_cast<float>(sc.dt.fraction);
        integrator = integratorIndex(sc.integrator);
        return;
    }
    sc.integrator = integ;  // a reset keeps the choice
    sc.dt = p;
    scene.setStep(sim->dt(), sc.capture.criticalFactor);
}

// Running, the cut is made due now and the next step makes it, as a scripted cut of this time
// (a recorded take replays it exactly); paused, it is made at once. The message follows with
// the topology change.
void ViewSession::cutNext() {
    if (paused)
        sim->cutNextScripted();
    else
        sim->dueNextScripted();
}

// The camera now as a key of the take.
CameraKey ViewSession::cameraKey() {
    const Camera c = follow ? scene.defaultCamera(sim->model(), sim->state().time) : orbit.camera();
    CameraKey k;
    k.time = sim->state().time;
    k.eye = c.eye;
    k.target = c.target;
    k.up = c.up;
    k.fov = c.fovY;
    return k;
}

// A held tool takes its new pose a tick after now (Simulation::holdTool): drags add up and the
// tool is drawn where it was left, also while paused.
double ViewSession::justAfterNow() const {
    return std::nextafter(sim->state().time, std::numeric_limits<double>::infinity());
}

// A shift-drag of the first tool by (dx, dy) pixels, or a shift-scroll of `wheel` clicks.
void ViewSession::dragTool(double dx, double dy, double wheel) {
    const Eigen::Vector3d p = toolPose(sim->contact()->tools().front(), justAfterNow()).position;
    if (dx != 0 || dy != 0) sim->holdTool(0, orbit.dragged(p, dx, dy, renderer.height()));
    if (wheel != 0) sim->holdTool(0, p - 0.05 * orbit.distance * wheel * orbit.dir);
}

// The scene live in a window until it closes (or --frames frames are drawn).
int runView(const ViewArgs& a) {
    ViewSession session(a);
    return session.run();
}
#endif

}  // namespace

void addViewCommand(CLI::App& app) {
    auto args = std::make_shared<ViewArgs>();
    CLI::App* cmd = app.add_subcommand(
        "view", "Run a scene live in a window: drag rotates, scroll zooms, right-drag pans; keys: space pause/resume, "
                "s single step, r reset, c critical elements, w wireframe, p screenshot, x next scripted cut, h hide "
                "the panel, "
                "k follow the scene's camera keyframes (on/off), q or Esc quit. "
                "Exit codes: 2 bad scene, 3 diverged, 4 refused step, 5 no display");
    cmd->add_option("scene", args->scene, "Scene file (JSON, see docs/scene-format.md)")->required();
    cmd->add_option("--set", args->sets, "Override a scene value: key.path=value (JSON value)");
    cmd->add_option("--width", args->width, "Window width [px] (default: the scene's capture width)")
        ->check(CLI::Range(64, 8192));
    cmd->add_option("--height", args->height, "Window height [px] (default: the scene's capture height)")
        ->check(CLI::Range(64, 8192));
    cmd->add_option("--frames", args->frames,
                    "Draw N frames of 1/fps simulated seconds each, write --screenshot, exit (for scripts and tests)")
        ->check(CLI::Range(1, 1000000));
    cmd->add_option("--screenshot", args->screenshot,
                    "PNG that p (and the end of --frames) writes (default view_NNN.png)");
    cmd->add_option("--threads", args->threads,
                    "Worker threads (0: chosen by measuring one thread against all cores as the run goes)")
        ->check(CLI::Range(0, 1024));
    cmd->add_option("--report", args->report, "Write the session's report.json (as `cutsim run` writes) here at exit");
    cmd->add_option("--tool-at", args->toolAt,
                    "x y z: hold the scene's first tool there from the start, as shift-drag leaves it [m]")
        ->expected(3);
    cmd->add_option("--record", args->record,
                    "Write the take as a scene here at exit: the tools' paths as keyframes, the cuts made with x as "
                    "scripted cuts, so `cutsim run` replays it offscreen");
    cmd->add_flag("--record-camera", args->recordCamera, "With --record: the camera's moves as camera keyframes");
    cmd->add_flag("--scene-camera", args->sceneCamera,
                  "Follow the scene's camera keyframes (as `cutsim run` frames them) until a drag or scroll takes "
                  "over; k toggles");
    cmd->add_option("--drag", args->drags,
                    "F,DX,DY: at frame F, shift-drag the first tool by DX, DY pixels (scripted input, repeatable)");
    cmd->add_option("--orbit", args->orbits,
                    "F,DX,DY: at frame F, drag the camera by DX, DY pixels (scripted input, repeatable)");
    cmd->add_option("--press", args->presses, "F,KEY: at frame F, press KEY (a letter, space or escape; repeatable)");
    cmd->callback([args] {
#ifdef CUTSIM_HAVE_RENDER
        runCommand([&] {
            try {
                return runView(*args);
            } catch (const render::NoDisplayError& e) {
                std::fprintf(stderr, "error: %s\n", e.what());
                return static_cast<int>(ExitCode::NoDisplay);
            }
        });
#else
        needsRenderer();
#endif
    });
}

}  // namespace cutsim::app
