// Exact, certified and per-element time steps (docs/method.md sec. 2-3, thesis ch. 4).
// GCC 12 flags Eigen's AVX-512 max reduction (a system header) as uninitialized: a false positive.
#pragma GCC diagnostic ignored "-Wuninitialized"

#include "bench/random_cuts.hpp"
#include "fem/model.hpp"
#include "fem/tet.hpp"
#include "mesh/io.hpp"
#include "test_support.hpp"
#include "timestep/quality.hpp"
#include "timestep/timestep.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

namespace cutsim {
namespace {

using test::denseLambdaMax;

TetMesh regularTet(double a) {
    TetMesh t;
    t.X.resize(3, 4);
    t.X << 0, a, a / 2, a / 2,                                 //
        0, 0, a * std::sqrt(3.0) / 2, a * std::sqrt(3.0) / 6,  //
        0, 0, 0, a * std::sqrt(2.0 / 3.0);
    t.tets.resize(4, 1);
    t.tets << 0, 1, 2, 3;
    t.source = "regular";
    return t;
}

double minOf(const Eigen::VectorXd& v) { return v.minCoeff(); }

TEST(LargestEigenvalue, MatchesDenseSolverOnRandomAndDegenerateMatrices) {
    std::mt19937 rng(7);
    std::normal_distribution<double> nd;
    for (int t = 0; t < 200; ++t) {
        Mat12 B;
        for (int i = 0; i < 144; ++i) B(i) = nd(rng);
        const int rank = 1 + t % 12;
        Mat12 A = B.leftCols(rank) * B.leftCols(rank).transpose() * std::pow(10.0, t % 7 - 3);
        const double ref = Eigen::SelfAdjointEigenSolver<Mat12>(A).eigenvalues().maxCoeff();
        EXPECT_NEAR(largestEigenvalue(A), ref, 1e-12 * ref) << "case " << t;
    }
    // Repeated eigenvalues and reducible matrices.
    EXPECT_DOUBLE_EQ(largestEigenvalue(Mat12::Identity() * 3), 3);
    EXPECT_EQ(largestEigenvalue(Mat12::Zero()), 0);
    Mat12 D = Mat12::Zero();
    D.diagonal() << 1, 5, 5, 2, 5, 0, 0, 1, 3, 4, 5, 2;
    EXPECT_DOUBLE_EQ(largestEigenvalue(D), 5);
}

// The estimators' path: 8 matrices at a time on vector lanes, with splits (zero rows, repeated
// eigenvalues) finished per lane. Against Eigen's dense solver and the scalar routine.
TEST(LargestEigenvalue, LanesMatchDenseSolverOnSpdZeroRowAndRepeatedCases) {
    std::mt19937 rng(11);
    std::normal_distribution<double> nd;
    std::vector<Mat12, Eigen::aligned_allocator<Mat12>> A;
    for (int t = 0; t < 120; ++t) {
        Mat12 B;
        for (int i = 0; i < 144; ++i) B(i) = nd(rng);
        Mat12 M;
        if (t % 3 == 2) {
            // Repeated eigenvalues: Q diag Q^T with a spectrum of few distinct values.
            const Eigen::HouseholderQR<Mat12> qr(B);
            const Mat12 Q = qr.householderQ();
            Vec12 ev;
            for (int i = 0; i < 12; ++i) ev(i) = 1 + (i * (t % 5 + 1)) % 3;
            M = Q * ev.asDiagonal() * Q.transpose();
        } else {
            M = B * B.transpose() + 0.1 * Mat12::Identity();  // SPD
        }
        M *= std::pow(10.0, t % 9 - 4);
        // Fixed nodes: their three rows and columns are zero, as in K_r.
        for (int a = 0; a < 4; ++a)
            if ((t >> a) % 5 == 1) {
                M.middleRows<3>(3 * a).setZero();
                M.middleCols<3>(3 * a).setZero();
            }
        M = 0.5 * (M + M.transpose()).eval();
        A.push_back(M);
    }
    A.push_back(Mat12::Identity() * 3);
    A.push_back(Mat12::Zero());
    Mat12 D = Mat12::Zero();
    D.diagonal() << 1, 5, 5, 2, 5, 0, 0, 1, 3, 4, 5, 2;
    A.push_back(D);
    const int n = static_cast<int>(A.size());  // not a multiple of 8: the last block is padded
    std::vector<double> lanes(A.size());
    largestEigenvalues(A.data(), n, lanes.data());
    int zeroRows = 0;
    for (int t = 0; t < n; ++t) {
        const double ref = Eigen::SelfAdjointEigenSolver<Mat12>(A[t], Eigen::EigenvaluesOnly).eigenvalues()(11);
        EXPECT_NEAR(lanes[t], ref, 1e-12 * ref) << "case " << t;
        EXPECT_NEAR(lanes[t], largestEigenvalue(A[t]), 1e-12 * ref) << "case " << t;
        zeroRows += A[t].row(0).isZero() || A[t].row(3).isZero();
    }
    EXPECT_GE(zeroRows, 20);
    EXPECT_DOUBLE_EQ(lanes[n - 3], 3);
    EXPECT_EQ(lanes[n - 2], 0);
    EXPECT_DOUBLE_EQ(lanes[n - 1], 5);
}

// R1R and the element eigenvalue of every element of the liver, fixed at its back, some elements
// virtual: the lane path against 12x12 dense solves built from the assembled sparse K.
TEST(Estimators, LanePathMatchesDenseSolvesOnMeshElements) {
    ReadOptions ro;
    ro.scale = 0.0254;
    Model m = buildModel(readTetMesh(test::data("tet/sofa_liver.msh"), ro), Material{});
    for (int i = 0; i < m.nodes(); ++i) m.fixed[static_cast<size_t>(i)] = m.X(2, i) < kSceneLiverClampZ;
    for (int e = 0; e < m.elements(); e += 7) m.fraction(e) = 0.1 + 0.8 * (e % 5) / 5.0;
    updateMasses(m);
    const Eigen::SparseMatrix<double> K = assembleStiffness(m);
    const StiffnessRows rows = assembleStiffnessRows(m);
    std::vector<int> elems(static_cast<size_t>(m.elements()));
    for (int e = 0; e < m.elements(); ++e) elems[static_cast<size_t>(e)] = e;
    std::vector<double> r1r(elems.size()), element(elems.size());
    r1rLambdas(m, rows, elems.data(), m.elements(), r1r.data());
    elementLambdas(m, elems.data(), m.elements(), element.data());
    int withFixed = 0;
    for (int e = 0; e < m.elements(); ++e) {
        Mat12 Kr, Ke;
        const Mat12 Kel = elementStiffness(shapeGradients(m.dmInv(e)), m.volume(e), m.material);
        bool fixedNode = false;
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b) {
                const int i = m.tets(a, e), j = m.tets(b, e);
                const double si = std::sqrt(m.invMass(i)), sj = std::sqrt(m.invMass(j));
                const double own = (m.invMass(i) > 0 && m.invMass(j) > 0) ? 4.0 / (m.material.rho * m.volume(e)) : 0.0;
                for (int r = 0; r < 3; ++r)
                    for (int c = 0; c < 3; ++c) {
                        Kr(3 * a + r, 3 * b + c) = si * sj * K.coeff(3 * i + r, 3 * j + c);
                        Ke(3 * a + r, 3 * b + c) = own * Kel(3 * a + r, 3 * b + c);
                    }
                fixedNode |= !(m.invMass(i) > 0);
            }
        withFixed += fixedNode;
        const double refR = Eigen::SelfAdjointEigenSolver<Mat12>(Kr, Eigen::EigenvaluesOnly).eigenvalues()(11);
        const double refE = Eigen::SelfAdjointEigenSolver<Mat12>(Ke, Eigen::EigenvaluesOnly).eigenvalues()(11);
        EXPECT_NEAR(r1r[static_cast<size_t>(e)], refR, 1e-12 * refR) << "element " << e;
        EXPECT_NEAR(element[static_cast<size_t>(e)], refE, 1e-12 * refE) << "element " << e;
        // The single-element entry points are the same computation.
        EXPECT_EQ(r1rLambda(m, rows, e), r1r[static_cast<size_t>(e)]);
        EXPECT_EQ(elementLambda(m, e), element[static_cast<size_t>(e)]);
    }
    EXPECT_GT(withFixed, 10);
}

TEST(ExactDt, SingleRegularTetAgreesWithR1RElementAndDenseSolve) {
    const Model m = buildModel(regularTet(0.01), Material{});
    const double ref = denseLambdaMax(m);
    const ExactResult ex = exactCriticalDt(m);
    EXPECT_NEAR(ex.lambdaMax, ref, 1e-9 * ref);
    const StiffnessRows rows = assembleStiffnessRows(m);
    // One tet: K_r is K_e and M_r is M_e, so R1R == element eigenvalue == exact.
    EXPECT_NEAR(r1rLambda(m, rows, 0), ref, 1e-10 * ref);
    EXPECT_NEAR(elementLambda(m, 0), ref, 1e-10 * ref);
    // Closed form check of the scale: lambda ~ c_p^2 / a^2 times a shape constant, so doubling
    // the edge divides lambda by 4.
    const Model m2 = buildModel(regularTet(0.02), Material{});
    EXPECT_NEAR(exactCriticalDt(m2).lambdaMax, ref / 4, 1e-9 * ref);
    // Certified: Gershgorin is above lambda_max, so its dt is below.
    EXPECT_LE(certifiedDt(m), ex.dt);
}

TEST(ExactDt, SmallBoxMatchesDenseSolveWithAndWithoutFixedNodes) {
    Model m = buildModel(test::boxMesh(0.1, 0.08, 0.05, 3, 3, 2), Material{});
    const double free = denseLambdaMax(m);
    EXPECT_NEAR(exactCriticalDt(m).lambdaMax, free, 1e-8 * free);
    std::vector<int> bottom;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(2, i) == 0) bottom.push_back(i);
    fixNodes(m, bottom);
    const double fixed = denseLambdaMax(m);
    const ExactResult ex = exactCriticalDt(m);
    EXPECT_NEAR(ex.lambdaMax, fixed, 1e-8 * fixed);
    EXPECT_EQ(ex.freeDofs, 3 * (m.nodes() - static_cast<int>(bottom.size())));
}

