#include "run.hpp"

#include "cut/baselines.hpp"
#include "cut/xfem.hpp"
#include "contact/contact.hpp"
#include "fem/forces.hpp"
#include "embed/mi.hpp"
#include "fem/integrate.hpp"
#include "frames.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/analyzer.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numeric>
#include <unistd.h>

namespace cutsim::app {

namespace fs = std::filesystem;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr double kKeepStepWarnFraction = 0.01;  // keep_step adding more of the mass than this is reported

// Seconds spent in each stage of the run (DESIGN.md data flow); stages a scene does not use stay 0.
struct Stages {
    double contact = 0, forces = 0, integrate = 0, cut = 0, timestep = 0, render = 0, encode = 0;
    json toJson() const {
        return {{"contact", contact}, {"forces", forces}, {"integrate", integrate}, {"cut", cut},
                {"timestep", timestep}, {"render", render}, {"encode", encode}};
    }
};

// Connected components of elements joined through shared nodes: their volumes, largest first [m^3].
std::vector<double> pieceVolumes(const Model& m) {
    std::vector<int> parent(m.nodes());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int i) {
        while (parent[i] != i) i = parent[i] = parent[parent[i]];
        return i;
    };
    for (int e = 0; e < m.elements(); ++e)
        for (int a = 1; a < 4; ++a) parent[find(m.tets(a, e))] = find(m.tets(0, e));
    std::vector<double> byRoot(m.nodes(), -1.0);
    for (int e = 0; e < m.elements(); ++e) {
        double& v = byRoot[find(m.tets(0, e))];
        v = std::max(v, 0.0) + m.volume(e) * m.fraction(e);
    }
    std::vector<double> volumes;
    for (double v : byRoot)
        if (v >= 0) volumes.push_back(v);
    std::sort(volumes.begin(), volumes.end(), std::greater<>());
    return volumes;
}

int countPieces(const Model& m) { return static_cast<int>(pieceVolumes(m).size()); }

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

// Tool contact of a run: the Bullet world, its penalty parameters and the force record.
struct ToolRun {
    std::unique_ptr<ContactWorld> world;
    double stiffnessLimit = 0;     // stable penalty stiffness per point [N/m]
    double massRef = 1;            // effective mass of a point with the full penalty [kg]
    double spacing = 0;            // largest gap between surface contact points [m]
    std::vector<std::string> clamped;  // tools whose stiffness was lowered to the limit
    double maxForce = 0;           // largest |reaction| at full rate [N]
    double maxDepth = 0;           // deepest surface point inside a tool at any step [m]
    long contactSteps = 0;         // steps with at least one point in contact
    Eigen::Vector3d force = Eigen::Vector3d::Zero(); // reaction of the last step [N]
    json series = {{"time", json::array()}, {"fx", json::array()}, {"fy", json::array()}, {"fz", json::array()},
                   {"max", json::array()}};
    double nextSample = 0, blockMax = 0, sampleDt = 1e-3;
    std::vector<float> history;    // |F| at the HUD's rate, last 200 samples [N]

    // After a step from time t (the contact forces were found at t): the full-rate maximum and
    // one sample per sampleDt.
    void record(double t) {
        const ContactStep& st = world->last();
        force.setZero();
        for (const auto& r : st.reaction) force += r;
        const double mag = force.norm();
        maxForce = std::max(maxForce, mag);
        maxDepth = std::max(maxDepth, st.maxDepth);
        contactSteps += st.contacts > 0;
        blockMax = std::max(blockMax, mag);
        if (t >= nextSample - 1e-12) {
            series["time"].push_back(t);
            series["fx"].push_back(force.x());
            series["fy"].push_back(force.y());
            series["fz"].push_back(force.z());
            series["max"].push_back(blockMax);
            blockMax = 0;
            nextSample += sampleDt;
            history.push_back(static_cast<float>(mag));
            if (history.size() > 200) history.erase(history.begin());
        }
    }
};

