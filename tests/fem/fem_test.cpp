// Element, force and integrator tests with values derived by hand.
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "fem/tet.hpp"
#include "test_support.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace cutsim;

namespace {

Eigen::VectorXd flat(const Eigen::Matrix3Xd& x) { return Eigen::Map<const Eigen::VectorXd>(x.data(), x.size()); }

// Exact critical step over free DOFs, independent of physics/timestep.
double denseCriticalDt(const Model& m) { return 2.0 / std::sqrt(test::denseLambdaMax(m)); }

}  // namespace

// K for the unit right tet with E = 2.5, nu = 0.25 (lambda = mu = 1): entries by hand from
// K_ab = V [lambda g_a g_b^T + mu g_b g_a^T + mu (g_a.g_b) I], V = 1/6,
// g0 = (-1,-1,-1), g1 = e_x, g2 = e_y, g3 = e_z.
TEST(Tet, StiffnessOfUnitTetByHand) {
    Material mat{2.5, 0.25, 1.0};
    ASSERT_NEAR(mat.lambda(), 1.0, 1e-14);
    ASSERT_NEAR(mat.mu(), 1.0, 1e-14);
    const TetMesh t = test::unitTet();
    const Mat34 g = shapeGradients(restShapeMatrix(t.X).inverse());
    const Mat12 K = elementStiffness(g, 1.0 / 6.0, mat);
    const double V = 1.0 / 6.0;
    EXPECT_NEAR(K(3, 3), V * 3.0, 1e-14);   // K_11,xx = V (lambda + 2 mu)
    EXPECT_NEAR(K(4, 4), V * 1.0, 1e-14);   // K_11,yy = V mu
    EXPECT_NEAR(K(0, 0), V * 5.0, 1e-14);   // K_00,xx = V (lambda + mu + 3 mu)
    EXPECT_NEAR(K(0, 1), V * 2.0, 1e-14);   // K_00,xy = V (lambda + mu)
    EXPECT_NEAR(K(3, 7), V * 1.0, 1e-14);   // K_12,xy = V lambda
    EXPECT_NEAR(K(4, 6), V * 1.0, 1e-14);   // K_12,yx = V mu
    EXPECT_NEAR(K(3, 6), 0.0, 1e-14);       // K_12,xx = V mu (g1.g2) = 0
    EXPECT_NEAR(K(0, 3), -V * 3.0, 1e-14);  // K_01,xx = V (-lambda - mu - mu)
    // Symmetric, rows sum to zero (translation is free), diagonal formula of eqs. 4.3-4.10.
    EXPECT_NEAR((K - K.transpose()).norm(), 0.0, 1e-14);
    for (int r = 0; r < 12; ++r) EXPECT_NEAR(K.row(r).reshaped(3, 4).rowwise().sum().norm(), 0.0, 1e-13);
    EXPECT_NEAR((elementStiffnessDiagonal(g, V, mat) - K.diagonal()).norm(), 0.0, 1e-14);
}

// For small displacements the corotational force is -K u; the linear force is -K u exactly.
TEST(Forces, MatchStiffnessTimesDisplacement) {
    TetMesh t = test::unitTet();
    t.X.col(3) << 0.2, 0.1, 0.9;
    for (auto em : {ElementModel::Linear, ElementModel::Corotational}) {
        Model m = buildModel(t, Material{}, em);
        State s = makeState(m);
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> U(-1, 1);
        Eigen::Matrix3Xd u(3, 4);
        for (int i = 0; i < 12; ++i) u.data()[i] = 1e-6 * U(rng);
        s.x = m.X + u;
        computeForces(m, s);
        const Eigen::VectorXd Ku = Eigen::MatrixXd(assembleStiffness(m)) * flat(u);
        const double rel = (flat(s.f) + Ku).norm() / Ku.norm();
        EXPECT_LT(rel, em == ElementModel::Linear ? 1e-8 : 1e-5);  // round-off of X + u at |u| = 1e-6
    }
}

