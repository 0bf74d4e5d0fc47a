#include "timestep/modes.hpp"

#include "timestep/timestep.hpp"

#include <Spectra/MatOp/SparseSymShiftSolve.h>
#include <Spectra/SymEigsShiftSolver.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace cutsim {

Modes lowestModes(const Model& m, int k) {
    Modes out;
    int nf = 0;
    out.dofMap = freeDofMap(m, &nf);
    const Eigen::SparseMatrix<double> A = scaledFreeStiffness(m, out.dofMap, nf);
    // Shift-invert about 0: the largest magnitudes of A^-1 are A's smallest eigenvalues.
    Spectra::SparseSymShiftSolve<double> op(A);
    const int ncv = std::min(nf, std::max(2 * k + 1, k == 1 ? 12 : 20));
    Spectra::SymEigsShiftSolver<Spectra::SparseSymShiftSolve<double>> eigs(op, k, ncv, 0.0);
    eigs.init();
    computeEigs(eigs, "lowest modes", Spectra::SortRule::LargestMagn, 1000, 1e-10);
    if (eigs.info() != Spectra::CompInfo::Successful)
        throw EigenSolveError("lowest modes: Lanczos did not converge for " + std::to_string(k) + " modes (" +
                              std::to_string(nf) + " free DOFs)");
    // Spectra returns the shift-inverted order (largest 1/lambda first): lambda ascending.
    out.lambda = eigs.eigenvalues();
    out.vectors = eigs.eigenvectors();
    return out;
}

double lowestFrequency(const Model& m) { return std::sqrt(lowestModes(m, 1).lambda(0)) / (2 * M_PI); }

}  // namespace cutsim
