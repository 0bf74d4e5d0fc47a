#include "timestep/floor.hpp"

#include "util/stopwatch.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace cutsim {

double r1rTopMode(const Model& m, const StiffnessRows& rows, int e, Eigen::Matrix<double, 12, 1>& y) {
    // The matrix of r1rBlock (timestep.cpp): M_r^-1/2 K_r M_r^-1/2 from the assembled rows.
    Eigen::Matrix<double, 12, 12> A = Eigen::Matrix<double, 12, 12>::Zero();
    int n[4];
    double sq[4];
    for (int a = 0; a < 4; ++a) n[a] = m.tets(a, e), sq[a] = std::sqrt(m.invMass(n[a]));
    for (int a = 0; a < 4; ++a) {
        const std::vector<int>& nb = rows.nbr[static_cast<size_t>(n[a])];
        for (int b = 0; b < 4; ++b) {
            const auto it = std::find(nb.begin(), nb.end(), n[b]);
            if (it == nb.end()) continue;
            const Eigen::Matrix3d& K = rows.block[static_cast<size_t>(n[a])][static_cast<size_t>(it - nb.begin())];
            A.block<3, 3>(3 * a, 3 * b) = sq[a] * sq[b] * K;
        }
    }
    A = 0.5 * (A + A.transpose()).eval();
    // Dynamic size: GCC 12 warns of an uninitialised AVX-512 register inside Eigen's fixed 12x12
    // path (a false positive); the cost is one allocation per call, off the step's path.
    const Eigen::MatrixXd Ad = A;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Ad);
    y = eig.eigenvectors().col(11);
    return eig.eigenvalues()(11);
}

StepFloorResult holdStepFloor(Model& m, TimestepAnalyzer& ta, double dtFloor, const StepFloorOptions& opts) {
    Stopwatch sw;
    StepFloorResult res;
    res.dtFloor = dtFloor;
    if (!(dtFloor > 0) || !std::isfinite(dtFloor)) return res;
    const double lamAim = 4 / (dtFloor * dtFloor) * (1 - opts.margin) / std::max(opts.coherence, 1.0);
    // An R1R step is compared with the aim's step to a hair under it, so a sweep that brought a
    // mode exactly to the aim does not start another.
    const double dtAim = 2 / std::sqrt(lamAim) * (1 - 1e-9);
    if (m.addedMass.size() != m.nodes()) {
        const Eigen::Index old = m.addedMass.size();
        m.addedMass.conservativeResize(m.nodes());
        if (m.addedMass.size() > old) m.addedMass.tail(m.addedMass.size() - old).setZero();
    }
    std::vector<int> above;
    std::unordered_map<int, double> dm;  // node -> mass it asks for this sweep
    std::unordered_map<int, char> given;
    std::vector<int> changed;
    Eigen::Matrix<double, 12, 1> y;
    for (;;) {
        const Eigen::VectorXd& r1r = ta.estimates().r1r;
        above.clear();
        for (int e : ta.lastElements())
            if (r1r(e) < dtAim) above.push_back(e);
        if (res.sweeps == 0) res.elements = static_cast<int>(above.size());
        if (above.empty()) {
            res.reached = true;
            break;
        }
        if (res.sweeps == opts.maxSweeps) break;
        ++res.sweeps;
        dm.clear();
        for (int e : above) {
            const double lam = r1rTopMode(m, ta.rows(), e, y);
            if (!(lam > lamAim)) continue;
            double w[4], sumW2 = 0;
            for (int a = 0; a < 4; ++a) {
                w[a] = m.invMass(m.tets(a, e)) > 0 ? y.segment<3>(3 * a).squaredNorm() : 0.0;
                sumW2 += w[a] * w[a];
            }
            if (!(sumW2 > 0)) continue;  // no free DOF carries the mode (cannot happen for lambda > 0)
            const double beta = (lam / lamAim - 1) / sumW2;
            for (int a = 0; a < 4; ++a) {
                if (!(w[a] > 0)) continue;
                const int i = m.tets(a, e);
                double& d = dm[i];
                d = std::max(d, beta * m.mass(i) * w[a]);  // the most any element asks, not the sum
            }
        }
        if (dm.empty()) break;
        changed.clear();
        for (const auto& [i, d] : dm) {
            m.addedMass(i) += d;
            m.mass(i) += d;
            m.invMass(i) = 1 / m.mass(i);
            res.addedMass += d;
            given[i] = 1;
            changed.push_back(i);
        }
        std::sort(changed.begin(), changed.end());  // deterministic order for the update
        ta.update(m, {}, changed);
    }
    res.nodes = static_cast<int>(given.size());
    res.seconds = sw.seconds();
    return res;
}

