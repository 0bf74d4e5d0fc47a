// The cut stage of Simulation::step (sim/simulation.hpp) and what follows every topology change:
// scripted cuts, a driver's cuts, the after-cut response (CutResponse), the exact step a stroke
// owes, and the surface and contact points the cuts change. The blades are in blades.cpp.
#include "sim/simulation.hpp"

#include "fem/forces.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace cutsim {

using json = nlohmann::json;

bool Simulation::applyDueCuts() {
    while (nextCut_ < sc_.cutting.cuts.size() && take_.cutTime(sc_, nextCut_) <= state_.time + 1e-12) {
        const CutDef& cd = sc_.cutting.cuts[nextCut_++];
        beforeTopologyChange();
        const CutResult r = cutter_->cut(model_, state_, cutSurfaceOf(cd));
        applyTopologyChange(r, cd.path);
        if (status_ != RunStatus::Running) return false;
    }
    return true;
}

CutResult Simulation::cut(const CutSurface& surface, const std::string& key) {
    const StageTimer t(rec_.stages, Stage::Cuts);
    if (!cutter_) ensureCutter();
    beforeTopologyChange();
    const CutResult r = cutter_->cut(model_, state_, surface);
    applyTopologyChange(r, key);
    return r;
}

bool Simulation::cutNextScripted() {
    if (nextCut_ >= sc_.cutting.cuts.size() || status_ != RunStatus::Running) return false;
    const size_t k = nextCut_++;
    take_.cuts.push_back({k, std::min(take_.cutTime(sc_, k), state_.time)});  // when it was made, for the take
    const CutDef& cd = sc_.cutting.cuts[k];
    cut(cutSurfaceOf(cd), cd.path);
    return true;
}

int Simulation::dueNextScripted() {
    const size_t n = sc_.cutting.cuts.size();
    size_t k = nextCut_;  // cuts due by now already wait for the next step
    while (k < n && take_.cutTime(sc_, k) <= state_.time + 1e-12) ++k;
    if (k >= n || status_ != RunStatus::Running) return -1;
    take_.cuts.push_back({k, state_.time});
    return static_cast<int>(k);
}

void Simulation::applyTopologyChange(const CutResult& r, const std::string& key) { respondToCut(r, key, false); }

