// The blade part of a step's cut stage (sim/stages.hpp): blade sweeps through the tissue.
#include "sim/stages.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <string>

namespace cutsim {

using json = nlohmann::json;

namespace {

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
void syncSlot(const SimSetup& s, SimData& d, int i) {
    const SceneDef& sc = s.scene;
    if (!sc.cutting.bladeSlot) return;
    if (d.slots.size() < sc.tools.size()) d.slots.resize(sc.tools.size()), d.slotsBefore.resize(sc.tools.size());
    ContactWorld::Slot& slot = d.slots[static_cast<size_t>(i)];
    const CutSurface* cs = d.stroke == i ? d.cutter->strokeSurface() : nullptr;
    if (!cs) {  // between strokes: kept (see keepSlots); the next stroke in its plane adds to it
        d.slotsBefore[static_cast<size_t>(i)] = slot;
        return;
    }
    const ContactWorld::Slot& before = d.slotsBefore[static_cast<size_t>(i)];
    Eigen::Vector3d u, v;
    planeAxes(cs->normal, u, v);
    const double halfWidth = 0.55 * sc.tools[static_cast<size_t>(i)].size.z();
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
    d.contact->setSlot(i, slot);
}

// Closes the slot of each blade that is not cutting and has left its slot's plane at time t.
void keepSlots(const SimSetup& s, SimData& d, double t) {
    for (size_t b = 0; b < s.bladeTools.size() && s.scene.cutting.bladeSlot; ++b) {
        const int i = s.bladeTools[b];
        const auto k = static_cast<size_t>(i);
        if (d.stroke == i || k >= d.slots.size() || d.slots[k].polygons.empty()) continue;
        ContactWorld::Slot& slot = d.slots[k];
        const Pose pose = toolPose(d.contact->tools()[k], t);
        const Eigen::Vector3d n = slot.u.cross(slot.v), nb = pose.orientation * Eigen::Vector3d::UnitZ();
        if (std::abs(n.dot(nb)) > 1 - 1e-6 && std::abs(n.dot(pose.position - slot.origin)) <= 0.1 * slot.halfWidth)
            continue;
        slot = {};
        d.slotsBefore[k] = {};
        d.contact->setSlot(i, slot);
    }
}

// report.json's entry for the stroke that ended: its costs by stage and its cut latencies.
json strokeEntry(const SimData& d, int tool, double dtDuring, const StageTimes& before) {
    const StrokeLog& L = d.strokeLog;
    const RunRecord& rec = d.record;
    json stages = json::object();
    for (Stage st : {Stage::Cuts, Stage::Timestep, Stage::Contact, Stage::Forces, Stage::Integrate})
        stages[stageName(st)] = rec.stages[st] - L.stages[st];
    std::vector<double> lat = L.latency;
    std::sort(lat.begin(), lat.end());
    auto pct = [&](double q) {
        return lat.empty() ? 0.0 : lat[std::min(lat.size() - 1, static_cast<size_t>(q * double(lat.size())))];
    };
    return {{"tool", tool},
            {"start", L.start},
            {"end", d.state.time},
            {"steps", d.state.steps - L.steps},
            {"blade_steps", lat.size()},
            {"stages", stages},
            {"latency", {{"median", pct(0.5)}, {"p99", pct(0.99)}, {"max", lat.empty() ? 0.0 : lat.back()}}},
            {"dt_during", dtDuring},
            {"dt_after", d.choice.dt},
            {"exact_after", std::isnan(d.limits.exact) ? json(nullptr) : json(d.limits.exact)},
            {"exact_seconds", rec.stages[Stage::Timestep] - before[Stage::Timestep]},
            {"pieces", pieceVolumes(d.model).size()}};
}

// Whether any blade's swept box over [t0, t1] (from where its edge was) meets the object's box.
// The box is widened by three margins, past any fattened element box the tree could hold, so a
// blade that would have met one is still queried.
bool bladeNearObject(const SimSetup& s, const SimData& d, double t0, double t1) {
    const Eigen::Vector3d pad = Eigen::Vector3d::Constant(3 * s.bladeMargin);
    const Eigen::Vector3d objLo = d.state.x.rowwise().minCoeff() - pad, objHi = d.state.x.rowwise().maxCoeff() + pad;
    for (size_t b = 0; b < s.bladeTools.size(); ++b) {
        const ToolDef& tool = d.contact->tools()[static_cast<size_t>(s.bladeTools[b])];
        Eigen::Vector3d lo, hi;
        sweptAabb(tool, t0, t1, lo, hi);
        const BladeEdge& from = d.lastEdge[b];
        if (!(from.a == from.b))
            for (const Eigen::Vector3d& p : {from.a, from.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
        if ((lo.array() <= objHi.array()).all() && (hi.array() >= objLo.array()).all()) return true;
    }
    return false;
}

// Blade b's sweep of the step [t0, t1]; false when a cut stopped the run.
bool sweepBlade(const SimSetup& s, SimData& d, size_t b, double t0, double t1) {
    const int i = s.bladeTools[b];
    const ToolDef& tool = d.contact->tools()[static_cast<size_t>(i)];
    BladeEdge from = d.lastEdge[b], to;
    if (from.a == from.b) bladeEdge(tool, t0, from.a, from.b);  // first step
    bladeEdge(tool, t1, to.a, to.b);
    d.lastEdge[b] = to;
    // the elements the edge's swept quad may meet (the engine reaches further through their
    // face neighbours): the blade's body only presses, so its box would offer many more
    Eigen::Vector3d lo = from.a, hi = from.a;
    for (const Eigen::Vector3d& p : {from.b, to.a, to.b}) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    d.bladePhase->query(lo, hi, d.candidates);
    if (d.candidates.empty()) {
        if (d.stroke == i) endStroke(s, d);
        return true;
    }
    if (d.stroke != i) {
        endStroke(s, d);
        d.stroke = i;
        d.strokeLog = {i, d.state.time, d.record.stages, d.state.steps, {}};
    }
    if (d.tough && !toughSweep(d, tool, t0, from, to)) return true;  // the front holds: nothing to cut
    beforeTopologyChange(d);  // a sweep may split elements (r.changed() tells after it)
    const CutResult r = d.cutter->sweep(d.model, d.state, from, to, &d.candidates);
    if (r.cut >= 0) d.contact->ignoreCut(i, r.cut);  // the blade slides in its own cut
    syncSlot(s, d, i);
    if (!r.changed()) {
        if (d.tough) reseedFront(d, tool, t0);
        return true;
    }
    d.bladePhase->refit(d.model.tets, d.state.x);  // the new elements, for the next blade
    if (d.tough) reseedFront(d, tool, t0);
    ++d.record.bladeCutSteps;
    respondToCut(s, d, r, "tools[" + std::to_string(i) + "]", true);
    d.strokeLog.latency.push_back(d.record.cuts.back()["latency"].get<double>());
    return d.status == RunStatus::Running;
}

}  // namespace

// The open stroke ends: the slot closes, the exact step its blade steps deferred is solved (the
// step may grow back to its fraction of it) and the stroke's costs go to the report.
void endStroke(const SimSetup& s, SimData& d) {
    if (d.stroke < 0) return;
    const int was = d.stroke;
    d.cutter->endStroke();
    if (d.tough) d.tough->endStroke();
    d.stroke = -1;
    syncSlot(s, d, was);
    refreshSurface(s, d);
    const double dtDuring = d.choice.dt;
    const StageTimes before = d.record.stages;
    settleExact(s, d);
    if (d.strokeLog.latency.empty()) return;  // the blade met elements but split none
    d.record.strokes.push_back(strokeEntry(d, was, dtDuring, before));
}

bool applyBlades(const SimSetup& s, SimData& d) {
    if (!d.bladePhase) return true;
    const double t0 = d.state.time, t1 = d.state.time + d.choice.dt;
    keepSlots(s, d, t1);
    if (d.surfaceStale && d.state.time >= d.surfaceTime + kSurfaceRefresh) refreshSurface(s, d);
    // A blade whose swept box misses the object's box cannot cut: then no tree is refitted.
    if (!bladeNearObject(s, d, t0, t1)) {
        for (size_t b = 0; b < s.bladeTools.size(); ++b) {
            const ToolDef& tool = d.contact->tools()[static_cast<size_t>(s.bladeTools[b])];
            bladeEdge(tool, t1, d.lastEdge[b].a, d.lastEdge[b].b);  // where the next step starts from
        }
        endStroke(s, d);
        return true;
    }
    d.bladePhase->refit(d.model.tets, d.state.x);
    for (size_t b = 0; b < s.bladeTools.size(); ++b)
        if (!sweepBlade(s, d, b, t0, t1)) return false;
    return true;
}

}  // namespace cutsim
