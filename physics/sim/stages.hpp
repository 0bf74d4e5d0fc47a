// The stages of Simulation::step (sim/simulation.hpp) and what they share, as functions of the
// set-up compiled at load (SimSetup, never changed) and the data a run changes (SimData). Each
// stage times itself under a StageTimer (RunRecord::stages). In the order the step runs them:
//   1. loads      the scene's applied forces into State::fExt                     sim/dynamics.cpp
//   2. contact    contact.model penalty: tool and collider forces through Bullet  sim/dynamics.cpp
//   3. cuts       scripted cuts due now, blade sweeps over [t, t + dt]; each       sim/cuts.cpp,
//                 topology change answered by respondToCut                        sim/blades.cpp
//   4-5. forces and integration                                                   sim/dynamics.cpp
//   5a. material.toughness: the blade's edge on the crack front                   sim/toughness_stage.cpp
//   5b. contact   contact.model projection (the default)                          sim/dynamics.cpp
//   6. checks     non-finite values, divergence bounds, energy samples, tool force sim/checks.cpp
#pragma once

#include "sim/data.hpp"
#include "sim/setup.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdio>
#include <string>

namespace cutsim {

// A blade's steps rebuild the surface and its contact points at most this often (and when its
// stroke ends); in between each drops the contact points of the elements it split [s, simulated].
inline constexpr double kSurfaceRefresh = 0.01;

// printf into a string, for the run's messages
std::string fmt(const char* f, auto... args) {
    char buf[512];
    std::snprintf(buf, sizeof buf, f, args...);
    return buf;
}

// ---- at load (sim/compile.cpp): the scene compiled into the set-up and the first data ----

void compileRun(const SceneDef& scene, SimulationOptions opt, SimSetup& s, SimData& d);

// ---- the stages, in order ----

void stepLoads(const SimSetup& s, SimData& d);
void stepPenaltyContact(const SimSetup& s, SimData& d);
bool stepCuts(const SimSetup& s, SimData& d);  // false: a cut stopped the run
void stepIntegrate(const SimSetup& s, SimData& d);
void stepToughness(const SimSetup& s, SimData& d);
void stepProjection(const SimSetup& s, SimData& d);
void stepChecks(const SimSetup& s, SimData& d, double tStep);  // tStep: the time the step began [s]

// ---- shared by the stages and by a driver's calls (Simulation) ----

// The run stops with status s (not Running) and why.
void failRun(SimData& d, RunStatus s, const std::string& why);
// The step from the policy at the current limits, with its per-element damping and critical
// elements (sim/step_policy.cpp). Before the first step (`initial`) a refused step is bad input;
// after a cut it stops the run (exit 4) and the step stays as it was.
void applyStepPolicy(const SimSetup& s, SimData& d, bool initial);
// Energy at the capture rate: the report's samples, and the growth check (sim/checks.cpp).
void sampleEnergy(const SimSetup& s, SimData& d);

// sim/cuts.cpp
void ensureCutter(const SimSetup& s, SimData& d);  // the cut engine, made on first use
// Before anything may change the topology: the driver's hook (Simulation::setBeforeTopologyChange).
inline void beforeTopologyChange(SimData& d) {
    if (d.beforeTopologyChange) d.beforeTopologyChange();
}
// The one path after any cut: local estimator update, the exact limit, the step policy, contact
// points and the drawn surface, and a report entry under `key`. A blade step (`bladeStep`) may
// defer the exact step and the surface to its stroke's end.
void respondToCut(const SimSetup& s, SimData& d, const CutResult& r, const std::string& key, bool bladeStep);
void refreshSurface(const SimSetup& s, SimData& d);  // the surface and contact points, for the cuts since
void settleExact(const SimSetup& s, SimData& d);     // the exact step a stroke deferred
// The surface to draw (Simulation::surface), split for the cuts since it was last asked for.
const EmbeddedSurface* drawnSurface(const SimSetup& s, SimData& d);

// sim/blades.cpp
bool applyBlades(const SimSetup& s, SimData& d);  // the cut stage's blade sweeps; false: a cut stopped the run
void endStroke(const SimSetup& s, SimData& d);    // the open stroke ends (nothing when none is open)

// sim/toughness_stage.cpp (material.toughness)
void setupToughness(SimSetup& s, SimData& d);  // at load
bool toughSweep(SimData& d, const ToolDef& tool, double t, BladeEdge& from, BladeEdge& to);
void reseedFront(SimData& d, const ToolDef& tool, double t);
Eigen::Vector3d recordFront(const SimSetup& s, SimData& d, double t0, const ContactStep& st);
nlohmann::json toughnessReport(const SimSetup& s, const SimData& d);

// sim/report.cpp: report.json of the run so far
nlohmann::json runReport(const SimSetup& s, const SimData& d, const nlohmann::json& extra);
std::uint64_t stateHash(const State& st);  // 64-bit FNV-1a of x and v
int runThreads(const SimData& d);          // the threads the step runs on

}  // namespace cutsim
