// The simulation loop of a scene, one object for every driver (cutsim run, cutsim view, the
// benchmarks, the tests, the bindings), so that its behaviour is defined once.
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

#include "mesh/broadphase.hpp"
#include "contact/contact.hpp"
#include "cut/toughness.hpp"
#include "cut/xfem.hpp"
#include "fem/integrate.hpp"
#include "mesh/embedding.hpp"
#include "sim/record.hpp"
#include "sim/scene.hpp"
#include "sim/step_policy.hpp"
#include "sim/take_log.hpp"
#include "sim/thread_tuner.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/cut_response.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace cutsim {

// A blade's steps rebuild the surface and its contact points at most this often (and when its
// stroke ends); in between each drops the contact points of the elements it split [s, simulated].
inline constexpr double kSurfaceRefresh = 0.01;

// The status of a run (the cutsim program maps it to its exit code: app/exit_code.hpp).
enum class RunStatus : std::uint8_t { Running, Finished, Diverged, Refused };
const char* runStatusName(RunStatus s);  // running | ok | diverged | refused

// Bounds outside which a state is not physics but a blow-up (docs/scene-format.md, "checks").
// Derived from the scene unless it sets them: see divergenceBounds.
struct DivergenceBounds {
    double maxSpeed = 0;         // largest node speed [m/s]
    double maxDisplacement = 0;  // largest distance of a node from its rest position [m]
    double energyGrowth = 0;     // largest rise of the total energy when nothing does work [J]; 0: not checked
    int invertedElements = 0;    // inverted elements that count as a failure ...
    int invertedSteps = 0;       // ... when seen in this many consecutive steps (0: not checked)
    double waveSpeed = 0;        // p-wave speed of the material [m/s], for the report
    double size = 0;             // diagonal of the object's rest bounding box [m], for the report
};
// The rule (docs/scene-format.md): with c_p the p-wave speed, L the object's size, T the duration,
// g gravity, v_tool the fastest tool keyframe motion and a_load the largest acceleration the
// scene's forces can give the whole object:
//   speed        <= speed_factor c_p + (g + a_load) T + v_tool        (a node at strain speed_factor)
//   displacement <= displacement_factor L + (g + a_load) T^2 / 2 + tool travel
//   energy rise  <= M (g L + c_p^2 1e-4) when no tool or force does work (gravity moving all the
//                   mass through the object's size, or a strain of 1% everywhere)
//   inverted     > max(10, 5% of the elements) for 100 steps in a row, without stretch limiting
DivergenceBounds divergenceBounds(const SceneDef& sc, const Model& model);

// The steps a run implies, refused above SceneDef::maxSteps (exit 2) with the time they would take.
void checkStepBudget(const SceneDef& sc, double dt, int elements);