StepFloorResult holdCertifiedFloor(Model& m, TimestepAnalyzer& ta, double dtAim, const std::vector<int>& nodes) {
    Stopwatch sw;
    StepFloorResult res;
    res.dtFloor = dtAim;
    if (!(dtAim > 0) || !std::isfinite(dtAim)) return res;
    const double lamAim = 4 / (dtAim * dtAim) * (1 - 1e-9);  // a hair under, against rounding
    if (m.addedMass.size() != m.nodes()) {
        const Eigen::Index old = m.addedMass.size();
        m.addedMass.conservativeResize(m.nodes());
        if (m.addedMass.size() > old) m.addedMass.tail(m.addedMass.size() - old).setZero();
    }
    const StiffnessRows& rows = ta.rows();
    std::vector<int> changed;
    for (int i : nodes) {
        if (!(m.invMass(i) > 0) || !(ta.nodeBounds()(i) > lamAim)) continue;
        ++res.elements;
        const std::vector<int>& nb = rows.nbr[static_cast<size_t>(i)];
        const Eigen::Vector3d D = rows.block[static_cast<size_t>(i)][0].cwiseAbs().rowwise().sum();
        Eigen::Vector3d O = Eigen::Vector3d::Zero();
        for (size_t q = 1; q < nb.size(); ++q)
            O += std::sqrt(m.invMass(nb[q])) * rows.block[static_cast<size_t>(i)][q].cwiseAbs().rowwise().sum();
        double s = std::sqrt(m.invMass(i));
        for (int c = 0; c < 3; ++c)
            if (D(c) > 0)
                s = std::min(s, 2 * lamAim / (O(c) + std::sqrt(O(c) * O(c) + 4 * D(c) * lamAim)));
            else if (O(c) > 0)
                s = std::min(s, lamAim / O(c));
        const double mass = 1 / (s * s);
        if (!(mass > m.mass(i))) continue;
        const double d = mass - m.mass(i);
        m.addedMass(i) += d;
        m.mass(i) = mass;
        m.invMass(i) = 1 / mass;
        res.addedMass += d;
        changed.push_back(i);
    }
    res.nodes = static_cast<int>(changed.size());
    if (!changed.empty()) {
        ta.update(m, {}, changed);
        res.sweeps = 1;
    }
    res.reached = true;
    res.seconds = sw.seconds();
    return res;
}

KeepStepResult topUpStepFloor(Model& m, TimestepAnalyzer& ta, double dtFloor, const KeepStepOptions& keep) {
    const Eigen::VectorXd before = m.addedMass;
    const KeepStepResult r = keepStep(m, ta.rows(), dtFloor, keep);
    if (r.addedMass > 0) {
        std::vector<int> changed;
        for (int i = 0; i < m.nodes(); ++i)
            if (m.addedMass(i) != before(i)) changed.push_back(i);
        ta.update(m, {}, changed);
    }
    return r;
}

CertifiedFloorResult holdStepFloorCertified(Model& m, TimestepAnalyzer& ta, double dtFloor,
                                            const StepFloorOptions& opts, const KeepStepOptions& keep) {
    Stopwatch sw;
    CertifiedFloorResult res;
    res.local = holdStepFloor(m, ta, dtFloor, opts);
    res.topUp = topUpStepFloor(m, ta, dtFloor, keep);
    res.dtExact = res.topUp.dtAfter;
    res.toppedUp = res.topUp.addedMass > 0;
    res.seconds = sw.seconds();
    return res;
}

}  // namespace cutsim
