// Simulation: the set-up and the data of a run, the step's sequence of stages over them, and the
// calls drivers make between steps.
#include "sim/simulation.hpp"

#include "sim/stages.hpp"
#include "util/stopwatch.hpp"

#include <algorithm>

namespace cutsim {

const char* runStatusName(RunStatus s) {
    switch (s) {
    case RunStatus::Running: return "running";
    case RunStatus::Finished: return "ok";
    case RunStatus::Diverged: return "diverged";
    case RunStatus::Refused: return "refused";
    }
    return "?";
}

Simulation::Simulation(const SceneDef& scene, Options opt) : data_(std::make_unique<SimData>()) {
    auto s = std::make_unique<SimSetup>();
    compileRun(scene, opt, *s, *data_);
    setup_ = std::move(s);
}

Simulation::~Simulation() = default;
Simulation::Simulation(Simulation&&) noexcept = default;
Simulation& Simulation::operator=(Simulation&&) noexcept = default;

int Simulation::threads() const { return runThreads(*data_); }

// ---- the step ----

bool Simulation::finished() const { return data_->state.time >= setup_->scene.duration - 1e-9 * data_->choice.dt; }

RunStatus Simulation::step() {
    const SimSetup& s = *setup_;
    SimData& d = *data_;
    if (d.status != RunStatus::Running) return d.status;
    if (finished()) return d.status = RunStatus::Finished;
    const Stopwatch whole;
    const double tStep = d.state.time;
    stepLoads(s, d);
    stepPenaltyContact(s, d);
    if (!stepCuts(s, d)) return d.status;
    stepIntegrate(s, d);
    stepToughness(s, d);
    stepProjection(s, d);
    stepChecks(s, d, tStep);
    const double total = whole.seconds();
    d.record.wallLoop += total;
    if (d.tuner) d.tuner->after(total);
    if (d.status == RunStatus::Running && finished()) d.status = RunStatus::Finished;
    return d.status;
}

RunStatus Simulation::advance(double until) {
    SimData& d = *data_;
    while (d.status == RunStatus::Running && d.state.time < until - 1e-12 && !finished()) step();
    if (d.status == RunStatus::Running && finished()) d.status = RunStatus::Finished;
    return d.status;
}

std::uint64_t Simulation::stateHash() const { return cutsim::stateHash(data_->state); }

void Simulation::finish() {
    SimData& d = *data_;
    // the open stroke ends with the run: the report's limits are known at the end
    if (d.status == RunStatus::Running || d.status == RunStatus::Finished) endStroke();
    if (d.status == RunStatus::Running && finished()) d.status = RunStatus::Finished;
    if (d.status == RunStatus::Diverged) return;
    d.nextSample = d.state.time;  // the final state always
    sampleEnergy(*setup_, d);
}

nlohmann::json Simulation::report(const nlohmann::json& extra) const { return runReport(*setup_, *data_, extra); }

// The drawn surface is data a const reader brings up to date: the Simulation owns its data, not
// as a const object.
const EmbeddedSurface* Simulation::surface() const { return drawnSurface(*setup_, *data_); }

Eigen::Vector3d Simulation::toolForce(int i) const {
    const SimData& d = *data_;
    if (!d.contact || i < 0 || static_cast<size_t>(i) >= d.contact->last().reaction.size())
        return Eigen::Vector3d::Zero();
    Eigen::Vector3d f = d.contact->last().reaction[static_cast<size_t>(i)];
    if (d.tough && i == d.stroke) f += d.tough->reaction();
    return f;
}

// ---- cuts a driver makes ----

void Simulation::applyTopologyChange(const CutResult& r, const std::string& key) {
    respondToCut(*setup_, *data_, r, key, false);
}

void Simulation::endStroke() { cutsim::endStroke(*setup_, *data_); }

CutResult Simulation::cut(const CutSurface& surface, const std::string& key) {
    SimData& d = *data_;
    const StageTimer t(d.record.stages, Stage::Cuts);
    ensureCutter(*setup_, d);
    beforeTopologyChange(d);
    const CutResult r = d.cutter->cut(d.model, d.state, surface);
    applyTopologyChange(r, key);
    return r;
}

bool Simulation::cutNextScripted() {
    const SceneDef& sc = setup_->scene;
    SimData& d = *data_;
    if (d.nextCut >= sc.cutting.cuts.size() || d.status != RunStatus::Running) return false;
    const size_t k = d.nextCut++;
    d.take.cuts.push_back({k, std::min(d.take.cutTime(sc, k), d.state.time)});  // when it was made, for the take
    const CutDef& cd = sc.cutting.cuts[k];
    cut(cutSurfaceOf(cd), cd.path);
    return true;
}

int Simulation::dueNextScripted() {
    const SceneDef& sc = setup_->scene;
    SimData& d = *data_;
    const size_t n = sc.cutting.cuts.size();
    size_t k = d.nextCut;  // cuts due by now already wait for the next step
    while (k < n && d.take.cutTime(sc, k) <= d.state.time + 1e-12) ++k;
    if (k >= n || d.status != RunStatus::Running) return -1;
    d.take.cuts.push_back({k, d.state.time});
    return static_cast<int>(k);
}

// ---- interactive control ----

void Simulation::holdTool(int i, const Eigen::Vector3d& position,
                          const std::optional<Eigen::Quaterniond>& orientation) {
    SimData& d = *data_;
    if (!d.contact || i < 0 || i >= static_cast<int>(d.contact->tools().size())) return;
    holdToolKeys(d.contact->tools()[static_cast<size_t>(i)], d.state.time, position, orientation);
    d.take.holds.push_back({i, d.state.time, position, orientation});
}

std::string Simulation::setPolicy(Integrator integrator, const StepPolicy& policy) {
    const SceneDef& sc = setup_->scene;
    SimData& d = *data_;
    if (const char* why = precisionConflict(integrator, sc.precision))
        return sc.file + ": integrator.precision: " + why;
    const StepChoice c = chooseStep(policy, d.limits, integrator != Integrator::BackwardEuler);
    if (c.action == LimitAction::Refused)
        return fmt("step %.6g s is above the exact stable limit %.6g s of %s (integrator.dt.on_limit is \"refuse\")",
                   c.dt, c.limit, integratorName(integrator));
    d.integrator = integrator;
    d.policy = policy;
    applyStepPolicy(*setup_, d, false);
    d.stepper.reset();
    return {};
}

}  // namespace cutsim