TEST(ExactDt, FixedNodesRaiseDt) {
    Model m = buildModel(test::boxMesh(0.1, 0.1, 0.1, 4, 4, 4), Material{});
    const double freeDt = exactCriticalDt(m).dt;
    const ElementEstimates freeEst = estimateElements(m);
    std::vector<int> fixedNodes;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) == 0 || m.X(2, i) == 0) fixedNodes.push_back(i);
    fixNodes(m, fixedNodes);
    const double fixedDt = exactCriticalDt(m).dt;
    EXPECT_GE(fixedDt, freeDt * (1 - 1e-9));
    const ElementEstimates est = estimateElements(m);
    bool raised = false;
    for (int e = 0; e < m.elements(); ++e) {
        EXPECT_GE(est.r1r(e), freeEst.r1r(e) * (1 - 1e-12));
        EXPECT_GE(est.element(e), freeEst.element(e) * (1 - 1e-12));
        raised |= est.r1r(e) > freeEst.r1r(e) * 1.01;
    }
    EXPECT_TRUE(raised);
    // All nodes fixed: nothing can oscillate.
    std::vector<int> all(m.nodes());
    for (int i = 0; i < m.nodes(); ++i) all[i] = i;
    fixNodes(m, all);
    EXPECT_TRUE(std::isinf(exactCriticalDt(m).dt));
    EXPECT_TRUE(std::isinf(certifiedDt(m)));
}