// A rigid rotation (and translation) produces no corotational force; the linear model does.
TEST(Forces, RigidRotationGivesZeroCorotationalForce) {
    const TetMesh box = test::boxMesh(1, 0.5, 0.3, 3, 2, 2);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    for (auto em : {ElementModel::Corotational, ElementModel::Linear}) {
        Model m = buildModel(box, Material{}, em);
        State s = makeState(m);
        s.x = (R * m.X).colwise() + Eigen::Vector3d(0.3, -2, 5);
        // a few evaluations let the warm-started rotation converge, as in a run
        for (int k = 0; k < 3; ++k) computeForces(m, s);
        const double fmax = s.f.colwise().norm().maxCoeff();
        if (em == ElementModel::Corotational) {
            EXPECT_LT(fmax, 1e-9 * m.material.E);
            EXPECT_LT(elasticEnergy(m, s), 1e-18);
        } else {
            EXPECT_GT(fmax, 1e-3 * m.material.E * 0.01);  // linear elasticity sees rotation as strain
        }
    }
}

// Patch test: any affine field gives zero force at interior nodes, and forces balance overall.
TEST(Forces, PatchTest) {
    const TetMesh box = test::boxMesh(1, 1, 1, 4, 4, 4);
    Eigen::Matrix3d A;
    A << 1.02, 0.01, -0.03, 0.00, 0.97, 0.02, 0.01, 0.04, 1.05;
    const Eigen::Matrix3d Rot = Eigen::AngleAxisd(0.7, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
    for (auto em : {ElementModel::Linear, ElementModel::Corotational}) {
        Model m = buildModel(box, Material{}, em);
        State s = makeState(m);
        s.x = ((em == ElementModel::Corotational ? Rot * A : A) * m.X).colwise() + Eigen::Vector3d(0.1, 0.2, 0.3);
        for (int k = 0; k < 3; ++k) computeForces(m, s);
        const double scale = s.f.colwise().norm().maxCoeff();
        ASSERT_GT(scale, 1.0);
        int interior = 0;
        for (int i = 0; i < m.nodes(); ++i) {
            const Eigen::Vector3d X = m.X.col(i);
            if ((X.array() > 1e-9).all() && (X.array() < 1 - 1e-9).all()) {
                EXPECT_LT(s.f.col(i).norm(), 1e-10 * scale) << "node " << i;
                ++interior;
            }
        }
        EXPECT_EQ(interior, 27);
        EXPECT_LT(s.f.rowwise().sum().norm(), 1e-10 * scale);
    }
}

// The blocked force kernel gives, element by element, f_a = -alpha V fraction R sigma g_a with R
// from extractRotation, for a mesh that does not fill whole blocks, with large strains, varied
// fractions and alphas and a few inverted elements (Mueller's branch).
TEST(Forces, BlockKernelMatchesPerElementFormula) {
    const TetMesh box = test::boxMesh(1, 1, 0.5, 3, 3, 1);  // 54 tets: 6 blocks of 8 and a tail of 6
    const Eigen::Matrix3d Rot = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
    for (auto em : {ElementModel::Corotational, ElementModel::Linear}) {
        Model m = buildModel(box, Material{}, em);
        std::mt19937 rng(7);
        std::uniform_real_distribution<double> U(-1, 1);
        Eigen::VectorXd alpha(m.elements());
        for (int e = 0; e < m.elements(); ++e) {
            m.fraction(e) = 0.6 + 0.4 * std::abs(U(rng));
            alpha(e) = 0.5 + 0.5 * std::abs(U(rng));
        }
        State s = makeState(m);
        Eigen::Matrix3Xd x = m.X;
        for (int i = 0; i < m.nodes(); ++i) x.col(i) += 0.08 * Eigen::Vector3d(U(rng), U(rng), U(rng));
        x.col(m.tets(0, 5)) = x.col(m.tets(1, 5)) + 0.5 * (x.col(m.tets(1, 5)) - x.col(m.tets(0, 5)));  // invert
        s.x = Rot * x;
        const Eigen::Matrix<double, 9, Eigen::Dynamic> rot0 = s.rot;
        int kernelInverted = 0;
        elementForces(m, s, alpha.data(), 0, m.elements(), &kernelInverted);
        int inverted = 0;
        const double lam = m.material.lambda(), mu = m.material.mu();
        const double fmax = s.fe.cwiseAbs().maxCoeff();
        ASSERT_GT(fmax, 1.0);
        for (int e = 0; e < m.elements(); ++e) {
            const int* n = m.tets.col(e).data();
            Eigen::Matrix3d Ds;
            Ds << s.x.col(n[1]) - s.x.col(n[0]), s.x.col(n[2]) - s.x.col(n[0]), s.x.col(n[3]) - s.x.col(n[0]);
            const Eigen::Matrix3d F = Ds * m.dmInv(e);
            if (F.determinant() <= 0) ++inverted;
            const Eigen::Matrix3d R = em == ElementModel::Corotational
                                          ? extractRotation(F, Eigen::Map<const Eigen::Matrix3d>(rot0.col(e).data()))
                                          : Eigen::Matrix3d::Identity();
            const Eigen::Matrix3d H = R.transpose() * F - Eigen::Matrix3d::Identity();
            Eigen::Matrix3d sig = mu * (H + H.transpose());
            sig.diagonal().array() += lam * H.trace();
            const Eigen::Matrix3d G = shapeGradients(m.dmInv(e)).rightCols<3>();  // g_1..g_3 as columns
            const Eigen::Matrix3d P = -alpha(e) * m.volume(e) * m.fraction(e) * R * sig * G;
            for (int a = 0; a < 3; ++a)
                EXPECT_LT((s.fe.col(e).segment<3>(3 + 3 * a) - P.col(a)).norm(), 1e-12 * fmax) << "element " << e;
            EXPECT_LT((s.fe.col(e).head<3>() + P.rowwise().sum()).norm(), 1e-12 * fmax) << "element " << e;
            if (em == ElementModel::Corotational) {
                EXPECT_LT((Eigen::Map<const Eigen::Matrix3d>(s.rot.col(e).data()) - R).norm(), 1e-12)
                    << "element " << e;
            }
        }
        EXPECT_GE(inverted, 1);
        EXPECT_EQ(kernelInverted, inverted);
        // ranges that split blocks (as thread ranges may) give the same forces
        const Eigen::Matrix<double, 12, Eigen::Dynamic> fe = s.fe;
        s.fe.setZero();
        s.rot = rot0;
        int inv2 = 0;
        const int cuts[] = {0, 13, 21, 37, m.elements()};
        for (int k = 0; k < 4; ++k) elementForces(m, s, alpha.data(), cuts[k], cuts[k + 1], &inv2);
        EXPECT_EQ(inv2, inverted);
        EXPECT_LT((s.fe - fe).cwiseAbs().maxCoeff(), 1e-14 * fmax);
        // the fused force stage: each node's sum of its element slots plus gravity, and the flags
        m.gravity << 0.5, -1, -9.81;
        s.fExt.setRandom();
        Eigen::Matrix3Xd f(3, m.nodes());
        for (int i = 0; i < m.nodes(); ++i) {
            f.col(i) = s.fExt.col(i) + m.mass(i) * m.gravity;
            for (int e = 0; e < m.elements(); ++e)
                for (int a = 0; a < 4; ++a)
                    if (m.tets(a, e) == i) f.col(i) += fe.col(e).segment<3>(3 * a);
        }
        s.rot = rot0;
        computeForces(m, s, alpha.data());
        EXPECT_LT((s.f - f).cwiseAbs().maxCoeff(), 1e-14 * fmax);
        EXPECT_EQ(s.flags.inverted, inverted);
    }
}

// ForcePrecision::Single runs the kernel in float on 16 lanes: the double kernel's forces to float's
// rounding (F ~ I carries ~6e-8, here against strains ~0.1), the same inverted elements and the
// same rotations to float's precision; block splits do not change a lane's result, and the fused
// stage sums these forces in double. A lane mixed up or a value dropped would be off by ~fmax.
TEST(Forces, SinglePrecisionKernelMatchesDouble) {
    const TetMesh box = test::boxMesh(1, 1, 0.5, 3, 3, 1);  // 54 tets: 3 blocks of 16 and a tail of 6
    for (auto em : {ElementModel::Corotational, ElementModel::Linear}) {
        Model m = buildModel(box, Material{}, em);
        std::mt19937 rng(5);
        std::uniform_real_distribution<double> U(-1, 1);
        Eigen::VectorXd alpha(m.elements());
        for (int e = 0; e < m.elements(); ++e) alpha(e) = 0.5 + 0.5 * std::abs(U(rng));
        State s0 = makeState(m);
        for (int i = 0; i < m.nodes(); ++i) s0.x.col(i) += 0.08 * Eigen::Vector3d(U(rng), U(rng), U(rng));
        s0.x.col(m.tets(0, 37)) = s0.x.col(m.tets(1, 37)) + 0.5 * (s0.x.col(m.tets(1, 37)) - s0.x.col(m.tets(0, 37)));
        State d = s0, f = s0;
        int invD = 0, invF = 0;
        elementForces(m, d, alpha.data(), 0, m.elements(), &invD);
        m.precision = ForcePrecision::Single;
        elementForces(m, f, alpha.data(), 0, m.elements(), &invF);
        const double fmax = d.fe.cwiseAbs().maxCoeff();
        ASSERT_GT(fmax, 1.0);
        const double err = (f.fe - d.fe).cwiseAbs().maxCoeff();
        EXPECT_GT(err, 0) << "the single kernel ran in double";
        EXPECT_LT(err, 2e-6 * fmax);  // measured 2.4e-7 (corotational), 1.2e-7 (linear)
        EXPECT_GE(invD, 1);
        EXPECT_EQ(invF, invD);
        if (em == ElementModel::Corotational) {
            // near-flat and inverted elements keep their rotation (the inverted one from the
            // invertible-FEM path, per lane in double)
            for (int e = 0; e < m.elements(); ++e)
                if (f.rot.col(e) != s0.rot.col(e)) {
                    EXPECT_LT((f.rot.col(e) - d.rot.col(e)).cwiseAbs().maxCoeff(), 1e-5) << "element " << e;
                }
        }
        State g = s0;
        int inv2 = 0;
        const int cuts[] = {0, 13, 21, 37, m.elements()};
        for (int k = 0; k < 4; ++k) elementForces(m, g, alpha.data(), cuts[k], cuts[k + 1], &inv2);
        EXPECT_EQ(inv2, invD);
        EXPECT_EQ((g.fe - f.fe).cwiseAbs().maxCoeff(), 0.0);
        gatherForces(m, f, 0, m.nodes());
        State c = s0;
        computeForces(m, c, alpha.data());
        EXPECT_EQ((c.f - f.f).cwiseAbs().maxCoeff(), 0.0);
    }
}

// computeForces sums each node in element order on any number of threads, both on meshes small
// enough for the per-element slots (9216 tets) and on those where the kernel adds into the nodes
// (34,560 tets, above kFusedElements): its forces are bitwise those of elementForces then
// gatherForces, on one thread and on two (both meshes are above the parallel threshold, so the two
// threads' element ranges share a layer of nodes), in double and in single precision. Without
// allRotations only elements near flat store their rotation; with it, all do.
TEST(Forces, ForceStageIsBitwiseTheGatherOnAnyThreads) {
    for (int nz : {6, 10})
        for (auto precision : {ForcePrecision::Double, ForcePrecision::Single}) {
            const int nxy = nz == 6 ? 16 : 24;
            Model m = buildModel(test::boxMesh(1, 1, 0.25, nxy, nxy, nz), Material{});
            m.precision = precision;
            ASSERT_GE(m.elements(), 9000);
            m.gravity << 0, 0, -9.81;
            std::mt19937 rng(11);
            std::uniform_real_distribution<double> U(-1, 1);
            State s0 = makeState(m);
            const double h = std::min(1.0 / nxy, 0.25 / nz);
            for (int i = 0; i < m.nodes(); ++i) s0.x.col(i) += 0.15 * h * Eigen::Vector3d(U(rng), U(rng), U(rng));
            s0.x.col(m.tets(0, 100)) = s0.x.col(m.tets(1, 100));  // flattens element 100 (and bends its neighbours)
            s0.fExt.setRandom();
            State ref = s0;
            elementForces(m, ref, nullptr, 0, m.elements(), nullptr);
            gatherForces(m, ref, 0, m.nodes());
            for (int threads : {1, 2}) {
                setThreads(threads);
                for (bool all : {false, true}) {
                    State s = s0;
                    s.rot.setConstant(7.0);  // not a rotation: shows which were written
                    computeForces(m, s, nullptr, 0, all);
                    EXPECT_EQ((s.f - ref.f).cwiseAbs().maxCoeff(), 0.0)
                        << m.elements() << " tets, " << threads << " threads";
                    int written = 0;
                    for (int e = 0; e < m.elements(); ++e) {
                        const bool w = s.rot(0, e) != 7.0;
                        written += w;
                        if (w) {
                            EXPECT_EQ(s.rot.col(e), ref.rot.col(e)) << "element " << e;
                        }
                        const int* n = m.tets.col(e).data();
                        Eigen::Matrix3d Ds;
                        Ds << s.x.col(n[1]) - s.x.col(n[0]), s.x.col(n[2]) - s.x.col(n[0]),
                            s.x.col(n[3]) - s.x.col(n[0]);
                        if ((Ds * m.dmInv(e)).determinant() < 0.01) {
                            EXPECT_TRUE(w) << "element " << e << " is near flat";
                        }
                    }
                    if (all) {
                        EXPECT_EQ(written, m.elements());
                    } else {
                        EXPECT_LT(written, m.elements() / 100) << "the others' rotations are not stored";
                    }
                }
            }
        }
    setThreads(0);
}

// A tet with three clamped corners and the fourth pushed through the opposite face is pushed
// back to its rest shape by the corotational force (it would stay inverted with R = polar(F) of
// the wrong sign, or with no rotation that reflects it).
TEST(Forces, InvertedTetRecovers) {
    for (const double depth : {0.3, 1.0, 2.0}) {
        TetMesh t = test::unitTet();
        t.X *= 0.01;
        Model m = buildModel(t, Material{});
        m.massDamping = 200;  // [1/s]: decays e^-20 over the 0.2 s run
        fixNodes(m, {0, 1, 2});
        State s = makeState(m);
        s.x.col(3) << 0.003, 0.002, -depth * 0.01;
        computeForces(m, s);
        ASSERT_EQ(s.flags.inverted, 1);
        Stepper st;
        StepOptions opt;
        opt.dt = 1.0 / std::sqrt(test::denseLambdaMax(m));  // half the critical step
        const int steps = static_cast<int>(0.2 / opt.dt);
        for (int k = 0; k < steps; ++k) st.step(m, s, opt);
        EXPECT_EQ(s.flags.inverted, 0) << depth;
        EXPECT_LT((s.x.col(3) - m.X.col(3)).norm(), 1e-6) << depth;  // 1e-4 of the edge
    }
}

// A light node (Model::lightNodes) moving alone from rest positions: the force is zero, its
// neighbours are at rest, so one symplectic Euler step keeps 1 / (1 + c dt) = 2/3 of its velocity
// and moves it by dt times that; an ordinary node keeps all of it.
TEST(Integrate, LightNodeVelocityIsDampedImplicitly) {
    TetMesh t = test::unitTet();
    t.X *= 0.01;
    for (const bool light : {true, false}) {
        Model m = buildModel(t, Material{});
        buildIncidence(m);
        if (light) m.lightNodes = {3};
        State s = makeState(m);
        const Eigen::Vector3d v0(0.3, -0.2, 0.1);
        s.v.col(3) = v0;
        Stepper st;
        StepOptions opt;
        opt.dt = 1e-6;
        st.step(m, s, opt);
        const double keep = light ? 2.0 / 3.0 : 1.0;
        EXPECT_LT((s.v.col(3) - keep * v0).norm(), 1e-12);
        EXPECT_LT((s.x.col(3) - m.X.col(3) - opt.dt * keep * v0).norm(), 1e-15);
        for (int i = 0; i < 3; ++i) EXPECT_LT(s.v.col(i).norm(), 1e-9);  // only elastic forces of the 1e-7 m move
    }
}

// Row-sum lumping: every tet gives rho V / 4 to its nodes; gravity gives total weight.
TEST(Model, LumpedMassAndGravity) {
    const TetMesh box = test::boxMesh(0.2, 0.1, 0.1, 4, 2, 2);
    Model m = buildModel(box, Material{30e3, 0.3, 1100});
    EXPECT_NEAR(m.mass.sum(), 1100 * 0.002, 1e-12);
    m.gravity << 0, 0, -9.81;
    State s = makeState(m);
    computeForces(m, s);
    EXPECT_NEAR(s.f.row(2).sum(), -9.81 * 1100 * 0.002, 1e-10);
    EXPECT_NEAR(s.f.row(0).sum(), 0.0, 1e-12);
}

// Zero and inverted elements are refused by index.
TEST(Model, RejectsDegenerateElements) {
    TetMesh t = test::unitTet();
    t.X.col(3) << 0.3, 0.3, 0.0;  // flat
    try {
        buildModel(t, Material{});
        FAIL() << "zero volume accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("element 0 has zero volume"), std::string::npos) << e.what();
    }
    EXPECT_THROW(buildModel(test::unitTet(), Material{30e3, 0.5, 1000}), InputError);
}

// The explicit schemes are stable below 2/sqrt(lambda_max(M^-1 K)) and unstable above it:
// an undamped run at 0.9 of the exact limit keeps its energy bounded for 10^4 steps, at 1.05 it
// blows up. This proves both the integrators and the limit.
class StabilityLimit : public ::testing::TestWithParam<Integrator> {};

TEST_P(StabilityLimit, BoundedBelowDivergentAbove) {
    const TetMesh box = test::boxMesh(0.1, 0.04, 0.04, 5, 2, 2);
    Model m = buildModel(box, Material{}, ElementModel::Linear);
    test::fixBelow(m, 0, 1e-9);
    const double dtCrit = denseCriticalDt(m);
    for (double frac : {0.9, 1.05}) {
        State s = makeState(m);
        std::mt19937 rng(7);
        std::normal_distribution<double> N;
        for (int i = 0; i < m.nodes(); ++i)
            if (m.invMass(i) > 0) s.v.col(i) << N(rng), N(rng), N(rng);
        s.v *= 1e-4;
        Stepper stepper;
        StepOptions opt{GetParam(), frac * dtCrit};
        const double E0 = kineticEnergy(m, s);
        double Emax = 0, EmaxEarly = 0;
        for (int k = 0; k < 10000; ++k) {
            stepper.step(m, s, opt);
            const double E = kineticEnergy(m, s) + elasticEnergy(m, s);
            if (!std::isfinite(E) || E > 1e6 * E0) {
                Emax = E;
                break;
            }
            Emax = std::max(Emax, E);
            if (k < 1000) EmaxEarly = Emax;
        }
        if (frac < 1) {
            EXPECT_TRUE(s.flags.ok());
            // discrete energy oscillates with the top mode but does not grow
            EXPECT_LT(Emax, 10 * E0);
            EXPECT_LT(Emax, 1.05 * EmaxEarly);
        } else {
            EXPECT_TRUE(!std::isfinite(Emax) || Emax > 1e6 * E0) << "no blow-up at 1.05 dt_crit";
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Explicit, StabilityLimit,
                         ::testing::Values(Integrator::SymplecticEuler, Integrator::CentralDifference,
                                           Integrator::Newmark),
                         [](const auto& p) { return std::string(integratorName(p.param)); });

// Newmark's damping factor alpha = (dt_crit/dt)^2 keeps a step above the limit stable (eq. 3.15).
TEST(Newmark, AlphaStabilisesAboveLimit) {
    const TetMesh box = test::boxMesh(0.1, 0.04, 0.04, 5, 2, 2);
    Model m = buildModel(box, Material{}, ElementModel::Linear);
    const double dtCrit = denseCriticalDt(m);
    State s = makeState(m);
    s.v.setRandom();
    s.v *= 1e-4;
    const double E0 = kineticEnergy(m, s);
    Stepper stepper;
    StepOptions opt{Integrator::Newmark, 1.5 * dtCrit};
    opt.alpha = 0.95 / (1.5 * 1.5);
    for (int k = 0; k < 5000; ++k) stepper.step(m, s, opt);
    EXPECT_LT(kineticEnergy(m, s) + elasticEnergy(m, s), 10 * E0);
}

namespace {
// Cantilever: length L along x, square section h, clamped at x = 0, under gravity -z.
Model cantilever(int nx, int nyz, ElementModel em = ElementModel::Linear, int nz = 0) {
    const double L = 1.0, h = 0.1;
    Model m = buildModel(test::boxMesh(L, h, h, nx, nyz, nz > 0 ? nz : nyz), Material{1e8, 0.3, 1000}, em);
    test::fixBelow(m, 0, 1e-9);
    m.gravity << 0, 0, -9.81;
    return m;
}

double meanTipDeflection(const Model& m, const Eigen::Matrix3Xd& x) {
    double sum = 0;
    int n = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) > 1.0 - 1e-9) {
            sum += x(2, i) - m.X(2, i);
            ++n;
        }
    return sum / n;
}

// Static linear solve K u = f on free DOFs.
Eigen::Matrix3Xd staticSolve(const Model& m) {
    const Eigen::SparseMatrix<double> K = assembleStiffness(m);
    std::vector<int> map(3 * m.nodes(), -1);
    int nf = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0)
            for (int k = 0; k < 3; ++k) map[3 * i + k] = nf++;
    std::vector<Eigen::Triplet<double>> t;
    for (int c = 0; c < K.outerSize(); ++c)
        for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
            if (map[it.row()] >= 0 && map[it.col()] >= 0) t.emplace_back(map[it.row()], map[it.col()], it.value());
    Eigen::SparseMatrix<double> Kf(nf, nf);
    Kf.setFromTriplets(t.begin(), t.end());
    Eigen::VectorXd f(nf);
    for (int i = 0; i < m.nodes(); ++i)
        for (int k = 0; k < 3; ++k)
            if (map[3 * i + k] >= 0) f(map[3 * i + k]) = m.mass(i) * m.gravity(k);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(Kf);
    const Eigen::VectorXd u = ldlt.solve(f);
    Eigen::Matrix3Xd x = m.X;
    for (int i = 0; i < m.nodes(); ++i)
        for (int k = 0; k < 3; ++k)
            if (map[3 * i + k] >= 0) x(k, i) += u(map[3 * i + k]);
    return x;
}
}  // namespace

