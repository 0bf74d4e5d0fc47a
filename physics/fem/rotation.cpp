// Element rotations: polar decomposition by Newton's iteration, the invertible-FEM SVD otherwise.
#include "fem/kinematics.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <cmath>

namespace cutsim {

// Rotation of an inverted or degenerate F by the diagonalisation of Irving, Teran, Fedkiw 2004,
// "Invertible finite elements for robust simulation of large deformation" (sec. 4): F = U S V^T
// with U, V proper rotations and the smallest singular value negated when det F < 0. R = U V^T is
// then the rotation maximising tr(R^T F), R^T F = V S V^T is symmetric, and the linear stress of
// S - I pushes an inverted element back through its flat state. When the two smallest singular
// values tie, either may take the sign; the choice nearest the last rotation keeps R continuous.
Eigen::Matrix3d invertibleRotation(const Eigen::Matrix3d& F, const Eigen::Matrix3d& Rprev) {
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d U = svd.matrixU();
    const Eigen::Matrix3d& V = svd.matrixV();
    if ((U * V.transpose()).determinant() > 0) return U * V.transpose();
    // det(U V^T) = -1: negate the column of the smallest singular value (sorted descending)
    const Eigen::Vector3d sv = svd.singularValues();
    U.col(2) = -U.col(2);
    Eigen::Matrix3d R = U * V.transpose();
    if (sv[1] - sv[2] <= 1e-9 * sv[0]) {
        U.col(2) = -U.col(2);
        U.col(1) = -U.col(1);
        const Eigen::Matrix3d R2 = U * V.transpose();
        if ((R2 - Rprev).squaredNorm() < (R - Rprev).squaredNorm()) R = R2;
    }
    return R;
}

namespace {

// extractRotation with det F already known (the force loop needs it for the inverted count).
inline Eigen::Matrix3d polarRotation(const Eigen::Matrix3d& F, double detF, const Eigen::Matrix3d& Rprev) {
    // Newton needs det F well away from 0: its first step divides by it.
    const double scale = F.squaredNorm() / 3.0;
    if (!(detF > 1e-6 * scale * std::sqrt(scale))) return invertibleRotation(F, Rprev);
    Eigen::Matrix3d X = F;
    for (int it = 0; it < 30; ++it) {
        // X^-T = cof(X) / det X, with the cofactor columns as cross products of X's columns
        Eigen::Matrix3d C;
        C.col(0) = X.col(1).cross(X.col(2));
        C.col(1) = X.col(2).cross(X.col(0));
        C.col(2) = X.col(0).cross(X.col(1));
        const double halfInvDet = 0.5 / X.col(0).dot(C.col(0));
        const Eigen::Matrix3d Xn = 0.5 * X + halfInvDet * C;
        const double d = (Xn - X).squaredNorm();
        X = Xn;
        if (d < 1e-12) break;  // quadratic convergence: the error of X is now ~d/2 <= 1e-12
    }
    return X;
}

}  // namespace

Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& F, const Eigen::Matrix3d& Rprev) {
    return polarRotation(F, F.determinant(), Rprev);
}

}  // namespace cutsim
