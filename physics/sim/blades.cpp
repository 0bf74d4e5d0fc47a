// The blade stage of Simulation::step (sim/simulation.hpp): blade sweeps through the tissue.
#include "sim/simulation.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <string>

namespace cutsim {

using json = nlohmann::json;

// Blade sweeps of the step [t, t + dt]: each blade's edge moves from where the last step left it
// (a dragged blade cuts along the path it was dragged) to its pose at t + dt, and CutEngine::sweep
// splits the elements whose cross-section the swept area has covered. Edge (world space) and
// coverage (State::x) are both in the deformed configuration, so the broad phase is refitted on
// state.x. The engine keeps one stroke at a time: it ends when its blade leaves the tissue (no
// element's box meets its swept box) or another blade starts cutting.
// The slot blade i slides in: the area its open stroke swept (ContactWorld::setSlot), or none.
void Simulation::syncSlot(int i) {
    ContactWorld::Slot slot;
    const CutSurface* cs = stroke_ == i && sc_.cutting.bladeSlot ? cutter_->strokeSurface() : nullptr;
    if (cs) {
        slot.origin = cs->point;
        planeAxes(cs->normal, slot.u, slot.v);
        // the blade's half thickness, and a tenth of it for the contacts speculated just outside
        slot.halfWidth = 0.55 * sc_.tools[static_cast<size_t>(i)].size.z();
        slot.polygons = cs->regions;
    }
    contact_->setSlot(i, std::move(slot));
}

// The open stroke ends: the slot closes, the exact step its blade steps deferred is solved (the
// step may grow back to its fraction of it) and the stroke's costs go to the report.
void Simulation::endStroke() {
    if (stroke_ < 0) return;
    const int was = stroke_;
    cutter_->endStroke();
    stroke_ = -1;
    syncSlot(was);
    const double dtDuring = dt();
    const StageTimes before = rec_.stages;
    settleExact();
    const StrokeLog& L = strokeLog_;
    if (L.latency.empty()) return;  // the blade met elements but split none
    json stages = json::object();
    for (Stage st : {Stage::Cuts, Stage::Timestep, Stage::Contact, Stage::Forces, Stage::Integrate})
        stages[stageName(st)] = rec_.stages[st] - L.stages[st];
    std::vector<double> lat = L.latency;
    std::sort(lat.begin(), lat.end());
    auto pct = [&](double q) {
        return lat.empty() ? 0.0 : lat[std::min(lat.size() - 1, static_cast<size_t>(q * double(lat.size())))];
    };
    rec_.strokes.push_back(
        {{"tool", was},
         {"start", L.start},
         {"end", state_.time},
         {"steps", state_.steps - L.steps},
         {"blade_steps", lat.size()},
         {"stages", stages},
         {"latency", {{"median", pct(0.5)}, {"p99", pct(0.99)}, {"max", lat.empty() ? 0.0 : lat.back()}}},
         {"dt_during", dtDuring},
         {"dt_after", dt()},
         {"exact_after", std::isnan(limits_.exact) ? json(nullptr) : json(limits_.exact)},
         {"exact_seconds", rec_.stages[Stage::Timestep] - before[Stage::Timestep]}});
}

bool Simulation::applyBlades() {
    if (!bladePhase_) return true;
    const double t0 = state_.time, t1 = state_.time + choice_.dt;
    // A blade whose swept box misses the object's box cannot cut: then no tree is refitted. The
    // box is widened by three margins, past any fattened element box the tree could hold, so a
    // blade that would have met one is still queried.
    const Eigen::Vector3d pad = Eigen::Vector3d::Constant(3 * bladeMargin_);
    const Eigen::Vector3d objLo = state_.x.rowwise().minCoeff() - pad, objHi = state_.x.rowwise().maxCoeff() + pad;
    bool anyNear = false;
    for (size_t b = 0; b < bladeTools_.size() && !anyNear; ++b) {
        const ToolDef& tool = contact_->tools()[static_cast<size_t>(bladeTools_[b])];
        Eigen::Vector3d lo, hi;
        sweptAabb(tool, t0, t1, lo, hi);
        const BladeEdge& from = lastEdge_[b];
        if (!(from.a == from.b))
            for (const Eigen::Vector3d& p : {from.a, from.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
        anyNear = (lo.array() <= objHi.array()).all() && (hi.array() >= objLo.array()).all();
    }
    if (!anyNear) {
        for (size_t b = 0; b < bladeTools_.size(); ++b) {
            const ToolDef& tool = contact_->tools()[static_cast<size_t>(bladeTools_[b])];
            bladeEdge(tool, t1, lastEdge_[b].a, lastEdge_[b].b);  // where the next step starts from
        }
        endStroke();
        return true;
    }
    bladePhase_->refit(model_.tets, state_.x);
    for (size_t b = 0; b < bladeTools_.size(); ++b) {
        const int i = bladeTools_[b];
        const ToolDef& tool = contact_->tools()[static_cast<size_t>(i)];
        BladeEdge from = lastEdge_[b], to;
        if (from.a == from.b) bladeEdge(tool, t0, from.a, from.b);  // first step
        bladeEdge(tool, t1, to.a, to.b);
        lastEdge_[b] = to;
        Eigen::Vector3d lo, hi;
        sweptAabb(tool, t0, t1, lo, hi);
        for (const Eigen::Vector3d& p : {from.a, from.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
        bladePhase_->query(lo, hi, candidates_);
        if (candidates_.empty()) {
            if (stroke_ == i) endStroke();
            continue;
        }
        if (stroke_ != i) {
            endStroke();
            stroke_ = i;
            strokeLog_ = {i, state_.time, rec_.stages, state_.steps, {}};
        }
        beforeTopologyChange();  // a sweep may split elements (r.changed() tells after it)
        const CutResult r = cutter_->sweep(model_, state_, from, to, &candidates_);
        if (r.cut >= 0) contact_->ignoreCut(i, r.cut);  // the blade slides in its own cut
        syncSlot(i);
        if (!r.changed()) continue;
        bladePhase_->refit(model_.tets, state_.x);  // the new elements, for the next blade
        ++rec_.bladeCutSteps;
        respondToCut(r, "tools[" + std::to_string(i) + "]", true);
        strokeLog_.latency.push_back(rec_.cuts.back()["latency"].get<double>());
        if (status_ != RunStatus::Running) return false;
    }
    return true;
}

}  // namespace cutsim
