// What a run compiles once, at load, and never changes after (as mjModel): the scene, the options,
// the node sets and tool indices the stages look up, the rest surfaces, the bounds its checks
// hold it to, and what the set-up found for the report. What the step changes is SimData's
// (sim/data.hpp); Simulation (sim/simulation.hpp) holds the two.
#pragma once

#include "fem/model.hpp"
#include "mesh/embedding.hpp"
#include "mesh/mesh.hpp"
#include "sim/record.hpp"
#include "sim/scene.hpp"
#include "sim/step_policy.hpp"

#include <nlohmann/json.hpp>

#include <memory>
#include <vector>

namespace cutsim {

struct SimulationOptions {
    int threads = 0;             // worker threads; 0: chosen by measuring (ThreadTuner)
    bool renderSurface = false;  // keep Simulation::surface() current after cuts (drivers that draw)
};

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

struct SimSetup {
    SceneDef scene;  // as read; the step policy a driver sets later is SimData's
    SimulationOptions options;

    // the object
    std::vector<std::vector<int>> loadNodes;          // nodes of each scene load (scene.forces order)
    std::unique_ptr<const EmbeddedSurface> embedded;  // an MI object's surface in the uncut lattice, else null
    double latticeStep = 0;                           // MI: the lattice's shortest cell edge [m]
    std::unique_ptr<const EmbeddedSurface> visual;    // object.visual in the uncut mesh, else null
    std::vector<int> inputNode, inputElement;         // object.reorder: file index of each node and element
    TetMesh rest;                                     // the uncut rest mesh, for cutting.compare

    // the step and its checks
    StepLimits initial;  // of the uncut object
    DivergenceBounds bounds;
    bool energyChecked = false;  // no tool or force does work

    // contact and cutting
    ContactSettings contact;
    std::vector<int> bladeTools;  // scene tools that cut
    double bladeMargin = 0;       // fattening of the blade broad phase's element boxes [m]
    double toughStart[3] = {};    // material.toughness: elastic, kinetic, gravity energy at the start [J]

    // for the report (null: not used)
    nlohmann::json embedding;     // MI set-up (null: a tet mesh object)
    nlohmann::json visualReport;  // object.visual
    nlohmann::json improvement;   // object.improve
    nlohmann::json tetra;         // object.tetra
    nlohmann::json hybrid;        // object.element "hybrid" on load
};

}  // namespace cutsim
