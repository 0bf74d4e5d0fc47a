#include "mesh/generate.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <numeric>
#include <random>
#include <set>
#include <vector>

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

namespace {
// Nodes used both by elements [0, n/2) and by elements [n/2, n): what two threads' halves share.
int sharedByHalves(const TetMesh& m) {
    std::vector<int> side(static_cast<size_t>(m.nodes()), 0);
    const int half = m.elements() / 2;
    for (int e = 0; e < m.elements(); ++e)
        for (int k = 0; k < 4; ++k) side[static_cast<size_t>(m.tets(k, e))] |= e < half ? 1 : 2;
    return static_cast<int>(std::count(side.begin(), side.end(), 3));
}
}  // namespace

// spatialOrder renumbers a shuffled 12^3-cube box (10,368 tets): the same tets on the same points,
// each with its orientation, the node ids following their nodes; and the two halves of its
// elements (the Z-order's first bit: the mid-plane) share the 13 x 13 nodes of that plane, where
// the shuffled order's halves share nearly all 2,197.
TEST(BoxMesh, SpatialOrderIsAPermutationThatHalvesShareLittleOf) {
    TetMesh box = test::boxMesh(1.0, 1.0, 1.0, 12, 12, 12);
    std::mt19937 rng(3);
    std::vector<int> perm(static_cast<size_t>(box.nodes())), order(static_cast<size_t>(box.elements()));
    std::iota(perm.begin(), perm.end(), 0);
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::shuffle(order.begin(), order.end(), rng);
    TetMesh shuffled;
    shuffled.X.resize(3, box.nodes());
    shuffled.tets.resize(4, box.elements());
    shuffled.nodeIds.resize(static_cast<size_t>(box.nodes()));
    for (int i = 0; i < box.nodes(); ++i) {
        shuffled.X.col(perm[static_cast<size_t>(i)]) = box.X.col(i);
        shuffled.nodeIds[static_cast<size_t>(perm[static_cast<size_t>(i)])] = 1000 + i;
    }
    for (int e = 0; e < box.elements(); ++e)
        for (int k = 0; k < 4; ++k)
            shuffled.tets(k, e) = perm[static_cast<size_t>(box.tets(k, order[static_cast<size_t>(e)]))];

    const TetMesh m = spatialOrder(shuffled);
    ASSERT_EQ(m.nodes(), box.nodes());
    ASSERT_EQ(m.elements(), box.elements());
    // the same tets: each as its four corner points, in its corner order (orientation kept)
    auto corners = [](const TetMesh& t) {
        std::multiset<std::array<double, 12>> s;
        for (int e = 0; e < t.elements(); ++e) {
            std::array<double, 12> c{};
            for (int k = 0; k < 4; ++k)
                for (int d = 0; d < 3; ++d) c[static_cast<size_t>(3 * k + d)] = t.X(d, t.tets(k, e));
            s.insert(c);
        }
        return s;
    };
    EXPECT_TRUE(corners(m) == corners(box));
    for (int i = 0; i < m.nodes(); ++i) {  // id 1000 + i was box node i
        const int was = static_cast<int>(m.nodeIds[static_cast<size_t>(i)]) - 1000;
        EXPECT_EQ(m.X.col(i), box.X.col(was)) << i;
    }
    for (int e = 0; e < m.elements(); ++e) EXPECT_GT(tetSignedVolume(m, e), 0);
    const int before = sharedByHalves(shuffled), after = sharedByHalves(m);
    EXPECT_GT(before, 2000);
    EXPECT_EQ(after, 13 * 13);
    // deterministic
    const TetMesh again = spatialOrder(shuffled);
    EXPECT_TRUE(again.tets == m.tets && again.X == m.X);
}
