// The run's record and report.json (sim/record.hpp, Simulation::report), and cutting.compare.
#include "sim/simulation.hpp"
#include "sim/stages.hpp"

#include "cut/baselines.hpp"
#include "fem/forces.hpp"
#include "util/stopwatch.hpp"

#include <cstdio>

namespace cutsim {

using nlohmann::json;

namespace {

// cutting.compare: the scene's planes applied in order to the rest mesh with no fixed nodes by
// XFEM and by each baseline, with the exact step after each cut (thesis sec. 5.2, Table 6.1).
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
        Stopwatch sw;
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
        add("xfem", dts, sw.seconds());
    }
    for (const std::string& name : sc.cutting.compare) {
        Stopwatch sw;
        try {
            const auto dts = dtAfterPlaneCuts(rest, planes, parseCutMethod(name), sc.material);
            add(name, dts, sw.seconds());
        } catch (const std::exception& e) {
            out[name] = {{"error", e.what()}};
        }
    }
    return out;
}

}  // namespace

int Simulation::inputNode(int n) const {
    const SimData& d = *data_;
    const int o = d.cutter ? d.cutter->originalNode(n) : n;
    return setup_->inputNode.empty() ? o : setup_->inputNode[static_cast<size_t>(o)];
}

int Simulation::inputElement(int e) const {
    const SimData& d = *data_;
    const int o = d.cutter ? d.cutter->parentOf(e) : e;
    return setup_->inputElement.empty() ? o : setup_->inputElement[static_cast<size_t>(o)];
}

void Simulation::compareCutMethods() {
    const SimSetup& s = *setup_;
    if (!s.scene.cutting.compare.empty() && data_->status == RunStatus::Finished)
        data_->record.compare = cutsim::compareCutMethods(s.scene, s.rest);
}

void ToolRecord::add(double t, double dt, const Eigen::Vector3d& f, double depth, int contacts) {
    force = f;
    const double mag = f.norm();
    maxForce = std::max(maxForce, mag);
    maxDepth = std::max(maxDepth, depth);
    contactSteps += contacts > 0;
    blockMax = std::max(blockMax, mag);
    impulse += f * dt;
    window += dt;
    if (t >= nextSample - 1e-12) {
        const Eigen::Vector3d mean = window > 0 ? Eigen::Vector3d(impulse / window) : f;
        impulse.setZero();
        window = 0;
        time.push_back(t);
        fx.push_back(mean.x());
        fy.push_back(mean.y());
        fz.push_back(mean.z());
        blockMaxima.push_back(blockMax);
        blockMax = 0;
        nextSample += sampleDt;
        history.push_back(static_cast<float>(mean.norm()));
        if (history.size() > 200) history.erase(history.begin());
    }
}

const char* stageName(Stage s) {
    switch (s) {
    case Stage::Loads: return "loads";
    case Stage::Contact: return "contact";
    case Stage::Cuts: return "cut";
    case Stage::Forces: return "forces";
    case Stage::Integrate: return "integrate";
    case Stage::Checks: return "checks";
    case Stage::Timestep: return "timestep";
    case Stage::Render: return "render";
    case Stage::Encode: return "encode";
    case Stage::Count: break;
    }
    return "?";
}

const char* warningName(Warning w) {
    switch (w) {
    case Warning::KeepStepMass: return "keep_step_mass";
    case Warning::ToolStiffnessClamped: return "tool_stiffness_clamped";
    case Warning::TetraNotCached: return "tetra_not_cached";
    case Warning::Count: break;
    }
    return "?";
}

json Warnings::toJson() const {
    json j = json::array();
    for (int w = 0; w < kWarnings; ++w)
        if (stat[static_cast<size_t>(w)].count > 0)
            j.push_back({{"kind", warningName(static_cast<Warning>(w))},
                         {"count", stat[static_cast<size_t>(w)].count},
                         {"message", stat[static_cast<size_t>(w)].first}});
    return j;
}

json StageTimes::toJson() const {
    json j = json::object();
    for (int s = 0; s < kStages; ++s) j[stageName(static_cast<Stage>(s))] = seconds[static_cast<size_t>(s)];
    return j;
}