// Static tip deflection against Euler-Bernoulli q L^4 / (8 E I) plus Timoshenko shear
// q L^2 / (2 kappa G A), kappa = 5/6: the 3D solution on a fine mesh is within a few percent.
TEST(Cantilever, StaticDeflectionMatchesBeamTheory) {
    const Model m = cantilever(100, 4, ElementModel::Linear, 16);  // 38400 tets, 16 through the depth
    const double L = 1, h = 0.1, E = 1e8, G = E / 2.6, q = 1000 * 9.81 * h * h, I = h * h * h * h / 12;
    const double beam = q * L * L * L * L / (8 * E * I) + q * L * L / (2 * (5.0 / 6.0) * G * h * h);
    const double tip = -meanTipDeflection(m, staticSolve(m));
    RecordProperty("tip_over_beam", std::to_string(tip / beam));
    EXPECT_NEAR(tip / beam, 1.0, 0.04) << "tip " << tip << " beam " << beam;
}

// Damped dynamics settle on the static solution: explicit corotational at 0.9 of its limit and
// implicit backward Euler at a far larger step agree with the linear static solve.
TEST(Cantilever, DynamicsSettleOnStaticSolution) {
    Model m = cantilever(10, 2, ElementModel::Corotational);
    m.massDamping = 40;
    const double ref = meanTipDeflection(m, staticSolve(m));
    const double dtCrit = denseCriticalDt(m);
    {
        State s = makeState(m);
        Stepper st;
        StepOptions opt{Integrator::SymplecticEuler, 0.9 * dtCrit};
        while (s.time < 0.6) st.step(m, s, opt);
        EXPECT_NEAR(meanTipDeflection(m, s.x) / ref, 1.0, 0.01);
    }
    {
        State s = makeState(m);
        Stepper st;
        StepOptions opt{Integrator::BackwardEuler, 100 * dtCrit};
        while (s.time < 0.6) st.step(m, s, opt);
        EXPECT_NEAR(meanTipDeflection(m, s.x) / ref, 1.0, 0.01);
    }
}

