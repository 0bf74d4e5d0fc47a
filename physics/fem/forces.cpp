#include "fem/forces.hpp"

#include <Eigen/Geometry>
#include <omp.h>

#include <cmath>

namespace cutsim {

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
    s.rot.conservativeResize(4, m.elements());
    for (Eigen::Index e = old; e < m.elements(); ++e) s.rot.col(e) << 0, 0, 0, 1;
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

Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& A, double* qc, int maxIter) {
    // Mueller, Bender, Chentanez, Macklin 2016, "A robust method to extract the rotational part of
    // deformations": rotate q about omega until R's columns align with A's. A first-order
    // quaternion update replaces the exact exponential: same fixed point, no trigonometry.
    Eigen::Quaterniond q(qc[3], qc[0], qc[1], qc[2]);
    Eigen::Matrix3d R = q.toRotationMatrix();
    for (int it = 0; it < maxIter; ++it) {
        const Eigen::Vector3d num = R.col(0).cross(A.col(0)) + R.col(1).cross(A.col(1)) + R.col(2).cross(A.col(2));
        const double den = std::abs(R.col(0).dot(A.col(0)) + R.col(1).dot(A.col(1)) + R.col(2).dot(A.col(2))) + 1e-12;
        const Eigen::Vector3d w = num / den;
        const double w2 = w.squaredNorm();
        if (w2 < 1e-26) break;
        // exp(w) as a quaternion; exact for large angles so convergence from a cold start is robust
        const double ang = std::sqrt(w2);
        Eigen::Quaterniond dq;
        if (ang < 1e-4) {
            dq = Eigen::Quaterniond(1.0, 0.5 * w.x(), 0.5 * w.y(), 0.5 * w.z());
        } else {
            const double s = std::sin(0.5 * ang) / ang;
            dq = Eigen::Quaterniond(std::cos(0.5 * ang), s * w.x(), s * w.y(), s * w.z());
        }
        q = (dq * q).normalized();
        R = q.toRotationMatrix();
    }
    qc[0] = q.x(); qc[1] = q.y(); qc[2] = q.z(); qc[3] = q.w();
    return R;
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
        if (F.determinant() <= 0) ++inv;
        Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
        if (corot) R = extractRotation(F, s.rot.col(e).data(), 8);
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
#pragma omp parallel reduction(+ : inverted)
    {
        const int nt = omp_get_num_threads(), t = omp_get_thread_num();
        elementForces(m, s, alpha, static_cast<int>(static_cast<long>(ne) * t / nt),
                      static_cast<int>(static_cast<long>(ne) * (t + 1) / nt), &inverted);
#pragma omp barrier
        gatherForces(m, s, static_cast<int>(static_cast<long>(nn) * t / nt),
                     static_cast<int>(static_cast<long>(nn) * (t + 1) / nt));
    }
    s.flags.inverted = inverted;
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
            double q[4] = {s.rot(0, e), s.rot(1, e), s.rot(2, e), s.rot(3, e)};
            R = extractRotation(F, q);
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