// Two free regular tets, edges 2a and a, not connected: lambda scales as 1 / edge^2, so the small
// one's spectrum is 4x the large one's. Keeping the large one's step needs the small one's masses
// x4 (its top mode is the breathing mode, which moves the four corners alike, so the mass asked
// for is the same at each), x4 / (1 - margin) with the aim's margin: 3 m_small and a little more
// added, nothing on the large tet.
TEST(KeepStep, SlowsOnlyTheModesAboveTheTargetByHand) {
    const TetMesh big = regularTet(0.02), small = regularTet(0.01);
    TetMesh t;
    t.X.resize(3, 8);
    t.X.leftCols(4) = big.X;
    t.X.rightCols(4) = small.X.colwise() + Eigen::Vector3d(0.1, 0, 0);
    t.tets.resize(4, 2);
    t.tets.col(0) << 0, 1, 2, 3;
    t.tets.col(1) << 4, 5, 6, 7;
    Model m = buildModel(t, Material{});
    const Eigen::VectorXd mass0 = m.mass;
    const double dtBig = 2 / std::sqrt(denseLambdaMax(buildModel(big, Material{})));
    EXPECT_NEAR(2 / std::sqrt(denseLambdaMax(m)), dtBig / 2, 1e-9 * dtBig);

    const KeepStepOptions opts;
    const double scale = 4 / (1 - opts.margin);  // the small tet's masses, by hand
    const KeepStepResult r = keepStep(m, dtBig, opts);
    EXPECT_TRUE(r.reached);
    EXPECT_NEAR(r.dtBefore, dtBig / 2, 1e-8 * dtBig);
    const double dtAfter = 2 / std::sqrt(denseLambdaMax(m));  // independent of the Lanczos path
    EXPECT_GE(dtAfter, dtBig * (1 - 1e-9));
    EXPECT_NEAR(dtAfter, dtBig, 1e-9 * dtBig);  // the large tet's own step is now the model's
    EXPECT_NEAR(r.dtAfter, dtBig, 1e-8 * dtBig);
    const double mSmall = mass0.tail(4).sum();
    EXPECT_NEAR(r.addedMass, (scale - 1) * mSmall, 1e-6 * mSmall);
    EXPECT_NEAR(r.massFraction, (scale - 1) * mSmall / mass0.sum(), 1e-6);
    for (int i = 0; i < 4; ++i) {
        EXPECT_LT(m.addedMass(i), 1e-12 * mass0(i)) << "node " << i << " of the large tet";
        EXPECT_NEAR(m.addedMass(4 + i), (scale - 1) * mass0(4 + i), 1e-6 * mass0(4 + i));
    }
    // The added mass is part of the lumped mass, and survives a recomputation.
    updateMasses(m);
    EXPECT_NEAR(m.mass.sum(), mass0.sum() + r.addedMass, 1e-12 * m.mass.sum());

    // Already there: nothing added, one eigen-solve.
    const Eigen::VectorXd added = m.addedMass;
    const KeepStepResult again = keepStep(m, dtBig);
    EXPECT_TRUE(again.reached);
    EXPECT_EQ(again.addedMass, 0.0);
    EXPECT_EQ(again.nodes, 0);
    EXPECT_EQ(again.rounds, 1);
    EXPECT_EQ(m.addedMass, added);
}

