// A floor under the stable step through topology changes (docs/method.md sec. 5.3): local
// selective mass scaling on the reduced-one-ring problems of the elements a change touched.
//
// A cut leaves small pieces and thin bridges of tissue whose modes are nearly those of isolated
// elements, up to ~8x the uncut lambda_max on the liver. Each R1R problem (Fierz et al. 2012) is
// a principal submatrix of M^-1/2 K M^-1/2, so its largest eigenvalue bounds lambda_max from
// below and the largest of them sits within ~1% of it; bringing every re-estimated element's R1R
// eigenvalue under the floor's lambda costs 12x12 eigenpairs around the change, no global solve.
// Mass goes where the top R1R mode lives, as keepStep does with global modes: a node takes
// beta m_i w_i, w_i = |y at node i|^2 of the unit symmetric mode y, which brings that mode's
// Rayleigh quotient lambda / (1 + beta sum w_i^2) exactly to the aim.
#pragma once

#include "fem/model.hpp"
#include "timestep/analyzer.hpp"

#include <vector>

namespace cutsim {

struct StepFloorOptions {
    // Each R1R lambda is brought to lambda_floor (1 - margin): the global lambda_max lies above
    // the largest R1R one (within ~1% on the shipped meshes, a few percent next to a cut). [-]
    double margin = 0.03;
    // lambda_max over the largest R1R lambda of the uncut model (>= 1): how far the one-ring
    // problems sit under the global one on this mesh (1.01 on the liver; more on a regular lattice,
    // whose top mode spans many elements in phase). Each R1R lambda aims that much lower. [-]
    double coherence = 1;
    int maxSweeps = 24;  // rounds of scaling and local re-estimation
};

struct StepFloorResult {
    double dtFloor = 0;    // the step held [s]
    double addedMass = 0;  // mass added by this call [kg]
    int nodes = 0;         // nodes given mass
    int elements = 0;      // elements whose R1R step was under the aim before scaling
    int sweeps = 0;        // rounds of scaling
    bool reached = false;  // every re-estimated element's R1R step is at the aim
    double seconds = 0;    // wall time, re-estimation included [s]
};

// Call right after ta.update(m, ...) for a change: scans the elements that update re-estimated
// (ta.lastElements()) and adds mass (m.addedMass, m.mass, m.invMass) until each one's R1R step
// reaches dtFloor / sqrt(1 - margin), keeping ta current. Nothing is added when none is under.
StepFloorResult holdStepFloor(Model& m, TimestepAnalyzer& ta, double dtFloor, const StepFloorOptions& opts = {});

// The floor certified without a solve: every node of `nodes` (those whose Gershgorin row a change
// may have raised: ta.lastNodes() after the change's update) is given the mass that brings its row of M^-1/2 K M^-1/2
// under 4 / dtAim^2. With s = m_i^-1/2 the row is s^2 D_c + s O_c in each component c (D: |K_ii| row sums, O: the sum
// of s_j |K_ij| over the neighbours), so the mass is 1 / s^2 at the positive root of s^2 D + s O = lambda. Mass at node
// i only lowers its neighbours' rows, so one pass holds them all: the certified step (Gershgorin) is >= dtAim wherever
// the change reached. ta is kept current. In the result, `elements` counts the rows that were over the aim.
StepFloorResult holdCertifiedFloor(Model& m, TimestepAnalyzer& ta, double dtAim, const std::vector<int>& nodes);

// The floor certified: holdStepFloor, then the exact step (Lanczos to its tolerance); when that
// is still under dtFloor, keepStep tops the mass up with global modes until it is not. ta is kept
// current. Throws EigenSolveError when an eigen-solve fails.
struct CertifiedFloorResult {
    StepFloorResult local;
    KeepStepResult topUp;   // dtBefore: the exact step after the local scaling
    bool toppedUp = false;  // the local scaling was not enough
    double dtExact = 0;     // exact step at the end [s]
    double seconds = 0;     // wall time, all of it [s]
};
// The certification alone: the exact step, and keepStep's global top-up when it is under dtFloor;
// ta is updated at the nodes given mass. dtAfter is the exact step at the end.
KeepStepResult topUpStepFloor(Model& m, TimestepAnalyzer& ta, double dtFloor, const KeepStepOptions& keep = {});

CertifiedFloorResult holdStepFloorCertified(Model& m, TimestepAnalyzer& ta, double dtFloor,
                                            const StepFloorOptions& opts = {}, const KeepStepOptions& keep = {});

// Top eigenpair of element e's R1R problem in symmetric form (unit y, 12 entries, zero at fixed DOFs).
double r1rTopMode(const Model& m, const StiffnessRows& rows, int e, Eigen::Matrix<double, 12, 1>& y);

}  // namespace cutsim
