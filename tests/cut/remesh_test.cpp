// Remeshing baseline with TetGen (cut/remesh.hpp): the remeshed piece keeps the analytic volume.
#include "cut/remesh.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cutsim {
namespace {

TEST(Remesh, BoxHalfKeepsTheAnalyticVolumeAndBoundary) {
    if (!haveTetGen()) GTEST_SKIP() << "built without TetGen";
    const TetMesh box = test::boxMesh(1, 1, 1, 3, 3, 3);
    RemeshOptions o;
    o.keep = KeepSide::Positive;
    const RemeshResult r = remeshCut(box, CutPlane{Eigen::Vector3d(0.5, 0, 0), Eigen::Vector3d::UnitX()}, o);
    EXPECT_EQ(r.report.pieces, 1);
    EXPECT_NEAR(totalVolume(r.mesh), 0.5, 1e-9);
    EXPECT_NEAR(test::boundaryArea(r.mesh), 4.0, 1e-9);  // [0.5,1] x [0,1] x [0,1]
    for (int e = 0; e < r.mesh.elements(); ++e) ASSERT_GT(tetSignedVolume(r.mesh, e), 0) << "tet " << e;
    // Six box faces reach TetGen as six polygons, not as the split triangles.
    EXPECT_EQ(r.report.facets, 6);
    for (int i = 0; i < r.mesh.nodes(); ++i) EXPECT_GE(r.mesh.X(0, i), 0.5 - 1e-12);
    // The volume bound holds: no tet above the input's mean tet volume (1/162).
    for (int e = 0; e < r.mesh.elements(); ++e) ASSERT_LE(tetSignedVolume(r.mesh, e), 1.0 / 162 * (1 + 1e-9));
}

TEST(Remesh, BothSidesAreRemeshedAsSeparatePieces) {
    if (!haveTetGen()) GTEST_SKIP() << "built without TetGen";
    const TetMesh box = test::boxMesh(1, 1, 1, 3, 3, 3);
    const CutPlane p{Eigen::Vector3d(0.5, 0.5, 0.5), Eigen::Vector3d(1, 2, 3).normalized()};
    const RemeshResult r = remeshCut(box, p);
    EXPECT_EQ(r.report.pieces, 2);
    EXPECT_EQ(connectedPieces(r.mesh), 2);
    EXPECT_NEAR(totalVolume(r.mesh), 1.0, 1e-9);
    for (int e = 0; e < r.mesh.elements(); ++e) ASSERT_GT(tetSignedVolume(r.mesh, e), 0) << "tet " << e;
    std::vector<int> piece;
    connectedPieces(r.mesh, &piece);
    double v[2] = {0, 0};
    for (int e = 0; e < r.mesh.elements(); ++e) v[piece[e]] += tetSignedVolume(r.mesh, e);
    EXPECT_NEAR(v[0], 0.5, 1e-9);  // central symmetry: equal halves
    EXPECT_NEAR(v[1], 0.5, 1e-9);
}

TEST(Remesh, SelfIntersectingPieceIsRejectedWithTetGensReason) {
    if (!haveTetGen()) GTEST_SKIP() << "built without TetGen";
    // Two tets sharing node 0 whose faces cross: their joint surface intersects itself.
    TetMesh m;
    m.X.resize(3, 7);
    m.X << 0, 1, 0, 0, 0.9, 0.3, 0.3,  //
        0, 0, 1, 0, 0.3, 0.9, 0.3,     //
        0, 0, 0, 1, 0.3, 0.3, 0.9;
    m.tets.resize(4, 2);
    m.tets << 0, 0, 1, 4, 2, 5, 3, 6;
    for (int e = 0; e < 2; ++e)
        if (tetSignedVolume(m, e) < 0) std::swap(m.tets(2, e), m.tets(3, e));
    m.source = "overlap";
    try {
        remeshPieces(m);
        FAIL() << "TetGen accepted a self-intersecting surface";
    } catch (const RemeshError& e) {
        // TetGen names the reason when it can; its error path may also crash (in the child process).
        const std::string msg = e.what();
        EXPECT_NE(msg.find("TetGen"), std::string::npos) << msg;
        EXPECT_NE(msg.find("piece 0 of overlap"), std::string::npos) << msg;
    }
}

}  // namespace
}  // namespace cutsim