// Fixed nodes take no mass, and a bad target is refused.
TEST(KeepStep, FixedNodesTakeNoMass) {
    Model m = buildModel(test::boxMesh(0.03, 0.02, 0.02, 3, 2, 2), Material{});
    test::fixBelow(m, 0, 1e-9);
    const double dt0 = exactCriticalDt(m).dt;
    const KeepStepResult r = keepStep(m, 1.5 * dt0);
    EXPECT_TRUE(r.reached);
    EXPECT_GE(2 / std::sqrt(denseLambdaMax(m)), 1.5 * dt0 * (1 - 1e-9));
    for (int i = 0; i < m.nodes(); ++i)
        if (m.fixed[i]) {
            EXPECT_EQ(m.addedMass(i), 0.0) << "fixed node " << i;
        }
    // At most the uniform scaling (x 2.25) that reaches the target exactly, and more than nothing.
    double freeMass = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (!m.fixed[i]) freeMass += m.mass(i) - m.addedMass(i);
    EXPECT_GT(r.addedMass, 0.1 * freeMass);
    EXPECT_LE(r.addedMass, 1.25 * freeMass * (1 + 1e-6));
    EXPECT_THROW(keepStep(m, 0.0), std::invalid_argument);
    EXPECT_THROW(keepStep(m, std::nan("")), std::invalid_argument);
}

