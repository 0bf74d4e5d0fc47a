// The changing part of a simulation: positions, velocities, forces, per-element rotations.
#pragma once

#include "fem/model.hpp"

#include <Eigen/Core>

#include <vector>

namespace cutsim {

// Numerical trouble seen in the last step, which the run reports and acts on. Reset at every step.
struct StepFlags {
    int nonFinite = 0;       // nodes with a non-finite position or velocity
    int inverted = 0;        // elements with det F <= 0
    int firstInverted = -1;  // one inverted element, for messages
    int nearFlat = 0;        // elements whose smallest stretch may be below the watch (stretch limiting)
    int limited = 0;         // elements the step projected back to its smallest stretch
    bool ok() const { return nonFinite == 0 && inverted == 0; }
};

struct State {
    Eigen::Matrix3Xd x;     // current positions (3 x nNodes) [m]
    Eigen::Matrix3Xd v;     // velocities (3 x nNodes) [m/s]; at half steps for central differences
    Eigen::Matrix3Xd f;     // total nodal force of the last evaluation (3 x nNodes) [N]
    Eigen::Matrix3Xd a;     // acceleration from f, Newmark's a_n (3 x nNodes) [m/s^2]
    Eigen::Matrix3Xd fExt;  // applied nodal forces, besides gravity (3 x nNodes) [N]
    Eigen::Matrix<double, 9, Eigen::Dynamic> rot;  // element rotation R of the last force evaluation,
                                                   // column-major 3x3 (9 x nElems, more after cuts:
                                                   // capacity); warm start for inverted elements
    Eigen::Matrix<double, 12, Eigen::Dynamic> fe;  // elastic force per element and local node (12 x nElems,
                                                   // more after cuts) [N]:
                                                   // all of it after elementForces; scratch of computeForces, which
                                                   // on large meshes fills only the slots of nodes two threads share
    std::vector<unsigned char> sharedNode;         // scratch of computeForces: node's elements span two ranges
    std::vector<unsigned char> nearFlat;           // computeForces with a watch: each element's bound of its
                                                   // smallest stretch in 1/255 (0 also: stretched long), which
                                                   // limitStretch compares with its own watch (nElems)
    double time = 0;                               // simulated time [s]
    long steps = 0;                                // steps taken
    bool started = false;                          // integrator history (a, half-step v) initialised
    StepFlags flags;
};

// A state at rest in the model's rest shape.
State makeState(const Model& model);

// Resizes per-element arrays after the model's elements changed (new elements start unrotated).
void resizeState(const Model& model, State& state);

// Room for `elements` elements in the widest per-element arrays (Model::DmInv, State::rot and
// State::fe: 240 bytes an element), which a cut grows by a quarter at a time: without room, a
// blade step that appends a few elements now and then reallocates and moves them whole, the
// slowest part of a cut on a fine mesh. Never shrinks them.
void reserveElements(Model& model, State& state, Eigen::Index elements);

}  // namespace cutsim
