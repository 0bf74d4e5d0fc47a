// A visual surface carried by a tet mesh (embed/visual.hpp): weights by hand in the unit tet,
// affine deformations followed exactly inside and outside, the nearest element outside.
#include "embed/visual.hpp"
#include "mesh/generate.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>

namespace cutsim {
namespace {

// Three vertices: inside the unit tet, outside it below its z = 0 face, and a triangle of them.
SurfaceMesh threePoints() {
    SurfaceMesh s;
    s.V.resize(3, 4);
    s.V.col(0) << 0.1, 0.2, 0.3;     // inside: weights (1 - 0.6, 0.1, 0.2, 0.3)
    s.V.col(1) << 0.2, 0.2, -0.5;    // 0.5 below the face z = 0: weight of corner 3 is -0.5
    s.V.col(2) << 0.3, 0.1, 0.1;     // inside
    s.V.col(3) << 50.0, 50.0, 50.0;  // used by no triangle: dropped, not "outside"
    s.F.resize(3, 1);
    s.F << 0, 1, 2;
    return s;
}

TEST(Visual, WeightsInTheUnitTetByHand) {
    const TetMesh t = test::unitTet();
    const VisualEmbedding ve = embedVisual(threePoints(), t.tets, t.X);
    ASSERT_EQ(ve.surface.vertices(), 3);
    EXPECT_EQ(ve.outside, 1);
    EXPECT_EQ(ve.farthest, 1);
    EXPECT_NEAR(ve.maxOutside, 0.5, 1e-15);
    EXPECT_TRUE(ve.surface.weights.col(0).isApprox(Eigen::Vector4d(0.4, 0.1, 0.2, 0.3), 1e-14));
    // extrapolated, not clamped: 1 - 0.2 - 0.2 + 0.5 = 1.1 on corner 0, -0.5 on corner 3
    EXPECT_TRUE(ve.surface.weights.col(1).isApprox(Eigen::Vector4d(1.1, 0.2, 0.2, -0.5), 1e-14));
}

// Under x = A X + b every vertex, inside or outside, moves to A p + b: the embedding is affine in
// each element. Checked on a 2x2x2 box of 48 tets with a vertex in each region.
TEST(Visual, VerticesFollowAnAffineDeformationExactly) {
    const TetMesh box = boxMesh(1, 1, 1, 2, 2, 2);
    SurfaceMesh s;
    s.V.resize(3, 6);
    s.V << 0.1, 0.7, 0.45, 1.2, -0.1, 0.5,  //
        0.2, 0.6, 0.55, 0.5, 0.5, 1.05,     //
        0.3, 0.2, 0.9, 0.5, 0.9, -0.02;
    s.F.resize(3, 2);
    s.F << 0, 3, 1, 4, 2, 5;
    const VisualEmbedding ve = embedVisual(s, box.tets, box.X);
    EXPECT_EQ(ve.outside, 3);
    EXPECT_NEAR(ve.maxOutside, 0.2, 1e-12);  // vertex 3, 0.2 beyond x = 1
    Eigen::Matrix3d A;
    A << 1.2, 0.3, -0.1, 0.05, 0.8, 0.2, -0.2, 0.1, 1.1;
    const Eigen::Vector3d b(0.5, -1, 2);
    const Eigen::Matrix3Xd x = (A * box.X).colwise() + b;
    Eigen::Matrix3Xd p;
    embeddedPositions(ve.surface, box.tets, x, p);
    for (int v = 0; v < 6; ++v) EXPECT_LT((p.col(v) - (A * s.V.col(v) + b)).norm(), 1e-13) << "vertex " << v;
}

}  // namespace
}  // namespace cutsim
