#include "fem/shape_matching.hpp"

#include "fem/kinematics.hpp"

namespace cutsim {

void shapeMatch(const Model& m, State& s, double dt, ShapeMatchScratch& w) {
    if (m.matchedList.empty()) return;
    if (w.pull.cols() != m.nodes()) w.pull = Eigen::Matrix3Xd::Zero(3, m.nodes()), w.mark.assign(m.nodes(), 0);
    w.touched.clear();
    const double rho = m.material.rho;
    const bool shares = m.massShare.cols() == m.elements();
    for (const int e : m.matchedList) {
        double me[4], total = 0;
        Eigen::Vector3d c = Eigen::Vector3d::Zero(), c0 = Eigen::Vector3d::Zero();
        for (int a = 0; a < 4; ++a) {
            const int n = m.tets(a, e);
            me[a] = rho * m.volume(e) * (shares ? m.massShare(a, e) : m.fraction(e) / 4);
            total += me[a];
            c += me[a] * s.x.col(n);
            c0 += me[a] * m.X.col(n);
        }
        if (!(total > 0)) continue;
        c /= total;
        c0 /= total;
        Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
        for (int a = 0; a < 4; ++a) {
            const int n = m.tets(a, e);
            A += me[a] * (s.x.col(n) - c) * (m.X.col(n) - c0).transpose();
        }
        const double scale = A.norm();
        if (!(scale > 0)) continue;
        // extractRotation's tests are made for F ~ I: A is scaled to norm 1 (the rotation is the same)
        const Eigen::Matrix3d R = extractRotation(A / scale, Eigen::Matrix3d::Identity());
        for (int a = 0; a < 4; ++a) {
            const int n = m.tets(a, e);
            if (!(m.invMass(n) > 0)) continue;
            if (!w.mark[static_cast<size_t>(n)]) w.mark[static_cast<size_t>(n)] = 1, w.touched.push_back(n);
            w.pull.col(n) += me[a] * (c + R * (m.X.col(n) - c0) - s.x.col(n));
        }
    }
    const double alpha = m.matchStiffness;
    for (const int n : w.touched) {
        const Eigen::Vector3d d = alpha * m.invMass(n) * w.pull.col(n);
        s.x.col(n) += d;
        s.v.col(n) += d / dt;
        w.pull.col(n).setZero();
        w.mark[static_cast<size_t>(n)] = 0;
    }
}

}  // namespace cutsim
