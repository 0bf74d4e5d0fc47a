// Exact critical step: Lanczos (Spectra) on M^-1/2 K M^-1/2 over the free DOFs (eq. 3.10).
#include "timestep/timestep.hpp"

#include <Spectra/SymEigsSolver.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace cutsim {

// ---- exact lambda_max: Lanczos on M^-1/2 K M^-1/2 over the free DOFs ----

namespace {

// The scaled operator (ScaledStiffness); y = A x in parallel over rows.
struct ScaledStiffnessOp {
    using Scalar = double;
    const ScaledStiffness& s;

    Eigen::Index rows() const { return s.dofs(); }
    Eigen::Index cols() const { return s.dofs(); }
    void perform_op(const double* x, double* y) const {
        const int nr = static_cast<int>(s.rowStart.size()) - 1;
#pragma omp parallel for schedule(static) if (nr > 4000)
        for (int r = 0; r < nr; ++r) {
            Eigen::Vector3d acc = Eigen::Vector3d::Zero();
            for (int k = s.rowStart[r]; k < s.rowStart[r + 1]; ++k)
                acc.noalias() += Eigen::Map<const Eigen::Matrix3d>(s.val.data() + 9 * k) *
                                 Eigen::Map<const Eigen::Vector3d>(x + 3 * s.col[k]);
            Eigen::Map<Eigen::Vector3d>(y + 3 * r) = acc;
        }
    }
};

// The operator over the free nodes (invMass > 0) of m, listed in freeNodes.
void buildScaledOp(const Model& m, const StiffnessRows& rows, ScaledStiffness& op, std::vector<int>& freeNodes) {
    // Free nodes get compact indices; fixed DOFs are removed from the eigenproblem.
    std::vector<int> compact(m.nodes(), -1);
    freeNodes.clear();
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0) {
            compact[i] = static_cast<int>(freeNodes.size());
            freeNodes.push_back(i);
        }
    const int nf = static_cast<int>(freeNodes.size());
    op.rowStart.assign(nf + 1, 0);
    for (int r = 0; r < nf; ++r) {
        int cnt = 0;
        for (int j : rows.nbr[freeNodes[r]]) cnt += compact[j] >= 0;
        op.rowStart[r + 1] = op.rowStart[r] + cnt;
    }
    op.col.resize(op.rowStart[nf]);
    op.val.resize(9 * static_cast<size_t>(op.rowStart[nf]));
#pragma omp parallel for schedule(static) if (nf > 4000)
    for (int r = 0; r < nf; ++r) {
        const int i = freeNodes[r];
        const double si = std::sqrt(m.invMass(i));
        int k = op.rowStart[r];
        for (size_t q = 0; q < rows.nbr[i].size(); ++q) {
            const int j = rows.nbr[i][q];
            if (compact[j] < 0) continue;
            op.col[k] = compact[j];
            Eigen::Map<Eigen::Matrix3d>(op.val.data() + 9 * k) = si * std::sqrt(m.invMass(j)) * rows.block[i][q];
            ++k;
        }
    }
}

}  // namespace

ExactResult exactCriticalDt(const Model& m, const StiffnessRows& rows, const ExactOptions& opts) {
    ScaledStiffness op;
    std::vector<int> freeNodes;
    buildScaledOp(m, rows, op, freeNodes);
    return exactCriticalDt(op, opts);
}

ExactResult exactCriticalDt(const ScaledStiffness& s, const ExactOptions& opts) {
    ScaledStiffnessOp op{s};
    ExactResult res;
    res.freeDofs = s.dofs();
    if (res.freeDofs == 0) {
        res.dt = dtFromLambda(0);
        return res;
    }
    // Largest algebraic eigenvalue (eq. 3.10). Spectra needs nev < ncv <= n.
    const int ncv = std::min(std::max(opts.ncv, 3), res.freeDofs);
    Spectra::SymEigsSolver<ScaledStiffnessOp> eigs(op, 1, ncv);
    eigs.init();
    computeEigs(eigs, "exact time step", Spectra::SortRule::LargestAlge, opts.maxIterations, opts.tol);
    res.iterations = static_cast<int>(eigs.num_iterations());
    res.matvecs = static_cast<int>(eigs.num_operations());
    if (eigs.info() != Spectra::CompInfo::Successful)
        throw EigenSolveError("exact time step: Lanczos did not converge after " + std::to_string(res.iterations) +
                              " restarts (" + std::to_string(res.freeDofs) + " free DOFs)");
    res.lambdaMax = eigs.eigenvalues()(0);
    res.dt = dtFromLambda(res.lambdaMax);
    return res;
}

ExactResult exactCriticalDt(const Model& m, const ExactOptions& opts) {
    return exactCriticalDt(m, assembleStiffnessRows(m), opts);
}

