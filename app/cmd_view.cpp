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

int runView(const ViewArgs& a) {
    SceneDef sc = loadScene(a.scene, a.sets);
    const auto presses = parseScript(a.presses, "--press", 1);
    std::vector<std::pair<int, int>> pressKeys;
    for (const auto& [f, k] : presses) pressKeys.emplace_back(f, keyCode(k[0]));
    auto moves = [](const std::vector<std::string>& items, const char* flag) {
        std::vector<std::tuple<int, double, double>> out;
        for (const auto& [f, d] : parseScript(items, flag, 2)) {
            char* e1 = nullptr;
            char* e2 = nullptr;
            const double dx = std::strtod(d[0].c_str(), &e1), dy = std::strtod(d[1].c_str(), &e2);
            if (*e1 || *e2 || d[0].empty() || d[1].empty())
                throw InputError(std::string(flag) + ": expected FRAME,DX,DY in pixels, got \"" + d[0] + "," + d[1] +
                                 "\"");
            out.emplace_back(f, dx, dy);
        }
        return out;
    };
    const auto dragMoves = moves(a.drags, "--drag"), orbitMoves = moves(a.orbits, "--orbit");
    Simulation::Options simOpt;
    simOpt.threads = a.threads;
    simOpt.renderSurface = true;
    auto sim = std::make_unique<Simulation>(sc, simOpt);
    printWarnings(*sim);
    if (a.toolAt.size() == 3) {
        if (!sim->contact()) throw InputError(sc.file + ": --tool-at: the scene has no tools");
        sim->holdTool(0, Eigen::Vector3d(a.toolAt[0], a.toolAt[1], a.toolAt[2]));
    }
    const int width = a.width > 0 ? a.width : sc.capture.width, height = a.height > 0 ? a.height : sc.capture.height;
    const bool headless = a.frames > 0;
    render::Window win("cutsim view: " + sc.name, width, height, !headless);

    render::RenderOptions ro;
    ro.width = win.framebufferWidth();
    ro.height = win.framebufferHeight();
    ro.xray = sc.capture.xray;
    ro.floor = sc.capture.floor;
    ro.samples = sc.capture.samples;
    ro.wireframe = true;  // the snapshot has edges only when wireframe is on
    ro.hud = false;       // the panel shows the HUD values
    render::Renderer renderer(ro, render::RenderTarget::CurrentContext);

    SceneSnapshot scene(sc, sim->model(), sim->analyzer().estimates().r1r, sim->dt(), sim->surface());
    int drawnVersion = sim->topologyVersion();
    Orbit orbit(scene.defaultCamera(sim->model(), 0));
    const double frameDt = 1.0 / sc.capture.fps;

    bool paused = false, stepOnce = false, shot = false, panel = true;
    bool follow = a.sceneCamera;  // the scene's camera keyframes, until the mouse moves the camera
    // The orbit takes over from wherever the followed camera is now.
    auto takeCamera = [&] {
        if (follow) orbit = Orbit(scene.defaultCamera(sim->model(), sim->state().time));
        follow = false;
    };
    std::string message;
    // Rates over the last half second of wall time.
    double rateSteps = 0, rateSim = 0, rateWall = 0, stepsPerSecond = 0, realTime = 0;
    auto last = WallClock::now();
    const auto start = WallClock::now();
    float fraction = static_cast<float>(sc.dt.fraction);
    int integrator = static_cast<int>(std::find(std::begin(kIntegrators), std::end(kIntegrators), sc.integrator) -
                                      std::begin(kIntegrators));
    int colormap = static_cast<int>(std::find_if(std::begin(kColormaps), std::end(kColormaps),
                                                 [&](const char* c) { return scene.colormap() == c; }) -
                                    std::begin(kColormaps));
    double maxToolForce = 0;
    std::vector<float> forceHistory;
    auto statusLine = [&]() -> std::string {
        switch (sim->status()) {
        case RunStatus::Running: return "running";
        case RunStatus::Finished: return "end of scene (r resets)";
        default: return sim->message() + " (r resets)";
        }
    };
    // The scene from the start: the cuts undone, tools back on their keyframes (a new Simulation).
    auto reset = [&] {
        sim = std::make_unique<Simulation>(sc, simOpt);
        scene.topologyChanged(sim->model(),
                              sim->surface() ? *sim->surface() : boundarySurface(sim->model().tets, sim->model().X),
                              sim->analyzer().estimates().r1r, sim->dt());
        drawnVersion = sim->topologyVersion();
        maxToolForce = 0;
        paused = false;
    };
    // New integrator or step fraction: the policy chooses again; a refused step keeps the old one.
    auto applyPolicy = [&](Integrator integ, double frac) {
        StepPolicy p = sc.dt;
        p.fixed = false;
        p.fraction = frac;
        message = sim->setPolicy(integ, p);
        if (!message.empty()) {
            fraction = static_cast<float>(sc.dt.fraction);
            integrator = static_cast<int>(std::find(std::begin(kIntegrators), std::end(kIntegrators), sc.integrator) -
                                          std::begin(kIntegrators));
            return;
        }
        sc.integrator = integ;  // a reset keeps the choice
        sc.dt = p;
        scene.setStep(sim->dt(), sc.capture.criticalFactor);
    };
    // Running, the cut is made due now and the next step makes it, as a scripted cut of this time
    // (a recorded take replays it exactly); paused, it is made at once. The message follows with
    // the topology change.
    auto cutNext = [&] {
        if (paused)
            sim->cutNextScripted();
        else
            sim->dueNextScripted();
    };
    // The take's camera: a key whenever the orbit moves (record-camera).
    std::vector<CameraKey> cameraKeys;
    auto cameraKey = [&] {
        const Camera c = follow ? scene.defaultCamera(sim->model(), sim->state().time) : orbit.camera();
        CameraKey k;
        k.time = sim->state().time;
        k.eye = c.eye;
        k.target = c.target;
        k.up = c.up;
        k.fov = c.fovY;
        return k;
    };
    CameraKey lastCamera = cameraKey();
    // A held tool takes its new pose a tick after now (Simulation::holdTool): drags add up and
    // the tool is drawn where it was left, also while paused.
    auto justAfterNow = [&] { return std::nextafter(sim->state().time, std::numeric_limits<double>::infinity()); };
    // A shift-drag of the first tool by (dx, dy) pixels, or a shift-scroll of `wheel` clicks.
    auto dragTool = [&](double dx, double dy, double wheel) {
        const Eigen::Vector3d p = toolPose(sim->contact()->tools().front(), justAfterNow()).position;
        if (dx != 0 || dy != 0) sim->holdTool(0, orbit.dragged(p, dx, dy, renderer.height()));
        if (wheel != 0) sim->holdTool(0, p - 0.05 * orbit.distance * wheel * orbit.dir);
    };

    for (int frame = 0; !win.shouldClose(); ++frame) {
        win.beginFrame();
        ImGuiIO& io = ImGui::GetIO();
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
            if (ImGui::IsMouseDown(ImGuiMouseButton_Right))
                orbit.pan(io.MouseDelta.x, io.MouseDelta.y, renderer.height());
            if (io.MouseWheel != 0) orbit.zoom(io.MouseWheel);
        }

        // Simulate: up to the next capture frame's time when headless (the same steps as
        // `cutsim run`), else the wall time since the last frame, stopping early to keep the
        // window responsive.
        if (sim->contact() && !sim->contact()->tools().empty())
            for (const auto& [f, dx, dy] : dragMoves)
                if (f == frame) dragTool(dx, dy, 0);
        for (const auto& [f, dx, dy] : orbitMoves)
            if (f == frame) {
                takeCamera();
                orbit.rotate(dx, dy);
            }
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
                std::snprintf(msg, sizeof msg, "%s: %d elements split, dt %.3e s (%s)",
                              c["key"].get<std::string>().c_str(), c["split"].get<int>(), sim->dt(),
                              c["limit_action"].get<std::string>().c_str());
                message = msg;
            }
        }
        const Eigen::Vector3d toolForce = sim->record().tool.force;
        maxToolForce = std::max(maxToolForce, sim->record().tool.maxForce);
        rateSteps += static_cast<double>(sim->state().steps - steps0);
        rateSim += sim->state().time - t0;
        rateWall += wallFrame;
        if (rateWall >= 0.5) {
            stepsPerSecond = rateSteps / rateWall;
            realTime = rateSim / rateWall;
            rateSteps = rateSim = rateWall = 0;
        }

        // Panel: HUD values and controls.
        const Model& model = sim->model();
        // h hides it; narrow widgets keep it to a corner of a 960x540 window.
        if (panel) {
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
                ImGui::PlotLines("##force", forceHistory.data(), static_cast<int>(forceHistory.size()), 0, nullptr,
                                 0.0f, FLT_MAX, ImVec2(0, 40));
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

        // Scene, then the panel over it.
        renderer.resize(win.framebufferWidth(), win.framebufferHeight());
        const FrameInfo fi = frameInfoOf(*sim, secondsSince(start));
        RenderSnapshot& snap = scene.update(model, sim->state(), fi);
        snap.camera = follow ? scene.defaultCamera(model, sim->state().time) : orbit.camera();
        if (a.recordCamera) {
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

        const bool lastFrame = headless && frame + 1 >= a.frames;
        if (shot || (lastFrame && !a.screenshot.empty())) {
            const std::string path = a.screenshot.empty() ? nextShotName() : a.screenshot;
            render::writePng(path, win.readBackBuffer());
            std::fprintf(stderr, "screenshot: %s\n", path.c_str());
            shot = false;
        }
        win.swap();
        if (lastFrame) break;
    }
    if (!a.record.empty()) {
        writeFileAtomic(a.record, jsonText(takeScene(*sim, a.record, a.recordCamera ? &cameraKeys : nullptr)));
        std::fprintf(stderr, "recorded: %s (replay: cutsim run %s --out DIR)\n", a.record.c_str(), a.record.c_str());
    }
    if (!a.report.empty()) {
        const nlohmann::json report = sim->report({{"wall_time", secondsSince(start)}, {"frames", 0}, {"video", ""}});
        writeFileAtomic(a.report, jsonText(report));
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
