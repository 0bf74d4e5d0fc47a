#include "fem/forces.hpp"

#include <Eigen/Geometry>
#include <omp.h>

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

void elementForces(const Model& m, State& s, const double* alpha, int begin, int end, int* inverted) {
    const double lam = m.material.lambda(), mu = m.material.mu();
    const bool corot = m.elementModel == ElementModel::Corotational;
    int inv = 0;
    for (int e = begin; e < end; ++e) {
        const int* n = m.tets.col(e).data();
        const Eigen::Vector3d x0 = s.x.col(n[0]);
        Eigen::Matrix3d Ds;
        Ds << s.x.col(n[1]) - x0, s.x.col(n[2]) - x0, s.x.col(n[3]) - x0;
        const Eigen::Map<const Eigen::Matrix3d> DmInv(m.DmInv.col(e).data());
        const Eigen::Matrix3d F = Ds * DmInv;
        const double detF = F.determinant();
        if (detF <= 0) ++inv;
        Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
        if (corot) {
            Eigen::Map<Eigen::Matrix3d> Rs(s.rot.col(e).data());
            R = polarRotation(F, detF, Rs);
            Rs = R;
        }
        // Linear stress of the unrotated displacement gradient H = R^T F - I; f_a = -V R sigma g_a
        // equals -R K_e (R^T x - X) of eq. 2.41 without forming K_e.
        const Eigen::Matrix3d H = R.transpose() * F - Eigen::Matrix3d::Identity();
        Eigen::Matrix3d sigma = mu * (H + H.transpose());
        sigma.diagonal().array() += lam * H.trace();
        double scale = -m.volume(e) * m.fraction(e);
        if (alpha) scale *= alpha[e];
        const Eigen::Matrix3d P = scale * (R * sigma) * DmInv.transpose(); // columns: forces on nodes 1..3
        double* fe = s.fe.col(e).data();
        Eigen::Map<Eigen::Matrix3d> f123(fe + 3);
        Eigen::Map<Eigen::Vector3d> f0(fe);
        f123 = P;
        f0 = -P.rowwise().sum();
    }
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
