// Quasi-static relaxation of the control points a cut made.
#include "fem/forces.hpp"
#include "fem/kinematics.hpp"

#include <algorithm>
#include <cmath>

namespace cutsim {

void relaxNodes(const Model& m, State& s, const std::vector<int>& nodes, int iterations) {
    const double mu = m.material.mu(), lambda = m.material.lambda();
    std::vector<double> floorDet;  // per incident element: half its det F before the move (at most 1/2)
    for (int it = 0; it < iterations; ++it)
        for (int n : nodes) {
            Eigen::Vector3d f = Eigen::Vector3d::Zero();
            Eigen::Matrix3d K = Eigen::Matrix3d::Zero();
            double size = 1e300;
            floorDet.clear();
            for (int sl = m.nodeSlotStart[n]; sl < m.nodeSlotEnd[n]; ++sl) {
                const int e = m.nodeSlots[static_cast<size_t>(sl)] / 4, a = m.nodeSlots[static_cast<size_t>(sl)] % 4;
                const Eigen::Matrix3d F = deformationGradient(m, s, e);
                floorDet.push_back(0.5 * std::min(F.determinant(), 1.0));
                const double vf = m.volume(e) * m.fraction(e);
                if (vf <= 0) continue;
                const Eigen::Matrix3d Di = m.dmInv(e);
                const Eigen::Matrix3d R = extractRotation(F, Eigen::Map<const Eigen::Matrix3d>(s.rot.col(e).data()));
                // Linear stress of the corotated strain; forces H = -V P Dm^-T (corners 1..3).
                const Eigen::Matrix3d eps = 0.5 * (R.transpose() * F + F.transpose() * R) - Eigen::Matrix3d::Identity();
                const Eigen::Matrix3d P = R * (2 * mu * eps + lambda * eps.trace() * Eigen::Matrix3d::Identity());
                const Eigen::Matrix3d H = -vf * P * Di.transpose();
                const Eigen::Vector3d g =
                    a == 0 ? Eigen::Vector3d(-Di.row(0).transpose() - Di.row(1).transpose() - Di.row(2).transpose())
                           : Eigen::Vector3d(Di.row(a - 1).transpose());
                f += a == 0 ? Eigen::Vector3d(-H.rowwise().sum()) : Eigen::Vector3d(H.col(a - 1));
                const Eigen::Vector3d rg = R * g;
                K += vf * (mu * g.squaredNorm() * Eigen::Matrix3d::Identity() + (mu + lambda) * rg * rg.transpose());
                size = std::min(size, std::cbrt(m.volume(e)));
            }
            if (size == 1e300) continue;
            Eigen::Vector3d dx = K.ldlt().solve(f);
            const double len = dx.norm(), cap = 0.25 * size;
            if (!(len < 1e300)) continue;
            if (len > cap) dx *= cap / len;
            // Backtrack so that no element around the node flattens below half its det F.
            const Eigen::Vector3d x0 = s.x.col(n);
            for (int tries = 0; tries < 6; ++tries, dx *= 0.5) {
                s.x.col(n) = x0 + dx;
                bool ok = true;
                for (int sl = m.nodeSlotStart[n], k = 0; sl < m.nodeSlotEnd[n] && ok; ++sl, ++k)
                    ok = deformationGradient(m, s, m.nodeSlots[static_cast<size_t>(sl)] / 4).determinant() >=
                         floorDet[static_cast<size_t>(k)];
                if (ok) break;
                s.x.col(n) = x0;
            }
        }
}

}  // namespace cutsim
