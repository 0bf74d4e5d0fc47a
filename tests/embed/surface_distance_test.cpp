// The Hausdorff distance between surfaces (mesh/surface_distance.hpp) on nested cubes, whose
// distances follow from the geometry.
#include "embed/surface_distance.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cutsim {
namespace {

// The surface of the cube [-h, h]^3, outward.
SurfaceMesh cube(double h) {
    SurfaceMesh s;
    s.V.resize(3, 8);
    for (int i = 0; i < 8; ++i) s.V.col(i) = Eigen::Vector3d(i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h);
    s.F.resize(3, 12);
    s.F << 0, 0, 1, 1, 0, 0, 2, 2, 0, 0, 4, 4,  //
        6, 4, 3, 7, 1, 5, 7, 6, 3, 2, 5, 7,     //
        2, 6, 7, 5, 5, 4, 3, 7, 1, 3, 7, 6;
    return s;
}

// A cube of half-edge 0.5 inside one of 0.55: every point of the inner one lies 0.05 or more from the
// outer faces, at most 0.05 (the face centres); the outer corners lie 0.05 sqrt(3) from the inner
// corners, the farthest. Each bound is at most spacing / sqrt(3) above the exact value.
TEST(SurfaceDistance, NestedCubes) {
    const SurfaceMesh a = cube(0.5), b = cube(0.55);
    const double spacing = 0.01, slack = spacing / std::sqrt(3.0);
    const double inner = farthestDistance(a, b, spacing), outer = farthestDistance(b, a, spacing);
    EXPECT_GE(inner, 0.05 - 1e-12);
    EXPECT_LE(inner, 0.05 + slack);
    EXPECT_GE(outer, 0.05 * std::sqrt(3.0) - 1e-12);
    EXPECT_LE(outer, 0.05 * std::sqrt(3.0) + slack);
    EXPECT_DOUBLE_EQ(hausdorffDistance(a, b, spacing), std::max(inner, outer));
    EXPECT_LE(farthestDistance(a, a, spacing), slack);
}

// Points at distances from the cube [-0.5, 0.5]^3 that the geometry gives: its centre 0.5 from
// every face, a point past a face, past an edge and past a corner, and one on a face.
TEST(SurfaceDistance, PointDistancesToACube) {
    const SurfaceMesh c = cube(0.5);
    Eigen::Matrix3Xd p(3, 5);
    p << 0, 1, 1, 1, 0.5,  //
        0, 0, 1, 1, 0.2,   //
        0, 0, 0, 1, -0.1;
    const std::vector<double> d = pointDistances(p, c);
    ASSERT_EQ(d.size(), 5u);
    EXPECT_NEAR(d[0], 0.5, 1e-12);
    EXPECT_NEAR(d[1], 0.5, 1e-12);
    EXPECT_NEAR(d[2], 0.5 * std::sqrt(2.0), 1e-12);
    EXPECT_NEAR(d[3], 0.5 * std::sqrt(3.0), 1e-12);
    EXPECT_NEAR(d[4], 0, 1e-12);
}

}  // namespace
}  // namespace cutsim
