// A cut must not change the mechanics of the moment it is made: the pieces partition each cut
// element, so elastic and kinetic energy stay, and the forces on the copies of a node sum to the
// force the node had (virtual node algorithm, thesis sec. 2.3).
#include "random_cuts.hpp"

#include <map>

namespace cutsim {
namespace {

TEST(CutConsistency, RandomCutsKeepEnergyAndForcesOfTheMoment) {
    std::mt19937 rng(5);
    for (bool liver : {true, false}) {
        Model m = test::randomCutModel(liver);
        State s = makeState(m);
        const Eigen::Vector3d lo = m.X.rowwise().minCoeff(), hi = m.X.rowwise().maxCoeff();
        StepOptions opt;
        opt.dt = 0.9 * TimestepAnalyzer(m).exact(m).dt;
        Stepper stepper;
        CutOptions co;
        co.relaxIterations = 0;  // the cut alone; relaxing its fresh control points is meant to lower the energy
        co.mergeDebris = false;  // and fusing a piece to a side that has moved apart moves its material
        CutEngine eng(co);
        for (int c = 0; c < 6; ++c) {
            for (int k = 0; k < 100; ++k) stepper.step(m, s, opt);  // deformed and moving
            computeForces(m, s);
            // forces summed over all copies of each node of the uncut mesh
            const Model base = test::randomCutModel(liver);
            const int N = base.nodes();
            auto grouped = [&] {
                Eigen::Matrix3Xd g = Eigen::Matrix3Xd::Zero(3, N);
                for (int n = 0; n < m.nodes(); ++n)
                    if (!base.fixed[static_cast<size_t>(eng.originalNode(n))]) g.col(eng.originalNode(n)) += s.f.col(n);
                return g;
            };
            const Eigen::Matrix3Xd f0 = grouped();
            const double e0 = elasticEnergy(m, s), k0 = kineticEnergy(m, s);
            const CutResult r = eng.cut(m, s, randomCutPlane(lo, hi, rng));
            opt.dt = 0.9 * TimestepAnalyzer(m).exact(m).dt;
            stepper.reset();
            computeForces(m, s);
            EXPECT_NEAR(elasticEnergy(m, s), e0, 1e-9 * e0) << "cut " << c;
            EXPECT_NEAR(kineticEnergy(m, s), k0, 1e-9 * k0 + 1e-15) << "cut " << c;
            const Eigen::Matrix3Xd f1 = grouped();
            const double scale = f0.cwiseAbs().maxCoeff();
            for (int n = 0; n < N; ++n)
                ASSERT_LT((f1.col(n) - f0.col(n)).norm(), 1e-9 * scale)
                    << "node " << n << " cut " << c << " split " << r.split;
        }
    }
}

}  // namespace
}  // namespace cutsim

namespace cutsim {
namespace {

// Row i of K as neighbour -> block, independent of the order the rows were assembled in.
std::map<int, Eigen::Matrix3d> rowOf(const StiffnessRows& rows, int i) {
    std::map<int, Eigen::Matrix3d> r;
    for (size_t k = 0; k < rows.nbr[i].size(); ++k) r[rows.nbr[i][k]] = rows.block[i][k];
    return r;
}

// The analysis updated with what a cut reports as changed must equal one computed from scratch:
// the step of every later cut is taken from it. A cut can regroup the copies of a node so that an
// element of an uncut parent moves to another copy; its rows are then stale unless it is reported.
TEST(CutConsistency, LocalTimestepUpdateMatchesRebuild) {
    std::mt19937 rng(225);
    int compared = 0;
    for (bool liver : {false, true}) {
        Model m = test::randomCutModel(liver);
        State s = makeState(m);
        const Eigen::Vector3d lo = m.X.rowwise().minCoeff(), hi = m.X.rowwise().maxCoeff();
        StepOptions opt;
        opt.dt = 0.9 * TimestepAnalyzer(m).exact(m).dt;
        Stepper stepper;
        CutEngine eng;
        TimestepAnalyzer ta(m);
        for (int c = 0; c < 8; ++c) {
            for (int k = 0; k < 30; ++k) stepper.step(m, s, opt);
            const CutResult r = eng.cut(m, s, randomCutPlane(lo, hi, rng));
            ta.update(m, r.changedElements, r.changedNodes);
            stepper.reset();
            const TimestepAnalyzer fresh(m);
            for (int i = 0; i < m.nodes(); ++i) {
                const auto a = rowOf(ta.rows(), i), b = rowOf(fresh.rows(), i);
                ASSERT_EQ(a.size(), b.size()) << "node " << i << " cut " << c;
                for (const auto& [j, blk] : b) {
                    ASSERT_TRUE(a.count(j)) << "node " << i << " misses neighbour " << j << " after cut " << c;
                    ASSERT_LT((a.at(j) - blk).norm(), 1e-9 * blk.norm() + 1e-12) << "node " << i << " cut " << c;
                }
                ASSERT_NEAR(ta.nodeBounds()(i), fresh.nodeBounds()(i), 1e-9 * fresh.nodeBounds()(i)) << "node " << i;
            }
            ++compared;
            opt.dt = 0.9 * ta.exact(m).dt;
        }
    }
    EXPECT_EQ(compared, 16);
}

}  // namespace
}  // namespace cutsim
