// Kinematics of one element: its deformation gradient and the rotation of its polar decomposition.
#pragma once

#include "fem/state.hpp"

#include <Eigen/Core>

namespace cutsim {

// F = Ds DmInv of element e at the current positions.
inline Eigen::Matrix3d deformationGradient(const Model& m, const State& s, int e) {
    const int* n = m.tets.col(e).data();
    const Eigen::Vector3d x0 = s.x.col(n[0]);
    Eigen::Matrix3d Ds;
    Ds << s.x.col(n[1]) - x0, s.x.col(n[2]) - x0, s.x.col(n[3]) - x0;
    return Ds * m.dmInv(e);
}

// Rotation of the polar decomposition F = R S. Newton's iteration X <- (X + X^-T) / 2 (Higham
// 1986) converges quadratically for det F > 0; a degenerate or inverted F goes to the SVD of
// invertible FEM (Irving, Teran, Fedkiw 2004): the proper rotation maximising tr(R^T F), with
// Rprev deciding a tie between two equal smallest singular values.
Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& F, const Eigen::Matrix3d& Rprev);

// The SVD branch alone (an inverted or degenerate F), for the force kernel's slow path.
Eigen::Matrix3d invertibleRotation(const Eigen::Matrix3d& F, const Eigen::Matrix3d& Rprev);

}  // namespace cutsim
