#include "fem/forces.hpp"

#include <Eigen/Geometry>
#include <omp.h>

#include <algorithm>
#include <cmath>

namespace cutsim {

// Below this many elements a step is a few tens of microseconds: a fork and barrier would cost
// more than they save, and far more on a loaded machine.
constexpr int kParallelElements = 8192;

State makeState(const Model& m) {
    State s;
    s.x = m.X;
    s.v = Eigen::Matrix3Xd::Zero(3, m.nodes());
    s.f = Eigen::Matrix3Xd::Zero(3, m.nodes());
    s.a = Eigen::Matrix3Xd::Zero(3, m.nodes());
    s.fExt = Eigen::Matrix3Xd::Zero(3, m.nodes());
    resizeState(m, s);
    return s;
}

void resizeState(const Model& m, State& s) {
    const Eigen::Index old = s.rot.cols();
    s.rot.conservativeResize(9, m.elements());
    for (Eigen::Index e = old; e < m.elements(); ++e) s.rot.col(e) << 1, 0, 0, 0, 1, 0, 0, 0, 1;
    s.fe.resize(12, m.elements());
    const Eigen::Index oldN = s.x.cols();
    if (oldN != m.nodes()) {
        for (auto* mat : {&s.x, &s.v, &s.f, &s.a, &s.fExt}) mat->conservativeResize(3, m.nodes());
        for (Eigen::Index i = oldN; i < m.nodes(); ++i) {
            s.x.col(i) = m.X.col(i);
            s.v.col(i).setZero();
            s.f.col(i).setZero();
            s.a.col(i).setZero();
            s.fExt.col(i).setZero();
        }
    }
}

namespace {

// Mueller, Bender, Chentanez, Macklin 2016, "A robust method to extract the rotational part of
// deformations": rotate q about omega until R's columns align with A's. Slow (linear) but proper
// for any A, including inverted ones.
Eigen::Matrix3d muellerRotation(const Eigen::Matrix3d& A, const Eigen::Matrix3d& Rprev) {
    Eigen::Quaterniond q(Rprev);
    Eigen::Matrix3d R = q.toRotationMatrix();
    for (int it = 0; it < 50; ++it) {
        const Eigen::Vector3d num = R.col(0).cross(A.col(0)) + R.col(1).cross(A.col(1)) + R.col(2).cross(A.col(2));
        const double den = std::abs(R.col(0).dot(A.col(0)) + R.col(1).dot(A.col(1)) + R.col(2).dot(A.col(2))) + 1e-12;
        const Eigen::Vector3d w = num / den;
        const double ang = w.norm();
        if (ang < 1e-12) break;
        q = (Eigen::Quaterniond(Eigen::AngleAxisd(ang, w / ang)) * q).normalized();
        R = q.toRotationMatrix();
    }
    return R;
}

} // namespace

namespace {

// extractRotation with det F already known (the force loop needs it for the inverted count).
inline Eigen::Matrix3d polarRotation(const Eigen::Matrix3d& F, double detF, const Eigen::Matrix3d& Rprev) {
    // Newton needs det F well away from 0: its first step divides by it.
    const double scale = F.squaredNorm() / 3.0;
    if (!(detF > 1e-6 * scale * std::sqrt(scale))) return muellerRotation(F, Rprev);
    Eigen::Matrix3d X = F;
    for (int it = 0; it < 30; ++it) {
        // X^-T = cof(X) / det X, with the cofactor columns as cross products of X's columns
        Eigen::Matrix3d C;
        C.col(0) = X.col(1).cross(X.col(2));
        C.col(1) = X.col(2).cross(X.col(0));
        C.col(2) = X.col(0).cross(X.col(1));
        const double halfInvDet = 0.5 / X.col(0).dot(C.col(0));
        const Eigen::Matrix3d Xn = 0.5 * X + halfInvDet * C;
        const double d = (Xn - X).squaredNorm();
        X = Xn;
        if (d < 1e-12) break;  // quadratic convergence: the error of X is now ~d/2 <= 1e-12
    }
    return X;
}

} // namespace

Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& F, const Eigen::Matrix3d& Rprev) {
    return polarRotation(F, F.determinant(), Rprev);
}

