// `cutsim view SCENE`: the scene running live in a window, with an orbit camera and a panel.
// Same scene loading and step as `cutsim run` (run.hpp), same frame content (frames.hpp).
#include "commands.hpp"
#include "frames.hpp"
#include "run.hpp"

#include "fem/forces.hpp"
#include "mesh/mesh.hpp"

#ifdef CUTSIM_HAVE_RENDER
#include "png_writer.hpp"
#include "renderer.hpp"
#include "window.hpp"

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
#include <memory>
#include <string>

namespace cutsim::app {
namespace {

struct ViewArgs {
    std::string scene;
    std::vector<std::string> sets;
    int width = 0, height = 0;  // 0: the scene's capture size
    int frames = 0;             // > 0: draw this many frames, save the screenshot, exit
    std::string screenshot;     // where p (and the end of --frames) writes
    int threads = 0;
    std::vector<double> toolAt; // x y z: the first tool held there from the start, as a mouse drag leaves it [m]
};

#ifdef CUTSIM_HAVE_RENDER
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// A camera orbiting a target: drag rotates about the up axis and the screen's horizontal axis,
// scroll changes the distance, right-drag moves the target in the view plane.
struct Orbit {
    Eigen::Vector3d target, dir, up; // dir: unit vector from target to eye
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
    void rotate(double dx, double dy) { // pixels
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

constexpr const char* kColormaps[] = {"timestep", "displacement", "stress", "none"};
constexpr Integrator kIntegrators[] = {Integrator::SymplecticEuler, Integrator::CentralDifference, Integrator::Newmark,
                                       Integrator::BackwardEuler};

int runView(const ViewArgs& a) {
    SceneDef sc = loadScene(a.scene, a.sets);
    setThreads(a.threads);
    Simulation sim = prepareScene(sc);
    const double exact0 = sim.exact.dt;
    const int width = a.width > 0 ? a.width : sc.capture.width, height = a.height > 0 ? a.height : sc.capture.height;
    const bool headless = a.frames > 0;
    render::Window win("cutsim view: " + sc.name, width, height, !headless);

    render::RenderOptions ro;
    ro.width = win.framebufferWidth();
    ro.height = win.framebufferHeight();
    ro.xray = sc.capture.xray;
    ro.wireframe = true; // the snapshot has edges only when wireframe is on
    ro.hud = false;      // the panel shows the HUD values
    render::Renderer renderer(ro, render::RenderTarget::CurrentContext);

    SceneSnapshot scene(sc, sim.model, sim.ta.estimates().r1r, sim.dt, sim.surface.get());
    State state = makeState(sim.model);
    Stepper stepper;
    StepOptions so = sc.stepOptions(sim.dt, sim.alphaElem);
    Orbit orbit(scene.defaultCamera(sim.model, 0));
    const double frameDt = 1.0 / sc.capture.fps;

    bool paused = false, stepOnce = false, shot = false;
    std::string status = "running", message;
    int exitCode = 0;
    // Rates over the last half second of wall time.
    double rateSteps = 0, rateSim = 0, rateWall = 0, stepsPerSecond = 0, realTime = 0;
    auto last = Clock::now();
    const auto start = Clock::now();
    float fraction = static_cast<float>(sc.dt.fraction);
    int integrator = static_cast<int>(std::find(std::begin(kIntegrators), std::end(kIntegrators), sc.integrator) -
                                      std::begin(kIntegrators));
    int colormap = static_cast<int>(std::find_if(std::begin(kColormaps), std::end(kColormaps),
                                                 [&](const char* c) { return scene.colormap() == c; }) -
                                    std::begin(kColormaps));

    // Scripted cuts (cutting.cuts): applied at their times, or the next one at once with x. Blade
    // tools cut as they move, on their keyframes or dragged, as in `cutsim run`.
    double bladeMargin = 0;
    const std::vector<int> bladeTools = bladeToolsOf(sc, bladeMargin);
    std::unique_ptr<CutEngine> cutter;
    std::unique_ptr<BladeStrokes> blades;
    std::vector<BladeEdge> lastEdge;  // each blade's edge after the previous step (a drag moves it between steps)
    size_t nextCut = 0;
    int cutsDone = 0, bladeCuts = 0, lastCutId = -1;
    auto makeCutter = [&] {
        cutter.reset();
        blades.reset();
        lastEdge.clear();
        nextCut = 0;
        cutsDone = bladeCuts = 0;
        lastCutId = -1;
        if (sc.cutting.cuts.empty() && bladeTools.empty()) return;
        cutter = std::make_unique<CutEngine>(cutOptions(sc.cutting));
        cutter->prepare(sim.model);
        if (!bladeTools.empty()) blades = std::make_unique<BladeStrokes>(bladeMargin);
    };
    makeCutter();
    // Tools: Bullet contact as in `cutsim run`; shift-drag moves the first tool in the view plane,
    // shift-scroll along the view direction. A dragged tool holds its pose (its keyframes are dropped).
    ContactSetup contact = makeContact(sc, sim);
    Eigen::Vector3d toolForce = Eigen::Vector3d::Zero();
    double maxToolForce = 0;
    std::vector<float> forceHistory;
    auto holdTool = [&](const Eigen::Vector3d& position) {
        if (!contact.world || contact.world->tools().empty()) return;
        ToolDef& t = contact.world->tools().front();
        ToolKey k;
        k.pose = toolPose(t, state.time);
        k.opening = toolOpening(t, state.time);
        k.pose.position = position;
        t.keys.assign(1, k);
    };
    if (a.toolAt.size() == 3) {
        if (!contact.world) throw InputError(sc.file + ": --tool-at: the scene has no tools");
        holdTool(Eigen::Vector3d(a.toolAt[0], a.toolAt[1], a.toolAt[2]));
    }
    auto stepChanged = [&] {
        so = sc.stepOptions(sim.dt, sim.alphaElem);
        stepper.reset();
    };
    // After a cut changed the model: the step, the contact points and the drawn surface follow.
    auto afterCut = [&](const std::string& what, const CutResult& r, bool update) {
        try {
            if (update) updateAfterCut(sc, sim, r);
            char msg[160];
            std::snprintf(msg, sizeof msg, "%s: %d elements split, dt exact %.3e s (%.3f of uncut)", what.c_str(),
                          r.split, sim.exact.dt, sim.exact.dt / exact0);
            message = msg;
        } catch (const InputError& e) {
            message = e.what();
            status = "stopped: the step is above the limit after the cut (r resets)";
        }
        stepChanged();
        EmbeddedSurface cutSurface = sim.surface ? cutter->surface(sim.model, *sim.surface) : cutter->surface(sim.model);
        if (contact.world) {
            ContactPoints pts = contactPoints(cutSurface, sim.model.tets, sim.model.X, contact.spacing);
            scaleByMass(pts, sim.model.invMass, contact.massRef);
            contact.world->setSurface(std::move(pts));
        }
        scene.topologyChanged(sim.model, std::move(cutSurface), sim.ta.estimates().r1r, sim.dt);
    };
    auto cutNext = [&] {
        if (!cutter || nextCut >= sc.cutting.cuts.size()) return;
        const CutDef& cd = sc.cutting.cuts[nextCut++];
        CutResult r;
        try {
            r = cutScene(sc, sim, state, *cutter, cutSurfaceOf(cd));
        } catch (const InputError& e) {
            message = e.what();
            status = "stopped: the step is above the limit after the cut (r resets)";
        }
        ++cutsDone;
        afterCut(cd.path, r, false);
    };
    // Blade sweeps of the step [t, t + dt], as in `cutsim run`; the edge moves from where the
    // previous step left it, so a dragged blade cuts along the path it was dragged.
    auto applyBlades = [&] {
        if (!blades || !contact.world) return;
        blades->refit(sim.model, state);
        const double t0 = state.time, t1 = state.time + sim.dt;
        lastEdge.resize(bladeTools.size());
        for (size_t b = 0; b < bladeTools.size(); ++b) {
            const int i = bladeTools[b];
            const ToolDef& tool = contact.world->tools()[static_cast<size_t>(i)];
            BladeEdge from = lastEdge[b], to;
            if (from.a == from.b) bladeEdge(tool, t0, from.a, from.b);  // first step
            bladeEdge(tool, t1, to.a, to.b);
            lastEdge[b] = to;
            const CutResult r = blades->sweep(*cutter, sim.model, state, contact.world.get(), i, tool, from, to, t0, t1);
            if (!r.changed()) continue;
            if (r.cut != lastCutId) ++bladeCuts, lastCutId = r.cut;
            afterCut(tool.name.empty() ? "blade" : tool.name, r, true);
            if (status != "running") return;
        }
    };
    auto reset = [&] {
        if (cutsDone > 0 || bladeCuts > 0) {  // the cuts changed the model: build it again
            sim = prepareScene(sc);
            stepChanged();
            scene.topologyChanged(sim.model, sim.surface ? *sim.surface : boundarySurface(sim.model.tets, sim.model.X),
                                  sim.ta.estimates().r1r, sim.dt);
            makeCutter();
        }
        contact = makeContact(sc, sim);  // tools back on their keyframes
        lastEdge.clear();
        if (blades) blades->endStroke(*cutter);
        state = makeState(sim.model);
        stepper.reset();
        status = "running";
        paused = false;
    };
    // New integrator or step fraction: the policy chooses again; a refused step keeps the old one.
    auto applyPolicy = [&](Integrator integ, double frac) {
        SceneDef next = sc;
        next.integrator = integ;
        next.dt.mode = DtPolicy::Mode::Fraction;
        next.dt.fraction = frac;
        try {
            if (const char* why = precisionConflict(integ, sc.precision))
                throw InputError(sc.file + ": integrator.precision: " + why);
            chooseStep(next, sim); // changes sim only when it accepts
        } catch (const InputError& e) {
            message = e.what();
            fraction = static_cast<float>(sc.dt.fraction);
            integrator = static_cast<int>(std::find(std::begin(kIntegrators), std::end(kIntegrators), sc.integrator) -
                                          std::begin(kIntegrators));
            return;
        }
        message.clear();
        sc.integrator = next.integrator;
        sc.dt = next.dt;
        so = sc.stepOptions(sim.dt, sim.alphaElem);
        stepper.reset();
        scene.setStep(sim.dt, sc.capture.criticalFactor);
    };

    for (int frame = 0; !win.shouldClose(); ++frame) {
        win.beginFrame();
        ImGuiIO& io = ImGui::GetIO();
        for (int key : win.takeKeys()) {
            switch (key) {
            case GLFW_KEY_SPACE: paused = !paused; break;
            case GLFW_KEY_S: stepOnce = true; paused = true; break;
            case GLFW_KEY_R: reset(); break;
            case GLFW_KEY_C: renderer.options().xray = !renderer.options().xray; break;
            case GLFW_KEY_W: scene.setWireframe(!scene.wireframe()); break;
            case GLFW_KEY_P: shot = true; break;
            case GLFW_KEY_X: cutNext(); break;
            case GLFW_KEY_Q:
            case GLFW_KEY_ESCAPE: win.close(); break;
            default: break;
            }
        }
        const bool toolDrag = io.KeyShift && contact.world && !contact.world->tools().empty();
        if (!io.WantCaptureMouse && toolDrag) {
            const Eigen::Vector3d p = toolPose(contact.world->tools().front(), state.time).position;
            if (ImGui::IsMouseDown(ImGuiMouseButton_Left) && (io.MouseDelta.x != 0 || io.MouseDelta.y != 0))
                holdTool(orbit.dragged(p, io.MouseDelta.x, io.MouseDelta.y, renderer.height()));
            if (io.MouseWheel != 0) holdTool(p - 0.05 * orbit.distance * io.MouseWheel * orbit.dir);
        } else if (!io.WantCaptureMouse) {
            if (ImGui::IsMouseDown(ImGuiMouseButton_Left)) orbit.rotate(io.MouseDelta.x, io.MouseDelta.y);
            if (ImGui::IsMouseDown(ImGuiMouseButton_Right)) orbit.pan(io.MouseDelta.x, io.MouseDelta.y, renderer.height());
            if (io.MouseWheel != 0) orbit.zoom(io.MouseWheel);
        }

        // Simulate: a capture frame's worth of time when headless (reproducible), else the wall
        // time since the last frame, stopping early to keep the window responsive.
        const double wallFrame = std::min(since(last), 0.1);
        last = Clock::now();
        const auto simStart = Clock::now();
        long steps = 0;
        const double t0 = state.time;
        if (status == "running" && (!paused || stepOnce)) {
            const double target = stepOnce ? state.time : state.time + (headless ? frameDt : wallFrame);
            do {
                if (cutter && nextCut < sc.cutting.cuts.size() && sc.cutting.cuts[nextCut].time <= state.time + 1e-12) {
                    cutNext();
                    if (status != "running") break;
                }
                if (blades) {
                    applyBlades();
                    if (status != "running") break;
                }
                applyLoads(sc, sim, state);
                if (contact.world) {
                    contact.world->addForces(state.x, state.v, state.time, sim.dt, state.fExt);
                    toolForce.setZero();
                    for (const auto& f : contact.world->last().reaction) toolForce += f;
                    maxToolForce = std::max(maxToolForce, toolForce.norm());
                }
                stepper.step(sim.model, state, so);
                ++steps;
                if (state.flags.nonFinite > 0) {
                    status = "diverged at t = " + std::to_string(state.time) + " s (r resets)";
                    exitCode = 3;
                    break;
                }
            } while (state.time < target - 1e-12 && (headless || since(simStart) < 0.05));
            stepOnce = false;
            if (state.time >= sc.duration - 1e-12 && status == "running") {
                status = "end of scene (r resets)";
            }
        }
        rateSteps += static_cast<double>(steps);
        rateSim += state.time - t0;
        rateWall += wallFrame;
        if (rateWall >= 0.5) {
            stepsPerSecond = rateSteps / rateWall;
            realTime = rateSim / rateWall;
            rateSteps = rateSim = rateWall = 0;
        }

        // Panel: HUD values and controls.
        ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
        ImGui::SetNextWindowBgAlpha(0.75f);
        ImGui::Begin("cutsim", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
        ImGui::Text("%s: %d tets, %d nodes", sc.name.c_str(), sim.model.elements(), sim.model.nodes());
        ImGui::Text("%s%s", status.c_str(), paused && status == "running" ? " (paused)" : "");
        ImGui::Separator();
        ImGui::Text("t          %.4f s", state.time);
        ImGui::Text("dt used    %.3e s", sim.dt);
        ImGui::Text("dt cert    %.3e s", sim.certified);
        ImGui::Text("dt exact   %.3e s", sim.exact.dt);
        // Until the first half second is over, the rates so far.
        const bool early = stepsPerSecond == 0 && rateWall > 0;
        ImGui::Text("steps/s    %.0f", early ? rateSteps / rateWall : stepsPerSecond);
        ImGui::Text("real time  %.3f x", early ? rateSim / rateWall : realTime);
        ImGui::Text("critical   %d elements", sim.criticalElements);
        if (contact.world) {
            forceHistory.push_back(static_cast<float>(toolForce.norm()));
            if (forceHistory.size() > 200) forceHistory.erase(forceHistory.begin());
            ImGui::Text("tool F     %.3f N (max %.3f N)", toolForce.norm(), maxToolForce);
            ImGui::PlotLines("##force", forceHistory.data(), static_cast<int>(forceHistory.size()), 0, nullptr, 0.0f,
                             FLT_MAX, ImVec2(0, 40));
        }
        if (!sc.cutting.cuts.empty()) {
            ImGui::Text("cuts       %d of %d", cutsDone, static_cast<int>(sc.cutting.cuts.size()));
            ImGui::SameLine();
            if (ImGui::Button("cut next (x)")) cutNext();
        }
        if (!bladeTools.empty()) ImGui::Text("blade cuts %d (strokes that split elements)", bladeCuts);
        ImGui::Separator();
        const char* integNames[] = {integratorName(kIntegrators[0]), integratorName(kIntegrators[1]),
                                    integratorName(kIntegrators[2]), integratorName(kIntegrators[3])};
        const bool integChanged = ImGui::Combo("integrator", &integrator, integNames, 4);
        ImGui::SliderFloat("dt fraction", &fraction, 0.05f, 1.2f, "%.2f");
        if (integChanged || ImGui::IsItemDeactivatedAfterEdit()) // the slider applies on release
            applyPolicy(kIntegrators[integrator], fraction);
        ImGui::SameLine();
        ImGui::TextDisabled("of %s", sc.dt.of.c_str());
        if (ImGui::Combo("colour map", &colormap, kColormaps, 4)) scene.setColormap(kColormaps[colormap]);
        if (!message.empty()) ImGui::TextWrapped("%s", message.c_str());
        if (ImGui::CollapsingHeader("keys and mouse")) {
            ImGui::TextUnformatted("space pause/resume   s single step   r reset\n"
                                   "c critical elements  w wireframe     p screenshot\n"
                                   "x next scripted cut\n"
                                   "q, Esc quit\n"
                                   "drag rotate   scroll zoom   right-drag pan\n"
                                   "shift-drag move tool   shift-scroll tool depth");
        }
        ImGui::End();

        // Scene, then the panel over it.
        renderer.resize(win.framebufferWidth(), win.framebufferHeight());
        FrameInfo fi;
        fi.time = state.time;
        fi.dt = sim.dt;
        fi.dtCertified = sim.certified;
        fi.dtExact = sim.exact.dt;
        fi.criticalElements = sim.criticalElements;
        fi.cuts = cutsDone + bladeCuts;
        fi.wall = since(start);
        RenderSnapshot& snap = scene.update(sim.model, state, fi);
        snap.camera = orbit.camera();
        snap.tools.clear();
        if (contact.world)
            for (const auto& t : contact.world->tools()) appendToolShapes(t, state.time, snap.tools);
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
    if (headless) {
        std::printf("view: t = %.4f s, %ld steps, %d cuts", state.time, state.steps, cutsDone + bladeCuts);
        if (contact.world) std::printf(", tool force %.4g N (max %.4g N)", toolForce.norm(), maxToolForce);
        std::printf("\n");
    }
    return exitCode;
}
#endif

} // namespace

void addViewCommand(CLI::App& app) {
    auto args = std::make_shared<ViewArgs>();
    CLI::App* cmd = app.add_subcommand(
        "view", "Run a scene live in a window: drag rotates, scroll zooms, right-drag pans; keys: space pause/resume, "
                "s single step, r reset, c critical elements, w wireframe, p screenshot, x next scripted cut, q or Esc quit. "
                "Exit codes: 2 bad scene, 3 diverged (--frames), 4 no display");
    cmd->add_option("scene", args->scene, "Scene file (JSON, see docs/scene-format.md)")->required();
    cmd->add_option("--set", args->sets, "Override a scene value: key.path=value (JSON value)");
    cmd->add_option("--width", args->width, "Window width [px] (default: the scene's capture width)")
        ->check(CLI::Range(64, 8192));
    cmd->add_option("--height", args->height, "Window height [px] (default: the scene's capture height)")
        ->check(CLI::Range(64, 8192));
    cmd->add_option("--frames", args->frames,
                    "Draw N frames of 1/fps simulated seconds each, write --screenshot, exit (for scripts and tests)")
        ->check(CLI::Range(1, 1000000));
    cmd->add_option("--screenshot", args->screenshot, "PNG that p (and the end of --frames) writes (default view_NNN.png)");
    cmd->add_option("--threads", args->threads, "Worker threads (0 = all cores)")->check(CLI::Range(0, 1024));
    cmd->add_option("--tool-at", args->toolAt, "x y z: hold the scene's first tool there from the start, as shift-drag leaves it [m]")
        ->expected(3);
    cmd->callback([args] {
#ifdef CUTSIM_HAVE_RENDER
        try {
            setExitCode(runView(*args));
        } catch (const render::NoDisplayError& e) {
            std::fprintf(stderr, "error: %s\n", e.what());
            setExitCode(4);
        } catch (const std::exception& e) {
            std::fprintf(stderr, "error: %s\n", e.what());
            setExitCode(2);
        }
#else
        std::fprintf(stderr, "error: this cutsim was built without the renderer (-DCUTSIM_RENDER=OFF)\n");
        setExitCode(2);
#endif
    });
}

} // namespace cutsim::app
