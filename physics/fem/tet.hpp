// Geometry and stiffness of one linear tetrahedron (docs/method.md sec. 1, thesis eqs. 2.20-2.30, 4.3-4.10).
#pragma once

#include "fem/material.hpp"

#include <Eigen/Core>
#include <Eigen/LU>

namespace cutsim {

using Mat34 = Eigen::Matrix<double, 3, 4>;
using Mat12 = Eigen::Matrix<double, 12, 12>;
using Vec12 = Eigen::Matrix<double, 12, 1>;

// Rest shape matrix Dm = [X1-X0, X2-X0, X3-X0] of the 4 nodes given as columns.
Eigen::Matrix3d restShapeMatrix(const Mat34& X);

// Shape gradients g_a = grad N_a as columns; rows of Dm^-1 give g_1..g_3, g_0 = -(g_1+g_2+g_3).
Mat34 shapeGradients(const Eigen::Matrix3d& DmInv);

// Element stiffness, block (a,b) = V [lambda g_a g_b^T + mu g_b g_a^T + mu (g_a.g_b) I].
// DOF order: node a, axis i -> 3a + i.
Mat12 elementStiffness(const Mat34& g, double volume, const Material& mat);

// Diagonal of the element stiffness without forming it (eqs. 4.3-4.10):
// K_aa,xx = V [Ehat g_ax^2 + mu (g_ay^2 + g_az^2)].
Vec12 elementStiffnessDiagonal(const Mat34& g, double volume, const Material& mat);

}  // namespace cutsim