namespace {

// Elements per block of the force kernel: one AVX-512 register of doubles. Each quantity of a
// block is held as [component][lane] so the per-element arithmetic runs across lanes; Eigen's
// fixed 3x3 products vectorise only within one element.
constexpr int kLanes = 8;

// Forces of the elements e0 .. e0 + count - 1 (count <= kLanes); lanes past count are padded
// with an undeformed unit element and not written back.
inline int elementBlock(const Model& m, State& s, const double* alpha, int e0, int count, double lam, double mu,
                        bool corot) {
    alignas(64) double F[9][kLanes], X[9][kLanes], Dm[9][kLanes], scale[kLanes];
    alignas(64) int active[kLanes];
    const double* xs = s.x.data();
    for (int l = 0; l < kLanes; ++l) {
        if (l < count) {
            const int e = e0 + l;
            const int* n = m.tets.col(e).data();
            const double* p0 = xs + 3 * n[0];
            const double* dm = m.DmInv.col(e).data();
            double ds[9];  // Ds column-major: columns x_a - x_0, a = 1..3
            for (int a = 0; a < 3; ++a) {
                const double* pa = xs + 3 * n[a + 1];
                for (int r = 0; r < 3; ++r) ds[3 * a + r] = pa[r] - p0[r];
            }
            for (int k = 0; k < 9; ++k) Dm[k][l] = dm[k];
            // F = Ds DmInv, column-major F(r, c) at 3c + r
            for (int c = 0; c < 3; ++c)
                for (int r = 0; r < 3; ++r)
                    F[3 * c + r][l] = ds[r] * dm[3 * c] + ds[3 + r] * dm[3 * c + 1] + ds[6 + r] * dm[3 * c + 2];
            scale[l] = -m.volume(e) * m.fraction(e) * (alpha ? alpha[e] : 1.0);
        } else {
            for (int k = 0; k < 9; ++k) Dm[k][l] = F[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
            scale[l] = 0;
        }
    }
    int inv = 0, anyActive = 0;
#pragma omp simd reduction(+ : inv) reduction(| : anyActive)
    for (int l = 0; l < kLanes; ++l) {
        const double d = F[0][l] * (F[4][l] * F[8][l] - F[7][l] * F[5][l]) -
                         F[3][l] * (F[1][l] * F[8][l] - F[7][l] * F[2][l]) +
                         F[6][l] * (F[1][l] * F[5][l] - F[4][l] * F[2][l]);
        inv += (l < count && d <= 0) ? 1 : 0;
        double sq = 0;
        for (int k = 0; k < 9; ++k) sq += F[k][l] * F[k][l];
        const double sc = sq / 3.0;
        // Newton needs det F well away from 0: its first step divides by it.
        const int newton = corot && d > 1e-6 * sc * std::sqrt(sc);
        active[l] = newton;
        anyActive |= newton;
        for (int k = 0; k < 9; ++k) X[k][l] = F[k][l];
    }
    if (corot) {
        for (int l = 0; l < count; ++l) {
            if (active[l]) continue;
            // degenerate or inverted: Mueller's iteration warm-started from the last rotation
            Eigen::Matrix3d Fl, R;
            for (int k = 0; k < 9; ++k) Fl(k % 3, k / 3) = F[k][l];
            R = muellerRotation(Fl, Eigen::Map<const Eigen::Matrix3d>(s.rot.col(e0 + l).data()));
            for (int k = 0; k < 9; ++k) X[k][l] = R(k % 3, k / 3);
        }
        for (int l = count; l < kLanes; ++l) active[l] = 0;  // padding is already the identity
        // Polar rotation by Newton's iteration X <- (X + X^-T) / 2 (Higham 1986), per lane until
        // that lane's update is below 1e-6 (its error is then ~1e-12); converged lanes are frozen.
        for (int it = 0; it < 30 && anyActive; ++it) {
            anyActive = 0;
#pragma omp simd reduction(| : anyActive)
            for (int l = 0; l < kLanes; ++l) {
                // X^-T = cof(X) / det X, with the cofactor columns as cross products of X's columns
                const double x0 = X[0][l], x1 = X[1][l], x2 = X[2][l], x3 = X[3][l], x4 = X[4][l], x5 = X[5][l],
                             x6 = X[6][l], x7 = X[7][l], x8 = X[8][l];
                const double c0 = x4 * x8 - x5 * x7, c1 = x5 * x6 - x3 * x8, c2 = x3 * x7 - x4 * x6;
                const double c3 = x7 * x2 - x8 * x1, c4 = x8 * x0 - x6 * x2, c5 = x6 * x1 - x7 * x0;
                const double c6 = x1 * x5 - x2 * x4, c7 = x2 * x3 - x0 * x5, c8 = x0 * x4 - x1 * x3;
                const double h = 0.5 / (x0 * c0 + x1 * c1 + x2 * c2);
                const double n0 = 0.5 * x0 + h * c0, n1 = 0.5 * x1 + h * c1, n2 = 0.5 * x2 + h * c2;
                const double n3 = 0.5 * x3 + h * c3, n4 = 0.5 * x4 + h * c4, n5 = 0.5 * x5 + h * c5;
                const double n6 = 0.5 * x6 + h * c6, n7 = 0.5 * x7 + h * c7, n8 = 0.5 * x8 + h * c8;
                const double d = (n0 - x0) * (n0 - x0) + (n1 - x1) * (n1 - x1) + (n2 - x2) * (n2 - x2) +
                                 (n3 - x3) * (n3 - x3) + (n4 - x4) * (n4 - x4) + (n5 - x5) * (n5 - x5) +
                                 (n6 - x6) * (n6 - x6) + (n7 - x7) * (n7 - x7) + (n8 - x8) * (n8 - x8);
                const int a = active[l];
                X[0][l] = a ? n0 : x0; X[1][l] = a ? n1 : x1; X[2][l] = a ? n2 : x2;
                X[3][l] = a ? n3 : x3; X[4][l] = a ? n4 : x4; X[5][l] = a ? n5 : x5;
                X[6][l] = a ? n6 : x6; X[7][l] = a ? n7 : x7; X[8][l] = a ? n8 : x8;
                const int still = a && !(d < 1e-12);
                active[l] = still;
                anyActive |= still;
            }
        }
    } else {
        for (int l = 0; l < kLanes; ++l)
            for (int k = 0; k < 9; ++k) X[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
    }
    alignas(64) double P[9][kLanes];
#pragma omp simd
    for (int l = 0; l < kLanes; ++l) {
        // Linear stress of the unrotated displacement gradient H = R^T F - I; f_a = -V R sigma g_a
        // equals -R K_e (R^T x - X) of eq. 2.41 without forming K_e.
        double H[9], sig[9], RS[9];
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r)
                H[3 * c + r] = X[3 * r][l] * F[3 * c][l] + X[3 * r + 1][l] * F[3 * c + 1][l] +
                               X[3 * r + 2][l] * F[3 * c + 2][l] - (r == c ? 1.0 : 0.0);
        const double tr = lam * (H[0] + H[4] + H[8]);
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r) sig[3 * c + r] = mu * (H[3 * c + r] + H[3 * r + c]) + (r == c ? tr : 0.0);
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r)
                RS[3 * c + r] = X[r][l] * sig[3 * c] + X[3 + r][l] * sig[3 * c + 1] + X[6 + r][l] * sig[3 * c + 2];
        // P = scale (R sigma) DmInv^T: columns are the forces on nodes 1..3
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r)
                P[3 * c + r][l] = scale[l] * (RS[r] * Dm[c][l] + RS[3 + r] * Dm[3 + c][l] + RS[6 + r] * Dm[6 + c][l]);
    }
    for (int l = 0; l < count; ++l) {
        double* fe = s.fe.col(e0 + l).data();
        for (int k = 0; k < 9; ++k) fe[3 + k] = P[k][l];
        for (int r = 0; r < 3; ++r) fe[r] = -(P[r][l] + P[3 + r][l] + P[6 + r][l]);
        if (corot) {
            double* rot = s.rot.col(e0 + l).data();
            for (int k = 0; k < 9; ++k) rot[k] = X[k][l];
        }
    }
    return inv;
}

} // namespace

