// The cut stage of a step (sim/stages.hpp) and what follows every topology change: scripted cuts,
// the after-cut response (CutResponse), the exact step a stroke owes, and the surface and contact
// points the cuts change. The blades are in blades.cpp.
#include "fem/forces.hpp"
#include "sim/stages.hpp"

#include <cmath>
#include <string>

namespace cutsim {

using json = nlohmann::json;

namespace {

constexpr int kVisualCapLevels = 2;  // object.visual: cut faces clipped to it on 16 sub-triangles each

// Scripted cuts due now (their scene time, or the time a driver gave them); false when one
// stopped the run.
bool applyDueCuts(const SimSetup& s, SimData& d) {
    const auto& cuts = s.scene.cutting.cuts;
    while (d.nextCut < cuts.size() && d.take.cutTime(s.scene, d.nextCut) <= d.state.time + 1e-12) {
        const CutDef& cd = cuts[d.nextCut++];
        beforeTopologyChange(d);
        const CutResult r = d.cutter->cut(d.model, d.state, cutSurfaceOf(cd));
        respondToCut(s, d, r, cd.path, false);
        if (d.status != RunStatus::Running) return false;
    }
    return true;
}

// The limits after a cut's response, and the step chosen again for them.
void takeLimits(const SimSetup& s, SimData& d, const CutResponseResult& res) {
    d.limits.exact = res.exact;
    d.limits.certified = d.analyzer.certifiedDt();
    d.limits.estimate = d.analyzer.minR1r();
    d.record.floorMass += res.addedMass();
    d.stepper.reset();
    // The one after-cut rule: the scene's policy chosen again at the new limits.
    applyStepPolicy(s, d, false);
}

// Elements a cut made critical at the step it was taken with that the response answered, kept
// capture.answered_seconds.
void keepAnswered(const SimSetup& s, SimData& d, const std::vector<int>& criticalAtCut) {
    const double keep = s.scene.capture.answeredSeconds, now = d.state.time;
    std::erase_if(d.answered, [&](const AnsweredElement& a) { return a.time < now - keep; });
    if (keep > 0)
        for (int e : criticalAtCut)
            if (d.model.isMatched(e) || !(d.analyzer.estimates().r1r(e) < s.scene.capture.criticalFactor * d.choice.dt))
                d.answered.push_back({e, now});
}

// The contact points and the drawn surface follow the cut: at once after a scripted cut; a blade
// step only drops the contact points its elements carried (they span the split) and the rest
// follows at the stroke's end or kSurfaceRefresh later (refreshSurface).
void followSurface(const SimSetup& s, SimData& d, const CutResult& r, bool bladeStep) {
    if (!d.contact && !s.options.renderSurface) return;
    d.surfaceStale = d.drawnStale = true;
    d.visualStale = s.visual && s.options.renderSurface;
    if (!bladeStep || d.state.time >= d.surfaceTime + kSurfaceRefresh) {
        refreshSurface(s, d);
        return;
    }
    const StageTimer t(d.record.stages, Stage::Contact);
    if (!d.contact) return;
    for (int e : r.changedElements)
        for (int a = 0; a < 4; ++a) d.dropped.push_back(d.model.tets(a, e));
    d.dropped.insert(d.dropped.end(), r.changedNodes.begin(), r.changedNodes.end());
    d.contact->dropPoints(d.dropped);
    d.dropped.clear();
}

json stepFloorEntry(const SimData& d, const CutResponseResult& res) {
    const double floor = d.response.options().dtFloor;
    if (!(floor > 0)) return nullptr;
    return {{"dt", floor},
            {"added_mass", res.addedMass()},
            {"local_added_mass", res.floor.addedMass},
            {"certified_added_mass", res.certified.addedMass},
            {"nodes", res.floor.nodes},
            {"certified_nodes", res.certified.nodes},
            {"elements_under", res.floor.elements},
            {"sweeps", res.floor.sweeps},
            {"topped_up", res.topUp.addedMass > 0},
            {"matched", res.floorMatched.added},
            {"seconds", res.floor.seconds + res.floorMatched.seconds + res.certified.seconds}};
}

// report.json's entry for a topology change.
json cutEntry(const SimSetup& s, const SimData& d, const CutResult& r, const CutResponseResult& res,
              const std::string& key, bool bladeStep) {
    const bool exactKnown = !std::isnan(d.limits.exact);
    const Model& m = d.model;
    return {{"time", d.state.time},
            {"key", key},
            {"cut_id", r.cut},
            {"crossed", r.crossed},
            {"split", r.split},
            {"elements_cut", r.split},
            {"latency", r.seconds + res.updateSeconds},
            {"pending", r.pending},
            {"dropped", r.dropped},
            {"merged_pieces", r.merged},
            {"new_nodes", r.newNodes.size()},
            {"new_elements", r.newElements.size()},
            {"nodes", m.nodes()},
            {"elements", m.elements()},
            {"volume_change", r.volumeBefore > 0 ? (r.volumeAfter - r.volumeBefore) / r.volumeBefore : 0.0},
            {"mass_change", r.massBefore > 0 ? (r.massAfter - r.massBefore) / r.massBefore : 0.0},
            {"seconds", r.seconds},
            {"update_seconds", res.updateSeconds},
            {"exact_seconds", res.exactSeconds},
            {"step_floor", stepFloorEntry(d, res)},
            {"hybrid",
             s.scene.hybrid
                 ? json{{"added", res.hybrid.added}, {"matched", res.hybrid.matched}, {"seconds", res.hybrid.seconds}}
                 : json(nullptr)},
            {"exact_deferred", res.deferred},
            {"dt_after",
             {{"exact", exactKnown ? json(d.limits.exact) : json(nullptr)},
              {"certified", d.limits.certified},
              {"estimate", d.limits.estimate}}},
            {"dt_ratio", exactKnown ? json(d.limits.exact / s.initial.exact) : json(nullptr)},
            {"dt_used", d.choice.dt},
            {"limit_action", limitActionName(d.status == RunStatus::Refused ? LimitAction::Refused : d.choice.action)},
            {"critical_elements", d.critical},
            // a blade step's entry leaves the count (a pass over the mesh) to its stroke's entry
            {"pieces", bladeStep ? json(nullptr) : json(pieceVolumes(m).size())}};
}

}  // namespace

// 3. cuts: scripted cuts due now, blade sweeps over [t, t + dt]; each is a topology change (the
// after-cut step and contact points inside it are their own stages)
bool stepCuts(const SimSetup& s, SimData& d) {
    if (!d.cutter) return true;
    const StageTimer t(d.record.stages, Stage::Cuts);
    return applyDueCuts(s, d) && applyBlades(s, d);
}

void ensureCutter(const SimSetup& s, SimData& d) {
    if (d.cutter) return;
    d.cutter = std::make_unique<CutEngine>(cutOptions(s.scene.cutting));
    d.cutter->prepare(d.model);
    // room for the cuts' elements now, not at the first cut (fem/state.hpp)
    const Eigen::Index ne = d.model.elements();
    reserveElements(d.model, d.state, ne + ne / 4 + 16);
}

void respondToCut(const SimSetup& s, SimData& d, const CutResult& r, const std::string& key, bool bladeStep) {
    if (!r.changed()) return;
    // Local update of the estimators and the certified bound around the cut, the floor or the
    // hybrid, and the exact step unless a blade's stroke defers it to its end (CutResponse).
    const double dtBefore = d.choice.dt;
    const bool defer = bladeStep && s.scene.cutting.exactAtStrokeEnd;
    const CutResponseResult res = [&] {
        const StageTimer t(d.record.stages, Stage::Timestep);
        return d.response.apply(d.model, d.analyzer, r.changedElements, r.changedNodes, defer);
    }();
    // What the cut made critical at the step it was taken with, before anything answered it.
    std::vector<int> criticalAtCut;
    const double criticalBound = s.scene.capture.criticalFactor * dtBefore;
    for (int e : d.analyzer.lastElements())
        if (d.analyzer.estimates().r1r(e) < criticalBound) criticalAtCut.push_back(e);
    takeLimits(s, d, res);
    ++d.topologyVersion;
    keepAnswered(s, d, criticalAtCut);
    followSurface(s, d, r, bladeStep);
    if (s.energyChecked) d.energyRef = totalEnergy(d.model, d.state);  // a cut releases energy, never adds it
    if (r.cut != d.lastCutId) ++d.record.cutsMade, d.lastCutId = r.cut;
    d.record.cuts.push_back(cutEntry(s, d, r, res, key, bladeStep));
}

// The surface and its contact points rebuilt for the cuts since the last time (see respondToCut).
// The surface is the work of the stage open (the cut stage's in a step), its contact points the
// contact stage's.
void refreshSurface(const SimSetup& s, SimData& d) {
    if (!d.surfaceStale) return;
    d.surfaceStale = false;
    d.surfaceTime = d.state.time;
    // an MI object keeps its own surface, split by the cuts, with cut faces only inside it; a
    // visual surface is drawn the same way but touched on the mesh's boundary
    std::unique_ptr<EmbeddedSurface> touched;
    if (d.contact || !s.visual)
        touched = std::make_unique<EmbeddedSurface>(s.embedded ? d.cutter->surface(d.model, *s.embedded)
                                                               : d.cutter->surface(d.model));
    d.visualStale = s.visual && s.options.renderSurface;
    if (d.contact) {
        const StageTimer t(d.record.stages, Stage::Contact);
        ContactPoints pts = contactPoints(*touched, d.model.tets, d.model.X, s.contact.spacing);
        scaleByMass(pts, d.model.invMass, s.contact.massRef);
        // a cut's virtual nodes take no contact correction (MI's outside lattice nodes do: its
        // surface points sit mostly on them)
        d.contact->setSurface(std::move(pts), &d.model.X, d.cutter->virtualNodes(d.model));
    }
    if (s.options.renderSurface && !s.visual) d.surface = std::move(touched);
    d.drawnStale = false;
}

void settleExact(const SimSetup& s, SimData& d) {
    if (!d.response.owed()) {
        if (d.analyzer.ownPending()) {
            const StageTimer t(d.record.stages, Stage::Timestep);
            d.analyzer.refreshOwn(d.model);
        }
        return;
    }
    const CutResponseResult res = [&] {
        const StageTimer t(d.record.stages, Stage::Timestep);
        return d.response.settle(d.model, d.analyzer);
    }();
    takeLimits(s, d, res);
}

const EmbeddedSurface* drawnSurface(const SimSetup& s, SimData& d) {
    if (d.drawnStale && s.options.renderSurface && !s.visual) {  // blade steps since the last refresh
        d.surface = std::make_unique<EmbeddedSurface>(s.embedded ? d.cutter->surface(d.model, *s.embedded)
                                                                 : d.cutter->surface(d.model));
        d.drawnStale = false;
    }
    if (d.visualStale) {
        d.surface = std::make_unique<EmbeddedSurface>(d.cutter->surface(d.model, *s.visual, kVisualCapLevels));
        d.visualStale = false;
    }
    return d.surface ? d.surface.get() : s.visual ? s.visual.get() : s.embedded.get();
}

}  // namespace cutsim