TEST(Estimators, HsUsesTheDiagonalOfTheAssembledStiffness) {
    Model m = buildModel(test::boxMesh(0.1, 0.07, 0.05, 3, 2, 2), Material{});
    m.fraction(3) = 0.4;  // a virtual element: its stiffness is scaled too
    fixNodes(m, {0, 5});
    const Eigen::SparseMatrix<double> K = assembleStiffness(m);
    const Eigen::Matrix3Xd diag = assembleStiffnessDiagonal(m);
    for (int i = 0; i < m.nodes(); ++i)
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(diag(k, i), K.coeff(3 * i + k, 3 * i + k), 1e-9 * diag(k, i));
    for (int e = 0; e < m.elements(); ++e) {
        double mx = 0;
        std::vector<double> D;
        for (int a = 0; a < 4; ++a)
            for (int k = 0; k < 3; ++k) {
                const int n = m.tets(a, e);
                D.push_back(K.coeff(3 * n + k, 3 * n + k) * m.invMass(n));
                mx = std::max(mx, D.back());
            }
        EXPECT_NEAR(hsLambda(m, diag, e), mx, 1e-9 * mx);
        // Hp reading (docs/method.md sec. 3): j is the first index whose preceding sum exceeds half.
        std::sort(D.rbegin(), D.rend());
        double total = 0, run = 0, hp = -1;
        for (double d : D) total += d;
        for (size_t j = 0; j < D.size() && hp < 0; ++j) {
            if (run > total / 2) hp = D[0] + D[j];
            run += D[j];
        }
        EXPECT_NEAR(hpLambda(m, diag, e), hp, 1e-9 * hp);
    }
}

TEST(Estimators, CharacteristicLengthIsTheSmallestHeight) {
    const Model m = buildModel(regularTet(0.03), Material{});
    EXPECT_NEAR(characteristicLength(m, 0), 0.03 * std::sqrt(2.0 / 3.0), 1e-12);
    EXPECT_NEAR(estimateElements(m).le(0), 0.03 * std::sqrt(2.0 / 3.0) / m.material.pWaveSpeed(), 1e-15);
}

// Bounds that must hold on any mesh: certified <= exact <= min R1R (interlacing), and the
// element eigenvalue bound min dt_element <= exact.
void expectBounds(const Model& m, const std::string& what) {
    const StiffnessRows rows = assembleStiffnessRows(m);
    const ExactResult ex = exactCriticalDt(m, rows);
    const double cert = certifiedDt(m, rows);
    ElementEstimates est;
    estimateElements(m, rows, assembleStiffnessDiagonal(m), nullptr, est);
    EXPECT_LE(cert, ex.dt) << what;
    EXPECT_GT(cert, 0.3 * ex.dt) << what;
    EXPECT_GE(minOf(est.r1r), ex.dt * (1 - 1e-7)) << what;
    EXPECT_LE(minOf(est.element), ex.dt * (1 + 1e-7)) << what;
}

TEST(Bounds, HoldOnBoxes) {
    expectBounds(buildModel(test::boxMesh(1, 1, 1, 1, 1, 1), Material{}), "unit cube");
    expectBounds(buildModel(test::boxMesh(0.1, 0.02, 0.03, 8, 2, 3), Material{}), "bar");
    expectBounds(buildModel(test::boxMesh(0.05, 0.05, 0.05, 6, 6, 6), Material{2e5, 0.45, 1100}), "cube");
}

