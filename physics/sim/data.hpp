// Everything a run changes (as mjData): the object and its state, the step and its limits, the
// contact world, the cut engine and its bookkeeping, the drawn surface, the checks' counters, the
// record, the status and what drivers did (the take's events). The stages (sim/stages.hpp) read
// SimSetup (sim/setup.hpp) and change this; Simulation (sim/simulation.hpp) holds the two.
#pragma once

#include "contact/contact.hpp"
#include "cut/toughness.hpp"
#include "cut/xfem.hpp"
#include "fem/integrate.hpp"
#include "mesh/broadphase.hpp"
#include "mesh/embedding.hpp"
#include "sim/record.hpp"
#include "sim/scene.hpp"
#include "sim/step_policy.hpp"
#include "sim/take_log.hpp"
#include "sim/thread_tuner.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/cut_response.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace cutsim {

// The status of a run (the cutsim program maps it to its exit code: app/exit_code.hpp).
enum class RunStatus : std::uint8_t { Running, Finished, Diverged, Refused };
const char* runStatusName(RunStatus s);  // running | ok | diverged | refused

// An element a cut made critical that the step floor, the hybrid or the step chosen again
// answered, with the time of that cut (Simulation::answered).
struct AnsweredElement {
    int element;
    double time;  // [s]
};

// The open blade stroke's costs so far, for report.json "strokes".
struct StrokeLog {
    int tool = -1;
    double start = 0;             // [s]
    StageTimes stages;            // the run's stage times when the stroke began
    long steps = 0;               // the run's steps then
    std::vector<double> latency;  // each blade step's cut latency [s]
};

struct SimData {
    // the object
    Model model;
    State state;

    // the step: the policy (the scene's until a driver sets another), its choice at the current limits
    Integrator integrator = Integrator::SymplecticEuler;
    StepPolicy policy;
    Stepper stepper;
    StepOptions stepOptions;
    TimestepAnalyzer analyzer;
    StepLimits limits;  // current limits (exact NaN: unknown)
    StepChoice choice;
    Eigen::VectorXd alphaElem;              // per-element damping (on_limit damp), else empty
    int critical = 0;                       // elements under capture.critical_factor x the step
    std::vector<AnsweredElement> answered;  // kept capture.answered_seconds
    CutResponse response;                   // the after-cut update, and the exact step a stroke owes

    // contact
    std::unique_ptr<ContactWorld> contact;
    std::vector<int> projected;  // nodes the last projection moved (repairInverted)
    std::vector<int> dropped;    // scratch: nodes whose contact points a blade step drops

    // the surfaces the cuts change (Simulation::surface brings `surface` up to date when asked)
    std::unique_ptr<EmbeddedSurface> surface;  // drawn surface after cuts
    bool visualStale = false;                  // surface lags the cuts of SimSetup::visual
    bool drawnStale = false;                   // surface lags blade steps (no visual)
    bool surfaceStale = false;                 // contact points lag blade steps (refreshSurface)
    double surfaceTime = 0;                    // when the contact points were last rebuilt [s]
    int topologyVersion = 0;

    // cutting
    std::unique_ptr<CutEngine> cutter;
    size_t nextCut = 0;  // the next scripted cut (scene cutting.cuts)
    int lastCutId = -1;
    std::unique_ptr<ElementBroadphase> bladePhase;
    std::vector<BladeEdge> lastEdge;  // each blade's edge at the end of the last step
    std::vector<int> candidates;      // scratch: elements a blade's sweep may meet
    int stroke = -1;                  // blade whose stroke the engine holds, or -1
    StrokeLog strokeLog;
    std::vector<ContactWorld::Slot> slots;        // each blade's slot (cutting.blade_slot), by tool index
    std::vector<ContactWorld::Slot> slotsBefore;  // ... as its earlier strokes left it
    std::unique_ptr<BladeToughness> tough;        // material.toughness > 0 with a blade, else null
    double toughDamped = 0;                       // energy the last step's mass damping took [J]

    // the checks
    double energyRef = 0;   // total energy the growth is measured from [J]
    int invertedRun = 0;    // consecutive steps over bounds.invertedElements
    double nextSample = 0;  // time of the next energy sample [s]

    // the run
    RunStatus status = RunStatus::Running;
    std::string message;  // why the run stopped, or ""
    RunRecord record;
    TakeLog take;                                // what drivers did, for the take
    std::unique_ptr<ThreadTuner> tuner;          // threads chosen by measuring, else null
    std::function<void()> beforeTopologyChange;  // the driver's hook (Simulation::setBeforeTopologyChange)
};

}  // namespace cutsim
