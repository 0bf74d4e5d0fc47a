// The simulation loop of a scene, one object for every driver (cutsim run, cutsim view, the
// benchmarks, the tests, the bindings), so that its behaviour is defined once. It holds what the
// scene compiled into at load (SimSetup, sim/setup.hpp: never changed after) and what the run
// changes (SimData, sim/data.hpp), and runs the stages (sim/stages.hpp) over them.
//
// Simulation::step() runs the stages of one step in this order, each timed into RunRecord::stages:
//   1. loads      the scene's applied forces into State::fExt
//   2. contact    contact.model penalty: tool and collider forces through Bullet
//                 (contact/contact.hpp), added into fExt
//   3. cuts       scripted cuts due now and blade sweeps over [t, t + dt] (cut/xfem.hpp); each
//                 topology change goes through applyTopologyChange
//   4. forces     internal forces (fem/forces.hpp)
//   5. integrate  the scheme's velocity and position update (fem/integrate.hpp)
//   5b. contact   contact.model projection (the default): the surface points inside a tool or
//                 collider stopped and moved back onto it (ContactWorld::project), timed as contact
//   6. checks     non-finite values, divergence bounds, inverted elements, energy samples
#pragma once

#include "sim/data.hpp"
#include "sim/setup.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace cutsim {

class Simulation {
public:
    using Options = SimulationOptions;

    // Builds the scene's object, analyses its time step, chooses the step and sets up contact and
    // cutting. Throws InputError for bad input and for scenes that cannot do anything.
    explicit Simulation(const SceneDef& scene, Options opt = {});
    ~Simulation();
    Simulation(Simulation&&) noexcept;
    Simulation& operator=(Simulation&&) noexcept;

    // One step of the stages above. Returns the status after it; a run that is not Running takes
    // no more steps.
    RunStatus step();
    // Steps until the scene's duration, `until` (simulated time) or a failure.
    RunStatus advance(double until);
    // 64-bit FNV-1a of the positions and velocities, to compare runs bitwise.
    std::uint64_t stateHash() const;
    // After the last step: the status and the final energy sample.
    void finish();
    // cutting.compare: the scene's planes cut by XFEM and the baselines on the rest mesh, for the
    // report (after a finished run; it costs a global solve per cut and method).
    void compareCutMethods();

    // The one path after any cut (scripted, blade, or a driver's): local estimator update, the
    // exact limit when the scene asks for it, the step policy, contact points and the drawn surface,
    // and a report entry under `key`. May set the status to Refused.
    void applyTopologyChange(const CutResult& r, const std::string& key);
    // A blade's open stroke ends now (the slot closes, the exact step it deferred is solved and
    // its costs go to report.json "strokes"); nothing when no stroke is open.
    void endStroke();
    // A cut by `surface` now (the engine is made on first use), then applyTopologyChange.
    CutResult cut(const CutSurface& surface, const std::string& key);
    // The next scripted cut (cutting.cuts) now, ahead of its time; false when none is left.
    bool cutNextScripted();
    // The next scripted cut made due now: the next step applies it in its cut stage, as it applies
    // a scripted cut of this time (so a take that gives the cut this time replays it exactly).
    // Returns its index in cutting.cuts, or -1 when none is left.
    int dueNextScripted();

    // Interactive control: hold tool i at `position` from just after now on. Its keys become the
    // pose now (toolKeyAt) and the held pose one tick of time later (holdToolKeys), so the step
    // that ends now and the next one see the tool as the take (takeLog) replays it.
    // With an orientation (local -> world, normalised) the held pose turns too; without, it keeps
    // the orientation the tool has now.
    void holdTool(int i, const Eigen::Vector3d& position,
                  const std::optional<Eigen::Quaterniond>& orientation = std::nullopt);
    // A new scheme or policy (the scene stays as read); returns an empty string when accepted, else
    // why it was refused (nothing changes then).
    std::string setPolicy(Integrator integrator, const StepPolicy& policy);