TEST(Bounds, HoldOnRandomlyPerturbedBoxes) {
    std::mt19937 rng(12345);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int t = 0; t < 50; ++t) {
        const int n = 2 + t % 4;
        TetMesh mesh = test::boxMesh(0.1, 0.08, 0.06, n, n + 1, n);
        const double h = 0.06 / n;
        TetMesh moved = mesh;
        for (int i = 0; i < mesh.nodes(); ++i) {
            for (int k = 0; k < 3; ++k) moved.X(k, i) += 0.2 * h * u(rng);
        }
        bool ok = true;
        for (int e = 0; e < moved.elements(); ++e) ok &= tetSignedVolume(moved, e) > 0;
        if (!ok) moved = mesh;  // keep the case, unperturbed
        Model m = buildModel(moved, Material{});
        // Random virtual elements and fixed nodes.
        for (int e = 0; e < m.elements(); ++e)
            if (u(rng) > 0.8) m.fraction(e) = 0.05 + 0.95 * (u(rng) + 1) / 2;
        std::vector<int> fixedNodes;
        for (int i = 0; i < m.nodes(); ++i)
            if (u(rng) > 0.9) fixedNodes.push_back(i);
        fixNodes(m, fixedNodes);
        expectBounds(m, "perturbed box " + std::to_string(t));
    }
}

TEST(Bounds, HoldOnEveryDataMesh) {
    int seen = 0;
    for (const auto& f : std::filesystem::directory_iterator(test::data("tet"))) {
        ReadOptions opts;
        opts.reorient = false;
        const Model m = buildModel(readTetMesh(f.path().string(), opts), Material{});
        expectBounds(m, f.path().filename().string());
        ++seen;
    }
    EXPECT_GE(seen, 5);
}

// Thesis Table 4.3 (ms), as restated in docs/method.md sec. 3: exact, R1R, Hp, Hs, Le.
struct Table43 {
    const char* file;
    double scale, exact, r1r, hp, hs, le;
};

class ThesisTable43 : public ::testing::TestWithParam<Table43> {};

TEST_P(ThesisTable43, EstimatorsMatchWithinHalfAPercent) {
    const Table43 row = GetParam();
    ReadOptions opts;
    opts.scale = row.scale;
    const Model m = buildModel(readTetMesh(test::data(row.file), opts), Material{});
    const ExactResult ex = exactCriticalDt(m);
    const ElementEstimates est = estimateElements(m);
    auto within = [](double got, double want) { return std::abs(got - want) <= 0.005 * want; };
    EXPECT_PRED2(within, ex.dt * 1e3, row.exact);
    EXPECT_PRED2(within, minOf(est.r1r) * 1e3, row.r1r);
    EXPECT_PRED2(within, minOf(est.hp) * 1e3, row.hp);
    EXPECT_PRED2(within, minOf(est.hs) * 1e3, row.hs);
    EXPECT_PRED2(within, minOf(est.le) * 1e3, row.le);
}

INSTANTIATE_TEST_SUITE_P(
    Meshes, ThesisTable43,
    ::testing::Values(Table43{"tet/sofa_liver.msh", 0.0254, 0.4510, 0.4514, 0.4189, 0.4838, 0.1630},
                      Table43{"tet/sofa_Armadillo_Tetra_4406.vtu", 0.01, 0.0642, 0.0642, 0.0879, 0.1025, 0.0061}),
    [](const ::testing::TestParamInfo<Table43>& p) { return std::string(p.index == 0 ? "liver" : "armadillo"); });

