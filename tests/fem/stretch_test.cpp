// Stretch limiting (fem/stretch.cpp): projections worked by hand, momentum, no inversion.
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "fem/kinematics.hpp"
#include "test_support.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace cutsim;

namespace {

// The smallest principal stretch of a tet's F, signed like the limiter's (negative when inverted).
double smallestStretchOf(const Model& m, const State& s, int e) {
    const Eigen::Vector3d x0 = s.x.col(m.tets(0, e));
    Eigen::Matrix3d Ds;
    Ds << s.x.col(m.tets(1, e)) - x0, s.x.col(m.tets(2, e)) - x0, s.x.col(m.tets(3, e)) - x0;
    const Eigen::Matrix3d F = Ds * m.dmInv(e);
    const double s3 = Eigen::JacobiSVD<Eigen::Matrix3d>(F).singularValues()[2];
    return F.determinant() < 0 ? -s3 : s3;
}

// The 1 cm unit tet with its corners 0, 1, 2 (on z = 0) clamped.
Model clampedTet() {
    TetMesh t = test::unitTet();
    t.X *= 0.01;
    Model m = buildModel(t, Material{});
    fixNodes(m, {0, 1, 2});
    return m;
}

}  // namespace

// Stretch limiting by hand: three corners clamped on z = 0, the fourth pushed straight down
// through the face to z = -0.3 h. F = diag(1, 1, z / h). Inverted, det F = z / h is projected to
// 0 first (its gradient for node 3 is e_z / h); then sigma3 = z / h along e_z, gradient e_z / h
// again, so node 3 ends at z = 0.2 h exactly, x and y unchanged, its closing velocity stopped.
TEST(Forces, StretchLimitProjectsByHand) {
    Model m = clampedTet();
    State s = makeState(m);
    s.x.col(3) << 0, 0, -0.003;
    s.v.col(3) << 0.5, -0.25, -2.0;
    std::vector<int> scratch;
    EXPECT_EQ(limitStretch(m, s, 0.2, scratch), 1);
    EXPECT_NEAR(s.x(0, 3), 0.0, 1e-15);
    EXPECT_NEAR(s.x(1, 3), 0.0, 1e-15);
    EXPECT_NEAR(s.x(2, 3), 0.002, 1e-15);
    EXPECT_NEAR(s.v(0, 3), 0.5, 1e-15);
    EXPECT_NEAR(s.v(1, 3), -0.25, 1e-15);
    EXPECT_NEAR(s.v(2, 3), 0.0, 1e-15);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(s.x.col(i), m.X.col(i));
    // an opening element below the limit keeps its opening velocity; one above is left alone
    s.v.col(3) << 0, 0, 1.0;
    s.x(2, 3) = 0.001;
    limitStretch(m, s, 0.2, scratch);
    EXPECT_NEAR(s.v(2, 3), 1.0, 1e-15);
    EXPECT_NEAR(s.x(2, 3), 0.002, 1e-15);
    EXPECT_EQ(limitStretch(m, s, 0.1, scratch), 0);
}

// A partial element (fraction < 1: a cut piece, a mesh-intersection interface element) is held
// at the larger bound: the same tet squeezed to z = 0.3 h is left alone at sMin 0.2, and brought
// to z = 0.5 h exactly (the same projection as above) when it stands for half its volume.
TEST(Forces, StretchLimitHoldsPartialElementsAtTheirBound) {
    Model m = clampedTet();
    State s = makeState(m);
    s.x.col(3) << 0, 0, 0.003;
    std::vector<int> scratch;
    EXPECT_EQ(limitStretch(m, s, 0.2, scratch, kPartialMinStretch), 0);  // a whole element: 0.3 > 0.2
    EXPECT_EQ(s.x(2, 3), 0.003);
    m.fraction(0) = 0.5;
    EXPECT_EQ(limitStretch(m, s, 0.2, scratch, kPartialMinStretch), 1);
    EXPECT_NEAR(s.x(2, 3), 0.005, 1e-15);
    EXPECT_NEAR(smallestStretchOf(m, s, 0), 0.5, 1e-12);
}

// On a free tet with equal node masses the correction keeps momentum and the centre of mass, and
// leaves the smallest stretch at the limit (a little above: the singular vectors turn).
TEST(Forces, StretchLimitKeepsMomentum) {
    TetMesh t = test::unitTet();
    t.X *= 0.01;
    Model m = buildModel(t, Material{});
    State s = makeState(m);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int i = 0; i < 4; ++i) s.v.col(i) << u(rng), u(rng), u(rng);
    s.x.col(3) << 0.004, 0.001, -0.002;
    ASSERT_LT(smallestStretchOf(m, s, 0), 0);
    const Eigen::Vector3d p0 = s.v * m.mass, c0 = s.x * m.mass;
    std::vector<int> scratch;
    ASSERT_EQ(limitStretch(m, s, 0.3, scratch), 1);
    EXPECT_LT((s.v * m.mass - p0).norm(), 1e-15);
    EXPECT_LT((s.x * m.mass - c0).norm(), 1e-17);
    EXPECT_GE(smallestStretchOf(m, s, 0), 0.3 - 1e-9);
    EXPECT_LT(smallestStretchOf(m, s, 0), 0.35);
}

