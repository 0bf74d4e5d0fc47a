#include "run.hpp"

#include "exit_code.hpp"

#include "fem/forces.hpp"
#include "frames.hpp"
#include "output_folder.hpp"
#include "mesh/io.hpp"
#include "sim/simulation.hpp"
#include "util/atomic_file.hpp"
#include "util/stopwatch.hpp"
#include "util/json_text.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <unistd.h>

namespace cutsim::app {

namespace fs = std::filesystem;

void printWarnings(const Simulation& sim) {
    for (const WarningStat& w : sim.record().warnings.stat)
        if (w.count > 0) std::fprintf(stderr, "warning: %s\n", w.first.c_str());
}
using nlohmann::json;

namespace {

// Progress on stderr: a bar on a terminal, a line per tenth otherwise; steps per second and the
// time left from the rate so far.
class Progress {
public:
    Progress(double total, bool quiet) : total_(total), quiet_(quiet), tty_(isatty(2)) {}
    void update(double t, long steps, bool last = false) {
        if (quiet_) return;
        const double frac = std::min(1.0, t / total_), el = clock_.seconds();
        const double rate = el > 0 ? steps / el : 0, eta = frac > 0 ? el * (1 - frac) / frac : 0;
        if (tty_) {
            if (sinceDraw_.seconds() < 0.1 && !last) return;
            sinceDraw_.restart();
            const int w = 30, fill = static_cast<int>(frac * w);
            std::fprintf(stderr, "\r[%s%s] %3.0f%%  t = %.3f / %.3f s  %.3g steps/s  elapsed %.1f s  ETA %.1f s ",
                         std::string(fill, '#').c_str(), std::string(w - fill, ' ').c_str(), 100 * frac, t, total_,
                         rate, el, eta);
            if (last) std::fprintf(stderr, "\n");
        } else {
            const int decile = static_cast<int>(frac * 10);
            if (decile <= lastDecile_ || last) return;
            lastDecile_ = decile;
            std::fprintf(stderr, "progress %3d%%  t = %.3f s  %.3g steps/s  elapsed %.1f s  ETA %.1f s\n", decile * 10,
                         t, rate, el, eta);
        }
    }

private:
    double total_;
    bool quiet_, tty_;
    Stopwatch clock_, sinceDraw_;
    int lastDecile_ = -1;
};

// The deformed mesh with its fields for ParaView: per element the R1R step estimate [s], whether
// it is critical, von Mises stress [Pa]; per node the displacement vector [m].
void writeStateVtu(const Simulation& sim, const std::string& path) {
    const Model& model = sim.model();
    TetMesh deformed;
    deformed.X = sim.state().x;
    deformed.tets = model.tets;
    const auto& est = sim.analyzer().estimates();
    std::vector<double> r1r(est.r1r.data(), est.r1r.data() + est.r1r.size()), crit(r1r.size());
    for (size_t e = 0; e < r1r.size(); ++e)
        crit[e] = r1r[e] < sim.scene().capture.criticalFactor * sim.dt() ? 1.0 : 0.0;
    const Eigen::VectorXd vm = vonMisesStress(model, sim.state());
    const Eigen::Matrix3Xd u = sim.state().x - model.X;
    std::vector<Field> cells = {
        {"dt_r1r", r1r}, {"critical", crit}, {"von_mises", std::vector<double>(vm.data(), vm.data() + vm.size())}};
    std::vector<Field> points = {{"displacement", std::vector<double>(u.data(), u.data() + u.size()), 3}};
    // object.reorder: the mesh file's numbering beside the run's (docs/scene-format.md)
    if (sim.reordered()) {
        std::vector<double> node(static_cast<size_t>(model.nodes())), element(r1r.size());
        for (size_t n = 0; n < node.size(); ++n) node[n] = sim.inputNode(static_cast<int>(n));
        for (size_t e = 0; e < element.size(); ++e) element[e] = sim.inputElement(static_cast<int>(e));
        cells.push_back({"input_element", element});
        points.push_back({"input_node", node});
    }
    writeVtu(path, deformed, cells, points);
}

// The drawn surface now (boundary, or after cuts the cut surface) as OBJ, cut faces in group "cut".
void writeSurfaceObj(const Simulation& sim, const std::string& path) {
    const EmbeddedSurface s = sim.surface() ? *sim.surface() : boundarySurface(sim.model().tets, sim.model().X);
    Eigen::Matrix3Xd p;
    embeddedPositions(s, sim.model().tets, sim.state().x, p);
    std::string out = "# cutsim: surface at t = " + std::to_string(sim.state().time) + " s [m]\n";
    char line[96];
    for (int v = 0; v < p.cols(); ++v) {
        std::snprintf(line, sizeof line, "v %.9g %.9g %.9g\n", p(0, v), p(1, v), p(2, v));
        out += line;
    }
    for (bool cut : {false, true}) {
        out += cut ? "g cut\n" : "g outside\n";
        for (int t = 0; t < s.faces(); ++t) {
            if (s.cutFace(t) != cut) continue;
            std::snprintf(line, sizeof line, "f %d %d %d\n", s.triangles(0, t) + 1, s.triangles(1, t) + 1,
                          s.triangles(2, t) + 1);
            out += line;
        }
    }
    writeFileAtomic(path, out);
}

// The frame PNGs in `dir`, as an interrupted run keeps them.
int keptPngs(const fs::path& dir) {
    std::error_code ec;
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir, ec))
        n += e.path().extension() == ".png" && e.path().filename().string().rfind("frame_", 0) == 0;
    return n;
}

}  // namespace

