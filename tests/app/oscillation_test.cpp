// Measured and predicted oscillation of a mode: the signal fit on signals known in closed form,
// the integrators' mode formulas by hand, and both against real runs of the integrators.
#include "bench/oscillation.hpp"
#include "test_support.hpp"
#include "fem/tet.hpp"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <cmath>

using namespace cutsim;

// y = c + A exp(-sigma t) cos(2 pi f t + phi): the fit gives f and sigma back.
TEST(Oscillation, FitsADampedSinusoid) {
    for (double sigma : {0.0, 1.5, -0.4}) {
        std::vector<double> t, y;
        for (int k = 0; k <= 20000; ++k) {
            t.push_back(1e-4 * k);
            y.push_back(-0.3 + 0.02 * std::exp(-sigma * t.back()) * std::cos(2 * M_PI * 5 * t.back() + 0.4));
        }
        const Oscillation o = fitOscillation(t, y);
        EXPECT_NEAR(o.frequency, 5.0, 5e-4) << sigma;
        EXPECT_NEAR(o.decay, sigma, 2e-3) << sigma;
        EXPECT_GE(o.halfCycles, 18);
    }
    // fewer than two upward crossings: no frequency
    const Oscillation flat = fitOscillation({0, 1, 2, 3}, {1, 1, 1, 1});
    EXPECT_EQ(flat.frequency, 0);
}

// w = 10, dt = 0.1 (w dt = 1): backward Euler's z = 1 / (1 + i) decays by 1/sqrt(2) and turns by
// pi/4 per step; symplectic Euler turns by 2 asin(1/2) = pi/3 and keeps its amplitude.
TEST(Oscillation, IntegratorModesByHand) {
    const std::complex<double> be = integratorMode(Integrator::BackwardEuler, 10, 0.1);
    EXPECT_NEAR(be.real(), -std::log(2.0) / 0.2, 1e-12);
    EXPECT_NEAR(be.imag(), M_PI / 4 / 0.1, 1e-12);
    const std::complex<double> se = integratorMode(Integrator::SymplecticEuler, 10, 0.1);
    EXPECT_NEAR(se.real(), 0, 1e-15);
    EXPECT_NEAR(se.imag(), M_PI / 3 / 0.1, 1e-12);
    // |(-ln 2 / 0.2) + i (pi / 0.4 - 10)| / 10
    EXPECT_NEAR(modeError(be, 10), std::hypot(std::log(2.0) / 0.2, M_PI / 0.4 - 10) / 10, 1e-12);
    EXPECT_NEAR(modeError({0, 10.1}, 10), 0.01, 1e-12);
    EXPECT_THROW(integratorMode(Integrator::Newmark, 10, 0.1), std::invalid_argument);
}

// The returned dt meets the target exactly (the error rises with dt); a mesh already off by the
// target leaves no dt.
TEST(Oscillation, BackwardEulerDtForErrorMeetsTheTarget) {
    const double wRef = 32.0;
    for (double meshError : {0.0, 0.005, 0.009}) {
        const double w = wRef * (1 + meshError);
        const double dt = backwardEulerDtForError(w, wRef, 0.01);
        ASSERT_GT(dt, 0) << meshError;
        EXPECT_NEAR(modeError(integratorMode(Integrator::BackwardEuler, w, dt), wRef), 0.01, 1e-9);
        EXPECT_GT(modeError(integratorMode(Integrator::BackwardEuler, w, 1.01 * dt), wRef), 0.01);
    }
    // no period shortfall to offset the decay: damping ratio ~ w dt / 2 = 1% at w dt ~ 0.02
    EXPECT_NEAR(backwardEulerDtForError(wRef, wRef, 0.01) * wRef, 0.02, 2e-4);
    EXPECT_EQ(backwardEulerDtForError(1.01 * wRef, wRef, 0.01), 0);
    EXPECT_EQ(backwardEulerDtForError(1.02 * wRef, wRef, 0.01), 0);
}

// One free corner of a tet (linear elements): three modes of K_33 / m_3, distinct because the
// corner is off the axes. Started along the lowest one, the corner oscillates in it alone; the
// run's fitted frequency and decay are the formula's.
TEST(Oscillation, IntegratorRunsFollowTheirModeFormulas) {
    TetMesh tet = test::unitTet();
    tet.X.col(3) << 0.3, 0.2, 1;  // off the axes
    Model m0 = buildModel(tet, Material{1e4, 0.3, 1000}, ElementModel::Linear);
    fixNodes(m0, {0, 1, 2});
    m0.gravity.setZero();
    const Mat12 K = elementStiffness(shapeGradients(m0.dmInv(0)), m0.volume(0), m0.material);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(K.block<3, 3>(9, 9) / m0.mass(3));
    const double w = std::sqrt(es.eigenvalues()(0)), wMax = std::sqrt(es.eigenvalues()(2));
    const Eigen::Vector3d dir = es.eigenvectors().col(0);
    for (Integrator integ : {Integrator::BackwardEuler, Integrator::SymplecticEuler}) {
        // backward Euler at w dt = 0.15; symplectic Euler at 0.8 of its limit 2 / wMax
        const double dt = integ == Integrator::BackwardEuler ? 0.15 / w : 0.8 * 2 / wMax;
        Model m = m0;
        State s = makeState(m);
        s.x.col(3) += 1e-3 * dir;
        Stepper st;
        const StepOptions opt{integ, dt};
        std::vector<double> t, q;
        const double periods = 12;
        for (int k = 0; k * dt * w < 2 * M_PI * periods; ++k) {
            st.step(m, s, opt);
            t.push_back(s.time);
            q.push_back(dir.dot(s.x.col(3) - m.X.col(3)));
        }
        const Oscillation o = fitOscillation(t, q);
        const std::complex<double> want = integratorMode(integ, w, dt);
        EXPECT_NEAR(2 * M_PI * o.frequency, want.imag(), 2e-3 * want.imag()) << integratorName(integ);
        EXPECT_NEAR(-o.decay, want.real(), 0.02 * std::abs(want.real()) + 1e-3 * w) << integratorName(integ);
    }
}
