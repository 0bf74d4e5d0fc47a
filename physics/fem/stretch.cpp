// Stretch limiting: elements below the smallest principal stretch projected back to it.
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "fem/kinematics.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

namespace cutsim {

namespace {

// A lower bound of the smallest singular value, sigma3 = det F / (sigma1 sigma2), from two upper
// bounds of sigma1 sigma2: |F|^2 / 2, and |cof F|, the Frobenius norm of the cofactor matrix (whose
// singular values are sigma1 sigma2, sigma1 sigma3, sigma2 sigma3). The second stays tight for a
// stretched element (F = diag(10, 1, 1): 0.70 where the first gives 0.20), so elements pulled long,
// as the light shares of cut elements often are, are not sent to the SVD every step.
// Negative when inverted.
double smallestStretchBound(const Eigen::Matrix3d& F) {
    const double det = F.determinant();
    const Eigen::Vector3d c0 = F.col(1).cross(F.col(2)), c1 = F.col(2).cross(F.col(0)), c2 = F.col(0).cross(F.col(1));
    const double cof2 = c0.squaredNorm() + c1.squaredNorm() + c2.squaredNorm();
    const double a = 2 * det / F.squaredNorm(), b = cof2 > 0 ? det / std::sqrt(cof2) : a;
    return std::max(a, b);
}

// The smallest principal stretch of F and its gradient with respect to the four nodes:
// sigma3 = u3^T Ds DmInv v3 (U, V rotations), so d sigma3 / d x_a = (DmInv v3)_a u3 for a = 1..3,
// node 0 minus their sum. For det F <= 0, det F itself and its gradient (below).
double smallestStretch(const Model& m, const State& s, int e, Eigen::Matrix<double, 3, 4>& g) {
    const Eigen::Matrix3d F = deformationGradient(m, s, e);
    if (!(F.determinant() > 0)) {
        // Inverted or flat: the sign of invertible FEM sits on the smallest singular value, which
        // need not be the direction that went through (F = diag(1, 1, -3) negates a 1). det F and
        // its gradient (the cofactor of Ds times det DmInv) always point back; the stretch
        // constraint takes over once det F > 0.
        const int* n = m.tets.col(e).data();
        const Eigen::Vector3d x0 = s.x.col(n[0]);
        const Eigen::Vector3d a = s.x.col(n[1]) - x0, b = s.x.col(n[2]) - x0, c = s.x.col(n[3]) - x0;
        const double d = m.dmInv(e).determinant();
        g.col(1) = d * b.cross(c);
        g.col(2) = d * c.cross(a);
        g.col(3) = d * a.cross(b);
        g.col(0) = -(g.col(1) + g.col(2) + g.col(3));
        return F.determinant();
    }
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Vector3d u3 = svd.matrixU().col(2), v3 = svd.matrixV().col(2);
    if (svd.matrixU().determinant() < 0) u3 = -u3;
    if (svd.matrixV().determinant() < 0) v3 = -v3;
    const Eigen::Vector3d w = m.dmInv(e) * v3;
    for (int a = 0; a < 3; ++a) g.col(a + 1) = w[a] * u3;
    g.col(0) = -(w[0] + w[1] + w[2]) * u3;
    return u3.dot(F * v3);
}

// The largest principal stretch sigma1 = u1^T F v1 and its gradient, as smallestStretch's; 0 (no
// bound to hold) for an inverted or flat element.
double largestStretch(const Model& m, const State& s, int e, Eigen::Matrix<double, 3, 4>& g) {
    const Eigen::Matrix3d F = deformationGradient(m, s, e);
    if (!(F.determinant() > 0)) return 0;
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Vector3d u1 = svd.matrixU().col(0), v1 = svd.matrixV().col(0);
    const Eigen::Vector3d w = m.dmInv(e) * v1;
    for (int a = 0; a < 3; ++a) g.col(a + 1) = w[a] * u1;
    g.col(0) = -(w[0] + w[1] + w[2]) * u1;
    return svd.singularValues()[0];
}

}  // namespace

int limitStretch(const Model& m, State& s, double sMinAll, std::vector<int>& scratch, double sMinPartial,
                 const std::vector<int>* seeds) {
    // Gauss-Seidel over the violating elements: elements sharing nodes converge together; sigma3
    // is linear in x along its gradient while the singular vectors hold, so a few sweeps suffice.
    // A correction can push a neighbour below the limit: the next round scans the elements around
    // the nodes this one moved, a few rounds at most.
    constexpr int kRounds = 4, kSweeps = 8;
    constexpr double kTol = 1e-9;
    Eigen::Matrix<double, 3, 4> g;
    const bool partial = sMinPartial > sMinAll;
    auto bound = [&](int e) { return partial && m.fraction(e) < 1 ? sMinPartial : sMinAll; };
    // Every element is held below kMaxStretch too (forces.hpp).

    auto below = [&](int e) {
        const double sMin = bound(e);
        const Eigen::Matrix3d F = deformationGradient(m, s, e);
        if (F.squaredNorm() > kMaxStretch * kMaxStretch && largestStretch(m, s, e, g) > kMaxStretch * (1 + kTol))
            return true;
        return smallestStretchBound(F) < sMin * (1 - kTol) && smallestStretch(m, s, e, g) < sMin * (1 - kTol);
    };
    auto light = [&](int i) { return std::binary_search(m.lightNodes.begin(), m.lightNodes.end(), i); };
    std::vector<int> around;
    int corrected = 0;
    for (int round = 0; round < kRounds; ++round) {
        if (round == 0) {
            scratch.clear();
            if (seeds) {
                for (const int e : *seeds)
                    if (below(e)) scratch.push_back(e);
                if (scratch.empty()) break;
            }
            // the force stage's bound of each element against the element's own watch (a full
            // element's 2/3 when undeformed stays clear of a 0.2 + margin watch even while partial
            // elements are watched at 0.5 + margin)
            const bool marked = s.nearFlat.size() == static_cast<size_t>(m.elements());
            for (int e = 0; !seeds && e < m.elements(); ++e)
                if ((!marked || s.nearFlat[static_cast<size_t>(e)] < 255 * (bound(e) + kStretchWatchMargin)) &&
                    below(e))
                    scratch.push_back(e);
        } else {
            around.clear();
            for (const int e : scratch)
                for (int a = 0; a < 4; ++a) {
                    const int i = m.tets(a, e);
                    for (int k = m.nodeSlotStart[i]; k < m.nodeSlotEnd[i]; ++k) around.push_back(m.nodeSlots[k] >> 2);
                }
            std::sort(around.begin(), around.end());
            around.erase(std::unique(around.begin(), around.end()), around.end());
            scratch.clear();
            for (const int e : around)
                if (below(e)) scratch.push_back(e);
        }
        if (scratch.empty()) break;
        corrected = std::max(corrected, static_cast<int>(scratch.size()));
        for (int sweep = 0; sweep < kSweeps; ++sweep) {
            bool moved = false;
            for (const int e : scratch) {
                const double sMin = bound(e);
                // C >= 0 holds the bound: sigma3 - sMin, or sMax - sigma1 (its gradient negated)
                double C = smallestStretch(m, s, e, g) - sMin;
                // |F|^2 bounds sigma1^2: the second SVD only for an element that may be stretched past
                if (C >= -kTol * sMin && deformationGradient(m, s, e).squaredNorm() > kMaxStretch * kMaxStretch) {
                    C = kMaxStretch - largestStretch(m, s, e, g);
                    g = -g;
                }
                if (C >= -kTol * sMin) continue;
                const int* n = m.tets.col(e).data();
                // Weights: the inverse node masses, so that the correction is orthogonal in the
                // mass norm and only takes energy out. (Masses capped below at the element's mean
                // moved light nodes as if heavy: on an MI object landing on a floor the capped
                // projection and the contact's fed the body ~10 J; docs/method.md, Contact.) A light
                // node of a small cut share takes most of the correction.
                double w[4], denom = 0;
                for (int a = 0; a < 4; ++a) {
                    w[a] = m.invMass(n[a]);
                    denom += w[a] * g.col(a).squaredNorm();
                }
                if (!(denom > 0)) continue;
                // A trust region: no node moves more than the element's rest edge in one correction
                // (sigma3 is linear along g only near x). A node that would is held, as if fixed,
                // and the others take the correction (the last one that can move goes an edge's
                // length). Without it a light node with a small gradient takes a move of up to
                // sqrt(m_heavy / m_light) / 2 times the heavy nodes' (docs/method.md, Cutting finer
                // objects).
                const double edge = std::cbrt(6 * std::sqrt(2.0) * m.volume(e));
                Eigen::Matrix<double, 3, 4> dx = Eigen::Matrix<double, 3, 4>::Zero();
                bool held[4] = {false, false, false, false};
                double free = denom;
                for (int pass = 0; pass < 4 && free > 0; ++pass) {
                    const double lambda = -C / free;
                    int far = -1;
                    double farMove = edge;
                    for (int a = 0; a < 4; ++a)
                        if (!held[a] && std::abs(lambda) * w[a] * g.col(a).norm() > farMove) {
                            far = a;
                            farMove = std::abs(lambda) * w[a] * g.col(a).norm();
                        }
                    if (far < 0) {
                        for (int a = 0; a < 4; ++a)
                            if (!held[a]) dx.col(a) = lambda * w[a] * g.col(a);
                        break;
                    }
                    const double others = free - w[far] * g.col(far).squaredNorm();
                    if (!(others > 1e-12 * free)) {  // the last node that can move: an edge's move
                        dx.col(far) = (edge / farMove) * lambda * w[far] * g.col(far);
                        break;
                    }
                    held[far] = true;
                    free = others;
                }
                // The rate of C, g . v: a closing one is removed (an inelastic stop), an opening one
                // kept. The nodes that are not light (Model::lightNodes) stop their part of it
                // together, weighted as above; each light node stops its own part alone. Every
                // stop takes energy out, and a light node no longer takes the heavy ones' momentum:
                // stopped with the others, a light node whose gradient is small gets up to
                // sqrt(m_heavy / m_light) / 2 times their closing speed.
                double rate = 0, wv[4], vdenom = 0;
                bool heavy[4];
                for (int a = 0; a < 4; ++a) {
                    heavy[a] = !light(n[a]);
                    wv[a] = heavy[a] ? w[a] : 0.0;
                    if (heavy[a]) rate += g.col(a).dot(s.v.col(n[a]));
                    vdenom += wv[a] * g.col(a).squaredNorm();
                }
                const double mu = vdenom > 0 ? std::min(rate, 0.0) / vdenom : 0.0;
                for (int a = 0; a < 4; ++a) {
                    s.x.col(n[a]) += dx.col(a);
                    if (heavy[a]) {
                        s.v.col(n[a]) -= mu * wv[a] * g.col(a);
                    } else if (w[a] > 0) {
                        const double own = g.col(a).dot(s.v.col(n[a])), g2 = g.col(a).squaredNorm();
                        if (own < 0 && g2 > 0) s.v.col(n[a]) -= own / g2 * g.col(a);
                    }
                }
                moved = true;
            }
            if (!moved) break;
        }
    }
    return corrected;
}

}  // namespace cutsim