struct SimulationOptions {
    int threads = 0;             // worker threads; 0: chosen by measuring (ThreadTuner)
    bool renderSurface = false;  // keep Simulation::surface() current after cuts (drivers that draw)
};

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
    void setBeforeTopologyChange(std::function<void()> hook) { beforeTopologyChange_ = std::move(hook); }

    // ---- what the drivers read ----
    const SceneDef& scene() const { return sc_; }  // as read: a driver's policy and cuts are not in it
    const Model& model() const { return model_; }
    const State& state() const { return state_; }
    const TimestepAnalyzer& analyzer() const { return ta_; }
    double dt() const { return choice_.dt; }
    LimitAction limitAction() const { return choice_.action; }
    const StepLimits& limits() const { return limits_; }          // current limits (exact NaN: unknown)
    const StepLimits& initialLimits() const { return initial_; }  // of the uncut object
    int criticalElements() const { return critical_; }
    // Elements a cut made critical (R1R step under capture.critical_factor x the step before it)
    // that the step floor, the hybrid or the step chosen again answered, with the time of that cut;
    // kept capture.answered_seconds for frames to show.
    struct Answered {
        int element;
        double time;  // [s]
    };
    const std::vector<Answered>& answered() const { return answered_; }
    RunStatus status() const { return status_; }
    const std::string& message() const { return message_; }  // why the run stopped, or ""
    bool finished() const;                                   // the scene's duration is reached
    const RunRecord& record() const { return rec_; }
    RunRecord& record() { return rec_; }  // drivers add render and encode time
    const DivergenceBounds& bounds() const { return bounds_; }
    // The tissue's force on tool i in the last step [N]: its contact reaction, and for the blade
    // whose stroke is open with material.toughness, the crack front's force on its edge.
    Eigen::Vector3d toolForce(int i) const;
    // material.toughness: the front's phase in the last step (idle without toughness)
    CutPhase cutPhase() const { return tough_ ? tough_->phase() : CutPhase::Idle; }
    // ... over the last `window` seconds: cutting when the front advanced in any of its steps
    CutPhase cutPhaseOver(double window) const {
        return tough_ ? tough_->phaseOver(state_.time, window) : CutPhase::Idle;
    }
    ContactWorld* contact() { return contact_.get(); }
    const ContactWorld* contact() const { return contact_.get(); }
    const ContactSettings& contactSettings() const { return contactSettings_; }
    const CutEngine* cutter() const { return cutter_.get(); }
    // object.reorder: a mesh file's nodes and elements are put in spatial order on load. These give
    // the index in the file of node n and element e (nodes and elements a cut made: of the node or
    // element they were copied from); the identity when the object was not reordered.
    bool reordered() const { return !inputNode_.empty(); }
    int inputNode(int n) const;
    int inputElement(int e) const;
    // The surface to draw: the MI object's embedded surface, the object.visual surface or the mesh
    // boundary, split by the cuts so far; null for a tet-mesh object without object.visual before
    // any cut (draw its boundary). Current after every
    // topology change when Options::renderSurface is set; topologyVersion() counts the changes.
    // The visual surface is split when asked for, once for all the cuts since (a blade cuts in
    // many steps between two frames).
    const EmbeddedSurface* surface() const;
    int topologyVersion() const { return topologyVersion_; }
    size_t scriptedCutsDone() const { return nextCut_; }
    int threads() const;
    // What drivers did as the run ran (holdTool, cutNextScripted, dueNextScripted), for the take.
    const TakeLog& takeLog() const { return take_; }

    // The report of the run so far (report.json); `extra` is merged in at the top level.
    nlohmann::json report(const nlohmann::json& extra = nlohmann::json::object()) const;

