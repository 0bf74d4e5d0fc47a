// Internal forces of linear and corotational tets (docs/method.md sec. 1, thesis eq. 2.41).
// Hot loops are free functions over an index range: gather, compute, scatter into the nodes the
// thread alone touches (computeForces); no locks, no atomics.
#pragma once

#include "fem/kinematics.hpp"
#include "fem/state.hpp"

#include <vector>

namespace cutsim {

// Elastic force of elements [begin, end) into state.fe; alpha (nullable, nElems) scales each
// element's force (per-element damping factor alpha_e, thesis eq. 3.16). Counts inverted elements
// into *inverted and into *nearFlat (nullable) those whose smallest principal stretch may be below
// watch (its lower bound 2 det F / |F|^2 is). Updates state.rot of every element (corotational).
void elementForces(const Model& model, State& state, const double* alpha, int begin, int end, int* inverted,
                   double watch = 0, int* nearFlat = nullptr);

// Nodal force of nodes [begin, end): sum of incident element forces + gravity + fExt.
void gatherForces(const Model& model, State& state, int begin, int end);

// The nodal forces state.f (elastic + gravity + fExt) of all elements on all threads, bitwise the
// same on any number of threads: each node sums its elements in element order, as gatherForces
// after elementForces would (which is what it does on small meshes; on large ones the kernel adds
// into the nodes a thread alone touches, forces.cpp kFusedElements). Fills state.flags.inverted (and .nearFlat:
// elements whose smallest principal stretch may be below watch). state.rot is updated for every element with
// allRotations (the implicit tangent needs it), else only for elements near flat, the ones whose
// rotation is read back (forces.cpp, kKeepRotation); state.fe is scratch.
// times (nullable) accumulates the wall time of its phases.
struct ForceStageSeconds {
    double elements = 0;  // element kernel, adding into the nodes of one thread
    double nodes = 0;     // outside the kernel: below kFusedElements the gather; above, each
                          // node's load and shared flag before and the shared nodes' sums after
    double update = 0;    // a NodeUpdate: the first thread's clock from its update to the region's end
};
// Whether node i's position or velocity has a non-finite component.
inline bool nonFiniteNode(const State& s, int i) { return !s.x.col(i).allFinite() || !s.v.col(i).allFinite(); }

// An explicit velocity and position update run by computeForces inside its parallel region, on
// each thread's nodes once their forces are summed (one fork and join and one pass over the
// nodes fewer than a loop of its own): v <- (a v + (h w) f) b, x <- x + dt v for a free node of
// inverse mass w; v <- 0 for a prescribed one. nonFinite counts the nodes whose x or v is then
// not finite.
struct NodeUpdate {
    double a = 1, h = 0, b = 1, dt = 0;
    int nonFinite = 0;
};
void computeForces(const Model& model, State& state, const double* alpha = nullptr, double watch = 0,
                   bool allRotations = false, ForceStageSeconds* times = nullptr, NodeUpdate* update = nullptr);

// Stretch limiting (strain limiting on the principal stretches by projection, as Thomaszewski,
// Pabst, Strasser 2009 do for cloth): each element whose smallest principal stretch sigma3 is
// below sMin at the current positions is moved back to sigma3 = sMin along the gradient of sigma3
// (an inverted one first along the gradient of det F), Gauss-Seidel over those elements, then
// over the elements around the moved nodes that a correction pushed below; the closing rate is
// removed from the velocities (an inelastic stop). Prescribed nodes do not move; a free element
// with equal node masses keeps its momentum and centre of mass. Returns the most elements
// corrected in a round. Serial: it runs only in steps where the force stage saw an element that
// may be below its watch stretch.
// sMinPartial > sMin: the bound of the elements with fraction < 1 (StepOptions::holdPartial). Every
// element is held below kMaxStretch too.
// seeds: the first round looks at these elements only, not at every element's watch mark.
int limitStretch(const Model& model, State& state, double sMin, std::vector<int>& scratch, double sMinPartial = 0,
                 const std::vector<int>* seeds = nullptr);

// The largest principal stretch of any element while stretch limiting is on (limitStretch): a
// light node pulled far out (a cut's or a lattice's control point, a node of tiny elements)
// stiffens its elements' twist modes by lambda (tr S - 3) 2 / (s_i + s_j) (the corotated energy's
// Hessian), past what the step allows, and is thrown further out each step (docs/method.md,
// "Cutting finer objects"). The force stage flags |F|^2 above its square, an upper bound of the
// largest stretch's.
inline constexpr double kMaxStretch = 2.0;

// Quasi-static relaxation of `nodes` with the other nodes held: `iterations` Gauss-Seidel sweeps,
// each node moved by K_aa^-1 f_a (its corotated diagonal stiffness block from its elements against
// their corotational force; thesis eq. 2.14 restricted to one node), at most a quarter of its
// smallest incident element's size per move. Velocities are kept. Used on the fresh control points
// of a cut, which inherit the stress of the element they came from.
void relaxNodes(const Model& model, State& state, const std::vector<int>& nodes, int iterations);

// Elastic energy 1/2 V (lambda tr(e)^2 + 2 mu e:e) with e = sym(R^T F) - I [J].
double elasticEnergy(const Model& model, const State& state);
// 1/2 sum m v^2 [J] (free nodes).
double kineticEnergy(const Model& model, const State& state);
// -sum m g.x [J].
double gravityEnergy(const Model& model, const State& state);
// The three above summed [J].
double totalEnergy(const Model& model, const State& state);

// Number of threads used by the parallel loops (0 = all cores).
void setThreads(int n);
int threads();

// Von Mises stress of each element from the corotated linear stress (nElems) [Pa].
Eigen::VectorXd vonMisesStress(const Model& model, const State& state);
}  // namespace cutsim
