#include "test_support.hpp"

#include <gtest/gtest.h>

using namespace cutsim;

// The generated box is conforming and exact: volume and boundary area follow from its size.
TEST(BoxMesh, VolumeAndBoundary) {
    const TetMesh m = test::boxMesh(1.0, 2.0, 3.0, 2, 3, 4);
    EXPECT_EQ(m.nodes(), 3 * 4 * 5);
    EXPECT_EQ(m.elements(), 6 * 2 * 3 * 4);
    EXPECT_NEAR(totalVolume(m), 6.0, 1e-12);
    for (int e = 0; e < m.elements(); ++e) EXPECT_GT(tetSignedVolume(m, e), 0);
    const Eigen::Matrix3Xi F = boundaryFaces(m);
    // 2 triangles per boundary square: 2*(2*3 + 3*4 + 2*4) squares
    EXPECT_EQ(F.cols(), 2 * 2 * (6 + 12 + 8));
    SurfaceMesh s{m.X, F, "box"};
    EXPECT_NEAR(enclosedVolume(s), 6.0, 1e-12);
}