private:
    void buildObject();
    void improveOnLoad(TetMesh& mesh);
    TetMesh tetraMesh();
    void embedVisualSurface(const SurfaceMesh& vis);
    void chooseAndApply(bool initial);
    void setupContact();
    void ensureCutter();
    bool applyDueCuts();
    bool applyBlades();
    void syncSlot(int i);
    void keepSlots(double t);
    void refreshSurface();
    void settleExact();
    void respondToCut(const CutResult& r, const std::string& key, bool bladeStep);
    void check();
    void sampleEnergy();
    void fail(RunStatus s, const std::string& why);
    void recordTool(double t);
    // material.toughness (sim/toughness_stage.cpp): the blade presses the crack front until it pays
    void setupToughness();
    bool toughSweep(const ToolDef& tool, double t, BladeEdge& from, BladeEdge& to);
    void reseedFront(const ToolDef& tool, double t);
    VirtualNodeTest isVirtualNode() const;
    void pressFront();
    Eigen::Vector3d recordFront(double t0, const ContactStep& st);
    nlohmann::json toughnessReport() const;
    void beforeTopologyChange() {
        if (beforeTopologyChange_) beforeTopologyChange_();
    }

    SceneDef sc_;
    Options opt_;
    Integrator integrator_;  // the scene's, or a driver's (setPolicy)
    StepPolicy policy_;
    Model model_;
    State state_;
    Stepper stepper_;
    StepOptions so_;
    TimestepAnalyzer ta_;
    StepLimits limits_, initial_;
    StepChoice choice_;
    Eigen::VectorXd alphaElem_;  // per-element damping (on_limit damp), else empty
    int critical_ = 0;
    std::vector<Answered> answered_;
    std::vector<std::vector<int>> loadNodes_;           // nodes of each scene load (sc.forces order)
    std::unique_ptr<EmbeddedSurface> embedded_;         // an MI object's surface in the uncut lattice
    nlohmann::json embedding_;                          // MI set-up for the report (null: a tet mesh object)
    std::unique_ptr<EmbeddedSurface> visual_;           // object.visual in the uncut mesh, else null
    nlohmann::json visualReport_;                       // object.visual for the report (null: none)
    nlohmann::json improvement_;                        // object.improve for the report (null: not asked)
    std::vector<int> inputNode_, inputElement_;         // object.reorder: file index of each node and element
    nlohmann::json tetra_;                              // object.tetra for the report (null: not used)
    nlohmann::json hybrid_;                             // object.element "hybrid" on load, for the report (null: not)
    double hybridDtSim_ = 0;                            // the hybrid's dt_sim: 0.95 of the FEM object's exact step [s]
    TetMesh rest_;                                      // the uncut rest mesh, for cutting.compare
    mutable std::unique_ptr<EmbeddedSurface> surface_;  // drawn surface after cuts (see surface())
    mutable bool visualStale_ = false;                  // surface_ lags the cuts of visual_
    mutable bool drawnStale_ = false;                   // surface_ lags blade steps (no visual_)
    bool surfaceStale_ = false;                         // contact points lag blade steps (refreshSurface)
    double surfaceTime_ = 0;                            // when the contact points were last rebuilt [s]
    std::vector<int> dropped_;                          // scratch: nodes whose contact points a blade step drops
    int topologyVersion_ = 0;
    std::function<void()> beforeTopologyChange_;

    std::unique_ptr<ContactWorld> contact_;
    ContactSettings contactSettings_;
    std::unique_ptr<CutEngine> cutter_;
    std::unique_ptr<ElementBroadphase> bladePhase_;
    std::vector<int> bladeTools_;      // scene tools that cut
    double bladeMargin_ = 0;           // fattening of bladePhase_'s element boxes [m]
    std::vector<BladeEdge> lastEdge_;  // each blade's edge at the end of the last step
    std::vector<int> candidates_;
    int stroke_ = -1;  // blade whose stroke the engine holds, or -1
    struct StrokeLog {
        int tool = -1;
        double start = 0;             // [s]
        StageTimes stages;            // the run's stage times when the stroke began
        long steps = 0;               // the run's steps then
        std::vector<double> latency;  // each blade step's cut latency [s]
    } strokeLog_;
    CutResponse response_;
    std::vector<int> projected_;                   // nodes the last projection moved (repairInverted)
    std::unique_ptr<BladeToughness> tough_;        // material.toughness > 0 with a blade, else null
    double toughDamped_ = 0;                       // energy the last step's mass damping took [J]
    double toughStart_[3] = {0, 0, 0};             // elastic, kinetic, gravity energy at the start [J]
    std::vector<ContactWorld::Slot> slots_;        // each blade's slot (cutting.blade_slot), by tool index
    std::vector<ContactWorld::Slot> slotsBefore_;  // ... as its earlier strokes left it
    size_t nextCut_ = 0;
    int lastCutId_ = -1;

    DivergenceBounds bounds_;
    bool energyChecked_ = false;  // no tool or force does work
    double energyRef_ = 0;        // total energy the growth is measured from [J]
    int invertedRun_ = 0;         // consecutive steps over bounds_.invertedElements
    double nextSample_ = 0;       // time of the next energy sample [s]
    RunStatus status_ = RunStatus::Running;
    std::string message_;
    RunRecord rec_;
    TakeLog take_;
    std::unique_ptr<ThreadTuner> tuner_;
};

}  // namespace cutsim
