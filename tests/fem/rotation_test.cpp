// Element rotations (fem/rotation.cpp): the invertible-FEM branch.
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "fem/kinematics.hpp"
#include "test_support.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace cutsim;

// The rotation of an inverted F is the invertible-FEM one (Irving et al. 2004): a proper rotation
// with R^T F symmetric (a stationary point of tr(R^T F)) whose one negative eigenvalue is the
// smallest in magnitude (the maximum, not one of the saddles where a larger one is negated).
// Mueller's iteration from the identity missed this for about 40% of random inverted F.
TEST(Forces, InvertedRotationIsTheInvertibleFemOne) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 500; ++k) {
        Eigen::Matrix3d F;
        for (int i = 0; i < 9; ++i) F(i % 3, i / 3) = u(rng);
        if (F.determinant() > 0) F.col(0) *= -1;
        const Eigen::Matrix3d R = extractRotation(F, Eigen::Matrix3d::Identity());
        EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12);
        EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
        const Eigen::Matrix3d S = R.transpose() * F;
        ASSERT_LT((S - S.transpose()).norm(), 1e-9 * F.norm()) << "not stationary, F =\n" << F;
        const Eigen::Vector3d ev =
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(0.5 * (S + S.transpose())).eigenvalues();
        EXPECT_LT(ev[0], 0);  // ascending: det F < 0 leaves exactly one negative
        EXPECT_GT(ev[1], 0);
        EXPECT_LE(-ev[0], ev[1] + 1e-12) << "a saddle of tr(R^T F), F =\n" << F;
    }
}