// A clamped tet loaded through its face, the load ramped to 5 N (far beyond what E = 30 kPa on
// 1 cm holds; near the end one step carries the node past the face): without limiting it
// inverts, with it the smallest stretch after each step is at the limit or above.
TEST(Forces, StretchLimitStopsInversion) {
    for (const double limit : {0.0, 0.2}) {
        TetMesh t = test::unitTet();
        t.X *= 0.01;
        Model m = buildModel(t, Material{});
        m.massDamping = 20;
        fixNodes(m, {0, 1, 2});
        State s = makeState(m);
        Stepper st;
        StepOptions opt;
        opt.dt = 1.0 / std::sqrt(test::denseLambdaMax(m));
        opt.minStretch = limit;
        int inverted = 0, limited = 0;
        double smallest = 1;
        for (int k = 0; k < 4000; ++k) {
            s.fExt.col(3) << 0, 0, -5.0 * std::min(1.0, k / 2000.0);  // [N]
            st.step(m, s, opt);
            inverted += s.flags.inverted > 0;
            limited += s.flags.limited > 0;
            smallest = std::min(smallest, smallestStretchOf(m, s, 0));
        }
        if (limit == 0) {
            EXPECT_GT(inverted, 0);
        } else {
            EXPECT_LT(inverted, 10);  // seen by the force stage before the projection, never after
            EXPECT_GT(limited, 0);
            EXPECT_GT(smallest, limit - 1e-9);
        }
    }
}

// After a contact projection: an element it left inverted around the nodes it moved is limited
// back (the by-hand projection above, node 3 to z = 0.2 h), whether or not the node is light; a
// moved node whose elements are not inverted, no moved node, or stretch limiting off, leave the
// state as it is.
TEST(Forces, RepairAfterContactLimitsOnlyInvertedElements) {
    Model m = clampedTet();
    ASSERT_TRUE(m.lightNodes.empty());
    State s = makeState(m);
    Stepper stepper;
    StepOptions opt;
    opt.minStretch = 0.2;
    s.x.col(3) << 0, 0, 0.001;  // squeezed below the limit, not inverted: not the repair's business
    EXPECT_EQ(stepper.repairInverted(m, s, opt, {3}), 0);
    EXPECT_EQ(s.x(2, 3), 0.001);
    s.x.col(3) << 0, 0, -0.003;
    StepOptions off = opt;
    off.minStretch = 0;
    EXPECT_EQ(stepper.repairInverted(m, s, off, {3}), 0);
    EXPECT_EQ(stepper.repairInverted(m, s, opt, {}), 0);
    EXPECT_EQ(s.x(2, 3), -0.003);
    EXPECT_EQ(stepper.repairInverted(m, s, opt, {3}), 1);
    EXPECT_NEAR(s.x(2, 3), 0.002, 1e-15);
    EXPECT_GT(smallestStretchOf(m, s, 0), 0.2 - 1e-12);
}

// A light node whose gradient is small (the unit tet squashed along a direction tilted slightly
// towards node 3: sigma3's gradient there is 0.02 of the heavy nodes') takes no momentum from the
// heavy nodes' stop and is not thrown by the position correction. Weighted with the others it
// would get sqrt(m_heavy / m_light) / 2 times their closing rate (hundreds of m/s here) and a
// correction of 0.5 m; here its velocity is kept, its move stays within an edge or two, and the
// heavy nodes' closing rate is removed with the kinetic energy going down.
TEST(Forces, LightNodeTakesNoMomentumFromTheStopAndStaysNearItsElement) {
    TetMesh t = test::unitTet();
    const double h = 0.01;
    t.X *= h;
    Model m = buildModel(t, Material{});
    m.invMass << 1e3, 1e3, 1e3, 1e12;  // kg^-1: node 3 weighs 1e-12 kg, the others 1 g
    m.mass = m.invMass.cwiseInverse();
    m.lightNodes = {3};
    State s = makeState(m);
    s.x.col(1) << 0.1 * h, 0, 0.02 * h;
    s.v.col(1) << -1.0, 0, 0;  // closing
    const Eigen::Vector3d x3 = s.x.col(3);
    auto kinetic = [&] {
        double k = 0;
        for (int i = 0; i < 4; ++i) k += 0.5 * m.mass(i) * s.v.col(i).squaredNorm();
        return k;
    };
    const double before = kinetic();
    std::vector<int> scratch;
    EXPECT_EQ(limitStretch(m, s, 0.2, scratch), 1);
    EXPECT_EQ(s.v.col(3), Eigen::Vector3d::Zero().eval());
    EXPECT_LT((s.x.col(3) - x3).norm(), 2 * h);
    EXPECT_LE(kinetic(), before);
    EXPECT_GT(smallestStretchOf(m, s, 0), 0.2 - 1e-9);
    // the heavy nodes no longer close: sigma3's rate over them is >= 0 (finite differences)
    State later = s;
    const double dt = 1e-7;
    for (int i = 0; i < 3; ++i) later.x.col(i) += dt * s.v.col(i);
    EXPECT_GE(smallestStretchOf(m, later, 0) - smallestStretchOf(m, s, 0), -1e-9);
}
