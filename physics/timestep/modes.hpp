// The lowest vibration modes of a model: shift-invert Lanczos (Spectra) on M^-1/2 K M^-1/2 over
// the free DOFs, for natural frequencies (the accuracy benchmarks, a scene's slowest motion).
#pragma once

#include "fem/model.hpp"

#include <Eigen/Core>

#include <vector>

namespace cutsim {

struct Modes {
    Eigen::VectorXd lambda;   // the k lowest eigenvalues of M^-1/2 K M^-1/2, ascending (k) [1/s^2]
    Eigen::MatrixXd vectors;  // their eigenvectors over the free DOFs (nFree x k), M^1/2-scaled displacements
    std::vector<int> dofMap;  // global DOF 3i+c -> row of vectors, or -1 (freeDofMap)
};

// The k lowest modes of the rest stiffness with the lumped mass. Throws EigenSolveError when
// Lanczos does not converge.
Modes lowestModes(const Model& m, int k);

// The lowest natural frequency sqrt(lambda_1) / 2 pi [Hz].
double lowestFrequency(const Model& m);

}  // namespace cutsim