int runScene(const SceneDef& sc, const RunOptions& opt) {
    Stopwatch wall;
    const bool capturing = opt.render && sc.capture.enabled;
    Simulation::Options so;
    so.threads = opt.threads;
    so.renderSurface = capturing || sc.capture.cutObj;
    // Outputs go to a staging folder that replaces --out at the end (output_folder.hpp).
    StagedFolder folder(opt.out);
    const fs::path out = folder.staging();
    // the renderer is made on the drawing thread, and ffmpeg started, while the simulation is built
    std::unique_ptr<FrameSink> sink = capturing ? makeFrameSink(sc, out.string(), opt.pipelined) : nullptr;
    Simulation sim(sc, so);
    printWarnings(sim);
    // from here on a signal stops the run between steps and leaves its outputs whole
    const InterruptGuard interrupt;

    if (sink) try {
            sink->begin(sim.model(), sim.analyzer().estimates().r1r, sim.dt(), sim.surface());
        } catch (const std::exception& e) {
            std::fprintf(stderr, "frames: no rendering (%s); running without frames\n", e.what());
            sink.reset();
        }
    const double setupSeconds = wall.seconds();
    double surfaceSeconds = 0;  // the drawn surface split after cuts (Simulation::surface())

    // A frame of the state now; its render and encode time go to the run's stages.
    // With capture.vtu, a .vtu per captured frame and a .pvd series naming them with their times.
    std::string pvd;
    int vtuFrames = 0;
    const bool vtu = sc.capture.enabled && sc.capture.vtu;
    if (vtu) fs::create_directories(out / "vtu");
    int drawnVersion = sim.topologyVersion();
    auto frame = [&] {
        if (vtu) {
            char name[40];
            std::snprintf(name, sizeof name, "vtu/frame_%06d.vtu", vtuFrames++);
            writeStateVtu(sim, (out / name).string());
            char entry[128];
            std::snprintf(entry, sizeof entry, "    <DataSet timestep=\"%.9g\" part=\"0\" file=\"%s\"/>\n",
                          sim.state().time, name);
            pvd += entry;
        }
        if (!sink) return;
        if (sim.topologyVersion() != drawnVersion) {
            // the cut surface and the new per-element limits, once per frame however many steps cut
            const Stopwatch ts;
            drawnVersion = sim.topologyVersion();
            sink->topologyChanged(sim.model(), *sim.surface(), sim.analyzer().estimates().r1r, sim.dt());
            surfaceSeconds += ts.seconds();
        }
        // no wall-clock rates in captured frames: they would make every run's frames differ (report.json has them)
        sink->frame(sim.model(), sim.state(), frameInfoOf(sim, std::numeric_limits<double>::quiet_NaN()));
    };
    // The report, built by Simulation::report from the run's record, the capture's time in its
    // stages (render: the surface split after cuts, the snapshots, drawing and reading back;
    // encode: the hand-off to the writers and their drain) and its parts in "capture".
    auto makeReport = [&](int frames, const std::string& video) {
        const CaptureTimes ct = sink ? sink->times() : CaptureTimes{};
        if (sink) {
            sim.record().stages[Stage::Render] = surfaceSeconds + ct.render();
            sim.record().stages[Stage::Encode] = ct.encode();
        }
        json report = sim.report({{"wall_time", wall.seconds()}, {"frames", frames}, {"video", video}});
        report["exit_code"] = static_cast<int>(exitCodeOf(sim.status()));
        if (!sink) return report;
        report["capture"] = ct.toJson();
        report["capture"]["surface_seconds"] = surfaceSeconds;
        report["capture"]["setup_seconds"] = setupSeconds;
        report["renderer"] = sink->renderer();
        return report;
    };

    Progress progress(sc.duration, opt.quiet);
    const double frameDt = 1.0 / sc.capture.fps;
    double nextFrame = 0;
    while (sim.status() == RunStatus::Running && !sim.finished() && !interrupt.signal()) {
        if (sim.state().time >= nextFrame - 1e-12) {
            frame();
            nextFrame += frameDt;
        }
        sim.step();
        progress.update(sim.state().time, sim.state().steps);
    }
    // A signal at any time before the outputs move into place, also after the last step, makes the
    // run "interrupted": the frames so far and a report that says so, under FOLDER.incomplete.
    auto interrupted = [&](int sig) {
        json report = makeReport(sink ? sink->frames() : 0, "");
        sink.reset();  // taken frames are drawn and written; an unfinished video is removed, not left as .tmp
        // the frames kept: the video's when it was finished, else the PNGs (png_every thins them)
        if (fs::exists(out / "video.mp4"))
            report["video"] = (folder.incomplete() / "video.mp4").string();
        else
            report["frames"] = keptPngs(out / "frames");
        report["status"] = "interrupted";
        report["exit_code"] = 128 + sig;
        report["message"] = std::string("stopped by ") + (sig == SIGINT ? "SIGINT" : "SIGTERM") +
                            " at t = " + std::to_string(sim.state().time) + " s of " + std::to_string(sc.duration) +
                            " s";
        writeFileAtomic((out / "report.json").string(), jsonText(report));
        folder.keepIncomplete();
        std::fprintf(stderr, "\n%s: interrupted at t = %.4g of %.4g s; partial outputs in %s (%s left as it was)\n",
                     sc.name.c_str(), sim.state().time, sc.duration, folder.incomplete().c_str(), opt.out.c_str());
        return 128 + sig;
    };
    if (const int sig = interrupt.signal()) return interrupted(sig);
    sim.finish();
    sim.compareCutMethods();
    const bool ok = sim.status() == RunStatus::Finished;
    if (ok) frame();
    if (sink) sink->finish();
    progress.update(sim.state().time, sim.state().steps, true);

    // Outputs: the final mesh with per-element fields, then the report; then the folder moves into place.
    if (sc.writeVtu && ok) writeStateVtu(sim, (out / "final.vtu").string());
    if (vtu)
        writeFileAtomic((out / "series.pvd").string(),
                        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n" +
                            pvd + "  </Collection>\n</VTKFile>\n");
    if (sc.capture.cutObj && ok) writeSurfaceObj(sim, (out / "cut_surface.obj").string());
    const bool video = sink && !sink->videoPath().empty();
    const json report = makeReport(sink ? sink->frames() : 0, video ? (fs::path(opt.out) / "video.mp4").string() : "");
    if (const int sig = interrupt.signal()) return interrupted(sig);
    writeFileAtomic((out / "report.json").string(), jsonText(report));
    if (const int sig = interrupt.signal()) return interrupted(sig);  // the report is rewritten as interrupted
    folder.commit();
    if (!opt.quiet || !ok)  // a failure is always said
        std::fprintf(stderr, "%s: %s, %ld steps of %.3g s (exact limit %.3g s), %.2f s wall, %d frames -> %s\n",
                     sc.name.c_str(), report["status"].get<std::string>().c_str(), sim.state().steps, sim.dt(),
                     sim.initialLimits().exact, wall.seconds(), sink ? sink->frames() : 0, opt.out.c_str());
    // A signal as the outputs moved into place: they are whole, but the caller asked to stop (a
    // script's loop must not go on), so the exit says so.
    if (const int sig = interrupt.signal()) {
        std::fprintf(stderr, "%s: %s after the outputs were in place; %s is complete\n", sc.name.c_str(),
                     sig == SIGINT ? "SIGINT" : "SIGTERM", opt.out.c_str());
        return 128 + sig;
    }
    return static_cast<int>(exitCodeOf(sim.status()));
}

}  // namespace cutsim::app
