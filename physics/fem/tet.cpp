#include "fem/tet.hpp"

namespace cutsim {

Eigen::Matrix3d restShapeMatrix(const Mat34& X) {
    Eigen::Matrix3d Dm;
    Dm << X.col(1) - X.col(0), X.col(2) - X.col(0), X.col(3) - X.col(0);
    return Dm;
}

Mat34 shapeGradients(const Eigen::Matrix3d& DmInv) {
    Mat34 g;
    g.rightCols<3>() = DmInv.transpose();
    g.col(0) = -g.rightCols<3>().rowwise().sum();
    return g;
}

Mat12 elementStiffness(const Mat34& g, double volume, const Material& mat) {
    const double lam = mat.lambda(), mu = mat.mu();
    Mat12 K;
    for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b)
            K.block<3, 3>(3 * a, 3 * b) =
                volume * (lam * g.col(a) * g.col(b).transpose() + mu * g.col(b) * g.col(a).transpose() +
                          mu * g.col(a).dot(g.col(b)) * Eigen::Matrix3d::Identity());
    return K;
}

Vec12 elementStiffnessDiagonal(const Mat34& g, double volume, const Material& mat) {
    const double eh = mat.pWaveModulus(), mu = mat.mu();
    Vec12 d;
    for (int a = 0; a < 4; ++a) {
        const Eigen::Vector3d s = g.col(a).cwiseAbs2();
        const double sum = s.sum();
        for (int i = 0; i < 3; ++i) d(3 * a + i) = volume * (eh * s(i) + mu * (sum - s(i)));
    }
    return d;
}

}  // namespace cutsim