    // Called just before anything may change the topology (a scripted cut, a blade sweep, a
    // driver's cut): after it, the model's and state's arrays and the analyzer's estimates may be
    // reallocated. A driver that lends out their memory (the Python views) takes it back here;
    // the hook may replace those arrays' storage by an equal copy. Empty: none.
    void setBeforeTopologyChange(std::function<void()> hook) { data_->beforeTopologyChange = std::move(hook); }

    // ---- what the drivers read ----
    const SimSetup& setup() const { return *setup_; }        // compiled at load
    const SimData& data() const { return *data_; }           // all the run changes
    const SceneDef& scene() const { return setup_->scene; }  // as read: a driver's policy and cuts are not in it
    const Model& model() const { return data_->model; }
    const State& state() const { return data_->state; }
    const TimestepAnalyzer& analyzer() const { return data_->analyzer; }
    double dt() const { return data_->choice.dt; }
    LimitAction limitAction() const { return data_->choice.action; }
    const StepLimits& limits() const { return data_->limits; }           // current limits (exact NaN: unknown)
    const StepLimits& initialLimits() const { return setup_->initial; }  // of the uncut object
    int criticalElements() const { return data_->critical; }
    // Elements a cut made critical (R1R step under capture.critical_factor x the step before it)
    // that the step floor, the hybrid or the step chosen again answered, with the time of that cut;
    // kept capture.answered_seconds for frames to show.
    using Answered = AnsweredElement;
    const std::vector<Answered>& answered() const { return data_->answered; }
    RunStatus status() const { return data_->status; }
    const std::string& message() const { return data_->message; }  // why the run stopped, or ""
    bool finished() const;                                         // the scene's duration is reached
    const RunRecord& record() const { return data_->record; }
    RunRecord& record() { return data_->record; }  // drivers add render and encode time
    const DivergenceBounds& bounds() const { return setup_->bounds; }
    // The tissue's force on tool i in the last step [N]: its contact reaction, and for the blade
    // whose stroke is open with material.toughness, the crack front's force on its edge.
    Eigen::Vector3d toolForce(int i) const;
    // material.toughness: the front's phase in the last step (idle without toughness)
    CutPhase cutPhase() const { return data_->tough ? data_->tough->phase() : CutPhase::Idle; }
    // ... over the last `window` seconds: cutting when the front advanced in any of its steps
    CutPhase cutPhaseOver(double window) const {
        return data_->tough ? data_->tough->phaseOver(data_->state.time, window) : CutPhase::Idle;
    }
    ContactWorld* contact() { return data_->contact.get(); }
    const ContactWorld* contact() const { return data_->contact.get(); }
    const ContactSettings& contactSettings() const { return setup_->contact; }
    const CutEngine* cutter() const { return data_->cutter.get(); }
    // object.reorder: a mesh file's nodes and elements are put in spatial order on load. These give
    // the index in the file of node n and element e (nodes and elements a cut made: of the node or
    // element they were copied from); the identity when the object was not reordered.
    bool reordered() const { return !setup_->inputNode.empty(); }
    int inputNode(int n) const;
    int inputElement(int e) const;
    // The surface to draw: the MI object's embedded surface, the object.visual surface or the mesh
    // boundary, split by the cuts so far; null for a tet-mesh object without object.visual before
    // any cut (draw its boundary). Current after every
    // topology change when Options::renderSurface is set; topologyVersion() counts the changes.
    // The visual surface is split when asked for, once for all the cuts since (a blade cuts in
    // many steps between two frames).
    const EmbeddedSurface* surface() const;
    int topologyVersion() const { return data_->topologyVersion; }
    size_t scriptedCutsDone() const { return data_->nextCut; }
    int threads() const;
    // What drivers did as the run ran (holdTool, cutNextScripted, dueNextScripted), for the take.
    const TakeLog& takeLog() const { return data_->take; }

    // The report of the run so far (report.json); `extra` is merged in at the top level.
    nlohmann::json report(const nlohmann::json& extra = nlohmann::json::object()) const;

private:
    // Heap-held, so that the addresses the contact world and the step options keep stay valid
    // when a Simulation moves.
    std::unique_ptr<const SimSetup> setup_;
    std::unique_ptr<SimData> data_;
};

}  // namespace cutsim
