#include "run.hpp"

#include "fem/forces.hpp"
#include "embed/mi.hpp"
#include "fem/integrate.hpp"
#include "frames.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/analyzer.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <unistd.h>

namespace cutsim::app {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Seconds spent in each stage of the run (DESIGN.md data flow); stages a scene does not use stay 0.
struct Stages {
    double contact = 0, forces = 0, integrate = 0, cut = 0, timestep = 0, render = 0, encode = 0;
    json toJson() const {
        return {{"contact", contact}, {"forces", forces}, {"integrate", integrate}, {"cut", cut},
                {"timestep", timestep}, {"render", render}, {"encode", encode}};
    }
};

// Connected components of elements joined through shared nodes.
int countPieces(const Model& m) {
    std::vector<int> parent(m.nodes());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int i) {
        while (parent[i] != i) i = parent[i] = parent[parent[i]];
        return i;
    };
    std::vector<char> used(m.nodes(), 0);
    for (int e = 0; e < m.elements(); ++e)
        for (int a = 0; a < 4; ++a) {
            used[m.tets(a, e)] = 1;
            parent[find(m.tets(a, e))] = find(m.tets(0, e));
        }
    int pieces = 0;
    for (int i = 0; i < m.nodes(); ++i) pieces += used[i] && find(i) == i;
    return pieces;
}

class Progress {
public:
    Progress(double total, bool quiet) : total_(total), quiet_(quiet), tty_(isatty(2)), start_(Clock::now()) {}
    void update(double t) {
        if (quiet_) return;
        const double frac = std::min(1.0, t / total_);
        const double el = since(start_);
        if (tty_) {
            if (since(last_) < 0.1 && frac < 1) return;
            last_ = Clock::now();
            const int w = 30, fill = static_cast<int>(frac * w);
            const double eta = frac > 0 ? el * (1 - frac) / frac : 0;
            std::fprintf(stderr, "\r[%s%s] %3.0f%%  t = %.3f / %.3f s  elapsed %.1f s  ETA %.1f s ",
                         std::string(fill, '#').c_str(), std::string(w - fill, ' ').c_str(), 100 * frac, t,
                         total_, el, eta);
            if (frac >= 1) std::fprintf(stderr, "\n");
        } else {
            const int decile = static_cast<int>(frac * 10);
            if (decile <= lastDecile_) return;
            lastDecile_ = decile;
            std::fprintf(stderr, "progress %3d%%  t = %.3f s  elapsed %.1f s\n", decile * 10, t, el);
        }
    }

private:
    double total_;
    bool quiet_, tty_;
    Clock::time_point start_, last_{};
    int lastDecile_ = -1;
};

void writeJsonFile(const fs::path& p, const json& j) {
    const fs::path tmp = p.string() + ".tmp";
    {
        std::ofstream out(tmp);
        if (!out) throw InputError(tmp.string(), 0, "cannot write");
        out << j.dump(2) << "\n";
    }
    fs::rename(tmp, p);
}

} // namespace

