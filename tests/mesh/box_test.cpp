#include "mesh/generate.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <set>

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

// Red refinement: 8 positive children per tet, same volume, coarse nodes kept with their indices,
// one new node per edge; refining the box of 1 cube twice gives the box of 4 x 4 x 4 sub-cube size.
TEST(BoxMesh, RefineTetsIntoEight) {
    const TetMesh m = test::boxMesh(1.0, 2.0, 3.0, 2, 1, 1);
    const TetMesh r = refineTets(m);
    ASSERT_EQ(r.elements(), 8 * m.elements());
    for (int e = 0; e < r.elements(); ++e) EXPECT_GT(tetSignedVolume(r, e), 0);
    EXPECT_NEAR(totalVolume(r), 6.0, 1e-12);
    EXPECT_TRUE(r.X.leftCols(m.nodes()).isApprox(m.X));
    // edges of 2 Kuhn-split cubes: 12 per cube less 4 shared, 3 face diagonals each less 1 shared, 1 body diagonal each
    const int edges = (12 + 12 - 4) + (6 + 6 - 1) + 2;
    EXPECT_EQ(r.nodes(), m.nodes() + edges);
    const Eigen::Matrix3Xi F = boundaryFaces(r);
    EXPECT_EQ(F.cols(), 4 * boundaryFaces(m).cols());  // conforming: every boundary face into 4
    SurfaceMesh s{r.X, F, "refined"};
    EXPECT_NEAR(enclosedVolume(s), 6.0, 1e-12);
    // all children of the same size class: volumes V/8 each
    for (int e = 0; e < m.elements(); ++e)
        for (int k = 0; k < 8; ++k) EXPECT_NEAR(tetSignedVolume(r, 8 * e + k), tetSignedVolume(m, e) / 8, 1e-12);
}

namespace {

// Tets as sorted node quadruples, after mapping node (i, j, k) to (i, ny - j, k) or the like.
std::set<std::array<int, 4>> reflectedTets(const TetMesh& m, int nx, int ny, int nz, int axis) {
    const int px = nx + 1, py = ny + 1, n[3] = {nx, ny, nz};
    std::set<std::array<int, 4>> out;
    for (int e = 0; e < m.elements(); ++e) {
        std::array<int, 4> q;
        for (int a = 0; a < 4; ++a) {
            int v = m.tets(a, e), c[3] = {v % px, (v / px) % py, v / (px * py)};
            if (axis >= 0) c[axis] = n[axis] - c[axis];
            q[a] = c[0] + px * (c[1] + py * c[2]);
        }
        std::sort(q.begin(), q.end());
        out.insert(q);
    }
    return out;
}

}  // namespace

// The mirrored split is conforming (its boundary is the Kuhn split's count of triangles, so no
// interior face is unmatched), positive, exact in volume, and with even counts it maps onto itself
// under the box's three mirror planes, which the Kuhn split does not.
TEST(BoxMesh, MirroredSplitIsConformingAndSymmetric) {
    const int nx = 4, ny = 2, nz = 6;
    const TetMesh m = boxMesh(1.0, 2.0, 3.0, nx, ny, nz, BoxSplit::Mirrored);
    const TetMesh kuhn = boxMesh(1.0, 2.0, 3.0, nx, ny, nz, BoxSplit::Kuhn);
    ASSERT_EQ(m.elements(), 6 * nx * ny * nz);
    for (int e = 0; e < m.elements(); ++e) EXPECT_GT(tetSignedVolume(m, e), 0);
    EXPECT_NEAR(totalVolume(m), 6.0, 1e-12);
    EXPECT_EQ(boundaryFaces(m).cols(), 2 * 2 * (nx * ny + ny * nz + nx * nz));
    const auto self = reflectedTets(m, nx, ny, nz, -1), selfKuhn = reflectedTets(kuhn, nx, ny, nz, -1);
    for (int axis = 0; axis < 3; ++axis) {
        EXPECT_EQ(reflectedTets(m, nx, ny, nz, axis), self) << "axis " << axis;
        EXPECT_NE(reflectedTets(kuhn, nx, ny, nz, axis), selfKuhn) << "axis " << axis;
    }
}
