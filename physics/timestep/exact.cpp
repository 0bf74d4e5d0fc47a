// Exact critical step: Lanczos (Spectra) on M^-1/2 K M^-1/2 over the free DOFs (eq. 3.10).
#include "timestep/timestep.hpp"

#include <Spectra/SymEigsSolver.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace cutsim {

// ---- exact lambda_max: Lanczos on M^-1/2 K M^-1/2 over the free DOFs ----

namespace {

// The scaled operator as a block CSR over the free nodes; y = A x in parallel over rows.
struct ScaledStiffnessOp {
    using Scalar = double;
    std::vector<int> rowStart, col;  // block CSR over free nodes
    std::vector<double> val;         // 9 per block, column-major
    Eigen::Index n = 0;              // 3 * free nodes

    Eigen::Index rows() const { return n; }
    Eigen::Index cols() const { return n; }
    void perform_op(const double* x, double* y) const {
        const int nr = static_cast<int>(rowStart.size()) - 1;
#pragma omp parallel for schedule(static) if (nr > 4000)
        for (int r = 0; r < nr; ++r) {
            Eigen::Vector3d acc = Eigen::Vector3d::Zero();
            for (int k = rowStart[r]; k < rowStart[r + 1]; ++k)
                acc.noalias() += Eigen::Map<const Eigen::Matrix3d>(val.data() + 9 * k) *
                                 Eigen::Map<const Eigen::Vector3d>(x + 3 * col[k]);
            Eigen::Map<Eigen::Vector3d>(y + 3 * r) = acc;
        }
    }
};

} // namespace

ExactResult exactCriticalDt(const Model& m, const StiffnessRows& rows, const ExactOptions& opts) {
    // Free nodes get compact indices; fixed DOFs are removed from the eigenproblem.
    std::vector<int> compact(m.nodes(), -1);
    std::vector<int> freeNodes;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0) {
            compact[i] = static_cast<int>(freeNodes.size());
            freeNodes.push_back(i);
        }
    ExactResult res;
    const int nf = static_cast<int>(freeNodes.size());
    res.freeDofs = 3 * nf;
    if (nf == 0) {
        res.dt = dtFromLambda(0);
        return res;
    }
    ScaledStiffnessOp op;
    op.n = 3 * nf;
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
    // Largest algebraic eigenvalue (eq. 3.10). Spectra needs nev < ncv <= n.
    const int ncv = std::min<int>(std::max(opts.ncv, 3), op.n);
    Spectra::SymEigsSolver<ScaledStiffnessOp> eigs(op, 1, ncv);
    eigs.init();
    eigs.compute(Spectra::SortRule::LargestAlge, opts.maxIterations, opts.tol);
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

} // namespace cutsim
