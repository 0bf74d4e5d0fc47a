// The checks stage of a step (sim/stages.hpp): the tool force record, numerical trouble of the
// step, the divergence bounds and the energy samples.
#include "fem/forces.hpp"
#include "sim/stages.hpp"

#include <algorithm>
#include <cmath>

namespace cutsim {

namespace {

constexpr long kBoundsEvery = 4;  // steps between the speed and displacement checks

// The run diverged: why, and when on_limit "damp" let the step stand above its limit, that too.
void diverge(SimData& d, const std::string& why) {
    const StepChoice& c = d.choice;
    failRun(d, RunStatus::Diverged,
            why + (c.action == LimitAction::Damped ? fmt("; integrator.dt.on_limit \"damp\" could not hold a step of "
                                                         "%.4g s, %.3g x the exact limit %.4g s",
                                                         c.dt, c.dt / c.limit, c.limit)
                                                   : std::string()));
}

// Speeds and displacements against the scene's bounds: a blow-up grows by a factor per step and
// is caught while still finite, at a fraction of a percent of the step.
void checkBounds(const SimSetup& s, SimData& d) {
    const State& st = d.state;
    const DivergenceBounds& b = s.bounds;
    double v2 = 0, d2 = 0;
    int vNode = -1, dNode = -1;
    const double *x = st.x.data(), *v0 = st.v.data(), *X = d.model.X.data();
    for (int i = 0; i < d.model.nodes(); ++i) {
        const double* vi = v0 + 3 * i;
        const double dx = x[3 * i] - X[3 * i], dy = x[3 * i + 1] - X[3 * i + 1], dz = x[3 * i + 2] - X[3 * i + 2];
        const double sv = vi[0] * vi[0] + vi[1] * vi[1] + vi[2] * vi[2], sd = dx * dx + dy * dy + dz * dz;
        if (sv > v2) v2 = sv, vNode = i;
        if (sd > d2) d2 = sd, dNode = i;
    }
    const double v = std::sqrt(v2), dist = std::sqrt(d2);
    d.record.maxSpeed = std::max(d.record.maxSpeed, v);
    d.record.maxDisplacement = std::max(d.record.maxDisplacement, dist);
    if (v > b.maxSpeed) {
        diverge(d, fmt("diverged: node %d moves at %.3g m/s at step %ld (t = %.6g s), above the bound %.3g m/s "
                       "(checks.speed_factor %g x the p-wave speed %.3g m/s, plus gravity, loads and tools)",
                       vNode, v, st.steps, st.time, b.maxSpeed, s.scene.checks.speedFactor, b.waveSpeed));
        return;
    }
    if (dist > b.maxDisplacement) {
        diverge(d,
                fmt("diverged: node %d is %.3g m from its rest position at step %ld (t = %.6g s), above the bound "
                    "%.3g m (checks.displacement_factor %g x the object's size %.3g m, plus gravity, loads and tools)",
                    dNode, dist, st.steps, st.time, b.maxDisplacement, s.scene.checks.displacementFactor, b.size));
    }
}

// Numerical trouble of the last step (State::flags), and the divergence bounds.
void check(const SimSetup& s, SimData& d) {
    const StepFlags& fl = d.state.flags;
    RunRecord& rec = d.record;
    if (fl.inverted > 0) {
        ++rec.invertedSteps;
        rec.maxInverted = std::max(rec.maxInverted, fl.inverted);
    }
    if (fl.limited > 0) {
        ++rec.limitedSteps;
        rec.maxLimited = std::max(rec.maxLimited, fl.limited);
    }
    const int it = d.stepper.lastSolverIterations();
    rec.solverIterations += it;
    rec.solverIterationsMax = std::max(rec.solverIterationsMax, it);
    if (fl.nonFinite > 0) {
        diverge(d, fmt("diverged: non-finite positions or velocities at step %ld (t = %.6g s)", d.state.steps,
                       d.state.time));
        return;
    }
    const DivergenceBounds& b = s.bounds;
    if (b.invertedSteps > 0) {
        d.invertedRun = fl.inverted > b.invertedElements ? d.invertedRun + 1 : 0;
        if (d.invertedRun >= b.invertedSteps) {
            diverge(d, fmt("diverged: more than %d elements inverted for %d steps in a row (%d at t = %.6g s); "
                           "integrator.min_stretch limits stretch, checks.inverted_steps sets the count",
                           b.invertedElements, d.invertedRun, fl.inverted, d.state.time));
            return;
        }
    }
    if (d.state.steps % kBoundsEvery == 0) checkBounds(s, d);
}

}  // namespace

void failRun(SimData& d, RunStatus s, const std::string& why) {
    d.status = s;
    d.message = why;
}

// 6. checks: the step's tool force (taken at its start time tStep), then the state's
void stepChecks(const SimSetup& s, SimData& d, double tStep) {
    const StageTimer t(d.record.stages, Stage::Checks);
    if (d.contact) {
        const ContactStep& st = d.contact->last();
        Eigen::Vector3d f = Eigen::Vector3d::Zero();
        for (const auto& r : st.reaction) f += r;
        if (d.tough) f += recordFront(s, d, tStep, st);
        d.record.tool.add(tStep, d.choice.dt, f, st.maxDepth, st.contacts);
    }
    check(s, d);
    if (d.status == RunStatus::Running) sampleEnergy(s, d);
}

void sampleEnergy(const SimSetup& s, SimData& d) {
    const State& st = d.state;
    const double fps = s.scene.capture.fps;
    if (st.time < d.nextSample - 1e-12) return;
    d.nextSample += 1.0 / fps;
    if (d.nextSample <= st.time) d.nextSample = st.time + 1.0 / fps;
    const double ek = kineticEnergy(d.model, st), ee = elasticEnergy(d.model, st), eg = gravityEnergy(d.model, st);
    const double total = ek + ee + eg;
    d.record.energy.push_back({{"time", st.time}, {"kinetic", ek}, {"elastic", ee}, {"gravity", eg}, {"total", total}});
    if (s.energyChecked && total - d.energyRef > s.bounds.energyGrowth)
        diverge(d, fmt("diverged: the total energy rose by %.3g J by t = %.6g s with no work done by loads or tools "
                       "(bound %.3g J: the object's weight lifted through its size, or a 1%% strain)",
                       total - d.energyRef, st.time, s.bounds.energyGrowth));
}

}  // namespace cutsim