void Simulation::respondToCut(const CutResult& r, const std::string& key, bool bladeStep) {
    if (!r.changed()) return;
    // Local update of the estimators and the certified bound around the cut, the floor or the
    // hybrid, and the exact step unless a blade's stroke defers it to its end (CutResponse).
    const double dtBefore = dt();
    const bool defer = bladeStep && sc_.cutting.exactAtStrokeEnd;
    const CutResponseResult res = [&] {
        const StageTimer t(rec_.stages, Stage::Timestep);
        return response_.apply(model_, ta_, r.changedElements, r.changedNodes, defer);
    }();
    // What the cut made critical at the step it was taken with, before anything answered it.
    std::vector<int> criticalAtCut;
    const double criticalBound = sc_.capture.criticalFactor * dtBefore;
    for (int e : ta_.lastElements())
        if (ta_.estimates().r1r(e) < criticalBound) criticalAtCut.push_back(e);
    limits_.exact = res.exact;
    limits_.certified = ta_.certifiedDt();
    limits_.estimate = ta_.minR1r();
    const double updateSeconds = res.updateSeconds, exactSeconds = res.exactSeconds;
    rec_.floorMass += res.addedMass();
    stepper_.reset();
    // The one after-cut rule: the scene's policy chosen again at the new limits.
    chooseAndApply(false);
    ++topologyVersion_;
    const double keep = sc_.capture.answeredSeconds;
    std::erase_if(answered_, [&](const Answered& a) { return a.time < state_.time - keep; });
    if (keep > 0)
        for (int e : criticalAtCut)
            if (model_.isMatched(e) || !(ta_.estimates().r1r(e) < sc_.capture.criticalFactor * dt()))
                answered_.push_back({e, state_.time});
    // The contact points and the drawn surface follow the cut: at once after a scripted cut; a
    // blade step only drops the contact points its elements carried (they span the split) and the
    // rest follows at the stroke's end or kSurfaceRefresh later (refreshSurface).
    if (contact_ || opt_.renderSurface) {
        surfaceStale_ = drawnStale_ = true;
        visualStale_ = visual_ && opt_.renderSurface;
        if (!bladeStep || state_.time >= surfaceTime_ + kSurfaceRefresh) {
            refreshSurface();
        } else {
            const StageTimer t(rec_.stages, Stage::Contact);
            if (contact_) {
                for (int e : r.changedElements)
                    for (int a = 0; a < 4; ++a) dropped_.push_back(model_.tets(a, e));
                dropped_.insert(dropped_.end(), r.changedNodes.begin(), r.changedNodes.end());
                contact_->dropPoints(dropped_);
                dropped_.clear();
            }
        }
    }
    if (energyChecked_) energyRef_ = totalEnergy(model_, state_);  // a cut releases energy, never adds it
    if (r.cut != lastCutId_) ++rec_.cutsMade, lastCutId_ = r.cut;
    const bool exactKnown = !std::isnan(limits_.exact);
    rec_.cuts.push_back(
        {{"time", state_.time},
         {"key", key},
         {"cut_id", r.cut},
         {"crossed", r.crossed},
         {"split", r.split},
         {"elements_cut", r.split},
         {"latency", r.seconds + updateSeconds},
         {"pending", r.pending},
         {"dropped", r.dropped},
         {"merged_pieces", r.merged},
         {"new_nodes", r.newNodes.size()},
         {"new_elements", r.newElements.size()},
         {"nodes", model_.nodes()},
         {"elements", model_.elements()},
         {"volume_change", r.volumeBefore > 0 ? (r.volumeAfter - r.volumeBefore) / r.volumeBefore : 0.0},
         {"mass_change", r.massBefore > 0 ? (r.massAfter - r.massBefore) / r.massBefore : 0.0},
         {"seconds", r.seconds},
         {"update_seconds", updateSeconds},
         {"exact_seconds", exactSeconds},
         {"step_floor", response_.options().dtFloor > 0
                            ? json{{"dt", response_.options().dtFloor},
                                   {"added_mass", res.addedMass()},
                                   {"local_added_mass", res.floor.addedMass},
                                   {"certified_added_mass", res.certified.addedMass},
                                   {"nodes", res.floor.nodes},
                                   {"certified_nodes", res.certified.nodes},
                                   {"elements_under", res.floor.elements},
                                   {"sweeps", res.floor.sweeps},
                                   {"topped_up", res.topUp.addedMass > 0},
                                   {"matched", res.floorMatched.added},
                                   {"seconds", res.floor.seconds + res.floorMatched.seconds + res.certified.seconds}}
                            : json(nullptr)},
         {"hybrid",
          sc_.hybrid
              ? json{{"added", res.hybrid.added}, {"matched", res.hybrid.matched}, {"seconds", res.hybrid.seconds}}
              : json(nullptr)},
         {"exact_deferred", res.deferred},
         {"dt_after",
          {{"exact", exactKnown ? json(limits_.exact) : json(nullptr)},
           {"certified", limits_.certified},
           {"estimate", limits_.estimate}}},
         {"dt_ratio", exactKnown ? json(limits_.exact / initial_.exact) : json(nullptr)},
         {"dt_used", choice_.dt},
         {"limit_action", limitActionName(status_ == RunStatus::Refused ? LimitAction::Refused : choice_.action)},
         {"critical_elements", critical_},
         // a blade step's entry leaves the count (a pass over the mesh) to its stroke's entry
         {"pieces", bladeStep ? json(nullptr) : json(pieceVolumes(model_).size())}});
}

// The surface and its contact points rebuilt for the cuts since the last time (see respondToCut).
// The surface is the work of the stage open (the cut stage's in a step), its contact points the
// contact stage's.
void Simulation::refreshSurface() {
    if (!surfaceStale_) return;
    surfaceStale_ = false;
    surfaceTime_ = state_.time;
    // an MI object keeps its own surface, split by the cuts, with cut faces only inside it; a
    // visual surface is drawn the same way but touched on the mesh's boundary
    std::unique_ptr<EmbeddedSurface> touched;
    if (contact_ || !visual_)
        touched = std::make_unique<EmbeddedSurface>(embedded_ ? cutter_->surface(model_, *embedded_)
                                                              : cutter_->surface(model_));
    visualStale_ = visual_ && opt_.renderSurface;
    if (contact_) {
        const StageTimer t(rec_.stages, Stage::Contact);
        ContactPoints pts = contactPoints(*touched, model_.tets, model_.X, contactSettings_.spacing);
        scaleByMass(pts, model_.invMass, contactSettings_.massRef);
        // a cut's virtual nodes take no contact correction (MI's outside lattice nodes do: its
        // surface points sit mostly on them)
        contact_->setSurface(std::move(pts), &model_.X, cutter_->virtualNodes(model_));
    }
    if (opt_.renderSurface && !visual_) surface_ = std::move(touched);
    drawnStale_ = false;
}

void Simulation::settleExact() {
    if (!response_.owed()) return;
    const CutResponseResult res = [&] {
        const StageTimer t(rec_.stages, Stage::Timestep);
        return response_.settle(model_, ta_);
    }();
    limits_.exact = res.exact;
    limits_.certified = ta_.certifiedDt();
    limits_.estimate = ta_.minR1r();
    rec_.floorMass += res.addedMass();
    stepper_.reset();
    chooseAndApply(false);
}

}  // namespace cutsim