void elementForces(const Model& m, State& s, const double* alpha, int begin, int end, int* inverted) {
    const double lam = m.material.lambda(), mu = m.material.mu();
    const bool corot = m.elementModel == ElementModel::Corotational;
    int inv = 0;
    for (int e = begin; e < end; e += kLanes)
        inv += elementBlock(m, s, alpha, e, std::min(kLanes, end - e), lam, mu, corot);
    if (inverted) *inverted += inv;
}

void gatherForces(const Model& m, State& s, int begin, int end) {
    for (int i = begin; i < end; ++i) {
        Eigen::Vector3d f = s.fExt.col(i) + m.mass(i) * m.gravity;
        for (int k = m.nodeSlotStart[i]; k < m.nodeSlotStart[i + 1]; ++k) {
            const int slot = m.nodeSlots[k];
            f += Eigen::Map<const Eigen::Vector3d>(s.fe.col(slot >> 2).data() + 3 * (slot & 3));
        }
        s.f.col(i) = f;
    }
}

void computeForces(const Model& m, State& s, const double* alpha) {
    int inverted = 0;
    const int ne = m.elements(), nn = m.nodes();
#pragma omp parallel reduction(+ : inverted) if (ne >= kParallelElements)
    {
        const int nt = omp_get_num_threads(), t = omp_get_thread_num();
        elementForces(m, s, alpha, static_cast<int>(static_cast<long>(ne) * t / nt),
                      static_cast<int>(static_cast<long>(ne) * (t + 1) / nt), &inverted);
#pragma omp barrier
        gatherForces(m, s, static_cast<int>(static_cast<long>(nn) * t / nt),
                     static_cast<int>(static_cast<long>(nn) * (t + 1) / nt));
    }
    s.flags.inverted = inverted;
    s.flags.firstInverted = -1;
    // Rare: find one for messages with a scan instead of a shared write in the hot loop.
    for (int e = 0; inverted > 0 && e < ne; ++e) {
        const Eigen::Vector3d x0 = s.x.col(m.tets(0, e));
        Eigen::Matrix3d Ds;
        Ds << s.x.col(m.tets(1, e)) - x0, s.x.col(m.tets(2, e)) - x0, s.x.col(m.tets(3, e)) - x0;
        if ((Ds * m.dmInv(e)).determinant() <= 0) {
            s.flags.firstInverted = e;
            break;
        }
    }
}