// The single-precision kernel follows the double one on the bar swinging down under gravity
// (strains ~1e-3, so float's ~6e-8 on F is ~1e-4 of the stress): the tip's path over 0.2 s stays
// within 1e-4 of its largest deflection.
TEST(Cantilever, SinglePrecisionFollowsDouble) {
    Model m = cantilever(10, 2, ElementModel::Corotational);
    const double dt = 0.9 * denseCriticalDt(m);
    State d = makeState(m), f = makeState(m);
    Stepper sd, sf;
    const StepOptions opt{Integrator::SymplecticEuler, dt};
    Model mf = m;
    mf.precision = ForcePrecision::Single;
    double worst = 0, largest = 0;
    while (d.time < 0.2) {
        sd.step(m, d, opt);
        sf.step(mf, f, opt);
        const double td = meanTipDeflection(m, d.x);
        largest = std::max(largest, std::abs(td));
        worst = std::max(worst, std::abs(meanTipDeflection(m, f.x) - td));
    }
    RecordProperty("worst_over_largest", std::to_string(worst / largest));
    EXPECT_GT(largest, 1e-3);
    EXPECT_GT(worst, 0);
    EXPECT_LT(worst, 1e-4 * largest);  // measured 1.3e-5
}

// Backward Euler's CG solve gives the direct solve's steps: a bar swinging down under gravity at
// 10 times the explicit limit (dt^2 K far from small against M), 20 steps each.
TEST(BackwardEuler, CgMatchesTheDirectSolve) {
    Model m = cantilever(10, 2, ElementModel::Corotational);
    const double dt = 10 * denseCriticalDt(m);
    State a = makeState(m), b = makeState(m);
    Stepper sa, sb;
    StepOptions direct{Integrator::BackwardEuler, dt}, cg = direct;
    cg.solver = ImplicitSolver::ConjugateGradient;
    cg.cgTolerance = 1e-12;
    for (int k = 0; k < 20; ++k) {
        sa.step(m, a, direct);
        sb.step(m, b, cg);
        EXPECT_EQ(sa.lastSolverIterations(), 0);
        EXPECT_GT(sb.lastSolverIterations(), 0);
    }
    const double travel = (a.x - m.X).cwiseAbs().maxCoeff();
    ASSERT_GT(travel, 1e-4);
    EXPECT_LT((a.x - b.x).cwiseAbs().maxCoeff(), 1e-9 * travel);
    EXPECT_LT((a.v - b.v).cwiseAbs().maxCoeff(), 1e-9 * a.v.cwiseAbs().maxCoeff());
}

