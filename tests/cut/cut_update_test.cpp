// What a cut reports as changed is enough for the local time-step update: after blade steps and
// plane cuts, TimestepAnalyzer::update(changedElements, changedNodes) equals a full recompute
// (a missed element or node would keep a stale estimate or bound).
#include "random_cuts.hpp"
#include "timestep/cut_response.hpp"

namespace cutsim {
namespace {

void expectSameAnalysis(const TimestepAnalyzer& local, const TimestepAnalyzer& full, const std::string& where) {
    const ElementEstimates &a = local.estimates(), &b = full.estimates();
    ASSERT_EQ(a.r1r.size(), b.r1r.size()) << where;
    for (Eigen::Index e = 0; e < a.r1r.size(); ++e) {
        EXPECT_DOUBLE_EQ(a.r1r(e), b.r1r(e)) << where << ", element " << e;
        EXPECT_DOUBLE_EQ(a.hs(e), b.hs(e)) << where << ", element " << e;
        EXPECT_DOUBLE_EQ(a.hp(e), b.hp(e)) << where << ", element " << e;
        EXPECT_DOUBLE_EQ(a.le(e), b.le(e)) << where << ", element " << e;
        EXPECT_DOUBLE_EQ(a.element(e), b.element(e)) << where << ", element " << e;
        EXPECT_DOUBLE_EQ(local.shapes().meanRatio(e), full.shapes().meanRatio(e)) << where << ", element " << e;
    }
    ASSERT_EQ(local.nodeBounds().size(), full.nodeBounds().size()) << where;
    for (Eigen::Index i = 0; i < local.nodeBounds().size(); ++i)
        EXPECT_DOUBLE_EQ(local.nodeBounds()(i), full.nodeBounds()(i)) << where << ", node " << i;
    EXPECT_DOUBLE_EQ(local.certifiedDt(), full.certifiedDt()) << where;
}

TEST(CutUpdate, LocalTimestepUpdateAfterCutsEqualsFullRecompute) {
    for (MassLumping lumping : {MassLumping::Enrichment, MassLumping::RowSum}) {
        Model m = test::randomCutModel(true);
        State s = makeState(m);
        const Eigen::Vector3d lo = m.X.rowwise().minCoeff(), hi = m.X.rowwise().maxCoeff(), c = 0.5 * (lo + hi);
        TimestepAnalyzer an(m);
        CutOptions co;
        co.lumping = lumping;
        CutEngine eng(co);
        // A scalpel in the plane x = c.x entering from below in three steps, then two planes
        // across it (one through the fixed back, z < -0.028).
        auto edgeAt = [&](double y) { return BladeEdge{{c.x(), y, lo.z() - 0.01}, {c.x(), y, hi.z() + 0.01}}; };
        int changedTotal = 0;
        const double y0 = lo.y() - 0.01, dy = 0.3 * (hi.y() - lo.y());
        for (int k = 0; k < 3; ++k) {
            const CutResult r = eng.sweep(m, s, edgeAt(y0 + k * dy), edgeAt(y0 + (k + 1) * dy));
            an.update(m, r.changedElements, r.changedNodes);
            EXPECT_FALSE(an.lastUpdate().full);
            changedTotal += static_cast<int>(r.changedElements.size());
            expectSameAnalysis(an, TimestepAnalyzer(m),
                               std::string(lumpingName(lumping)) + " sweep " + std::to_string(k));
        }
        eng.endStroke();
        for (const Eigen::Vector3d& n : {Eigen::Vector3d(0, 1, 0.3), Eigen::Vector3d(0.2, 0.1, 1)}) {
            CutSurface cs;
            cs.point = c;
            cs.point.z() = n.z() > 0.5 ? -0.029 : c.z();
            cs.normal = n.normalized();
            const CutResult r = eng.cut(m, s, cs);
            an.update(m, r.changedElements, r.changedNodes);
            changedTotal += static_cast<int>(r.changedElements.size());
            expectSameAnalysis(an, TimestepAnalyzer(m), std::string(lumpingName(lumping)) + " plane");
        }
        EXPECT_GT(changedTotal, 100);  // the cuts did go through the liver
    }
}

// A blade's steps leave Le, the element estimate and the shape measures for the stroke's end
// (CutResponse defers them with the exact solve): meanwhile R1R, Hs, Hp and the Gershgorin rows
// are those of a full recompute and the three waiting arrays have not grown; after settle() every
// estimate is.
TEST(CutUpdate, DeferredBladeStepsLeaveOwnEstimatesForTheStrokeEnd) {
    Model m = test::randomCutModel(true);
    State s = makeState(m);
    const Eigen::Vector3d lo = m.X.rowwise().minCoeff(), hi = m.X.rowwise().maxCoeff(), c = 0.5 * (lo + hi);
    TimestepAnalyzer an(m);
    CutEngine eng;
    CutResponse response;  // exact at the stroke's end, no floor
    auto edgeAt = [&](double y) { return BladeEdge{{c.x(), y, lo.z() - 0.01}, {c.x(), y, hi.z() + 0.01}}; };
    const int elements0 = m.elements();
    const double y0 = lo.y() - 0.01, dy = 0.3 * (hi.y() - lo.y());
    for (int k = 0; k < 3; ++k) {
        const CutResult r = eng.sweep(m, s, edgeAt(y0 + k * dy), edgeAt(y0 + (k + 1) * dy));
        response.apply(m, an, r.changedElements, r.changedNodes, true);
        const TimestepAnalyzer full(m);
        const ElementEstimates &a = an.estimates(), &b = full.estimates();
        ASSERT_EQ(a.r1r.size(), m.elements());
        for (Eigen::Index e = 0; e < a.r1r.size(); ++e) {
            EXPECT_DOUBLE_EQ(a.r1r(e), b.r1r(e)) << "sweep " << k << ", element " << e;
            EXPECT_DOUBLE_EQ(a.hs(e), b.hs(e)) << "sweep " << k << ", element " << e;
            EXPECT_DOUBLE_EQ(a.hp(e), b.hp(e)) << "sweep " << k << ", element " << e;
        }
        EXPECT_DOUBLE_EQ(an.certifiedDt(), full.certifiedDt()) << "sweep " << k;
        EXPECT_EQ(an.ownPending(), m.elements() > elements0) << "sweep " << k;
        EXPECT_EQ(a.le.size(), elements0);
        EXPECT_EQ(an.shapes().meanRatio.size(), elements0);
    }
    ASSERT_GT(m.elements(), elements0);  // the blade split elements
    eng.endStroke();
    response.settle(m, an);
    EXPECT_FALSE(an.ownPending());
    expectSameAnalysis(an, TimestepAnalyzer(m), "after settle");
}

}  // namespace
}  // namespace cutsim
