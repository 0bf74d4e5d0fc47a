// Conforming plane cut with snapping (cut/conforming.hpp): volumes, conformity and snapping checked
// against values derivable by hand.
#include "cut/conforming.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

namespace cutsim {
namespace {

double sideVolume(const ConformingResult& r, int side) {
    double v = 0;
    for (int e = 0; e < r.mesh.elements(); ++e)
        if (r.side[e] == side) v += tetSignedVolume(r.mesh, e);
    return v;
}

// Every face is used by one or two tets, and a face used once lies on the unit box's boundary or
// on the cut plane: a hanging node would leave a face inside the box used once.
void expectConforming(const TetMesh& m, const CutPlane& p) {
    std::map<std::array<int, 3>, int> count;
    static constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    for (int e = 0; e < m.elements(); ++e)
        for (const auto& lf : kFace) {
            std::array<int, 3> f{m.tets(lf[0], e), m.tets(lf[1], e), m.tets(lf[2], e)};
            std::sort(f.begin(), f.end());
            ++count[f];
        }
    const Eigen::Vector3d n = p.normal.normalized();
    for (const auto& [f, c] : count) {
        ASSERT_LE(c, 2);
        if (c == 2) continue;
        bool onBox = false;
        for (int k = 0; k < 3 && !onBox; ++k)
            for (const double side : {0.0, 1.0}) {
                bool all = true;
                for (const int v : f) all = all && std::abs(m.X(k, v) - side) < 1e-12;
                onBox = onBox || all;
            }
        bool onPlane = true;
        for (const int v : f) onPlane = onPlane && std::abs(n.dot(m.X.col(v) - p.point)) < 1e-12;
        EXPECT_TRUE(onBox || onPlane) << "face " << f[0] << " " << f[1] << " " << f[2] << " used once inside the box";
    }
}

void expectPositive(const TetMesh& m) {
    for (int e = 0; e < m.elements(); ++e) ASSERT_GT(tetSignedVolume(m, e), 0) << "tet " << e;
}

TetMesh cornerTet() {
    TetMesh t;
    t.X.resize(3, 4);
    t.X << 0, 1, 0, 0,  //
        0, 0, 1, 0,     //
        0, 0, 0, 1;
    t.tets.resize(4, 1);
    t.tets << 0, 1, 2, 3;
    t.source = "corner";
    return t;
}

TEST(ConformingCut, AxisPlaneOnUnitBoxGivesAnalyticVolumesAndBoundary) {
    const TetMesh box = test::boxMesh(1, 1, 1, 4, 4, 4);
    const CutPlane p{Eigen::Vector3d(0.3, 0, 0), Eigen::Vector3d::UnitX()};
    ConformingOptions o;
    o.snapFraction = 0;
    const ConformingResult r = conformingCut(box, p, o);
    EXPECT_EQ(r.report.snappedNodes, 0);
    EXPECT_EQ(r.report.splitTets, 6 * 16);  // one layer of 4x4 cubes is crossed
    EXPECT_NEAR(sideVolume(r, -1), 0.3, 1e-12);
    EXPECT_NEAR(sideVolume(r, 1), 0.7, 1e-12);
    EXPECT_NEAR(r.report.volumeAfter, 1.0, 1e-12);
    EXPECT_GT(r.report.minVolume, 0);
    expectPositive(r.mesh);
    // Box boundary 6 plus the cut's two faces of area 1 each.
    EXPECT_NEAR(test::boundaryArea(r.mesh), 8.0, 1e-12);
    EXPECT_EQ(connectedPieces(r.mesh), 2);
    expectConforming(r.mesh, p);
    // Every cut point lies on the plane and is copied once for the negative side.
    EXPECT_EQ(r.report.duplicatedNodes, r.report.cutPoints);
}

TEST(ConformingCut, ObliquePlaneThroughCentreHalvesTheBoxAndStaysConforming) {
    const TetMesh box = test::boxMesh(1, 1, 1, 3, 3, 3);
    const CutPlane p{Eigen::Vector3d(0.5, 0.5, 0.5), Eigen::Vector3d(1, 2, 3).normalized()};
    ConformingOptions o;
    o.snapFraction = 0;
    const ConformingResult r = conformingCut(box, p, o);
    // Central symmetry of the cube about the plane's point: the two halves are equal.
    EXPECT_NEAR(sideVolume(r, -1), 0.5, 1e-12);
    EXPECT_NEAR(sideVolume(r, 1), 0.5, 1e-12);
    expectPositive(r.mesh);
    expectConforming(r.mesh, p);
    EXPECT_EQ(connectedPieces(r.mesh), 2);
    // Keeping one side returns exactly that side's tets.
    o.keep = KeepSide::Positive;
    const ConformingResult top = conformingCut(box, p, o);
    EXPECT_NEAR(totalVolume(top.mesh), 0.5, 1e-12);
    EXPECT_EQ(connectedPieces(top.mesh), 1);
    EXPECT_TRUE(std::all_of(top.side.begin(), top.side.end(), [](auto s) { return s == 1; }));
}

TEST(ConformingCut, OneVersusThreeSplitsIntoTetAndPrism) {
    // Plane x = 0.5 leaves node (1,0,0) alone: a corner tet of edge 0.5 and a prism of 3 tets.
    const CutPlane p{Eigen::Vector3d(0.5, 0, 0), Eigen::Vector3d::UnitX()};
    const ConformingResult r = conformingCut(cornerTet(), p);
    EXPECT_EQ(r.report.splitTets, 1);
    EXPECT_EQ(r.mesh.elements(), 4);
    EXPECT_EQ(r.report.cutPoints, 3);
    EXPECT_NEAR(sideVolume(r, 1), 0.125 / 6, 1e-15);
    EXPECT_NEAR(sideVolume(r, -1), 1.0 / 6 - 0.125 / 6, 1e-15);
    expectPositive(r.mesh);
}

TEST(ConformingCut, TwoVersusTwoSplitsIntoTwoPrisms) {
    // Plane x + y = 0.5: volume with x + y > 0.5 is int_0.5^1 u (1 - u) du = 1/12.
    const CutPlane p{Eigen::Vector3d(0.25, 0.25, 0), Eigen::Vector3d(1, 1, 0).normalized()};
    const ConformingResult r = conformingCut(cornerTet(), p);
    EXPECT_EQ(r.mesh.elements(), 6);
    EXPECT_EQ(r.report.cutPoints, 4);
    EXPECT_NEAR(sideVolume(r, 1), 1.0 / 12, 1e-15);
    EXPECT_NEAR(sideVolume(r, -1), 1.0 / 12, 1e-15);
    expectPositive(r.mesh);
}

TEST(ConformingCut, NodeOnPlaneGivesTetAndPyramid) {
    // Plane x = y holds nodes 0 and 3, nodes 1 and 2 lie on either side: one cut edge, 2 tets.
    const CutPlane p{Eigen::Vector3d::Zero(), Eigen::Vector3d(1, -1, 0).normalized()};
    const ConformingResult r = conformingCut(cornerTet(), p);
    EXPECT_EQ(r.mesh.elements(), 2);
    EXPECT_NEAR(sideVolume(r, 1), 1.0 / 12, 1e-15);
    // Plane x = (y + z) / 2 holds node 0 only; node 1 is alone on the positive side (tet + pyramid).
    const CutPlane q{Eigen::Vector3d::Zero(), Eigen::Vector3d(1, -0.5, -0.5).normalized()};
    const ConformingResult s = conformingCut(cornerTet(), q);
    EXPECT_EQ(s.mesh.elements(), 3);
    EXPECT_EQ(s.report.cutPoints, 2);
    // Positive part: tet (0, e1, cut(1,2), cut(1,3)) with cut points at 2/3 of the way to node 1.
    EXPECT_NEAR(sideVolume(s, 1), 1.0 / 6 * (2.0 / 3) * (2.0 / 3), 1e-15);
    EXPECT_NEAR(totalVolume(s.mesh), 1.0 / 6, 1e-15);
    expectPositive(s.mesh);
}

TEST(ConformingCut, SnappingMovesNodesWithinThresholdOntoThePlane) {
    // Nodes at x = 0.25 are 0.02 from the plane x = 0.27; their mean incident edge is ~0.3, so
    // 0.1 of it (> 0.02) snaps the whole layer and no tet needs splitting.
    const TetMesh box = test::boxMesh(1, 1, 1, 4, 4, 4);
    const CutPlane p{Eigen::Vector3d(0.27, 0, 0), Eigen::Vector3d::UnitX()};
    const ConformingResult r = conformingCut(box, p);
    EXPECT_EQ(r.report.snappedNodes, 25);
    EXPECT_EQ(r.report.splitTets, 0);
    EXPECT_EQ(r.report.duplicatedNodes, 25);
    int onPlane = 0;
    for (int i = 0; i < r.mesh.nodes(); ++i) {
        EXPECT_GT(std::abs(r.mesh.X(0, i) - 0.25), 1e-3) << "node " << i << " left near the plane";
        onPlane += r.mesh.X(0, i) == 0.27;
    }
    EXPECT_EQ(onPlane, 50);  // both copies, exactly on the plane
    // The layer moved as a whole: the sides are boxes again.
    EXPECT_NEAR(sideVolume(r, -1), 0.27, 1e-12);
    EXPECT_NEAR(sideVolume(r, 1), 0.73, 1e-12);
    expectPositive(r.mesh);
    EXPECT_EQ(connectedPieces(r.mesh), 2);
    // Beyond the threshold nothing snaps.
    ConformingOptions o;
    o.snapFraction = 0.05;
    EXPECT_EQ(conformingCut(box, p, o).report.snappedNodes, 0);
}

TEST(ConformingCut, SnappingCollapsesATetFlattenedIntoThePlane) {
    // Tet A has three nodes on z = 0 and its apex 0.05 above: snapping the apex flattens A into
    // the plane, which is removed; tet B below keeps its volume.
    TetMesh m;
    m.X.resize(3, 5);
    m.X << 0, 1, 0, 0.3, 0.3,  //
        0, 0, 1, 0.3, 0.3,     //
        0, 0, 0, 0.05, -1;
    m.tets.resize(4, 2);
    m.tets << 0, 0, 1, 2, 2, 1, 3, 4;
    for (int e = 0; e < 2; ++e)
        if (tetSignedVolume(m, e) < 0) std::swap(m.tets(2, e), m.tets(3, e));
    const double vb = std::abs(tetSignedVolume(m, 1));
    const ConformingResult r = conformingCut(m, CutPlane{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()});
    EXPECT_EQ(r.report.snappedNodes, 1);
    EXPECT_EQ(r.report.collapsedTets, 1);
    ASSERT_EQ(r.mesh.elements(), 1);
    EXPECT_EQ(r.side[0], -1);
    EXPECT_NEAR(tetSignedVolume(r.mesh, 0), vb, 1e-15);
}

TEST(ConformingCut, SnapThatWouldInvertATetIsRejected) {
    // Node 0 is 0.05 above z = 0 and only 0.02 above the tilted opposite face (z = -0.3 + 0.6 (x + y)
    // = 0.03 below it): projecting it onto the plane would invert the tet, so it stays and the tet
    // is split instead (1 node below vs 3 above), conserving the volume.
    TetMesh m;
    m.X.resize(3, 4);
    m.X << 0.275, 0, 1, 0,  //
        0.275, 0, 0, 1,     //
        0.05, -0.3, 0.3, 0.3;
    m.tets.resize(4, 1);
    m.tets << 0, 1, 2, 3;
    if (tetSignedVolume(m, 0) < 0) std::swap(m.tets(2, 0), m.tets(3, 0));
    const ConformingResult r = conformingCut(m, CutPlane{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()});
    EXPECT_EQ(r.report.rejectedSnaps, 1);
    EXPECT_EQ(r.report.snappedNodes, 0);
    EXPECT_EQ(r.report.splitTets, 1);
    EXPECT_EQ(r.mesh.elements(), 4);
    expectPositive(r.mesh);
    EXPECT_NEAR(totalVolume(r.mesh), totalVolume(m), 1e-15);
}

TEST(ConformingCut, SeveralPlanesInSequence) {
    const TetMesh box = test::boxMesh(1, 1, 1, 3, 3, 3);
    std::vector<CutPlane> planes;
    for (const double x : {0.2, 0.45, 0.6, 0.85})
        planes.push_back({Eigen::Vector3d(x, 0, 0), Eigen::Vector3d::UnitX()});
    ConformingOptions o;
    o.snapFraction = 0;
    const ConformingResult r = conformingCuts(box, planes, o);
    EXPECT_EQ(connectedPieces(r.mesh), 5);
    EXPECT_NEAR(r.report.volumeAfter, 1.0, 1e-12);
    EXPECT_NEAR(test::boundaryArea(r.mesh), 6.0 + 2 * 4, 1e-12);
    expectPositive(r.mesh);
    EXPECT_THROW(conformingCut(box, CutPlane{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}), InputError);
}

}  // namespace
}  // namespace cutsim