namespace {

// report.json "tool": the tools and colliders, their contact settings and the force record.
json toolReport(const SimSetup& s, const SimData& d) {
    json names = json::array(), k = json::array(), c = json::array();
    for (const auto& t : d.contact->tools()) {
        names.push_back(t.name);
        k.push_back(t.stiffness);
        c.push_back(t.damping);
    }
    const ToolRecord& tr = d.record.tool;
    const ContactSettings& cs = s.contact;
    json colliders = json::array();
    for (const auto& cd : d.contact->colliders()) colliders.push_back(cd.name);
    const long steps = d.state.steps;
    return {{"names", names},
            {"model", s.scene.contactModel == ContactModel::Projection ? "projection" : "penalty"},
            {"colliders", colliders},
            {"max_force", tr.maxForce},
            {"contact_steps", tr.contactSteps},
            {"max_depth", tr.maxDepth},
            {"final_depth", d.contact->last().maxDepth},
            {"final_force", {tr.force.x(), tr.force.y(), tr.force.z()}},
            {"stiffness", k},
            {"damping", c},
            {"mass_ref", cs.massRef},
            {"stiffness_limit", std::isfinite(cs.stiffnessLimit) ? json(cs.stiffnessLimit) : json(nullptr)},
            {"stiffness_clamped", cs.clamped},
            {"contact_points", d.contact->points().points()},
            {"seconds_per_step", steps > 0 ? d.record.stages[Stage::Contact] / double(steps) : 0.0},
            {"force_rate", s.scene.forceRate},
            {"series", {{"time", tr.time}, {"fx", tr.fx}, {"fy", tr.fy}, {"fz", tr.fz}, {"max", tr.blockMaxima}}}};
}

// The run's head: status, steps, time, threads, the scheme and the step.
void addRunHead(json& report, const SimSetup& s, const SimData& d) {
    const SceneDef& sc = s.scene;
    const RunRecord& rec = d.record;
    const long steps = d.state.steps;
    report["scene"] = sc.file;
    report["name"] = sc.name;
    report["status"] = d.status == RunStatus::Finished ? std::string("ok")
                       : d.message.empty()             ? std::string(runStatusName(d.status))
                                                       : d.message;
    report["warnings"] = rec.warnings.toJson();
    report["steps"] = steps;
    report["sim_time"] = d.state.time;
    report["wall_time"] = rec.wallSetup + rec.wallLoop;
    report["threads"] = runThreads(d);
    report["threads_auto"] = d.tuner != nullptr;
    report["integrator"] = integratorName(d.integrator);
    report["force_precision"] = sc.precision == ForcePrecision::Single ? "single" : "double";
    if (d.integrator == Integrator::BackwardEuler)
        report["implicit"] = {{"solver", implicitSolverName(sc.implicitSolver)},
                              {"cg_iterations_mean", steps ? double(rec.solverIterations) / double(steps) : 0.0},
                              {"cg_iterations_max", rec.solverIterationsMax}};
    report["dt"] = d.choice.dt;
    report["dt_policy"] = {{"mode", d.policy.fixed ? "fixed" : "fraction"},
                           {"of", limitOfName(d.policy.of)},
                           {"fraction", d.policy.fraction},
                           {"on_limit", onLimitName(d.policy.onLimit)}};
    report["dt_limit_action"] = limitActionName(d.choice.action);
    report["dt_initial"] = {
        {"exact", s.initial.exact}, {"certified", s.initial.certified}, {"estimate", s.initial.estimate}};
    report["critical_elements"] = d.critical;
}

// The object: its mesh and what the set-up did to it, cuts and strokes, pieces and mass.
void addObject(json& report, const SimSetup& s, const SimData& d) {
    const SceneDef& sc = s.scene;
    const RunRecord& rec = d.record;
    report["mesh"] = {{"file", !sc.surface.empty()        ? sc.surface
                               : !sc.tetraSurface.empty() ? sc.tetraSurface
                               : sc.mesh.empty()          ? std::string("box")
                                                          : sc.mesh},
                      {"nodes", rec.initial.value("nodes", 0)},
                      {"elements", rec.initial.value("elements", 0)},
                      {"fixed_nodes", rec.initial.value("fixed_nodes", 0)},
                      {"nodes_final", d.model.nodes()},
                      {"elements_final", d.model.elements()},
                      {"reordered", !s.inputNode.empty()}};
    if (!s.embedding.is_null()) report["embedding"] = s.embedding;
    if (!s.visualReport.is_null()) report["visual"] = s.visualReport;
    if (!s.improvement.is_null()) report["improve"] = s.improvement;
    if (!s.tetra.is_null()) report["tetra"] = s.tetra;
    if (!s.hybrid.is_null()) {
        report["hybrid"] = s.hybrid;
        report["hybrid"]["matched_final"] = d.model.matchedList.size();
    }
    report["cuts"] = rec.cuts;
    report["strokes"] = rec.strokes;
    if (d.bladePhase)
        report["blade"] = {
            {"tools", s.bladeTools},
            {"cut_steps", rec.bladeCutSteps},
            {"pending", d.cutter->pendingElements()},
            {"cut_seconds_per_step", d.state.steps > 0 ? rec.stages[Stage::Cuts] / double(d.state.steps) : 0.0}};
    if (d.tough) report["blade"]["toughness"] = toughnessReport(s, d);
    const bool exactKnown = !std::isnan(d.limits.exact);
    report["dt_final"] = {{"exact", exactKnown ? json(d.limits.exact) : json(nullptr)},
                          {"certified", d.limits.certified}};
    if (!rec.compare.is_null()) report["compare"] = rec.compare;
    const std::vector<double> pieces = pieceVolumes(d.model);
    report["pieces"] = pieces.size();
    report["piece_volumes"] = pieces;
    report["mass"] = {{"initial", rec.initial.value("mass", 0.0)},
                      {"final", d.model.mass.sum()},
                      {"step_floor_added", rec.floorMass}};
}

// What the checks saw against their bounds.
void addChecks(json& report, const SimSetup& s, const SimData& d) {
    const RunRecord& rec = d.record;
    const DivergenceBounds& b = s.bounds;
    report["energy"] = rec.energy;
    report["inverted"] = {{"steps", rec.invertedSteps},
                          {"max_elements", rec.maxInverted},
                          {"limited_steps", rec.limitedSteps},
                          {"max_limited", rec.maxLimited}};
    report["checks"] = {{"max_speed", b.maxSpeed},
                        {"max_displacement", b.maxDisplacement},
                        {"energy_growth", s.energyChecked ? json(b.energyGrowth) : json(nullptr)},
                        {"inverted_elements", b.invertedSteps > 0 ? json(b.invertedElements) : json(nullptr)},
                        {"inverted_steps", b.invertedSteps},
                        {"wave_speed", b.waveSpeed},
                        {"size", b.size},
                        {"speed_seen", rec.maxSpeed},
                        {"displacement_seen", rec.maxDisplacement}};
}

}  // namespace

