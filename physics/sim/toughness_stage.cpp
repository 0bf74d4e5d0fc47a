// material.toughness in a step (sim/stages.hpp): the cutting blade's edge presses the crack front
// and advances it only when it pays the fracture energy (cut/toughness.hpp).
#include "cut/toughness.hpp"
#include "fem/forces.hpp"
#include "sim/stages.hpp"

#include <algorithm>

namespace cutsim {

namespace {

// Front points along a blade's edge: spaced at most 1/256 of the edge, so the front's length in
// the material (the force cap's b) is measured to that.
constexpr int kFrontSamples = 256;

Eigen::Vector3d toughCutDirection(const ToolDef& tool, double t) {
    return toolPose(tool, t).orientation * Eigen::Vector3d(0, -1, 0);  // the edge is the local -y side
}

VirtualNodeTest isVirtualNode(const SimData& d) {
    return [&d](int n) { return d.cutter->isVirtualNode(d.model, n); };
}

}  // namespace

void setupToughness(SimSetup& s, SimData& d) {
    if (!(s.scene.toughness > 0) || s.bladeTools.empty()) return;
    d.tough = std::make_unique<BladeToughness>(s.scene.toughness, kFrontSamples, s.scene.forceRate);
    s.toughStart[0] = elasticEnergy(d.model, d.state);
    s.toughStart[1] = kineticEnergy(d.model, d.state);
    s.toughStart[2] = gravityEnergy(d.model, d.state);
}

// The edges the engine sweeps this step: the front's advance of the last step, or none (then a
// front is seeded where the edge entered the material). The candidates follow the sweep's box.
bool toughSweep(SimData& d, const ToolDef& tool, double t, BladeEdge& from, BladeEdge& to) {
    const BladeEdge now = from;
    if (!d.tough->sweepEdges(d.model, d.state.x, now, toughCutDirection(tool, t), d.candidates, isVirtualNode(d), from,
                             to))
        return false;
    Eigen::Vector3d lo = from.a, hi = from.a;
    for (const Eigen::Vector3d& p : {from.b, to.a, to.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    d.bladePhase->query(lo, hi, d.candidates);
    return true;
}

void reseedFront(SimData& d, const ToolDef& tool, double t) {
    d.tough->reseed(d.model, d.state.x, toughCutDirection(tool, t), d.candidates, isVirtualNode(d));
}

// After the integration, before contact: the energy mass damping took in the step (symplectic
// Euler's v = (v + dt a) / (1 + c dt) took (1 + c dt)^2 - 1 times the kinetic energy left), and the
// stroke's edge on its front.
void stepToughness(const SimSetup&, SimData& d) {
    if (!d.tough) return;
    const StageTimer t(d.record.stages, Stage::Contact);
    const double c = d.model.massDamping, h = d.choice.dt;
    State& st = d.state;
    d.toughDamped = 0;
    if (c > 0) d.toughDamped = kineticEnergy(d.model, st) * ((1 + c * h) * (1 + c * h) - 1);
    const auto stored = [&d] {
        return elasticEnergy(d.model, d.state) + kineticEnergy(d.model, d.state) + gravityEnergy(d.model, d.state) +
               d.toughDamped;
    };
    if (d.stroke < 0 || !d.tough->hasFront()) {
        d.tough->project(d.model, h, BladeEdge{}, Eigen::Vector3d::Zero(), stored, st.x, st.v);
        return;
    }
    const ToolDef& tool = d.contact->tools()[static_cast<size_t>(d.stroke)];
    BladeEdge e;
    bladeEdge(tool, st.time, e.a, e.b);
    d.tough->project(d.model, h, e, toughCutDirection(tool, st.time), stored, st.x, st.v);
}

// The step [t0, t0 + dt]'s blade work (every blade's contact reaction and the front's, along its
// edge's motion) into the ledger; returns the front's reaction for the tool force record.
Eigen::Vector3d recordFront(const SimSetup& s, SimData& d, double t0, const ContactStep& st) {
    const double t1 = d.state.time;
    double work = 0, along = 0;
    for (int i : s.bladeTools) {
        const ToolDef& tool = d.contact->tools()[static_cast<size_t>(i)];
        Eigen::Vector3d a0, b0, a1, b1;
        bladeEdge(tool, t0, a0, b0);
        bladeEdge(tool, t1, a1, b1);
        const Eigen::Vector3d moved = 0.5 * ((a1 + b1) - (a0 + b0));
        Eigen::Vector3d f = st.reaction[static_cast<size_t>(i)];
        if (i == d.stroke) f += d.tough->reaction();
        work -= f.dot(moved);  // the tissue's force resists the blade's motion
        if (i == d.stroke || (d.stroke < 0 && i == s.bladeTools.front())) along = -f.dot(toughCutDirection(tool, t1));
    }
    d.tough->record(t0, d.choice.dt, d.state.steps, work, along, d.toughDamped);
    return d.tough->reaction();
}

nlohmann::json toughnessReport(const SimSetup& s, const SimData& d) {
    return d.tough->report(s.toughStart[0], s.toughStart[1], s.toughStart[2], elasticEnergy(d.model, d.state),
                           kineticEnergy(d.model, d.state), gravityEnergy(d.model, d.state));
}

}  // namespace cutsim