// A free body at rest under gravity: the uniform velocity dt g is in the null space of K, so
// (M + dt^2 K) v = M dt g gives v = dt g at every node, exactly, with either solver.
TEST(BackwardEuler, FreeBodyFallsByHand) {
    Model m = buildModel(test::boxMesh(0.2, 0.1, 0.1, 4, 2, 2), Material{});
    m.gravity << 0, 0, -9.81;
    for (ImplicitSolver solver : {ImplicitSolver::Direct, ImplicitSolver::ConjugateGradient}) {
        State s = makeState(m);
        Stepper st;
        StepOptions opt{Integrator::BackwardEuler, 0.01};
        opt.solver = solver;
        st.step(m, s, opt);
        for (int i = 0; i < m.nodes(); ++i) {
            EXPECT_NEAR(s.v(2, i), -0.0981, 1e-9) << implicitSolverName(solver) << " node " << i;
            EXPECT_NEAR(s.v(0, i), 0, 1e-9);
            EXPECT_NEAR(s.x(2, i) - m.X(2, i), -0.000981, 1e-11);
        }
    }
    EXPECT_EQ(parseImplicitSolver("cg"), ImplicitSolver::ConjugateGradient);
    EXPECT_THROW(parseImplicitSolver("lu"), InputError);
}

// A non-finite velocity reaches the CG solve as a flag, at once, not as a search to the cap.
TEST(BackwardEuler, CgFlagsNonFinite) {
    Model m = cantilever(10, 2, ElementModel::Corotational);
    State s = makeState(m);
    s.v(2, m.nodes() - 1) = std::numeric_limits<double>::quiet_NaN();
    Stepper st;
    StepOptions opt{Integrator::BackwardEuler, 1e-3};
    opt.solver = ImplicitSolver::ConjugateGradient;
    st.step(m, s, opt);
    EXPECT_GT(s.flags.nonFinite, 0);
    EXPECT_EQ(st.lastSolverIterations(), 0);
}

// Non-finite values are flagged, not hidden.
TEST(Stepper, FlagsNonFinite) {
    Model m = buildModel(test::boxMesh(1, 1, 1, 1, 1, 1), Material{});
    State s = makeState(m);
    s.v(0, 3) = std::numeric_limits<double>::quiet_NaN();
    Stepper st;
    st.step(m, s, StepOptions{Integrator::SymplecticEuler, 1e-5});
    EXPECT_GT(s.flags.nonFinite, 0);
}