TEST(Shape, RegularTetScoresOne) {
    Eigen::Matrix<double, 3, 4> X = regularTet(2.0).X;
    const TetShape s = tetShape(X);
    EXPECT_NEAR(s.volumeLength, 1, 1e-12);
    EXPECT_NEAR(s.harmonicVolumeLength, 1, 1e-12);
    EXPECT_NEAR(s.minSineDihedral, 2 * std::sqrt(2.0) / 3, 1e-12);
    EXPECT_NEAR(s.radiusRatio, 1, 1e-12);
    EXPECT_NEAR(s.meanRatio, 1, 1e-12);
    EXPECT_NEAR(s.charLength, 2 * std::sqrt(2.0 / 3.0), 1e-12);
    // Right-corner tet: known values (dihedral angles 90 deg at the corner edges).
    X << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
    const TetShape c = tetShape(X);
    EXPECT_NEAR(c.minSineDihedral, std::sqrt(2.0 / 3.0), 1e-12);  // at the slanted edges
    EXPECT_NEAR(c.charLength, 3 * (1.0 / 6) / (std::sqrt(3.0) / 2), 1e-12);
    // r_in = 3V / sum A, r_circ = sqrt(3)/2.
    EXPECT_NEAR(c.radiusRatio, 3 * (0.5 / (1.5 + std::sqrt(3.0) / 2)) / (std::sqrt(3.0) / 2), 1e-12);
    // A sliver scores low on every measure.
    X << 0, 1, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0.01;
    const TetShape sl = tetShape(X);
    for (double q : {sl.volumeLength, sl.harmonicVolumeLength, sl.minSineDihedral, sl.radiusRatio, sl.meanRatio})
        EXPECT_LT(q, 0.1);
}

TEST(Shape, PearsonCorrelation) {
    Eigen::VectorXd a(5), b(5);
    a << 1, 2, 3, 4, 5;
    b << 2, 4, 6, 8, 10;
    EXPECT_NEAR(pearson(a, b), 1, 1e-12);
    EXPECT_NEAR(pearson(a, -b), -1, 1e-12);
    b << 1, -1, 0, 1, -1;
    b(4) = std::numeric_limits<double>::infinity();  // skipped
    EXPECT_TRUE(std::isfinite(pearson(a, b)));
}

// The element eigenvalue through the 6x6 strain-space problem equals the 12x12 one of K_e / M_e
// with fixed DOFs removed, on distorted tets with 0 to 3 fixed nodes.
TEST(ElementLambda, SixBySixMatchesTheTwelveByTwelveProblem) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-0.3, 0.3);
    int checked = 0;
    for (int t = 0; t < 40; ++t) {
        TetMesh mesh = regularTet(0.01);
        for (int i = 0; i < 4; ++i)
            for (int k = 0; k < 3; ++k) mesh.X(k, i) += 0.01 * u(rng);
        const Eigen::Matrix3d E = (Eigen::Matrix3d() << mesh.X.col(1) - mesh.X.col(0), mesh.X.col(2) - mesh.X.col(0),
                                   mesh.X.col(3) - mesh.X.col(0))
                                      .finished();
        if (!(E.determinant() > 1e-3 * 1e-6)) continue;  // keep distorted, not inverted
        Model m = buildModel(mesh, Material{});
        for (int i = 0; i < t % 4; ++i) m.fixed[static_cast<size_t>(i)] = 1;
        updateMasses(m);
        const double V = m.volume(0);
        Mat12 A = elementStiffness(shapeGradients(m.dmInv(0)), V, m.material) * (4.0 / (m.material.rho * V));
        for (int a = 0; a < 4; ++a)
            if (m.fixed[static_cast<size_t>(a)]) {
                A.middleRows<3>(3 * a).setZero();
                A.middleCols<3>(3 * a).setZero();
            }
        const double ref = Eigen::SelfAdjointEigenSolver<Mat12>(A).eigenvalues().maxCoeff();
        EXPECT_NEAR(elementLambda(m, 0), ref, 1e-10 * ref) << "tet " << t;
        ++checked;
    }
    EXPECT_GE(checked, 30);
}

}  // namespace
}  // namespace cutsim