double elasticEnergy(const Model& m, const State& s) {
    const double lam = m.material.lambda(), mu = m.material.mu();
    double E = 0;
    for (int e = 0; e < m.elements(); ++e) {
        const int* n = m.tets.col(e).data();
        Eigen::Matrix3d Ds;
        Ds << s.x.col(n[1]) - s.x.col(n[0]), s.x.col(n[2]) - s.x.col(n[0]), s.x.col(n[3]) - s.x.col(n[0]);
        const Eigen::Matrix3d F = Ds * m.dmInv(e);
        Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
        if (m.elementModel == ElementModel::Corotational) {
            R = extractRotation(F, Eigen::Map<const Eigen::Matrix3d>(s.rot.col(e).data()));
        }
        const Eigen::Matrix3d H = R.transpose() * F - Eigen::Matrix3d::Identity();
        const Eigen::Matrix3d eps = 0.5 * (H + H.transpose());
        E += 0.5 * m.volume(e) * m.fraction(e) * (lam * eps.trace() * eps.trace() + 2 * mu * eps.squaredNorm());
    }
    return E;
}

double kineticEnergy(const Model& m, const State& s) {
    double E = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0) E += 0.5 * m.mass(i) * s.v.col(i).squaredNorm();
    return E;
}

double gravityEnergy(const Model& m, const State& s) {
    double E = 0;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.invMass(i) > 0) E -= m.mass(i) * m.gravity.dot(s.x.col(i));
    return E;
}

void setThreads(int n) { omp_set_num_threads(n > 0 ? n : omp_get_num_procs()); }
int threads() { return omp_get_max_threads(); }

} // namespace cutsim

namespace cutsim {

Eigen::VectorXd vonMisesStress(const Model& m, const State& s) {
    const double lam = m.material.lambda(), mu = m.material.mu();
    Eigen::VectorXd out(m.elements());
    for (int e = 0; e < m.elements(); ++e) {
        const int* n = m.tets.col(e).data();
        Eigen::Matrix3d Ds;
        Ds << s.x.col(n[1]) - s.x.col(n[0]), s.x.col(n[2]) - s.x.col(n[0]), s.x.col(n[3]) - s.x.col(n[0]);
        const Eigen::Matrix3d F = Ds * m.dmInv(e);
        const Eigen::Matrix3d R = m.elementModel == ElementModel::Corotational
                                      ? extractRotation(F, Eigen::Map<const Eigen::Matrix3d>(s.rot.col(e).data()))
                                      : Eigen::Matrix3d::Identity();
        const Eigen::Matrix3d H = R.transpose() * F - Eigen::Matrix3d::Identity();
        Eigen::Matrix3d sig = mu * (H + H.transpose());
        sig.diagonal().array() += lam * H.trace();
        const Eigen::Matrix3d dev = sig - sig.trace() / 3.0 * Eigen::Matrix3d::Identity();
        out(e) = std::sqrt(1.5 * dev.squaredNorm());
    }
    return out;
}

} // namespace cutsim
