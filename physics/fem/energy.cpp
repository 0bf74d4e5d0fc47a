// Energies and stresses of a state, for reports, checks and colour maps.
#include "fem/forces.hpp"
#include "fem/kinematics.hpp"

#include <cmath>

namespace cutsim {

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

double totalEnergy(const Model& m, const State& s) {
    return kineticEnergy(m, s) + elasticEnergy(m, s) + gravityEnergy(m, s);
}

}  // namespace cutsim
