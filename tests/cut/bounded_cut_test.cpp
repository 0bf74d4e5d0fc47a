// Bounded conforming cut (ConformingOptions::limits, cut/conforming.hpp): the notch of the accuracy
// bench. Counts of duplicated nodes on lattices where they follow by hand, volume, and that the
// crack opens under a pull while the part below its front holds.
#include "cut/conforming.hpp"
#include "fem/model.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <vector>

namespace cutsim {
namespace {

using Key = std::array<long long, 3>;

// Rest position rounded to 1e-9, to find the copies of a node.
Key keyOf(const TetMesh& m, int i) {
    return {std::llround(1e9 * m.X(0, i)), std::llround(1e9 * m.X(1, i)), std::llround(1e9 * m.X(2, i))};
}

// Nodes of m at each position.
std::map<Key, std::vector<int>> copies(const TetMesh& m) {
    std::map<Key, std::vector<int>> c;
    for (int i = 0; i < m.nodes(); ++i) c[keyOf(m, i)].push_back(i);
    return c;
}

// The notch cut at x = xc with its front at z = 0.5: every tet positive, the nodes on the plane
// above the front in two copies and every other node in one, `duplicated` of them, one piece.
void expectNotch(const ConformingResult& r, double xc, int duplicated) {
    for (int e = 0; e < r.mesh.elements(); ++e) ASSERT_GT(tetSignedVolume(r.mesh, e), 0) << "tet " << e;
    for (const auto& [k, ids] : copies(r.mesh)) {
        const double x = 1e-9 * static_cast<double>(k[0]), z = 1e-9 * static_cast<double>(k[2]);
        const bool open = std::abs(x - xc) < 1e-9 && z > 0.5 + 1e-9;
        EXPECT_EQ(ids.size(), open ? 2u : 1u) << "node at x " << x << " z " << z;
    }
    EXPECT_EQ(r.report.duplicatedNodes, duplicated);
    EXPECT_EQ(connectedPieces(r.mesh), 1);
}

// The notch: x = xc from z = 0.5 up, through the whole width.
ConformingOptions notchOptions(double snap) {
    ConformingOptions o;
    o.snapFraction = snap;
    o.limits = {CutPlane{Eigen::Vector3d(0, 0, 0.5), Eigen::Vector3d::UnitZ()}};
    return o;
}

// The unit box of 4x4x4 Kuhn cubes notched at x = xc.
ConformingResult notchCut(double xc, double snap) {
    return conformingCut(test::boxMesh(1, 1, 1, 4, 4, 4), CutPlane{Eigen::Vector3d(xc, 0, 0), Eigen::Vector3d::UnitX()},
                         notchOptions(snap));
}

TEST(BoundedConformingCut, LatticePlaneOpensOnlyTheNodesAboveTheFront) {
    // x = 0.5 holds a 5x5 layer of nodes; those with z in {0.75, 1} (2 rows of 5) open.
    const ConformingResult r = notchCut(0.5, 0);
    expectNotch(r, 0.5, 10);
    EXPECT_EQ(r.report.splitTets, 0);
    EXPECT_EQ(r.mesh.nodes(), 125 + 10);
    EXPECT_NEAR(r.report.volumeAfter, 1.0, 1e-12);
    // The box's 6 plus both faces of the crack, 1 x 0.5 each: a plane triangle touching an open
    // node is a boundary face on both sides (it hinges on the front).
    EXPECT_NEAR(test::boundaryArea(r.mesh), 7.0, 1e-12);
}

TEST(BoundedConformingCut, PlaneThroughCellsSplitsAllAndOpensAboveTheFront) {
    // x = 0.375 crosses the layer of cubes x in [0.25, 0.5]: each Kuhn cube's x edges, two face
    // diagonals and body diagonal cross it, so the cut points are a 9x9 grid of spacing 0.125;
    // the 4 rows with z > 0.5 (36 points) open, the row at z = 0.5 is the front.
    const ConformingResult r = notchCut(0.375, 0);
    expectNotch(r, 0.375, 36);
    EXPECT_EQ(r.report.splitTets, 6 * 16);
    EXPECT_EQ(r.report.cutPoints, 81);
    EXPECT_EQ(r.mesh.nodes(), 125 + 81 + 36);
    EXPECT_NEAR(r.report.volumeAfter, 1.0, 1e-12);
    double neg = 0;
    for (int e = 0; e < r.mesh.elements(); ++e)
        if (r.side[e] < 0) neg += tetSignedVolume(r.mesh, e);
    EXPECT_NEAR(neg, 0.375, 1e-12);
    // Limits that hold the whole plane give the infinite cut, bit for bit.
    const TetMesh box = test::boxMesh(1, 1, 1, 4, 4, 4);
    const CutPlane p{Eigen::Vector3d(0.375, 0, 0), Eigen::Vector3d::UnitX()};
    ConformingOptions all;
    all.snapFraction = 0;
    const ConformingResult inf = conformingCut(box, p, all);
    all.limits = {CutPlane{Eigen::Vector3d(0, 0, -1), Eigen::Vector3d::UnitZ()}};
    const ConformingResult wide = conformingCut(box, p, all);
    EXPECT_EQ(wide.mesh.X, inf.mesh.X);
    EXPECT_EQ(wide.mesh.tets, inf.mesh.tets);
    EXPECT_EQ(connectedPieces(wide.mesh), 2);
}

TEST(BoundedConformingCut, NodesSnappedOutsideTheLimitsStayShared) {
    // x = 0.27 snaps the layer x = 0.25 (25 nodes, as for the infinite plane); only its nodes
    // above the front open.
    const ConformingResult r = notchCut(0.27, 0.1);
    expectNotch(r, 0.27, 10);
    EXPECT_EQ(r.report.snappedNodes, 25);
    EXPECT_EQ(r.report.splitTets, 0);
}

TEST(BoundedConformingCut, CrackOpensUnderAPullAndTheFrontHolds) {
    // Clamped at x = 0, the end x = 1 pulled along +x (linear statics): the far side of the notch
    // moves away from the near side above the front, more at the top; the front's nodes are shared.
    const ConformingResult r = notchCut(0.375, 0);
    Model m = buildModel(r.mesh, Material{});
    test::fixBelow(m, 0, 1e-9);
    int nf = 0;
    const std::vector<int> map = freeDofMap(m, &nf);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(freeStiffness(m, map, nf));
    ASSERT_EQ(ldlt.info(), Eigen::Success);  // one piece held by the clamp: no free motion
    Eigen::VectorXd f = Eigen::VectorXd::Zero(nf);
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) > 1 - 1e-9) f(map[3 * i]) = 1.0;
    const Eigen::VectorXd u = ldlt.solve(f);
    // Gap across the crack at each position: the positive side's node minus the negative side's copy.
    std::vector<std::uint8_t> onNeg(static_cast<size_t>(m.nodes()), 0);
    for (int e = 0; e < m.elements(); ++e)
        if (r.side[e] < 0)
            for (int a = 0; a < 4; ++a) onNeg[m.tets(a, e)] = 1;
    double gapTop = 0, gapLow = 0;
    for (const auto& [k, ids] : copies(r.mesh)) {
        if (ids.size() != 2) continue;
        const int pos = onNeg[ids[0]] ? ids[1] : ids[0], neg = onNeg[ids[0]] ? ids[0] : ids[1];
        ASSERT_FALSE(onNeg[pos]);
        const double gap = u(map[3 * pos]) - u(map[3 * neg]);
        EXPECT_GT(gap, 0) << "closed at z " << r.mesh.X(2, pos);
        if (r.mesh.X(2, pos) > 1 - 1e-9) gapTop = std::max(gapTop, gap);
        if (std::abs(r.mesh.X(2, pos) - 0.625) < 1e-9) gapLow = std::max(gapLow, gap);
    }
    EXPECT_GT(gapTop, 2 * gapLow);
    EXPECT_EQ(connectedPieces(r.mesh), 1);
}

TEST(BoundedConformingCut, RejectsOneSideAndZeroLimits) {
    const TetMesh box = test::boxMesh(1, 1, 1, 2, 2, 2);
    const CutPlane p{Eigen::Vector3d(0.3, 0, 0), Eigen::Vector3d::UnitX()};
    ConformingOptions o = notchOptions(0);
    o.keep = KeepSide::Positive;
    EXPECT_THROW(conformingCut(box, p, o), InputError);
    o = notchOptions(0);
    o.limits[0].normal.setZero();
    EXPECT_THROW(conformingCut(box, p, o), InputError);
}

}  // namespace
}  // namespace cutsim
