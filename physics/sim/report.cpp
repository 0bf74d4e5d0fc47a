// The run's record and report.json (sim/record.hpp, Simulation::report), and cutting.compare.
#include "sim/simulation.hpp"

#include "cut/baselines.hpp"
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
    const int o = cutter_ ? cutter_->originalNode(n) : n;
    return inputNode_.empty() ? o : inputNode_[static_cast<size_t>(o)];
}

int Simulation::inputElement(int e) const {
    const int o = cutter_ ? cutter_->parentOf(e) : e;
    return inputElement_.empty() ? o : inputElement_[static_cast<size_t>(o)];
}

void Simulation::compareCutMethods() {
    if (!sc_.cutting.compare.empty() && status_ == RunStatus::Finished)
        rec_.compare = cutsim::compareCutMethods(sc_, rest_);
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

json Simulation::report(const json& extra) const {
    const SceneDef& sc = sc_;
    const State& st = state_;
    const bool exactKnown = !std::isnan(limits_.exact);
    json report;
    report["scene"] = sc.file;
    report["name"] = sc.name;
    report["status"] = status_ == RunStatus::Finished ? std::string("ok")
                       : message_.empty()             ? std::string(runStatusName(status_))
                                                      : message_;
    report["warnings"] = rec_.warnings.toJson();
    report["steps"] = st.steps;
    report["sim_time"] = st.time;
    report["wall_time"] = rec_.wallSetup + rec_.wallLoop;
    report["threads"] = threads();
    report["threads_auto"] = tuner_ != nullptr;
    report["integrator"] = integratorName(integrator_);
    report["force_precision"] = sc.precision == ForcePrecision::Single ? "single" : "double";
    if (integrator_ == Integrator::BackwardEuler)
        report["implicit"] = {{"solver", implicitSolverName(sc.implicitSolver)},
                              {"cg_iterations_mean", st.steps ? double(rec_.solverIterations) / double(st.steps) : 0.0},
                              {"cg_iterations_max", rec_.solverIterationsMax}};
    report["dt"] = choice_.dt;
    report["dt_policy"] = {{"mode", policy_.fixed ? "fixed" : "fraction"},
                           {"of", limitOfName(policy_.of)},
                           {"fraction", policy_.fraction},
                           {"on_limit", onLimitName(policy_.onLimit)}};
    report["dt_limit_action"] = limitActionName(choice_.action);
    report["dt_initial"] = {
        {"exact", initial_.exact}, {"certified", initial_.certified}, {"estimate", initial_.estimate}};
    report["critical_elements"] = critical_;
    report["mesh"] = {{"file", !sc.surface.empty()        ? sc.surface
                               : !sc.tetraSurface.empty() ? sc.tetraSurface
                               : sc.mesh.empty()          ? std::string("box")
                                                          : sc.mesh},
                      {"nodes", rec_.initial.value("nodes", 0)},
                      {"elements", rec_.initial.value("elements", 0)},
                      {"fixed_nodes", rec_.initial.value("fixed_nodes", 0)},
                      {"nodes_final", model_.nodes()},
                      {"elements_final", model_.elements()},
                      {"reordered", reordered()}};
    if (!embedding_.is_null()) report["embedding"] = embedding_;
    if (!visualReport_.is_null()) report["visual"] = visualReport_;
    if (!improvement_.is_null()) report["improve"] = improvement_;
    if (!tetra_.is_null()) report["tetra"] = tetra_;
    if (!hybrid_.is_null()) {
        report["hybrid"] = hybrid_;
        report["hybrid"]["matched_final"] = model_.matchedList.size();
    }
    report["cuts"] = rec_.cuts;
    report["strokes"] = rec_.strokes;
    if (bladePhase_)
        report["blade"] = {{"tools", bladeTools_},
                           {"cut_steps", rec_.bladeCutSteps},
                           {"pending", cutter_->pendingElements()},
                           {"cut_seconds_per_step", st.steps > 0 ? rec_.stages[Stage::Cuts] / double(st.steps) : 0.0}};
    if (tough_) report["blade"]["toughness"] = toughnessReport();
    report["dt_final"] = {{"exact", exactKnown ? json(limits_.exact) : json(nullptr)},
                          {"certified", limits_.certified}};
    if (!rec_.compare.is_null()) report["compare"] = rec_.compare;
    const std::vector<double> pieces = pieceVolumes(model_);
    report["pieces"] = pieces.size();
    report["piece_volumes"] = pieces;
    report["mass"] = {{"initial", rec_.initial.value("mass", 0.0)},
                      {"final", model_.mass.sum()},
                      {"step_floor_added", rec_.floorMass}};
    report["energy"] = rec_.energy;
    report["inverted"] = {{"steps", rec_.invertedSteps},
                          {"max_elements", rec_.maxInverted},
                          {"limited_steps", rec_.limitedSteps},
                          {"max_limited", rec_.maxLimited}};
    report["checks"] = {
        {"max_speed", bounds_.maxSpeed},
        {"max_displacement", bounds_.maxDisplacement},
        {"energy_growth", energyChecked_ ? json(bounds_.energyGrowth) : json(nullptr)},
        {"inverted_elements", bounds_.invertedSteps > 0 ? json(bounds_.invertedElements) : json(nullptr)},
        {"inverted_steps", bounds_.invertedSteps},
        {"wave_speed", bounds_.waveSpeed},
        {"size", bounds_.size},
        {"speed_seen", rec_.maxSpeed},
        {"displacement_seen", rec_.maxDisplacement}};
    report["stages"] = rec_.stages.toJson();
    if (contact_) {
        json names = json::array(), k = json::array(), c = json::array();
        for (const auto& t : contact_->tools()) {
            names.push_back(t.name);
            k.push_back(t.stiffness);
            c.push_back(t.damping);
        }
        const ToolRecord& tr = rec_.tool;
        const ContactSettings& cs = contactSettings_;
        json colliders = json::array();
        for (const auto& cd : contact_->colliders()) colliders.push_back(cd.name);
        report["tool"] = {
            {"names", names},
            {"model", sc.contactModel == ContactModel::Projection ? "projection" : "penalty"},
            {"colliders", colliders},
            {"max_force", tr.maxForce},
            {"contact_steps", tr.contactSteps},
            {"max_depth", tr.maxDepth},
            {"final_depth", contact_->last().maxDepth},
            {"final_force", {tr.force.x(), tr.force.y(), tr.force.z()}},
            {"stiffness", k},
            {"damping", c},
            {"mass_ref", cs.massRef},
            {"stiffness_limit", std::isfinite(cs.stiffnessLimit) ? json(cs.stiffnessLimit) : json(nullptr)},
            {"stiffness_clamped", cs.clamped},
            {"contact_points", contact_->points().points()},
            {"seconds_per_step", st.steps > 0 ? rec_.stages[Stage::Contact] / double(st.steps) : 0.0},
            {"force_rate", sc.forceRate},
            {"series", {{"time", tr.time}, {"fx", tr.fx}, {"fy", tr.fy}, {"fz", tr.fz}, {"max", tr.blockMaxima}}}};
    }
    char hash[20];
    std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(stateHash()));
    report["state_hash"] = hash;
    report["steps_per_second"] = rec_.wallLoop > 0 ? double(st.steps) / rec_.wallLoop : 0.0;
    report["real_time_factor"] = rec_.wallLoop > 0 ? st.time / rec_.wallLoop : 0.0;
    for (auto& [k, v] : extra.items()) report[k] = v;
    return report;
}

}  // namespace cutsim
