// material.toughness in Simulation::step (sim/simulation.hpp): the cutting blade's edge presses
// the crack front and advances it only when it pays the fracture energy (cut/toughness.hpp).
#include "cut/toughness.hpp"
#include "fem/forces.hpp"
#include "sim/simulation.hpp"

#include <algorithm>

namespace cutsim {

namespace {

// Front points along a blade's edge: spaced at most 1/256 of the edge, so the front's length in
// the material (the force cap's b) is measured to that.
constexpr int kFrontSamples = 256;

Eigen::Vector3d toughCutDirection(const ToolDef& tool, double t) {
    return toolPose(tool, t).orientation * Eigen::Vector3d(0, -1, 0);  // the edge is the local -y side
}

}  // namespace

VirtualNodeTest Simulation::isVirtualNode() const {
    return [this](int n) { return cutter_->isVirtualNode(model_, n); };
}

void Simulation::setupToughness() {
    if (!(sc_.toughness > 0) || bladeTools_.empty()) return;
    tough_ = std::make_unique<BladeToughness>(sc_.toughness, kFrontSamples, sc_.forceRate);
    toughStart_[0] = elasticEnergy(model_, state_);
    toughStart_[1] = kineticEnergy(model_, state_);
    toughStart_[2] = gravityEnergy(model_, state_);
}

// The edges the engine sweeps this step: the front's advance of the last step, or none (then a
// front is seeded where the edge entered the material). The candidates follow the sweep's box.
bool Simulation::toughSweep(const ToolDef& tool, double t, BladeEdge& from, BladeEdge& to) {
    const BladeEdge now = from;
    if (!tough_->sweepEdges(model_, state_.x, now, toughCutDirection(tool, t), candidates_, isVirtualNode(), from, to))
        return false;
    Eigen::Vector3d lo = from.a, hi = from.a;
    for (const Eigen::Vector3d& p : {from.b, to.a, to.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    bladePhase_->query(lo, hi, candidates_);
    return true;
}

void Simulation::reseedFront(const ToolDef& tool, double t) {
    tough_->reseed(model_, state_.x, toughCutDirection(tool, t), candidates_, isVirtualNode());
}

// After the integration, before contact: the energy mass damping took in the step (symplectic
// Euler's v = (v + dt a) / (1 + c dt) took (1 + c dt)^2 - 1 times the kinetic energy left), and the
// stroke's edge on its front.
void Simulation::pressFront() {
    const double c = model_.massDamping, h = choice_.dt;
    toughDamped_ = 0;
    if (c > 0) toughDamped_ = kineticEnergy(model_, state_) * ((1 + c * h) * (1 + c * h) - 1);
    if (stroke_ < 0 || !tough_->hasFront()) {
        tough_->project(model_, h, BladeEdge{}, Eigen::Vector3d::Zero(), state_.x, state_.v);
        return;
    }
    const ToolDef& tool = contact_->tools()[static_cast<size_t>(stroke_)];
    BladeEdge e;
    bladeEdge(tool, state_.time, e.a, e.b);
    tough_->project(model_, h, e, toughCutDirection(tool, state_.time), state_.x, state_.v);
}

// The step [t0, t0 + dt]'s blade work (every blade's contact reaction and the front's, along its
// edge's motion) into the ledger; returns the front's reaction for the tool force record.
Eigen::Vector3d Simulation::recordFront(double t0, const ContactStep& st) {
    const double t1 = state_.time;
    double work = 0, along = 0;
    for (int i : bladeTools_) {
        const ToolDef& tool = contact_->tools()[static_cast<size_t>(i)];
        Eigen::Vector3d a0, b0, a1, b1;
        bladeEdge(tool, t0, a0, b0);
        bladeEdge(tool, t1, a1, b1);
        const Eigen::Vector3d moved = 0.5 * ((a1 + b1) - (a0 + b0));
        Eigen::Vector3d f = st.reaction[static_cast<size_t>(i)];
        if (i == stroke_) f += tough_->reaction();
        work -= f.dot(moved);  // the tissue's force resists the blade's motion
        if (i == stroke_ || (stroke_ < 0 && i == bladeTools_.front())) along = -f.dot(toughCutDirection(tool, t1));
    }
    tough_->record(t0, choice_.dt, state_.steps, work, along, toughDamped_);
    return tough_->reaction();
}

Eigen::Vector3d Simulation::toolForce(int i) const {
    if (!contact_ || i < 0 || static_cast<size_t>(i) >= contact_->last().reaction.size())
        return Eigen::Vector3d::Zero();
    Eigen::Vector3d f = contact_->last().reaction[static_cast<size_t>(i)];
    if (tough_ && i == stroke_) f += tough_->reaction();
    return f;
}

nlohmann::json Simulation::toughnessReport() const {
    return tough_->report(toughStart_[0], toughStart_[1], toughStart_[2], elasticEnergy(model_, state_),
                          kineticEnergy(model_, state_), gravityEnergy(model_, state_));
}

}  // namespace cutsim