// cutting.compare: the scene's cut planes applied in order to the rest mesh with no fixed nodes
// by XFEM and by each baseline, with the exact step after each cut (thesis sec. 5.2, Table 6.1).
// The same setting for every method, so the ratios compare the methods and nothing else.
json compareCutMethods(const SceneDef& sc, const TetMesh& rest) {
    std::vector<CutPlane> planes;
    for (const CutDef& cd : sc.cutting.cuts) planes.push_back({cd.point, cd.normal});
    const double dt0 = exactDtOf(rest, sc.material);
    json out = {{"setting", "rest shape, no fixed nodes, the cut planes in scene order"}, {"uncut_exact", dt0}};
    auto add = [&](const std::string& name, const std::vector<double>& dts, double seconds) {
        json ratios = json::array();
        for (double d : dts) ratios.push_back(d / dt0);
        out[name] = {{"dt_exact", dts}, {"dt_ratio", ratios}, {"seconds", seconds}};
    };
    {
        const auto t0 = Clock::now();
        Model m = buildModel(rest, sc.material);
        updateMasses(m);
        State s = makeState(m);
        CutEngine eng(cutOptions(sc.cutting));
        std::vector<double> dts;
        for (const CutPlane& p : planes) {
            CutSurface cs;
            cs.point = p.point;
            cs.normal = p.normal;
            eng.cut(m, s, cs);
            dts.push_back(TimestepAnalyzer(m).exact(m).dt);
        }
        add("xfem", dts, since(t0));
    }
    for (const std::string& name : sc.cutting.compare) {
        const auto t0 = Clock::now();
        try {
            const auto dts = dtAfterPlaneCuts(rest, planes, name == "remesh" ? CutMethod::Remesh : CutMethod::Subdivision,
                                              sc.material);
            add(name, dts, since(t0));
        } catch (const std::exception& e) {
            out[name] = {{"error", e.what()}};
        }
    }
    return out;
}

} // namespace

CutSurface cutSurfaceOf(const CutDef& cd) {
    CutSurface surf;
    surf.point = cd.point;
    surf.normal = cd.normal;
    if (!cd.polygon.empty()) {
        Eigen::Vector3d u, v;
        planeAxes(cd.normal, u, v);
        std::vector<Eigen::Vector2d> poly;
        for (const auto& p : cd.polygon) poly.emplace_back((p - cd.point).dot(u), (p - cd.point).dot(v));
        surf.regions.push_back(std::move(poly));
    }
    return surf;
}

CutResult cutScene(const SceneDef& sc, Simulation& sim, State& state, CutEngine& eng, const CutSurface& surf) {
    const CutResult r = eng.cut(sim.model, state, surf);
    updateAfterCut(sc, sim, r);
    return r;
}

void updateAfterCut(const SceneDef& sc, Simulation& sim, const CutResult& r) {
    if (!r.changed()) return;
    sim.ta.update(sim.model, r.changedElements, r.changedNodes);
    sim.certified = sim.ta.certifiedDt();
    sim.estimate = sim.ta.minDt().r1r;
    sim.exact = sim.ta.exact(sim.model);
    chooseStep(sc, sim);
}

std::vector<int> bladeToolsOf(const SceneDef& sc, double& margin) {
    std::vector<int> blades;
    margin = 1e300;
    for (size_t i = 0; i < sc.tools.size(); ++i)
        if (sc.tools[i].kind == ToolDef::Kind::Blade) {
            blades.push_back(static_cast<int>(i));
            margin = std::min(margin, sc.tools[i].size.z());
        }
    return blades;
}