std::uint64_t stateHash(const State& st) {
    std::uint64_t h = 1469598103934665603ull;
    auto mix = [&](const Eigen::Matrix3Xd& m) {
        const auto* p = reinterpret_cast<const unsigned char*>(m.data());
        for (size_t i = 0; i < static_cast<size_t>(m.size()) * sizeof(double); ++i) h = (h ^ p[i]) * 1099511628211ull;
    };
    mix(st.x);
    mix(st.v);
    return h;
}

int runThreads(const SimData& d) { return d.tuner ? d.tuner->current : threads(); }

json runReport(const SimSetup& s, const SimData& d, const json& extra) {
    json report;
    addRunHead(report, s, d);
    addObject(report, s, d);
    addChecks(report, s, d);
    report["stages"] = d.record.stages.toJson();
    if (d.contact) report["tool"] = toolReport(s, d);
    char hash[20];
    std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(stateHash(d.state)));
    report["state_hash"] = hash;
    const double loop = d.record.wallLoop;
    report["steps_per_second"] = loop > 0 ? double(d.state.steps) / loop : 0.0;
    report["real_time_factor"] = loop > 0 ? d.state.time / loop : 0.0;
    for (auto& [k, v] : extra.items()) report[k] = v;
    return report;
}

}  // namespace cutsim