int runScene(const SceneDef& sc, const RunOptions& opt) {
    const auto wallStart = Clock::now();
    Stages stages;
    setThreads(opt.threads);

    // Object: read, place, build. Everything that can fail on bad input fails before any output.
    ReadOptions ro;
    ro.scale = sc.scale;
    ro.reorient = sc.reorient;
    const double d2r = M_PI / 180.0;
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(sc.rotateDeg.z() * d2r, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(sc.rotateDeg.y() * d2r, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(sc.rotateDeg.x() * d2r, Eigen::Vector3d::UnitX())).toRotationMatrix();
    Model model;
    std::unique_ptr<EmbeddedSurface> embedded;  // the fine render surface of an MI object
    json embedding;
    if (!sc.surface.empty()) {
        // Mesh intersection: the placed surface in a regular lattice (thesis ch. 6).
        const auto te = Clock::now();
        SurfaceMesh surf = readSurfaceMesh(sc.surface, sc.scale);
        surf.V = (R * surf.V).colwise() + sc.translate;
        MiOptions mo;
        mo.cells = sc.surfaceCells;
        mo.h = sc.surfaceH;
        MiResult mi = buildMi(surf, sc.material, mo);
        embedding = {{"h", mi.h}, {"interface_elements", mi.count(ElementClass::Interface)},
                     {"volume_embedded", mi.embeddedVolume()}, {"volume_surface", enclosedVolume(surf)},
                     {"closed", mi.closed}, {"seconds", since(te)}};
        model = std::move(mi.model);
        model.elementModel = sc.element;
        embedded = std::make_unique<EmbeddedSurface>(std::move(mi.surface));
    } else {
        TetMesh mesh = sc.mesh.empty() ? boxMesh(sc.scale * sc.boxSize.x(), sc.scale * sc.boxSize.y(), sc.scale * sc.boxSize.z(),
                                                 sc.boxCells.x(), sc.boxCells.y(), sc.boxCells.z())
                                       : readTetMesh(sc.mesh, ro);
        mesh.X = (R * mesh.X).colwise() + sc.translate;
        model = buildModel(mesh, sc.material, sc.element);
    }
    model.gravity = sc.gravity;
    model.massDamping = sc.damping;
    for (const auto& reg : sc.fixed) {
        const auto nodes = selectNodes(reg, model.X);
        if (nodes.empty()) throw InputError(sc.file + ": " + reg.path + ": selects no node");
        for (int n : nodes) model.fixed[n] = 1;
    }
    updateMasses(model);
    std::vector<std::vector<int>> loadNodes;
    for (const auto& f : sc.forces) {
        loadNodes.push_back(selectNodes(f.region, model.X));
        if (loadNodes.back().empty()) throw InputError(sc.file + ": " + f.region.path + ": selects no node");
    }

    // Time step: exact, certified and estimated limits, then the scene's policy (METHOD.md sec. 2-3).
    auto t0 = Clock::now();
    TimestepAnalyzer ta(model);
    const ExactResult exact = ta.exact(model);
    const double certified = ta.certifiedDt();
    const double estimate = ta.minDt().r1r;
    stages.timestep += since(t0);
    double limit = sc.dt.of == "certified" ? certified : sc.dt.of == "estimate" ? estimate : exact.dt;
    double dt = sc.dt.mode == DtPolicy::Mode::Fixed ? sc.dt.value : sc.dt.fraction * limit;
    std::string limitAction = "none";
    Eigen::VectorXd alphaElem;
    const bool explicitScheme = sc.integrator != Integrator::BackwardEuler;
    if (explicitScheme && dt > exact.dt) {
        if (sc.dt.onLimit == "refuse")
        {
            char msg[256];
            std::snprintf(msg, sizeof msg, "step %.6g s is above the exact stable limit %.6g s of %s", dt, exact.dt,
                          integratorName(sc.integrator));
            throw InputError(sc.file + ": integrator.dt: " + msg +
                             "; set integrator.dt.on_limit to \"clamp\" or \"damp\" to allow it");
        }
        if (sc.dt.onLimit == "clamp") {
            dt = 0.98 * exact.dt;  // at exactly the limit the top mode is only marginally stable
            limitAction = "clamped";
        } else {
            // Per-element damping factor alpha_e = (dt_e / dt)^2 where dt_e < dt (thesis eq. 3.16).
            alphaElem = elementAlpha(ta.estimates().r1r, dt);
            limitAction = "damped";
        }
    }
    int criticalElements = 0;
    for (Eigen::Index e = 0; e < ta.estimates().r1r.size(); ++e)
        criticalElements += ta.estimates().r1r(e) < sc.capture.criticalFactor * dt;

    // Output folder: created and probed before the first step.
    const fs::path out(opt.out);
    std::error_code ec;
    fs::create_directories(out, ec);
    {
        const fs::path probe = out / ".write_probe";
        std::ofstream p(probe);
        if (ec || !p) throw InputError(opt.out, 0, "output folder is not writable");
        p.close();
        fs::remove(probe);
    }

    const bool capturing = opt.render && sc.capture.enabled;
    std::unique_ptr<FrameSink> sink;
    if (capturing) sink = makeFrameSink(sc, opt.out, model, ta.estimates().r1r, dt, embedded.get());

    State state = makeState(model);
    Stepper stepper;
    StepOptions so{sc.integrator, dt};
    if (alphaElem.size()) so.alphaElem = &alphaElem;

    const long nSteps = static_cast<long>(std::ceil(sc.duration / dt - 1e-9));
    const double frameDt = 1.0 / sc.capture.fps;
    double nextFrame = 0;
    json energy = json::array();
    std::string status = "ok";
    int exitCode = 0;
    long invertedSteps = 0;
    int maxInverted = 0;
    Progress progress(sc.duration, opt.quiet);
    const double mass0 = model.mass.sum();
    const auto loopStart = Clock::now();

    auto recordFrame = [&]() {
        const double ek = kineticEnergy(model, state), ee = elasticEnergy(model, state), eg = gravityEnergy(model, state);
        energy.push_back({{"time", state.time}, {"kinetic", ek}, {"elastic", ee}, {"gravity", eg}, {"total", ek + ee + eg}});
        if (sink) {
            FrameInfo fi{state.time, dt, certified, exact.dt, criticalElements, 0, since(loopStart)};
            const auto tr = Clock::now();
            sink->frame(model, state, fi);
            stages.render += since(tr) - sink->lastEncodeSeconds();
            stages.encode += sink->lastEncodeSeconds();
        }
    };

    for (long k = 0; k < nSteps; ++k) {
        if (state.time >= nextFrame - 1e-12) {
            recordFrame();
            nextFrame += frameDt;
        }
        // 1. contact stage: no tools yet, so it stays 0. Applied loads go to fExt.
        auto ts = Clock::now();
        if (!sc.forces.empty()) {
            state.fExt.setZero();
            for (size_t l = 0; l < sc.forces.size(); ++l) {
                const Eigen::Vector3d f = sc.forces[l].force * sc.forces[l].profile.at(state.time) /
                                          static_cast<double>(loadNodes[l].size());
                for (int n : loadNodes[l]) state.fExt.col(n) += f;
            }
        }
        // 2-4. forces, integrate, checks (fem/integrate.hpp)
        stepper.step(model, state, so);
        const double stepTime = since(ts);
        const double fshare = stepper.lastForceSeconds();
        stages.forces += fshare;
        stages.integrate += stepTime - fshare;
        if (state.flags.inverted > 0) {
            ++invertedSteps;
            maxInverted = std::max(maxInverted, state.flags.inverted);
        }
        if (state.flags.nonFinite > 0) {
            status = "diverged: non-finite positions or velocities at step " + std::to_string(state.steps) +
                     " (t = " + std::to_string(state.time) + " s)";
            exitCode = 3;
            break;
        }
        progress.update(state.time);
    }
    if (exitCode == 0) recordFrame();
    if (sink) {
        const auto tr = Clock::now();
        sink->finish();
        stages.encode += since(tr);
    }
    progress.update(sc.duration);

    // Outputs: final mesh with per-element fields, then the report.
    if (sc.writeVtu && exitCode == 0) {
        TetMesh deformed;
        deformed.X = state.x;
        deformed.tets = model.tets;
        const auto& est = ta.estimates();
        std::vector<double> r1r(est.r1r.data(), est.r1r.data() + est.r1r.size()), crit(r1r.size());
        for (size_t e = 0; e < r1r.size(); ++e) crit[e] = r1r[e] < sc.capture.criticalFactor * dt ? 1.0 : 0.0;
        std::vector<double> disp(model.nodes());
        for (int i = 0; i < model.nodes(); ++i) disp[i] = (state.x.col(i) - model.X.col(i)).norm();
        writeVtu((out / "final.vtu").string(), deformed, {{"dt_r1r", r1r}, {"critical", crit}}, {{"displacement", disp}});
    }
    json report;
    report["scene"] = sc.file;
    report["name"] = sc.name;
    report["status"] = status;
    report["steps"] = state.steps;
    report["sim_time"] = state.time;
    report["wall_time"] = since(wallStart);
    report["threads"] = threads();
    report["integrator"] = integratorName(sc.integrator);
    report["dt"] = dt;
    report["dt_limit_action"] = limitAction;
    report["dt_initial"] = {{"exact", exact.dt}, {"certified", certified}, {"estimate", estimate}};
    report["critical_elements"] = criticalElements;
    report["mesh"] = {{"file", !sc.surface.empty() ? sc.surface : sc.mesh.empty() ? std::string("box") : sc.mesh}, {"nodes", model.nodes()}, {"elements", model.elements()},
                      {"fixed_nodes", model.nodes() - model.freeDofs() / 3}};
    if (!embedding.is_null()) report["embedding"] = embedding;
    report["cuts"] = json::array();
    report["pieces"] = countPieces(model);
    report["mass"] = {{"initial", mass0}, {"final", model.mass.sum()}};
    report["energy"] = energy;
    report["inverted"] = {{"steps", invertedSteps}, {"max_elements", maxInverted}};
    report["stages"] = stages.toJson();
    report["frames"] = sink ? sink->frames() : 0;
    report["video"] = sink ? sink->videoPath() : "";
    const double simWall = since(loopStart);
    report["steps_per_second"] = simWall > 0 ? state.steps / simWall : 0;
    report["real_time_factor"] = simWall > 0 ? state.time / simWall : 0;
    writeJsonFile(out / "report.json", report);
    if (!opt.quiet)
        std::fprintf(stderr, "%s: %s, %ld steps of %.3g s (exact limit %.3g s), %.2f s wall, %d frames -> %s\n",
                     sc.name.c_str(), status.c_str(), state.steps, dt, exact.dt, since(wallStart),
                     sink ? sink->frames() : 0, opt.out.c_str());
    return exitCode;
}

} // namespace cutsim::app
