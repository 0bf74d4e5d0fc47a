// Stable time step of explicit FEM (docs/method.md sec. 2-3, thesis ch. 3-4): the exact global value,
// a certified lower bound and the per-element estimators. Times in seconds, lambdas in 1/s^2.
#pragma once

#include "fem/model.hpp"
#include "fem/tet.hpp"

#include <Eigen/Core>

#include <stdexcept>
#include <string>
#include <vector>

namespace cutsim {

// The global eigen-solve did not converge: reported, never replaced by a guess.
class EigenSolveError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Runs a Spectra solver's compute; Spectra's own failures (a tridiagonal eigen-decomposition that
// fails on entries out of range) become EigenSolveError naming `what`.
template <class Solver, class... Args>
void computeEigs(Solver& eigs, const char* what, Args... args) {
    try {
        eigs.compute(args...);
    } catch (const std::runtime_error& e) {
        throw EigenSolveError(std::string(what) + ": " + e.what() +
                              " (stiffness or mass entries out of range: check coordinates and material)");
    }
}

// Critical step of central differences / symplectic Euler, eq. 3.10 with c = 2; +inf if lambda <= 0.
double dtFromLambda(double lambda);

// Assembled stiffness by node rows of 3x3 blocks (each element scaled by its fraction).
// Rows are independent, so one can be rebuilt after a local change.
struct StiffnessRows {
    std::vector<std::vector<int>> nbr;                // nodes coupled to node i, i first (nNodes)
    std::vector<std::vector<Eigen::Matrix3d>> block;  // K_ij for j = nbr[i][k] [N/m] (nNodes)
};

// Row i of K from the elements incident to node i (model.nodeSlots).
void assembleStiffnessRow(const Model& m, int i, std::vector<int>& nbr, std::vector<Eigen::Matrix3d>& block);
StiffnessRows assembleStiffnessRows(const Model& m);

// Diagonal of K at node i via eqs. 4.3-4.10 summed over the one-ring, no 12x12 matrices.
Eigen::Vector3d nodeStiffnessDiagonal(const Model& m, int i);
Eigen::Matrix3Xd assembleStiffnessDiagonal(const Model& m);  // (3 x nNodes) [N/m]

// Exact lambda_max(M^-1 K) over the free DOFs (invMass > 0), via Lanczos (Spectra) on the symmetric
// form M^-1/2 K M^-1/2. Throws EigenSolveError when it does not converge.
struct ExactOptions {
    double tol = 1e-9;         // Spectra's relative residual tolerance
    int maxIterations = 2000;  // restarts
    int ncv = 24;              // Lanczos basis size
};
struct ExactResult {
    double lambdaMax = 0;  // [1/s^2]
    double dt = 0;         // 2 / sqrt(lambdaMax) [s]
    int freeDofs = 0;
    int iterations = 0;  // Lanczos restarts
    int matvecs = 0;     // operator applications
};
ExactResult exactCriticalDt(const Model& m, const StiffnessRows& rows, const ExactOptions& opts = {});
ExactResult exactCriticalDt(const Model& m, const ExactOptions& opts = {});
// M^-1/2 K M^-1/2 over the free nodes as a block CSR: row r's blocks are k in
// [rowStart[r], rowStart[r + 1]), of free node col[k], 9 doubles column-major at val[9 k].
struct ScaledStiffness {
    std::vector<int> rowStart, col;
    std::vector<double> val;
    int dofs() const { return rowStart.empty() ? 0 : 3 * (static_cast<int>(rowStart.size()) - 1); }
};
// The same from such an operator, for a caller that keeps its own rows (the mesh improver).
ExactResult exactCriticalDt(const ScaledStiffness& op, const ExactOptions& opts = {});

// Selective mass scaling to a target step, as explicit codes hold their step: mass is added to the
// nodes of every mode above lambda_target = (2 / dtTarget)^2 until the exact step reaches dtTarget
// (model.addedMass). Per round, mode y_j (unit, of M^-1/2 K M^-1/2) asks node i for
// beta_j m_i w_i, w_i = |y_j at node i|^2, which brings its Rayleigh quotient
// lambda_j / (1 + beta_j sum w_i^2) exactly to the aim just under the target; a node takes the
// most any mode asks. The modes' shapes shift a little, so rounds repeat until none is above.
// Used to make an MI embedding keep the step of its lattice.
struct KeepStepOptions {
    int modes = 8;           // top eigenpairs handled per round, doubled while all are above
    int maxModes = 64;       // up to this many
    double roundTol = 1e-6;  // Lanczos tolerance of the rounds; the step is decided at exact.tol
    int maxRounds = 60;      // eigen-solves at most
    double margin = 1e-4;    // once scaling, aim at lambda_target (1 - margin): the modes slowed
                             // gather there, and a cluster just under the top would stall the
                             // full-tolerance Lanczos. Nothing is added when the step already
                             // reaches the target to exact.tol (relative in lambda) [-]
    ExactOptions exact;
};
struct KeepStepResult {
    double dtTarget = 0;      // [s]
    double dtBefore = 0;      // exact step before [s]
    double dtAfter = 0;       // exact step after [s]
    double addedMass = 0;     // mass added this call [kg]
    double massFraction = 0;  // addedMass over the free nodes' mass before [-]
    int nodes = 0;            // nodes that were given mass
    int rounds = 0;           // eigen-solves
    bool reached = false;     // dtAfter >= dtTarget, to the eigen-solver's tolerance (exact.tol in lambda)
};
// Throws EigenSolveError when an eigen-solve fails; leaves the model scaled as far as it got
// (reached = false) when maxRounds is not enough.
KeepStepResult keepStep(Model& m, double dtTarget, const KeepStepOptions& opts = {});
// The same with the model's assembled rows at hand (K does not change, only M).
KeepStepResult keepStep(Model& m, const StiffnessRows& rows, double dtTarget, const KeepStepOptions& opts = {});

// Gershgorin bound on row i of M^-1/2 K M^-1/2 (max over its 3 free DOFs; 0 for a fixed node):
// sum_j |K_ij| / sqrt(m_i m_j), free j only. max_i of it bounds lambda_max from above.
double gershgorinNodeBound(const Model& m, const StiffnessRows& rows, int i);
// Certified step 2 / sqrt(max_i bound_i) <= exact dt (not in the thesis; docs/method.md sec. 3).
double certifiedDt(const Model& m, const StiffnessRows& rows);
double certifiedDt(const Model& m);

// Largest eigenvalue of a symmetric 12x12 matrix (Householder tridiagonalisation, then Laguerre
// iterations from the Gershgorin bound; accurate to ~1e-14 relative).
double largestEigenvalue(const Mat12& A);
// The same for A[0 .. n-1], 8 at a time on vector lanes (the estimators' path); equal to
// largestEigenvalue to rounding.
void largestEigenvalues(const Mat12* A, int n, double* lambda);
// The same for up to 8 matrices stored interleaved, a[8 (12 i + j) + l] = A_l(i, j); count of
// them in use, the other lanes finite. Saves a caller that assembles them the copy.
void largestEigenvaluesInterleaved(const double* a, int count, double* lambda);

// Per-element estimates of the critical step [s] (docs/method.md sec. 3; +inf when nothing is free).
struct ElementEstimates {
    Eigen::VectorXd r1r;      // reduced one ring, Fierz et al. 2012
    Eigen::VectorXd hs;       // scalar heuristic, 2 / sqrt(max D_r)
    Eigen::VectorXd hp;       // position heuristic
    Eigen::VectorXd le;       // characteristic length over P-wave speed
    Eigen::VectorXd element;  // isolated element eigenvalue, own masses
    void resize(int n);
};

// lambda_max(M_r^-1 K_r) of element e from the assembled rows; fixed DOFs dropped.
double r1rLambda(const Model& m, const StiffnessRows& rows, int e);
// The same for elems[0 .. n-1] into lambda, 8 elements at a time on vector lanes.
void r1rLambdas(const Model& m, const StiffnessRows& rows, const int* elems, int n, double* lambda);
// Hs and Hp lambdas from D_r = diag(K_r) / M_r (diag: assembleStiffnessDiagonal).
double hsLambda(const Model& m, const Eigen::Matrix3Xd& diag, int e);
double hpLambda(const Model& m, const Eigen::Matrix3Xd& diag, int e);
// lambda_max(M_e^-1 K_e), masses rho V / 4 (fraction cancels); fixed DOFs dropped.
double elementLambda(const Model& m, int e);
void elementLambdas(const Model& m, const int* elems, int n, double* lambda);  // as r1rLambdas
// Le = 3 V / largest face area of the rest element [m].
double characteristicLength(const Model& m, int e);

// R1R, Hs and Hp of elems[0 .. n-1] (what the assembled one-ring changes), serially.
void estimateOneRing(const Model& m, const StiffnessRows& rows, const Eigen::Matrix3Xd& diag, const int* elems, int n,
                     ElementEstimates& out);
// Le and the element eigenvalue of elems[0 .. n-1] (what only the element itself changes), serially.
void estimateOwn(const Model& m, const int* elems, int n, ElementEstimates& out);

// Fills the estimates of the listed elements (all when elements is null), in parallel.
void estimateElements(const Model& m, const StiffnessRows& rows, const Eigen::Matrix3Xd& diag,
                      const std::vector<int>* elements, ElementEstimates& out);
ElementEstimates estimateElements(const Model& m);

}  // namespace cutsim
