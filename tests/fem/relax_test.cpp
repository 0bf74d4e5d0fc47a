// Relaxation of a cut's fresh control points (fem/relax.cpp).
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "fem/kinematics.hpp"
#include "test_support.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace cutsim;

// One free node of a clamped tet, displaced: its equilibrium is the rest position (no load), and
// one corotated Newton step on its own diagonal block finds it exactly when it moved without
// rotating the element (small moves: the block is the exact stiffness of that node).
TEST(Forces, RelaxNodesReturnsAFreeNodeToRest) {
    TetMesh t = test::unitTet();
    t.X *= 0.01;
    Model m = buildModel(t, Material{});
    fixNodes(m, {0, 1, 2});
    buildIncidence(m);
    State s = makeState(m);
    const Eigen::Vector3d d(0.0003, -0.0002, 0.0004);
    s.x.col(3) += d;
    const double e0 = elasticEnergy(m, s);
    relaxNodes(m, s, {3}, 1);
    EXPECT_LT(elasticEnergy(m, s), 0.05 * e0);  // one sweep: the rotation is not known yet
    relaxNodes(m, s, {3}, 6);
    EXPECT_LT((s.x.col(3) - m.X.col(3)).norm(), 1e-9);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(s.x.col(i), m.X.col(i));
    // a move is capped at a quarter of the element's size, and never flattens the element
    s.x.col(3) = m.X.col(3) + Eigen::Vector3d(0, 0, -0.0099);  // det F = 0.01
    relaxNodes(m, s, {3}, 1);
    EXPECT_NEAR(s.x(2, 3), m.X(2, 3) - 0.0099 + 0.25 * std::cbrt(m.volume(0)), 1e-12);
}
