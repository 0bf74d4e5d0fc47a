// `cutsim run`: the run loop of a scene, its progress and its report.
#pragma once

#include "scene.hpp"
#include "contact/broadphase.hpp"
#include "contact/contact.hpp"
#include "cut/xfem.hpp"
#include "mesh/embedding.hpp"
#include "timestep/analyzer.hpp"

#include <nlohmann/json.hpp>

#include <memory>

#include <string>
#include <vector>

namespace cutsim::app {

struct RunOptions {
    std::string out;          // output folder
    bool render = true;       // false: no GL context, no frames
    int threads = 0;          // 0 = all cores
    bool quiet = false;       // no progress output
};

// A scene made ready to step, shared by `cutsim run` and `cutsim view`: the model, its time-step
// limits and the step the scene's policy chose (METHOD.md sec. 2-3).
struct Simulation {
    Model model;
    TimestepAnalyzer ta;             // per-element estimates of the model
    ExactResult exact;               // exact stable limit of the explicit schemes
    double certified = 0;            // certified limit [s]
    double estimate = 0;             // smallest per-element estimate (R1R) [s]
    double dt = 0;                   // step the policy chose [s]
    std::string limitAction = "none"; // none | clamped | damped
    Eigen::VectorXd alphaElem;       // per-element damping (nElems) when damped, else empty
    int criticalElements = 0;        // elements whose estimate is below criticalFactor * dt
    std::vector<std::vector<int>> loadNodes; // nodes of each scene load (sc.forces order)
    double timestepSeconds = 0;      // wall time of the analysis [s]
    std::unique_ptr<EmbeddedSurface> surface; // an MI object's fine surface riding the lattice, else null
    nlohmann::json embedding;        // MI set-up for the report (null: a tet mesh object)
};

// Reads and builds the scene's object, analyses its time step and chooses the step. Throws
// InputError for bad input (a region selecting nothing, a refused step).
Simulation prepareScene(const SceneDef& sc);
// (Re)chooses sim.dt, limitAction, alphaElem and criticalElements from the scene's integrator
// and dt policy and the limits already in sim. Throws InputError when the policy refuses.
void chooseStep(const SceneDef& sc, Simulation& sim);
// The scene's applied loads at state.time into state.fExt (zeroed first when the scene has loads or tools).
void applyLoads(const SceneDef& sc, const Simulation& sim, State& state);
// One step: the scene's loads into state.fExt, then forces, integrate, checks (fem/integrate.hpp).
void stepScene(const SceneDef& sc, const Simulation& sim, State& state, Stepper& stepper, const StepOptions& so);

// The world-space surface of a scripted cut (cutting.cuts[i]).
CutSurface cutSurfaceOf(const CutDef& cd);
// A cut of sim.model by eng (XFEM, cut/xfem.hpp), then the limits updated locally plus the exact
// one, and the step chosen again by the scene's policy (chooseStep: a fraction of the new limit).
// Throws InputError when the policy refuses; sim's step is then unchanged and above the limit.
CutResult cutScene(const SceneDef& sc, Simulation& sim, State& state, CutEngine& eng, const CutSurface& surf);
// The same after a cut already made (e.g. a blade sweep, CutEngine::sweep): limits, exact, step.
void updateAfterCut(const SceneDef& sc, Simulation& sim, const CutResult& r);

// Tool contact of a scene: a Bullet world on sim's surface (the embedded one for MI objects), with
// each tool's penalty stiffness below the limit that keeps sim.dt stable (contact/contact.hpp).
struct ContactSetup {
    std::unique_ptr<ContactWorld> world; // null when the scene has no tools
    double spacing = 0;                  // largest gap between contact points [m]
    double stiffnessLimit = 0;           // stable penalty stiffness per point [N/m]
    double massRef = 1;                  // effective mass of a point with the full penalty [kg] (scaleByMass)
    std::vector<std::string> clamped;    // tools whose stiffness was lowered to the limit
};
ContactSetup makeContact(const SceneDef& sc, const Simulation& sim);
// Indices of the scene's blade tools; margin: the thinnest blade's thickness (the element broad
// phase's fattening: a node moving less per step needs no tree update) [m], 1e300 without blades.
std::vector<int> bladeToolsOf(const SceneDef& sc, double& margin);

// Blade tools cutting as they move (CutEngine::sweep), for `cutsim run` and `cutsim view`: the
// element broad phase over the deformed mesh, and which blade holds the engine's one stroke.
class BladeStrokes {
public:
    explicit BladeStrokes(double margin) : broadphase_(margin) {}
    // The broad phase on the current positions, once per step before the sweeps.
    void refit(const Model& m, const State& s) { broadphase_.refit(m.tets, s.x); }
    // Blade `tool` (scene tool i) moved its edge from `from` to `to` over [t0, t1]. Its candidates
    // are the elements whose boxes meet its swept box; with none its stroke ends, and another
    // blade's first sweep ends the previous blade's stroke. The blade no longer touches its own
    // cut's faces (ContactWorld::ignoreCut; contact may be null), and the broad phase takes the
    // new elements when the sweep changed the mesh. Nothing swept: r.cut < 0.
    CutResult sweep(CutEngine& eng, Model& m, State& s, ContactWorld* contact, int i, const ToolDef& tool,
                    const BladeEdge& from, const BladeEdge& to, double t0, double t1);
    void endStroke(CutEngine& eng) {
        eng.endStroke();
        stroke_ = -1;
    }

private:
    ElementBroadphase broadphase_;
    std::vector<int> candidates_;
    int stroke_ = -1;  // blade whose stroke the engine holds, or -1
};

// Runs a scene; returns the process exit code (0 ok, 3 numerical failure). Throws InputError for
// bad input before anything is written.
int runScene(const SceneDef& scene, const RunOptions& opt);

} // namespace cutsim::app