namespace {

// The k largest eigenpairs of M^-1/2 K M^-1/2 (descending), to relative tolerance tol.
struct TopModes {
    Eigen::VectorXd lambda;
    Eigen::MatrixXd y;           // unit eigenvectors over the free DOFs
    std::vector<int> freeNodes;  // node of each block of 3 DOFs
};
TopModes topModes(const Model& m, const StiffnessRows& rows, int k, int ncvMin, double tol, int maxIterations) {
    ScaledStiffness s;
    TopModes t;
    buildScaledOp(m, rows, s, t.freeNodes);
    ScaledStiffnessOp op{s};
    const int n = s.dofs();
    if (n == 0) return t;
    k = std::clamp(k, 1, n - 1);  // n >= 3: one free node
    const int ncv = std::min(std::max(2 * k + 8, ncvMin), n);
    Spectra::SymEigsSolver<ScaledStiffnessOp> eigs(op, k, ncv);
    eigs.init();
    computeEigs(eigs, "keep step", Spectra::SortRule::LargestAlge, maxIterations, tol);
    if (eigs.info() != Spectra::CompInfo::Successful)
        throw EigenSolveError("keep step: Lanczos did not converge for the " + std::to_string(k) + " largest modes (" +
                              std::to_string(n) + " free DOFs)");
    t.lambda = eigs.eigenvalues();
    t.y = eigs.eigenvectors();
    return t;
}

}  // namespace

KeepStepResult keepStep(Model& m, double dtTarget, const KeepStepOptions& opts) {
    return keepStep(m, assembleStiffnessRows(m), dtTarget, opts);
}

KeepStepResult keepStep(Model& m, const StiffnessRows& rows, double dtTarget, const KeepStepOptions& opts) {
    if (!(dtTarget > 0) || !std::isfinite(dtTarget))
        throw std::invalid_argument("keepStep: target step must be positive and finite");
    KeepStepResult res;
    res.dtTarget = dtTarget;
    const double lamTarget = 4 / (dtTarget * dtTarget), lamAim = lamTarget * (1 - opts.margin);
    // At the target to the solver's tolerance: rounding must not add mass to the lattice itself.
    const double lamAbove = lamTarget * (1 + opts.exact.tol);
    if (m.addedMass.size() != m.nodes()) m.addedMass = Eigen::VectorXd::Zero(m.nodes());
    const Eigen::VectorXd addedBefore = m.addedMass;
    double freeMass = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0) freeMass += m.mass(i);

    // The exact step before, to full tolerance; most models (the lattice itself) stop here.
    auto exactTop = [&] {
        ++res.rounds;
        return exactCriticalDt(m, rows, opts.exact).lambdaMax;
    };
    double lamTop = exactTop();
    res.dtBefore = dtFromLambda(lamTop);
    // Rounds find the modes above loosely (a Ritz value never exceeds the true one, so a loose
    // solve can only miss a mode just above); once none shows, a full-tolerance solve decides,
    // and if it still finds the step short, the rounds go on at full tolerance.
    double roundTol = std::max(opts.roundTol, opts.exact.tol);
    int k = std::max(opts.modes, 1);
    bool stale = false;  // masses changed since lamTop was solved for
    while (lamTop > lamAbove && res.rounds < opts.maxRounds) {
        const TopModes t = topModes(m, rows, k, opts.exact.ncv, roundTol, opts.exact.maxIterations);
        ++res.rounds;
        if (t.lambda.size() == 0) break;
        int above = 0;
        for (int j = 0; j < t.lambda.size(); ++j) above += t.lambda(j) > lamAbove;
        if (above == 0) {
            lamTop = exactTop();
            stale = false;
            roundTol = opts.exact.tol;
            continue;
        }
        // More modes per round while all of those found are above (a cluster at the boundary).
        if (above == t.lambda.size()) k = std::min(2 * k, opts.maxModes);
        // Each mode above the target is slowed to the aim (its Rayleigh quotient, see the header).
        // A node takes the most any of them asks, not the sum: enough for each, and modes
        // sharing nodes are not paid for twice.
        const int nf = static_cast<int>(t.freeNodes.size());
        Eigen::VectorXd dm = Eigen::VectorXd::Zero(nf), w(nf);
        for (int j = 0; j < t.lambda.size(); ++j) {
            if (t.lambda(j) <= lamAbove) continue;
            for (int r = 0; r < nf; ++r) w(r) = t.y.col(j).segment<3>(3 * r).squaredNorm();
            const double beta = (t.lambda(j) / lamAim - 1) / w.squaredNorm();
            for (int r = 0; r < nf; ++r) dm(r) = std::max(dm(r), beta * m.mass(t.freeNodes[r]) * w(r));
        }
        for (int r = 0; r < nf; ++r) m.addedMass(t.freeNodes[r]) += dm(r);
        updateMasses(m);
        stale = true;
    }
    if (stale) lamTop = exactTop();  // out of rounds right after scaling: what the step is now
    res.dtAfter = dtFromLambda(lamTop);
    res.reached = lamTop <= lamAbove;
    for (int i = 0; i < m.nodes(); ++i) {
        const double d = m.addedMass(i) - addedBefore(i);
        res.addedMass += d;
        res.nodes += d > 0;
    }
    res.massFraction = freeMass > 0 ? res.addedMass / freeMass : 0;
    return res;
}

}  // namespace cutsim
