#include "timestep/quality.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>

namespace cutsim {

TetShape tetShape(const Eigen::Matrix<double, 3, 4>& X) {
    // Thesis Table 4.1. Edges (i,j) and the faces opposite the two other nodes (k,l).
    static constexpr int edges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                        {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
    static constexpr int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    Eigen::Matrix3d Dm;
    Dm << X.col(1) - X.col(0), X.col(2) - X.col(0), X.col(3) - X.col(0);
    const double V = Dm.determinant() / 6;
    double area[4], areaSum = 0, areaMax = 0;
    for (int f = 0; f < 4; ++f) {
        const auto& t = faces[f];
        area[f] = 0.5 * (X.col(t[1]) - X.col(t[0])).cross(X.col(t[2]) - X.col(t[0])).norm();
        areaSum += area[f];
        areaMax = std::max(areaMax, area[f]);
    }
    double l2 = 0, linv = 0, minSine = std::numeric_limits<double>::infinity();
    for (const auto& ed : edges) {
        const double l = (X.col(ed[1]) - X.col(ed[0])).norm();
        l2 += l * l;
        linv += 1 / l;
        // sin of the dihedral angle at edge l: 3 V l / (2 A_k A_l).
        minSine = std::min(minSine, 3 * V * l / (2 * area[ed[2]] * area[ed[3]]));
    }
    const double lrms = std::sqrt(l2 / 6), lharm = 6 / linv;
    // Circumcentre c relative to X0 solves 2 Dm^T c = |d_i|^2.
    const Eigen::Vector3d rhs(Dm.col(0).squaredNorm(), Dm.col(1).squaredNorm(), Dm.col(2).squaredNorm());
    const double rCirc = (Dm.transpose().inverse() * rhs / 2).norm();
    const double rIn = 3 * V / areaSum;
    TetShape s;
    s.volumeLength = 6 * std::sqrt(2.0) * V / (lrms * lrms * lrms);
    s.harmonicVolumeLength = 6 * std::sqrt(2.0) * V / (lharm * lharm * lharm);
    s.minSineDihedral = minSine;
    s.radiusRatio = 3 * rIn / rCirc;
    s.meanRatio = 12 * std::copysign(std::cbrt(9 * V * V), V) / l2;  // 12 (3V)^(2/3) / sum l^2
    s.charLength = areaMax > 0 ? 3 * V / areaMax : 0.0;
    return s;
}

void ShapeMeasures::resize(int n) {
    for (Eigen::VectorXd* v :
         {&volumeLength, &harmonicVolumeLength, &minSineDihedral, &radiusRatio, &meanRatio, &charLength})
        v->resize(n);
}

void ShapeMeasures::set(int e, const TetShape& s) {
    volumeLength(e) = s.volumeLength;
    harmonicVolumeLength(e) = s.harmonicVolumeLength;
    minSineDihedral(e) = s.minSineDihedral;
    radiusRatio(e) = s.radiusRatio;
    meanRatio(e) = s.meanRatio;
    charLength(e) = s.charLength;
}

TetShape elementShape(const Model& m, int e) {
    Eigen::Matrix<double, 3, 4> X;
    for (int a = 0; a < 4; ++a) X.col(a) = m.X.col(m.tets(a, e));
    return tetShape(X);
}

ShapeMeasures shapeMeasures(const Model& m) {
    ShapeMeasures s;
    s.resize(m.elements());
#pragma omp parallel for schedule(static) if (m.elements() > 1000)
    for (int e = 0; e < m.elements(); ++e) s.set(e, elementShape(m, e));
    return s;
}

double pearson(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    double sa = 0, sb = 0;
    long n = 0;
    for (Eigen::Index i = 0; i < std::min(a.size(), b.size()); ++i)
        if (std::isfinite(a(i)) && std::isfinite(b(i))) sa += a(i), sb += b(i), ++n;
    if (n < 2) return std::numeric_limits<double>::quiet_NaN();
    const double ma = sa / n, mb = sb / n;
    double cab = 0, caa = 0, cbb = 0;
    for (Eigen::Index i = 0; i < std::min(a.size(), b.size()); ++i)
        if (std::isfinite(a(i)) && std::isfinite(b(i))) {
            cab += (a(i) - ma) * (b(i) - mb);
            caa += (a(i) - ma) * (a(i) - ma);
            cbb += (b(i) - mb) * (b(i) - mb);
        }
    return caa > 0 && cbb > 0 ? cab / std::sqrt(caa * cbb) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace cutsim
