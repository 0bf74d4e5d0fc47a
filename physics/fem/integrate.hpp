// Time integration. The stages of one step, in this order (the force and integrate stages of
// Simulation::step, sim/simulation.hpp):
//   1. contact   (tools; applied as fExt by the caller before step())
//   2. forces    computeForces: node loads, element stage adding into each thread's own nodes,
//                then the nodes two threads share
//   3. integrate velocity and position update of the chosen scheme; fixed nodes stay put
//                (symplectic Euler and central difference: inside the force stage's parallel
//                region, on each thread's nodes once summed; fem/forces.hpp NodeUpdate)
//   4. checks    stretch limiting when asked; non-finite values and inverted elements into state.flags
#pragma once

#include "fem/shape_matching.hpp"
#include "fem/state.hpp"

#include <memory>
#include <string>
#include <vector>

namespace cutsim {

enum class Integrator {
    SymplecticEuler,    // v += dt a(x); x += dt v                         (docs/method.md sec. 2)
    CentralDifference,  // half-step velocities, centred damping            (docs/method.md sec. 2)
    Newmark,            // explicit Newmark beta=0, gamma=1/2, damping factor alpha (eqs. 3.11-3.12)
    BackwardEuler,      // implicit reference, linearised corotational (solver: ImplicitSolver)
};

// The linear solver of each backward-Euler step.
enum class ImplicitSolver {
    Direct,             // sparse LDL^T (Eigen's simplicial, AMD ordering), refactorised every step
    ConjugateGradient,  // Jacobi-preconditioned CG warm-started from the current velocity; cheap
                        // where dt^2 K is small against M, dear where it dominates (measured in
                        // `cutsim bench accuracy`)
};

ImplicitSolver parseImplicitSolver(const std::string& name);  // "direct" or "cg"; throws InputError
const char* implicitSolverName(ImplicitSolver s);

Integrator parseIntegrator(const std::string& name);  // throws InputError on an unknown name
const char* integratorName(Integrator i);

struct StepOptions {
    Integrator integrator = Integrator::SymplecticEuler;
    double dt = 1e-4;                            // time step [s]
    double alpha = 1.0;                          // Newmark's global damping factor on the acceleration, (0, 1]
    const Eigen::VectorXd* alphaElem = nullptr;  // per-element factor alpha_e (nElems), scales element
                                                 // forces; (dt_crit_e / dt)^2 where dt > dt_crit_e (eq. 3.16)
    double minStretch = 0;                       // > 0: project elements whose smallest principal stretch is
                                                 // below it back to it after the position update
                                                 // (fem/forces.hpp limitStretch); 0: off
    // With minStretch on, the elements that carry only part of their volume (fraction < 1: cut
    // pieces, mesh-intersection interface elements) are held at kPartialMinStretch or minStretch,
    // the larger: their far control points lie outside their material and weigh a share of a
    // node, so a piece squeezed to a fifth of its size by the stress it inherited, or by a blade,
    // inverts and is thrown out by the corotational force (docs/method.md, Cutting at any size).
    bool holdPartial = true;
    ImplicitSolver solver = ImplicitSolver::Direct;  // backward Euler only
    double cgTolerance = 1e-9;                       // CG: relative residual |A v - b| / |b| to stop at
};

// The force stage watches for elements whose smallest stretch may be within this margin above
// minStretch, so that the limiting pass runs only in steps that can need it.
inline constexpr double kStretchWatchMargin = 0.3;
// The least stretch of a partial element when stretch limiting is on (StepOptions::holdPartial).
inline constexpr double kPartialMinStretch = 0.5;

// Per-element damping factors for a step dt from per-element critical steps (thesis eq. 3.16).
Eigen::VectorXd elementAlpha(const Eigen::VectorXd& dtCritElem, double dt);

struct NodeUpdate;         // fem/forces.hpp
struct ImplicitWorkspace;  // sparse pattern and factorisation of the backward-Euler system

// Advances a state by one step. Owns the implicit workspace when the scheme needs one;
// call reset() after a topology change.
class Stepper {
public:
    Stepper();
    ~Stepper();
    Stepper(Stepper&&) noexcept;
    Stepper& operator=(Stepper&&) noexcept;

    void step(const Model& model, State& state, const StepOptions& opt);
    void reset();
    // Wall time of the force stage (element forces and gather) in the last step [s]; a node
    // update run inside it counts as integration.
    double lastForceSeconds() const { return forceSeconds_; }
    // CG iterations of the last backward-Euler step (0 for the direct solver or other schemes).
    int lastSolverIterations() const;
    // After a contact projection that moved `nodes` (sorted): the elements around them that it
    // left inverted are limited back (limitStretch from those elements), so that the stretch limit
    // holds after the projection as after the position update, and an inversion is not carried
    // into the next step, where the limiter and the contact would meet it again. A projection
    // moves a point's lighter nodes the most: a cut's light control points, and the nodes of an
    // MI lattice below a surface pressed onto a floor, which were pushed up past the nodes above
    // them (docs/method.md, Contact). Nothing when stretch limiting is off or no such element is
    // inverted. Returns the elements corrected.
    int repairInverted(const Model& model, State& state, const StepOptions& opt, const std::vector<int>& nodes);

private:
    void forces(const Model& model, State& state, const double* alpha, double watch, bool allRotations = false,
                NodeUpdate* update = nullptr);
    void limit(const Model& model, State& state, const StepOptions& opt, int nearFlat);

    std::unique_ptr<ImplicitWorkspace> implicit_;
    double forceSeconds_ = 0;
    std::vector<int> limitScratch_;  // elements below the smallest stretch (reused)
    std::vector<int> repairSeeds_;   // inverted elements around the nodes a projection moved (reused)
    Eigen::Matrix3Xd lightMean_;     // mean velocity around each of Model::lightNodes at the step's start [m/s]
    ShapeMatchScratch match_;        // hybrid elements' shape matching (Model::matched)
    Eigen::VectorXd matchAlpha_;     // per-element force factor with the matched elements at 0
    const double* forceFactors(const Model& m, const double* alpha);
    void lightMeans(const Model& m, const State& s);
    void dampLight(const Model& m, State& s, double dt) const;
    double partialStretch(const Model& m, const StepOptions& opt) const;
};

// Checks positions and velocities for non-finite values (state.flags.nonFinite).
void checkFinite(const Model& model, State& state);

}  // namespace cutsim
