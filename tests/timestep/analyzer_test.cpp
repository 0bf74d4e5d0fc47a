// Local update of the time-step analysis equals a full recompute (docs/method.md sec. 5).
#include "fem/model.hpp"
#include "test_support.hpp"
#include "timestep/analyzer.hpp"

#include <gtest/gtest.h>

#include <random>

namespace cutsim {
namespace {

void expectSame(const TimestepAnalyzer& local, const TimestepAnalyzer& full) {
    const ElementEstimates &a = local.estimates(), &b = full.estimates();
    ASSERT_EQ(a.r1r.size(), b.r1r.size());
    for (Eigen::Index e = 0; e < a.r1r.size(); ++e) {
        EXPECT_DOUBLE_EQ(a.r1r(e), b.r1r(e)) << "element " << e;
        EXPECT_DOUBLE_EQ(a.hs(e), b.hs(e)) << "element " << e;
        EXPECT_DOUBLE_EQ(a.hp(e), b.hp(e)) << "element " << e;
        EXPECT_DOUBLE_EQ(a.le(e), b.le(e)) << "element " << e;
        EXPECT_DOUBLE_EQ(a.element(e), b.element(e)) << "element " << e;
        EXPECT_DOUBLE_EQ(local.shapes().meanRatio(e), full.shapes().meanRatio(e)) << "element " << e;
        EXPECT_DOUBLE_EQ(local.shapes().minSineDihedral(e), full.shapes().minSineDihedral(e)) << "element " << e;
    }
    ASSERT_EQ(local.nodeBounds().size(), full.nodeBounds().size());
    for (Eigen::Index i = 0; i < local.nodeBounds().size(); ++i)
        EXPECT_DOUBLE_EQ(local.nodeBounds()(i), full.nodeBounds()(i)) << "node " << i;
    EXPECT_DOUBLE_EQ(local.certifiedDt(), full.certifiedDt());
    EXPECT_TRUE(local.stiffnessDiagonal().isApprox(full.stiffnessDiagonal()));
}

TEST(TimestepAnalyzer, LocalUpdateAfterFractionChangeEqualsFullRecompute) {
    Model m = buildModel(test::boxMesh(0.1, 0.1, 0.1, 6, 6, 6), Material{});
    TimestepAnalyzer an(m);
    const double before = an.certifiedDt();
    // A "cut": a few neighbouring elements become thin virtual elements (fraction < 1).
    std::vector<int> changed = {500, 501, 502, 503, 504, 505, 640};
    for (int e : changed) m.fraction(e) = 0.02;
    updateMasses(m);
    an.update(m, changed);
    EXPECT_FALSE(an.lastUpdate().full);
    EXPECT_LT(an.lastUpdate().elements, m.elements() / 4);
    expectSame(an, TimestepAnalyzer(m));
    EXPECT_NE(an.certifiedDt(), before);
    // The certified bound still holds against the exact value after the change.
    EXPECT_LE(an.certifiedDt(), an.exact(m).dt);
}

TEST(TimestepAnalyzer, LocalUpdateAfterFixingAndMovingNodes) {
    TetMesh mesh = test::boxMesh(0.1, 0.08, 0.06, 5, 4, 3);
    Model m = buildModel(mesh, Material{});
    TimestepAnalyzer an(m);
    // Fixing a node changes only its mass: pass it as a changed node.
    m.fixed[7] = 1;
    updateMasses(m);
    an.update(m, {}, {7});
    expectSame(an, TimestepAnalyzer(m));
    // Mesh improvement moves interior nodes; the model is rebuilt with the same numbering.
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.004, 0.004);
    std::vector<int> moved;
    for (int i = 0; i < mesh.nodes(); ++i)
        if (mesh.X(0, i) > 0.01 && mesh.X(0, i) < 0.09 && mesh.X(2, i) > 0.01 && mesh.X(2, i) < 0.05 && i % 3 == 0) {
            for (int k = 0; k < 3; ++k) mesh.X(k, i) += u(rng);
            moved.push_back(i);
        }
    ASSERT_FALSE(moved.empty());
    Model m2 = buildModel(mesh, Material{});
    m2.fixed = m.fixed;
    updateMasses(m2);
    an.updateMovedNodes(m2, moved);
    expectSame(an, TimestepAnalyzer(m2));
}

TEST(TimestepAnalyzer, LocalUpdateAfterAppendingAnElement) {
    TetMesh mesh = test::boxMesh(0.1, 0.1, 0.1, 3, 3, 3);
    Model m = buildModel(mesh, Material{});
    TimestepAnalyzer an(m);
    // A new node above the top face, and a tet joining it to a boundary triangle.
    const Eigen::Matrix3Xi faces = boundaryFaces(mesh);
    int f = 0;
    while (mesh.X(2, faces(0, f)) < 0.1 || mesh.X(2, faces(1, f)) < 0.1 || mesh.X(2, faces(2, f)) < 0.1) ++f;
    const Eigen::Vector3d c = (mesh.X.col(faces(0, f)) + mesh.X.col(faces(1, f)) + mesh.X.col(faces(2, f))) / 3;
    mesh.X.conservativeResize(3, mesh.nodes() + 1);
    mesh.X.col(mesh.nodes() - 1) = c + Eigen::Vector3d(0, 0, 0.02);
    mesh.tets.conservativeResize(4, mesh.elements() + 1);
    mesh.tets.col(mesh.elements() - 1) << faces(0, f), faces(2, f), faces(1, f), mesh.nodes() - 1;
    if (tetSignedVolume(mesh, mesh.elements() - 1) < 0)
        std::swap(mesh.tets(1, mesh.elements() - 1), mesh.tets(2, mesh.elements() - 1));
    const Model m2 = buildModel(mesh, Material{});
    an.update(m2, {m2.elements() - 1});
    EXPECT_FALSE(an.lastUpdate().full);
    expectSame(an, TimestepAnalyzer(m2));
}

TEST(TimestepAnalyzer, SummaryAndCorrelations) {
    const Model m = buildModel(test::boxMesh(0.1, 0.05, 0.05, 4, 2, 2), Material{});
    const TimestepAnalyzer an(m);
    const auto mn = an.minDt();
    const double exact = an.exact(m).dt;
    EXPECT_GE(mn.r1r, exact * (1 - 1e-9));
    EXPECT_LE(mn.element, exact * (1 + 1e-9));
    EXPECT_LE(an.certifiedDt(), exact);
    const auto corr = an.correlations();
    EXPECT_EQ(corr.size(), 10u);
    for (const auto& [name, r] : corr) EXPECT_TRUE(std::isnan(r) || std::abs(r) <= 1 + 1e-12) << name;
}

}  // namespace
}  // namespace cutsim
