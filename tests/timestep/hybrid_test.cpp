// The hybrid method (timestep/hybrid.hpp, fem/shape_matching.hpp): identification of the elements
// that limit the step, shape matching by hand, and a step above the FEM limit that stays stable.
#include "bench/random_cuts.hpp"
#include "cut/xfem.hpp"
#include "fem/integrate.hpp"
#include "mesh/io.hpp"
#include "timestep/hybrid.hpp"
#include "test_support.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace cutsim {
namespace {

Model oneTet() {
    TetMesh mesh;
    mesh.X.resize(3, 4);
    // a regular tet: sum (X - c0)(X - c0)^T = k I, so a stretch about the centre has no rotation
    mesh.X << 1, 1, -1, -1, 1, -1, 1, -1, 1, -1, -1, 1;
    mesh.X *= 0.005;
    mesh.X.colwise() += Eigen::Vector3d(0.02, 0.03, 0.04);
    mesh.tets.resize(4, 1);
    mesh.tets << 0, 2, 1, 3;  // positive orientation
    Model m = buildModel(mesh, Material{});
    m.matched = {1};
    m.matchedList = {0};
    return m;
}

// A matched tet moved rigidly is left where it is; a stretched one is put back to its rest shape,
// rotated and centred as it was (alpha = 1), with the move added to its velocity over dt.
TEST(ShapeMatching, RigidIsKeptStretchIsUndone) {
    Model m = oneTet();
    State s = makeState(m);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    for (int i = 0; i < 4; ++i) s.x.col(i) = R * m.X.col(i) + Eigen::Vector3d(0.1, 0.2, 0.3);
    const Eigen::Matrix3Xd rigid = s.x;
    ShapeMatchScratch w;
    shapeMatch(m, s, 1e-4, w);
    EXPECT_LT((s.x - rigid).norm(), 1e-15);
    EXPECT_LT(s.v.norm(), 1e-10);
    // stretch 20% along x about the centre: the goal is the rest shape about the same centre
    s = makeState(m);
    const Eigen::Vector3d c0 = m.X.rowwise().mean();
    for (int i = 0; i < 4; ++i) s.x.col(i) = c0 + Eigen::Vector3d(1.2, 1, 1).asDiagonal() * (m.X.col(i) - c0);
    const Eigen::Matrix3Xd before = s.x;
    shapeMatch(m, s, 1e-4, w);
    EXPECT_LT((s.x - m.X).norm(), 1e-12);
    EXPECT_LT((s.v - (m.X - before) / 1e-4).norm(), 1e-7);
    // alpha 1/2: half the way
    m.matchStiffness = 0.5;
    s = makeState(m);
    s.x = before;
    shapeMatch(m, s, 1e-4, w);
    EXPECT_LT((s.x - 0.5 * (before + m.X)).norm(), 1e-12);
}

// On the liver, matching the elements under 1.1 x 0.95 of the exact step lifts the FEM part's
// exact step above the full model's, and a run at a step 10% above the full model's limit
// stays bounded with them matched and blows up without.
TEST(Hybrid, LiverRunsAboveTheFemLimit) {
    const Model base = randomCutLiverModel(readTetMesh(test::data("tet/sofa_liver.msh"), ReadOptions{}));
    const double dt0 = TimestepAnalyzer(base).exact(base).dt;
    Model m = base;
    TimestepAnalyzer ta(m);
    const HybridResult h = matchCriticalCertified(m, ta, 0.95 * dt0, {}, true);
    EXPECT_GT(h.matched, 0);
    EXPECT_LT(h.matched, m.elements() / 10);
    EXPECT_GE(h.dtExact, 0.95 * dt0);
    EXPECT_GT(h.dtExact, 1.15 * dt0);
    EXPECT_NEAR(TimestepAnalyzer(m).exact(m).dt, h.dtExact, 1e-9 * h.dtExact);  // incremental = from scratch
    const double dt = 1.1 * dt0;
    for (const bool hybrid : {true, false}) {
        const Model& mm = hybrid ? m : base;
        State s = makeState(mm);
        Stepper st;
        double vmax = 0;
        for (int k = 0; k < 3000; ++k) {
            st.step(mm, s, StepOptions{Integrator::SymplecticEuler, dt});
            vmax = std::max(vmax, s.flags.nonFinite ? 1e30 : s.v.colwise().norm().maxCoeff());
            if (!(vmax < kBlowUpSpeed)) break;
        }
        if (hybrid) {
            EXPECT_LT(vmax, 1.0) << "hybrid";
        } else {
            EXPECT_FALSE(vmax < kBlowUpSpeed) << "plain FEM above its limit";
        }
    }
}

// After a cut, matching the re-estimated elements locally keeps the FEM part's exact step at
// 0.95 of the uncut one where the plain cut lost it.
TEST(Hybrid, KeepsTheStepThroughACut) {
    Model m = randomCutBarModel();
    TimestepAnalyzer ta(m);
    const double dt0 = ta.exact(m).dt;
    State s = makeState(m);
    CutEngine eng;
    CutSurface cs;
    cs.point = Eigen::Vector3d(0.0985, 0.015, 0.015);
    cs.normal = Eigen::Vector3d(1, 0.5, 0).normalized();
    const CutResult r = eng.cut(m, s, cs);
    ta.update(m, r.changedElements, r.changedNodes);
    EXPECT_LT(ta.exact(m).dt, 0.9 * dt0);
    const HybridResult h = matchCriticalCertified(m, ta, 0.95 * dt0);
    EXPECT_GT(h.added, 0);
    EXPECT_GE(h.dtExact, 0.95 * dt0);
    EXPECT_LT(h.matched, 20);
}

}  // namespace
}  // namespace cutsim
