// The step floor after cuts (timestep/floor.hpp): local R1R mass scaling, its certification by
// the exact step, and the random cut sequences it must hold.
#include "bench/random_cuts.hpp"
#include "cut/xfem.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/cut_response.hpp"
#include "timestep/floor.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

namespace cutsim {
namespace {

// One free tet: its R1R problem is the whole model, so the local scaling alone must bring the
// exact step to the aim dtFloor / sqrt(1 - margin), and with uniform masses scaled by c the step
// would grow by sqrt(c): the weighted scaling needs no more mass than that uniform one.
TEST(StepFloor, SingleTetReachesTheAimExactly) {
    TetMesh mesh;
    mesh.X.resize(3, 4);
    mesh.X << 0, 0.01, 0, 0, 0, 0, 0.01, 0, 0, 0, 0, 0.002;  // a flat tet: stiff across its height
    mesh.tets.resize(4, 1);
    mesh.tets << 0, 1, 2, 3;
    Model m = buildModel(mesh, Material{});
    TimestepAnalyzer ta(m);
    const double dt0 = ta.exact(m).dt;
    ta.update(m, {0});  // the floor scans what the last update re-estimated
    const double dtFloor = 1.5 * dt0;
    StepFloorOptions fo;
    const double mass0 = m.mass.sum();
    const StepFloorResult r = holdStepFloor(m, ta, dtFloor, fo);
    EXPECT_TRUE(r.reached);
    EXPECT_EQ(r.elements, 1);
    const double dtAim = dtFloor / std::sqrt(1 - fo.margin);
    const double dt = exactCriticalDt(m).dt;
    EXPECT_NEAR(dt / dtAim, 1.0, 1e-6);
    // uniform scaling to the same step: mass * (dtAim / dt0)^2
    EXPECT_LE(mass0 + r.addedMass, mass0 * std::pow(dtAim / dt0, 2) * (1 + 1e-9));
    EXPECT_NEAR(m.addedMass.sum(), r.addedMass, 1e-15);
    // the incremental estimates agree with a fresh analysis
    EXPECT_NEAR(TimestepAnalyzer(m).minDt().r1r, ta.minDt().r1r, 1e-12 * dt);
}

// Nothing is added where the step is already above the floor.
TEST(StepFloor, NothingAddedAboveTheFloor) {
    Model m = buildModel(boxMesh(0.04, 0.01, 0.01, 4, 1, 1), Material{});
    TimestepAnalyzer ta(m);
    const double dt0 = ta.exact(m).dt;
    ta.update(m, {0, 1, 2});
    const StepFloorResult r = holdStepFloor(m, ta, 0.9 * dt0);
    EXPECT_TRUE(r.reached);
    EXPECT_EQ(r.elements, 0);
    EXPECT_EQ(r.addedMass, 0.0);
}

// A plane that severs a thin wedge off the bar's free end leaves elements that are nearly free:
// without the floor the exact step falls to 0.86 of the uncut one; with it, certified, it is at 0.95.
TEST(StepFloor, SeveredSlabOfTheBar) {
    Model m = randomCutBarModel();
    TimestepAnalyzer ta(m);
    const double dt0 = ta.exact(m).dt;
    State s = makeState(m);
    CutEngine eng;
    CutSurface cs;
    cs.point = Eigen::Vector3d(0.0985, 0.015, 0.015);  // 1.5 mm from the free end
    cs.normal = Eigen::Vector3d(1, 0.5, 0).normalized();
    const CutResult r = eng.cut(m, s, cs);
    ASSERT_GT(r.split, 0);
    ta.update(m, r.changedElements, r.changedNodes);
    const double dtCut = ta.exact(m).dt;
    EXPECT_LT(dtCut, 0.9 * dt0);
    const double mass0 = m.mass.sum();
    const CertifiedFloorResult f = holdStepFloorCertified(m, ta, 0.95 * dt0);
    EXPECT_GE(f.dtExact, 0.95 * dt0 * (1 - 1e-6));
    EXPECT_GE(exactCriticalDt(m).dt, 0.95 * dt0 * (1 - 1e-6));  // from scratch
    EXPECT_GT(f.local.addedMass, 0.0);
    EXPECT_LT((f.local.addedMass + f.topUp.addedMass) / mass0, 5e-3);
    EXPECT_NEAR(m.mass.sum(), mass0 + f.local.addedMass + f.topUp.addedMass, 1e-12 * mass0);
}

// The certified floor on one free tet: its four rows are the whole Gershgorin bound, so after
// holdCertifiedFloor every row is at or under 4 / dtAim^2 (the certified step is at the aim, to
// rounding), the exact step is above the certified one, and at least one row sits at the aim
// (no more mass than the quadratic s^2 D + s O = lambda asks).
TEST(StepFloor, CertifiedFloorHoldsTheGershgorinRows) {
    TetMesh mesh;
    mesh.X.resize(3, 4);
    mesh.X << 0, 0.01, 0, 0, 0, 0, 0.01, 0, 0, 0, 0, 0.002;
    mesh.tets.resize(4, 1);
    mesh.tets << 0, 1, 2, 3;
    Model m = buildModel(mesh, Material{});
    TimestepAnalyzer ta(m);
    const double cert0 = ta.certifiedDt();
    ta.update(m, {0});
    const double dtAim = 1.7 * cert0;
    const StepFloorResult r = holdCertifiedFloor(m, ta, dtAim, {0, 1, 2, 3});
    EXPECT_GT(r.nodes, 0);
    EXPECT_GT(r.addedMass, 0.0);
    EXPECT_NEAR(m.addedMass.sum(), r.addedMass, 1e-15);
    const double cert = certifiedDt(m);  // from scratch
    EXPECT_GE(cert, dtAim * (1 - 1e-9));
    EXPECT_NEAR(ta.certifiedDt() / dtAim, 1.0, 1e-6);
    EXPECT_GE(exactCriticalDt(m).dt, cert * (1 - 1e-9));
    // nothing more where the rows are under the aim already
    ta.update(m, {0});
    EXPECT_EQ(holdCertifiedFloor(m, ta, dtAim, {0, 1, 2, 3}).addedMass, 0.0);
}

// The after-cut response on the severed slab of the bar: applied at once it equals the certified
// floor's sequence (floor, exact step, top-up); deferred, it leaves the exact step unknown, holds
// the certified step at its aim where the cut reached, and settle() then solves the same exact
// step a fresh analysis finds.
TEST(CutResponse, DeferredExactIsOwedAndSettled) {
    auto slab = [](Model& m) {
        State s = makeState(m);
        CutEngine eng;
        CutSurface cs;
        cs.point = Eigen::Vector3d(0.0985, 0.015, 0.015);
        cs.normal = Eigen::Vector3d(1, 0.5, 0).normalized();
        return eng.cut(m, s, cs);
    };
    const Model base = randomCutBarModel();
    const TimestepAnalyzer ta0(base);
    const double dt0 = ta0.exact(base).dt, cert0 = ta0.certifiedDt();
    CutResponseOptions o;
    o.dtFloor = 0.95 * dt0;
    o.dtCertified = std::min(o.dtFloor, cert0);

    Model now = base;
    TimestepAnalyzer taNow(now);
    const CutResult rNow = slab(now);
    CutResponse atOnce(o);
    const CutResponseResult a = atOnce.apply(now, taNow, rNow.changedElements, rNow.changedNodes);
    EXPECT_FALSE(a.deferred);
    EXPECT_FALSE(atOnce.owed());
    EXPECT_GE(a.exact, 0.95 * dt0 * (1 - 1e-6));
    EXPECT_EQ(a.certified.addedMass, 0.0);  // the exact step backs it: no certified floor

    Model later = base;
    TimestepAnalyzer taLater(later);
    const CutResult rLater = slab(later);
    CutResponse deferred(o);
    const CutResponseResult d = deferred.apply(later, taLater, rLater.changedElements, rLater.changedNodes, true);
    EXPECT_TRUE(d.deferred);
    EXPECT_TRUE(deferred.owed());
    EXPECT_TRUE(std::isnan(d.exact));
    EXPECT_GE(taLater.certifiedDt(), o.dtCertified * (1 - 1e-9));
    EXPECT_GE(certifiedDt(later), o.dtCertified * (1 - 1e-9));  // from scratch
    const CutResponseResult e = deferred.settle(later, taLater);
    EXPECT_FALSE(deferred.owed());
    EXPECT_GE(e.exact, 0.95 * dt0 * (1 - 1e-6));
    EXPECT_NEAR(e.exact, exactCriticalDt(later).dt, 1e-6 * e.exact);
    EXPECT_TRUE(std::isnan(deferred.settle(later, taLater).exact));  // nothing owed twice
    // the mass the floor added is in the model, and what the response says it added
    EXPECT_NEAR(later.addedMass.sum(), d.addedMass() + e.addedMass(), 1e-12 * later.mass.sum());
}

// Random cut sequences on the liver and the bar: with the certified floor no cut leaves the step
// under 0.95 of the uncut one, nothing blows up, and the mass added stays under 0.5%.
TEST(StepFloor, RandomCutsHoldTheFloor) {
    for (const bool liver : {true, false}) {
        const Model base = liver ? randomCutLiverModel(readTetMesh(test::data("tet/sofa_liver.msh"), ReadOptions{}))
                                 : randomCutBarModel();
        RandomCutOptions ro{MassLumping::Enrichment, 0.9, 0.2};
        ro.stepFloor = 0.95;
        ro.floor = RandomCutOptions::Floor::Certified;
        const RandomCutStats st = runRandomCuts(base, 8, 100, liver ? 31 : 32, ro);
        EXPECT_EQ(st.failures, 0) << st.firstFailure;
        EXPECT_GE(st.minDtRatio, 0.95 * (1 - 1e-6)) << (liver ? "liver" : "bar");
        EXPECT_EQ(st.cutsBelowFloor, 0);
        EXPECT_LT(st.maxAddedMass, 5e-3);
        EXPECT_LT(st.maxMassError, 1e-9);
    }
}

}  // namespace
}  // namespace cutsim
