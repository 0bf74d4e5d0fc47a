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
// The slot blade i slides in (ContactWorld::setSlot): the area its strokes swept in the plane it
// cuts in. It stays after a stroke ends while the blade stays in that plane: the faces a slot cut
// lie inside the blade's thickness, and a closed slot would push them out sideways by up to half
// of it in one step (a severed lobe sliding off the blade was thrown). A new stroke in the same
// plane adds its area; the slot closes once the blade leaves the plane.
void Simulation::syncSlot(int i) {
    if (!sc_.cutting.bladeSlot) return;
    if (slots_.size() < sc_.tools.size()) slots_.resize(sc_.tools.size()), slotsBefore_.resize(sc_.tools.size());
    ContactWorld::Slot& slot = slots_[static_cast<size_t>(i)];
    const CutSurface* cs = stroke_ == i ? cutter_->strokeSurface() : nullptr;
    if (!cs) {  // between strokes: kept (see keepSlots); the next stroke in its plane adds to it
        slotsBefore_[static_cast<size_t>(i)] = slot;
        return;
    }
    const ContactWorld::Slot& before = slotsBefore_[static_cast<size_t>(i)];
    Eigen::Vector3d u, v;
    planeAxes(cs->normal, u, v);
    const double halfWidth = 0.55 * sc_.tools[static_cast<size_t>(i)].size.z();
    const bool samePlane = !before.polygons.empty() && std::abs(before.u.cross(before.v).dot(cs->normal)) > 1 - 1e-9 &&
                           std::abs(cs->normal.dot(cs->point - before.origin)) <= 1e-3 * halfWidth;
    slot.origin = cs->point, slot.u = u, slot.v = v, slot.halfWidth = halfWidth;
    slot.polygons = cs->regions;
    if (samePlane)  // the earlier strokes' areas, in this stroke's (u, v)
        for (const auto& poly : before.polygons) {
            std::vector<Eigen::Vector2d> q;
            for (const Eigen::Vector2d& p : poly) {
                const Eigen::Vector3d x = before.origin + p.x() * before.u + p.y() * before.v - slot.origin;
                q.emplace_back(x.dot(u), x.dot(v));
            }
            slot.polygons.push_back(std::move(q));
        }
    contact_->setSlot(i, slot);
}

// Closes the slot of each blade that is not cutting and has left its slot's plane at time t.
void Simulation::keepSlots(double t) {
    for (size_t b = 0; b < bladeTools_.size() && sc_.cutting.bladeSlot; ++b) {
        const int i = bladeTools_[b];
        if (stroke_ == i || static_cast<size_t>(i) >= slots_.size() || slots_[static_cast<size_t>(i)].polygons.empty())
            continue;
        ContactWorld::Slot& slot = slots_[static_cast<size_t>(i)];
        const Pose pose = toolPose(contact_->tools()[static_cast<size_t>(i)], t);
        const Eigen::Vector3d n = slot.u.cross(slot.v), nb = pose.orientation * Eigen::Vector3d::UnitZ();
        if (std::abs(n.dot(nb)) > 1 - 1e-6 && std::abs(n.dot(pose.position - slot.origin)) <= 0.1 * slot.halfWidth)
            continue;
        slot = {};
        slotsBefore_[static_cast<size_t>(i)] = {};
        contact_->setSlot(i, slot);
    }
}

// The open stroke ends: the slot closes, the exact step its blade steps deferred is solved (the
// step may grow back to its fraction of it) and the stroke's costs go to the report.
void Simulation::endStroke() {
    if (stroke_ < 0) return;
    const int was = stroke_;
    cutter_->endStroke();
    if (tough_) tough_->endStroke();
    stroke_ = -1;
    syncSlot(was);
    refreshSurface();
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
         {"exact_seconds", rec_.stages[Stage::Timestep] - before[Stage::Timestep]},
         {"pieces", pieceVolumes(model_).size()}});
}

bool Simulation::applyBlades() {
    if (!bladePhase_) return true;
    const double t0 = state_.time, t1 = state_.time + choice_.dt;
    keepSlots(t1);
    if (surfaceStale_ && state_.time >= surfaceTime_ + kSurfaceRefresh) refreshSurface();
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
        // the elements the edge's swept quad may meet (the engine reaches further through their
        // face neighbours): the blade's body only presses, so its box would offer many more
        Eigen::Vector3d lo = from.a, hi = from.a;
        for (const Eigen::Vector3d& p : {from.b, to.a, to.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
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
        if (tough_ && !toughSweep(tool, t0, from, to)) continue;  // the front holds: nothing to cut
        beforeTopologyChange();  // a sweep may split elements (r.changed() tells after it)
        const CutResult r = cutter_->sweep(model_, state_, from, to, &candidates_);
        if (r.cut >= 0) contact_->ignoreCut(i, r.cut);  // the blade slides in its own cut
        syncSlot(i);
        if (!r.changed()) {
            if (tough_) reseedFront(tool, t0);
            continue;
        }
        bladePhase_->refit(model_.tets, state_.x);  // the new elements, for the next blade
        if (tough_) reseedFront(tool, t0);
        ++rec_.bladeCutSteps;
        respondToCut(r, "tools[" + std::to_string(i) + "]", true);
        strokeLog_.latency.push_back(rec_.cuts.back()["latency"].get<double>());
        if (status_ != RunStatus::Running) return false;
    }
    return true;
}

}  // namespace cutsim