CutResult BladeStrokes::sweep(CutEngine& eng, Model& m, State& s, ContactWorld* contact, int i, const ToolDef& tool,
                              const BladeEdge& from, const BladeEdge& to, double t0, double t1) {
    Eigen::Vector3d lo, hi;
    sweptAabb(tool, t0, t1, lo, hi);
    for (const Eigen::Vector3d& p : {from.a, from.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);  // a dragged edge
    broadphase_.query(lo, hi, candidates_);
    if (candidates_.empty()) {
        if (stroke_ == i) endStroke(eng);
        return {};
    }
    if (stroke_ != i) {
        if (stroke_ >= 0) eng.endStroke();
        stroke_ = i;
    }
    const CutResult r = eng.sweep(m, s, from, to, &candidates_);
    if (contact && r.cut >= 0) contact->ignoreCut(i, r.cut);  // the blade slides in its own cut
    if (r.changed()) broadphase_.refit(m.tets, s.x);          // the new elements, for the next blade
    return r;
}

Simulation prepareScene(const SceneDef& sc) {
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
        mo.fixOutsideNodes = sc.surfaceFixOutside;
        mo.keepLatticeStep = sc.surfaceKeepStep;
        MiResult mi = buildMi(surf, sc.material, mo);
        embedding = {{"h", mi.h}, {"interface_elements", mi.count(ElementClass::Interface)},
                     {"volume_embedded", mi.embeddedVolume()}, {"volume_surface", enclosedVolume(surf)},
                     {"closed", mi.closed}, {"fix_outside", sc.surfaceFixOutside}, {"seconds", since(te)}};
        if (sc.surfaceKeepStep) {
            const KeepStepResult& ks = mi.massScaling;
            embedding["keep_step"] = {{"dt_lattice", mi.dtLattice}, {"dt_before", ks.dtBefore}, {"dt_after", ks.dtAfter},
                                      {"added_mass", ks.addedMass}, {"mass_fraction", ks.massFraction},
                                      {"rounds", ks.rounds}, {"seconds", mi.seconds.keepStep}};
            // More than a percent changes the dynamics visibly: say so (thin parts on a coarse lattice).
            if (ks.massFraction > kKeepStepWarnFraction || !ks.reached)
                std::fprintf(stderr,
                             "warning: %s: object.surface.keep_step %s the lattice's step %.4g s by adding %.2f%% of the "
                             "mass (step without it %.4g s); a finer lattice needs less, keep_step false adds none\n",
                             sc.file.c_str(), ks.reached ? "kept" : "did not reach", mi.dtLattice, 100 * ks.massFraction,
                             ks.dtBefore);
        }
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
    model.precision = sc.precision;
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
    Simulation sim;
    sim.model = std::move(model);
    sim.ta = std::move(ta);
    sim.exact = exact;
    sim.certified = certified;
    sim.estimate = estimate;
    sim.loadNodes = std::move(loadNodes);
    sim.surface = std::move(embedded);
    sim.embedding = std::move(embedding);
    sim.timestepSeconds = since(t0);
    chooseStep(sc, sim);
    return sim;
}

void chooseStep(const SceneDef& sc, Simulation& sim) {
    const ExactResult& exact = sim.exact;
    const TimestepAnalyzer& ta = sim.ta;
    const double certified = sim.certified, estimate = sim.estimate;
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
    sim.dt = dt;
    sim.limitAction = limitAction;
    sim.alphaElem = std::move(alphaElem);
    sim.criticalElements = criticalElements;
}

void applyLoads(const SceneDef& sc, const Simulation& sim, State& state) {
    if (!sc.forces.empty() || !sc.tools.empty()) {
        state.fExt.setZero();
        for (size_t l = 0; l < sc.forces.size(); ++l) {
            const Eigen::Vector3d f = sc.forces[l].force * sc.forces[l].profile.at(state.time) /
                                      static_cast<double>(sim.loadNodes[l].size());
            for (int n : sim.loadNodes[l]) state.fExt.col(n) += f;
        }
    }
}

void stepScene(const SceneDef& sc, const Simulation& sim, State& state, Stepper& stepper, const StepOptions& so) {
    applyLoads(sc, sim, state);
    // 2-4. forces, integrate, checks (fem/integrate.hpp)
    stepper.step(sim.model, state, so);
}

ContactSetup makeContact(const SceneDef& sc, const Simulation& sim) {
    ContactSetup c;
    if (sc.tools.empty()) return c;
    const Model& model = sim.model;
    const double dt = sim.dt;
    const bool explicitScheme = sc.integrator != Integrator::BackwardEuler;
    c.world = std::make_unique<ContactWorld>(sc.tools);
    double spacing = sc.contactSpacing;
    if (spacing <= 0) {
        // half the smallest tool feature, so a tool cannot slip between points
        spacing = 1e300;
        for (const auto& t : sc.tools)
            for (const auto& p : toolParts(t, 0))
                spacing = std::min(spacing, 0.5 * (p.hull || p.shape == ToolShape::Kind::Box
                                                      ? std::max({p.size.x(), p.size.y(), p.size.z()}) : p.size.x()));
    }
    c.spacing = spacing;
    // an embedded (MI) object is touched on its own fine surface, through the embedding weights;
    // each point's penalty scaled by its effective mass (contact/contact.hpp scaleByMass)
    ContactPoints pts = contactPoints(sim.surface ? *sim.surface : boundarySurface(model.tets, model.X), model.tets,
                                      model.X, spacing);
    c.massRef = referenceMass(pts, model.invMass);
    scaleByMass(pts, model.invMass, c.massRef);
    c.world->setSurface(std::move(pts));
    // with on_limit = damp the step is above the limit already; give the penalty the headroom of 0.9
    c.stiffnessLimit = explicitScheme ? stableStiffness(c.world->points(), model, std::min(dt, 0.9 * sim.exact.dt), sim.exact.dt)
                                      : std::numeric_limits<double>::infinity();
    for (auto& t : c.world->tools()) {
        if (t.stiffness <= 0) {
            if (!std::isfinite(c.stiffnessLimit)) throw InputError(sc.file + ": tools: " + t.name + ": stiffness is required with an implicit scheme");
            t.stiffness = kDefaultStiffnessFraction * c.stiffnessLimit;
        } else if (t.stiffness > c.stiffnessLimit) {
            std::fprintf(stderr, "warning: tool %s: stiffness %.4g N/m is above the stable limit %.4g N/m for dt %.3g s; using the limit\n",
                         t.name.c_str(), t.stiffness, c.stiffnessLimit, dt);
            t.stiffness = c.stiffnessLimit;
            c.clamped.push_back(t.name);
        }
        // damping ratio 0.3 on every point of mass <= massRef (k and c scale alike below it);
        // c dt / m stays below the explicit limit 2
        if (t.damping < 0) t.damping = 0.6 * std::sqrt(t.stiffness * c.massRef);
    }
    return c;
}

int runScene(const SceneDef& sc, const RunOptions& opt) {
    const auto wallStart = Clock::now();
    Stages stages;
    setThreads(opt.threads);
    Simulation sim = prepareScene(sc);
    stages.timestep += sim.timestepSeconds;
    Model& model = sim.model;
    TimestepAnalyzer& ta = sim.ta;
    const ExactResult& exact = sim.exact;
    const double certified = sim.certified, estimate = sim.estimate;
    double dt = sim.dt;   // a cut may lower it (cutting.cuts, integrator.dt.on_limit)
    const std::string& limitAction = sim.limitAction;
    Eigen::VectorXd alphaElem = sim.alphaElem;
    int criticalElements = sim.criticalElements;
    const bool explicitScheme = sc.integrator != Integrator::BackwardEuler;

    // Contact: a Bullet world only when the scene has tools. Penalty stiffness stays below the
    // limit that keeps this step stable (contact/contact.hpp stableStiffness).
    ToolRun tools;
    if (!sc.tools.empty()) {
        ContactSetup cs = makeContact(sc, sim);
        tools.world = std::move(cs.world);
        tools.spacing = cs.spacing;
        tools.stiffnessLimit = cs.stiffnessLimit;
        tools.massRef = cs.massRef;
        tools.clamped = std::move(cs.clamped);
        tools.sampleDt = 1.0 / sc.forceRate;
    }

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
    if (capturing) sink = makeFrameSink(sc, opt.out, model, ta.estimates().r1r, dt, sim.surface.get());

    State state = makeState(model);
    Stepper stepper;
    StepOptions so = sc.stepOptions(dt, alphaElem);

    const double frameDt = 1.0 / sc.capture.fps;
    double nextFrame = 0;
    json energy = json::array();
    std::string status = "ok";
    int exitCode = 0;
    long invertedSteps = 0, limitedSteps = 0;
    long solverIterations = 0;       // CG iterations of backward Euler, summed over the steps
    int solverIterationsMax = 0;
    int maxInverted = 0, maxLimited = 0;
    Progress progress(sc.duration, opt.quiet);
    const double mass0 = model.mass.sum();
    const int nodes0 = model.nodes(), elements0 = model.elements(), fixed0 = model.nodes() - model.freeDofs() / 3;
    TetMesh rest;  // the uncut rest mesh, for cutting.compare
    if (!sc.cutting.compare.empty()) {
        rest.X = model.X;
        rest.tets = model.tets;
    }
    const auto loopStart = Clock::now();

    // Cutting: the engine's bookkeeping exists only in scenes that cut (DESIGN.md: pay for what you use).
    // Blade tools cut as well as touch (CutEngine::sweep); only they need the element broad phase.
    double bladeMargin = 0;
    const std::vector<int> bladeTools = bladeToolsOf(sc, bladeMargin);
    std::unique_ptr<CutEngine> cutter;
    std::unique_ptr<BladeStrokes> blades;
    long bladeCutSteps = 0;   // steps in which a blade split elements
    if (!sc.cutting.cuts.empty() || !bladeTools.empty()) {
        const auto tc = Clock::now();
        cutter = std::make_unique<CutEngine>(cutOptions(sc.cutting));
        cutter->prepare(model);
        // boxes fattened by the blade thickness: a node moving less than that per step needs no tree update
        if (!bladeTools.empty()) blades = std::make_unique<BladeStrokes>(bladeMargin);
        stages.cut += since(tc);
    }
    size_t nextCut = 0;
    json cutsJson = json::array();
    int cutsMade = 0, lastCutId = -1;  // cuts that split elements (a blade stroke counts once)
    double dtExactNow = exact.dt, dtCertifiedNow = certified;

    auto recordFrame = [&]() {
        const double ek = kineticEnergy(model, state), ee = elasticEnergy(model, state), eg = gravityEnergy(model, state);
        energy.push_back({{"time", state.time}, {"kinetic", ek}, {"elastic", ee}, {"gravity", eg}, {"total", ek + ee + eg}});
        if (sink) {
            FrameInfo fi{state.time,       dt,  dtCertifiedNow, dtExactNow,   criticalElements, cutsMade,
                         since(loopStart), {},  tools.force,    tools.history};
            for (const auto& t : sc.tools) appendToolShapes(t, state.time, fi.tools);
            const auto tr = Clock::now();
            sink->frame(model, state, fi);
            stages.render += since(tr) - sink->lastEncodeSeconds();
            stages.encode += sink->lastEncodeSeconds();
        }
    };

    // After any topology change (a scripted cut or a blade sweep that split elements): local
    // update of the estimators and the certified bound, the exact dt, the scene's on_limit policy,
    // the contact and render surfaces, and a report entry under `key`. False when the run must stop.
    auto afterCut = [&](const CutResult& r, const std::string& key) {
        // Local update of the estimators and the certified bound around the cut; no global solve.
        auto tc = Clock::now();
        ta.update(model, r.changedElements, r.changedNodes);
        const double updateSeconds = since(tc);
        stages.timestep += updateSeconds;
        dtCertifiedNow = ta.certifiedDt();
        double exactSeconds = 0;
        dtExactNow = std::numeric_limits<double>::quiet_NaN();
        if (sc.cutting.exactAfterCut) {
            tc = Clock::now();
            dtExactNow = ta.exact(model).dt;
            exactSeconds = since(tc);
            stages.timestep += exactSeconds;
        }
        stepper.reset();
        const double limitNow = std::isnan(dtExactNow) ? dtCertifiedNow : dtExactNow;
        std::string action = "none";
        if (explicitScheme && dt > limitNow) {
            if (sc.dt.onLimit == "clamp") {
                dt = 0.98 * limitNow;
                action = "clamped";
            } else if (sc.dt.onLimit == "damp") {
                action = "damped";
            } else {
                action = "refused";
            }
        }
        if (alphaElem.size() || action == "damped") {
            alphaElem = elementAlpha(ta.estimates().r1r, dt);
            so.alphaElem = &alphaElem;
        }
        so.dt = dt;
        criticalElements = 0;
        for (Eigen::Index e = 0; e < ta.estimates().r1r.size(); ++e)
            criticalElements += ta.estimates().r1r(e) < sc.capture.criticalFactor * dt;
        if (sink || tools.world) {
            tc = Clock::now();
            // an MI object keeps its own surface, split by the cuts, with cut faces only inside it
            EmbeddedSurface cutSurface = sim.surface ? cutter->surface(model, *sim.surface) : cutter->surface(model);
            // tools touch the new cut faces too
            if (tools.world) {
                ContactPoints pts = contactPoints(cutSurface, model.tets, model.X, tools.spacing);
                scaleByMass(pts, model.invMass, tools.massRef);
                tools.world->setSurface(std::move(pts));
            }
            stages.contact += since(tc);
            if (sink) sink->topologyChanged(model, std::move(cutSurface), ta.estimates().r1r, dt);
        }
        json dtAfter = {{"exact", std::isnan(dtExactNow) ? json(nullptr) : json(dtExactNow)},
                        {"certified", dtCertifiedNow}, {"estimate", ta.minDt().r1r}};
        if (r.cut != lastCutId) ++cutsMade, lastCutId = r.cut;
        cutsJson.push_back({{"time", state.time}, {"key", key}, {"cut_id", r.cut}, {"crossed", r.crossed}, {"split", r.split},
                            {"elements_cut", r.split}, {"latency", r.seconds + updateSeconds}, {"pending", r.pending}, {"dropped", r.dropped}, {"merged_pieces", r.merged}, {"new_nodes", r.newNodes.size()},
                            {"new_elements", r.newElements.size()}, {"nodes", model.nodes()},
                            {"elements", model.elements()},
                            {"volume_change", r.volumeBefore > 0 ? (r.volumeAfter - r.volumeBefore) / r.volumeBefore : 0.0},
                            {"mass_change", r.massBefore > 0 ? (r.massAfter - r.massBefore) / r.massBefore : 0.0},
                            {"seconds", r.seconds}, {"update_seconds", updateSeconds},
                            {"exact_seconds", exactSeconds}, {"dt_after", dtAfter},
                            {"dt_ratio", std::isnan(dtExactNow) ? json(nullptr) : json(dtExactNow / exact.dt)},
                            {"dt_used", dt}, {"limit_action", action}, {"critical_elements", criticalElements},
                            {"pieces", countPieces(model)}});
        if (action == "refused") {
            char msg[256];
            std::snprintf(msg, sizeof msg, "stopped: step %.6g s is above the stable limit %.6g s after the cut at t = %.4g s"
                          " (integrator.dt.on_limit is \"refuse\")", dt, limitNow, state.time);
            status = msg;
            exitCode = 4;
            return false;
        }
        return true;
    };

    // Applies the scripted cuts due at the current time; false when the run must stop.
    auto applyDueCuts = [&]() {
        while (nextCut < sc.cutting.cuts.size() && sc.cutting.cuts[nextCut].time <= state.time + 1e-12) {
            const CutDef& cd = sc.cutting.cuts[nextCut++];
            const CutSurface surf = cutSurfaceOf(cd);
            const auto tc = Clock::now();
            const CutResult r = cutter->cut(model, state, surf);
            stages.cut += since(tc);
            if (!afterCut(r, cd.path)) return false;
        }
        return true;
    };

    // Blade sweeps of the step [t, t + dt]: the cutting edge moves from its pose at t to its pose at
    // t + dt, and CutEngine::sweep splits the elements whose cross-section the swept area has
    // covered. Both the edge (toolPose is in world space) and the coverage test (State::x) are in
    // the current deformed configuration, so the broad phase is refitted on state.x, not model.X.
    // The engine keeps one stroke at a time: a stroke ends when its blade leaves the tissue (no
    // element's box meets its swept box) or another blade starts cutting.
    auto applyBlades = [&]() {
        if (!blades) return true;
        auto tc = Clock::now();
        blades->refit(model, state);
        for (int i : bladeTools) {
            const ToolDef& tool = sc.tools[static_cast<size_t>(i)];
            const double t0 = state.time, t1 = state.time + dt;
            BladeEdge from, to;
            bladeEdge(tool, t0, from.a, from.b);
            bladeEdge(tool, t1, to.a, to.b);
            const CutResult r = blades->sweep(*cutter, model, state, tools.world.get(), i, tool, from, to, t0, t1);
            stages.cut += since(tc);
            if (r.changed()) {
                ++bladeCutSteps;
                if (!afterCut(r, "tools[" + std::to_string(i) + "]")) return false;
            }
            tc = Clock::now();
        }
        stages.cut += since(tc);
        return true;
    };

    while (state.time < sc.duration - 1e-9 * dt) {
        if (cutter && !applyDueCuts()) break;
        if (!applyBlades()) break;
        if (state.time >= nextFrame - 1e-12) {
            recordFrame();
            nextFrame += frameDt;
        }
        // 1. applied loads and tool contact forces go to fExt
        const double tStep = state.time;
        auto ts = Clock::now();
        applyLoads(sc, sim, state);
        if (tools.world) {
            const auto tc = Clock::now();
            tools.world->addForces(state.x, state.v, state.time, dt, state.fExt);
            stages.contact += since(tc);
            ts = Clock::now();
        }
        // 2-4. forces, integrate, checks (fem/integrate.hpp)
        stepper.step(model, state, so);
        solverIterations += stepper.lastSolverIterations();
        solverIterationsMax = std::max(solverIterationsMax, stepper.lastSolverIterations());
        const double stepTime = since(ts);
        const double fshare = stepper.lastForceSeconds();
        stages.forces += fshare;
        stages.integrate += stepTime - fshare;
        if (state.flags.inverted > 0) {
            ++invertedSteps;
            maxInverted = std::max(maxInverted, state.flags.inverted);
        }
        if (state.flags.limited > 0) {
            ++limitedSteps;
            maxLimited = std::max(maxLimited, state.flags.limited);
        }
        if (state.flags.nonFinite > 0) {
            status = "diverged: non-finite positions or velocities at step " + std::to_string(state.steps) +
                     " (t = " + std::to_string(state.time) + " s)";
            exitCode = 3;
            break;
        }
        if (tools.world) tools.record(tStep);
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
    report["force_precision"] = sc.precision == ForcePrecision::Single ? "single" : "double";
    if (sc.integrator == Integrator::BackwardEuler)
        report["implicit"] = {{"solver", implicitSolverName(sc.implicitSolver)},
                              {"cg_iterations_mean", state.steps ? double(solverIterations) / double(state.steps) : 0.0},
                              {"cg_iterations_max", solverIterationsMax}};
    report["dt"] = dt;
    report["dt_limit_action"] = limitAction;
    report["dt_initial"] = {{"exact", exact.dt}, {"certified", certified}, {"estimate", estimate}};
    report["critical_elements"] = criticalElements;
    report["mesh"] = {{"file", !sc.surface.empty() ? sc.surface : sc.mesh.empty() ? std::string("box") : sc.mesh},
                      {"nodes", nodes0}, {"elements", elements0}, {"fixed_nodes", fixed0},
                      {"nodes_final", model.nodes()}, {"elements_final", model.elements()}};
    if (!sim.embedding.is_null()) report["embedding"] = sim.embedding;
    report["cuts"] = cutsJson;
    if (blades)
        report["blade"] = {{"tools", bladeTools}, {"cut_steps", bladeCutSteps}, {"pending", cutter->pendingElements()},
                           {"cut_seconds_per_step", state.steps > 0 ? stages.cut / state.steps : 0.0}};
    report["dt_final"] = {{"exact", std::isnan(dtExactNow) ? json(nullptr) : json(dtExactNow)}, {"certified", dtCertifiedNow}};
    if (!sc.cutting.compare.empty() && exitCode == 0) report["compare"] = compareCutMethods(sc, rest);
    const std::vector<double> pieces = pieceVolumes(model);
    report["pieces"] = pieces.size();
    report["piece_volumes"] = pieces;
    report["mass"] = {{"initial", mass0}, {"final", model.mass.sum()}};
    report["energy"] = energy;
    report["inverted"] = {{"steps", invertedSteps}, {"max_elements", maxInverted},
                          {"limited_steps", limitedSteps}, {"max_limited", maxLimited}};
    report["stages"] = stages.toJson();
    if (tools.world) {
        json names = json::array(), k = json::array(), c = json::array();
        for (const auto& t : tools.world->tools()) {
            names.push_back(t.name);
            k.push_back(t.stiffness);
            c.push_back(t.damping);
        }
        report["tool"] = {{"names", names}, {"max_force", tools.maxForce}, {"contact_steps", tools.contactSteps},
                          {"max_depth", tools.maxDepth}, {"final_depth", tools.world->last().maxDepth},
                          {"final_force", {tools.force.x(), tools.force.y(), tools.force.z()}},
                          {"stiffness", k}, {"damping", c}, {"mass_ref", tools.massRef}, {"stiffness_limit", std::isfinite(tools.stiffnessLimit) ? json(tools.stiffnessLimit) : json(nullptr)},
                          {"stiffness_clamped", tools.clamped}, {"contact_points", tools.world->points().points()},
                          {"seconds_per_step", state.steps > 0 ? stages.contact / state.steps : 0.0},
                          {"force_rate", sc.forceRate}, {"series", tools.series}};
    }
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
