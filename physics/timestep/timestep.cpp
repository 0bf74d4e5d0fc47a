#include "timestep/timestep.hpp"

#include <Eigen/Eigenvalues>


#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace cutsim {

double dtFromLambda(double lambda) {
    return lambda > 0 ? 2.0 / std::sqrt(lambda) : std::numeric_limits<double>::infinity();
}

void ElementEstimates::resize(int n) {
    r1r.resize(n);
    hs.resize(n);
    hp.resize(n);
    le.resize(n);
    element.resize(n);
}

// ---- assembled stiffness by node rows ----

void assembleStiffnessRow(const Model& m, int i, std::vector<int>& nbr, std::vector<Eigen::Matrix3d>& block) {
    nbr.clear();
    block.clear();
    nbr.push_back(i);
    block.push_back(Eigen::Matrix3d::Zero());
    const double lam = m.material.lambda(), mu = m.material.mu();
    for (int s = m.nodeSlotStart[i]; s < m.nodeSlotStart[i + 1]; ++s) {
        const int e = m.nodeSlots[s] / 4, a = m.nodeSlots[s] % 4;
        const double V = m.volume(e) * m.fraction(e);
        const Mat34 g = shapeGradients(m.dmInv(e));
        const Eigen::Vector3d ga = g.col(a);
        for (int b = 0; b < 4; ++b) {
            const int j = m.tets(b, e);
            size_t k = 0;
            while (k < nbr.size() && nbr[k] != j) ++k;
            if (k == nbr.size()) {
                nbr.push_back(j);
                block.push_back(Eigen::Matrix3d::Zero());
            }
            // Block (a,b) of the element stiffness (METHOD.md sec. 1).
            const Eigen::Vector3d gb = g.col(b);
            block[k] += V * (lam * ga * gb.transpose() + mu * gb * ga.transpose() +
                             mu * ga.dot(gb) * Eigen::Matrix3d::Identity());
        }
    }
}

StiffnessRows assembleStiffnessRows(const Model& m) {
    StiffnessRows rows;
    rows.nbr.resize(m.nodes());
    rows.block.resize(m.nodes());
#pragma omp parallel for schedule(dynamic, 256) if (m.nodes() > 2000)
    for (int i = 0; i < m.nodes(); ++i) assembleStiffnessRow(m, i, rows.nbr[i], rows.block[i]);
    return rows;
}

Eigen::Vector3d nodeStiffnessDiagonal(const Model& m, int i) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    for (int s = m.nodeSlotStart[i]; s < m.nodeSlotStart[i + 1]; ++s) {
        const int e = m.nodeSlots[s] / 4, a = m.nodeSlots[s] % 4;
        // Eqs. 4.3-4.10: the diagonal of K_e needs only the shape gradients.
        const Vec12 de = elementStiffnessDiagonal(shapeGradients(m.dmInv(e)), m.volume(e) * m.fraction(e), m.material);
        d += de.segment<3>(3 * a);
    }
    return d;
}

Eigen::Matrix3Xd assembleStiffnessDiagonal(const Model& m) {
    Eigen::Matrix3Xd d(3, m.nodes());
#pragma omp parallel for schedule(static) if (m.nodes() > 2000)
    for (int i = 0; i < m.nodes(); ++i) d.col(i) = nodeStiffnessDiagonal(m, i);
    return d;
}

// ---- certified bound: Gershgorin on M^-1/2 K M^-1/2 ----

double gershgorinNodeBound(const Model& m, const StiffnessRows& rows, int i) {
    if (!(m.invMass(i) > 0)) return 0;
    const double si = std::sqrt(m.invMass(i));
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (size_t q = 0; q < rows.nbr[i].size(); ++q) {
        const double sj = std::sqrt(m.invMass(rows.nbr[i][q]));
        if (sj == 0) continue;
        sum += sj * rows.block[i][q].cwiseAbs().rowwise().sum();
    }
    return si * sum.maxCoeff();
}

double certifiedDt(const Model& m, const StiffnessRows& rows) {
    double bound = 0;
#pragma omp parallel for schedule(static) reduction(max : bound) if (m.nodes() > 2000)
    for (int i = 0; i < m.nodes(); ++i) bound = std::max(bound, gershgorinNodeBound(m, rows, i));
    return dtFromLambda(bound);
}

double certifiedDt(const Model& m) { return certifiedDt(m, assembleStiffnessRows(m)); }

// ---- 12x12 largest eigenvalue ----

namespace {

// Largest root of det(x I - T) for an unreduced symmetric tridiagonal block (diagonal d, squared
// off-diagonal e2), by Laguerre's method from x0 >= every eigenvalue: for a polynomial with real
// roots it converges monotonically from the right, cubically at a simple root.
double tridiagonalLargest(const double* d, const double* e2, int n, double x0) {
    if (n == 1) return d[0];
    double x = x0;
    for (int it = 0; it < 200; ++it) {
        double p0 = 1, p1 = x - d[0], dp0 = 0, dp1 = 1, ddp0 = 0, ddp1 = 0;
        for (int k = 1; k < n; ++k) {
            const double t = x - d[k];
            const double p2 = t * p1 - e2[k - 1] * p0;
            const double dp2 = p1 + t * dp1 - e2[k - 1] * dp0;
            const double ddp2 = 2 * dp1 + t * ddp1 - e2[k - 1] * ddp0;
            p0 = p1, p1 = p2, dp0 = dp1, dp1 = dp2, ddp0 = ddp1, ddp1 = ddp2;
        }
        if (p1 == 0) return x;
        const double G = dp1 / p1, H = G * G - ddp1 / p1;
        const double disc = std::max(0.0, (n - 1) * (n * H - G * G));
        // Denominator of the larger magnitude; left of the root by rounding G < 0 gives step < 0.
        const double step = n / (G >= 0 ? G + std::sqrt(disc) : G - std::sqrt(disc));
        if (!(step > 0)) break;  // at the root to rounding
        x -= step;
        if (step <= 1e-15 * std::abs(x)) break;
    }
    return x;
}

// Householder reduction of a symmetric 12x12 matrix (full storage, overwritten) to tridiagonal
// form: diagonal d, off-diagonal e. Fixed size and plain loops: Eigen's general version costs
// several times more here, and this runs twice per element.
void tridiagonalize12(double (&a)[12][12], double (&d)[12], double (&e)[11]) {
    constexpr int n = 12;
    for (int k = 0; k < n - 2; ++k) {
        const int m = n - k - 1;  // length of the column below the diagonal
        double* x = &a[k][k + 1]; // row k == column k (symmetric)
        double tail = 0;
        for (int i = 1; i < m; ++i) tail += x[i] * x[i];
        if (tail == 0) {
            e[k] = x[0];
            continue;
        }
        const double norm = std::sqrt(x[0] * x[0] + tail);
        const double alpha = x[0] > 0 ? -norm : norm;
        double v[n];
        v[0] = x[0] - alpha;
        for (int i = 1; i < m; ++i) v[i] = x[i];
        const double beta = 2 / (v[0] * v[0] + tail);
        // p = beta A22 v, w = p - (beta/2)(v.p) v, A22 -= v w^T + w v^T.
        double p[n], vp = 0;
        for (int i = 0; i < m; ++i) {
            double s = 0;
            for (int j = 0; j < m; ++j) s += a[k + 1 + i][k + 1 + j] * v[j];
            p[i] = beta * s;
            vp += v[i] * p[i];
        }
        const double K = 0.5 * beta * vp;
        for (int i = 0; i < m; ++i) p[i] -= K * v[i];
        for (int i = 0; i < m; ++i)
            for (int j = 0; j < m; ++j) a[k + 1 + i][k + 1 + j] -= v[i] * p[j] + p[i] * v[j];
        e[k] = alpha;
    }
    e[n - 2] = a[n - 2][n - 1];
    for (int i = 0; i < n; ++i) d[i] = a[i][i];
}

} // namespace

double largestEigenvalue(const Mat12& A) {
    // Scale so every eigenvalue lies in [-1, 1]: the recurrences then stay far from overflow.
    const double g = A.cwiseAbs().rowwise().sum().maxCoeff();
    if (!(g > 0)) return 0;
    double a[12][12], d[12], e[11], e2[11];
    const double inv = 1 / g;
    for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) a[i][j] = A(i, j) * inv;
    tridiagonalize12(a, d, e);
    for (int k = 0; k < 11; ++k) e2[k] = e[k] * e[k];
    // Split at negligible off-diagonals; each unreduced block has simple eigenvalues.
    double best = -std::numeric_limits<double>::infinity();
    int start = 0;
    for (int k = 0; k < 12; ++k) {
        if (k < 11 && std::abs(e[k]) > 1e-15) continue;
        double hi = -std::numeric_limits<double>::infinity();
        for (int r = start; r <= k; ++r) {
            const double off = (r > start ? std::abs(e[r - 1]) : 0.0) + (r < k ? std::abs(e[r]) : 0.0);
            hi = std::max(hi, d[r] + off);
        }
        if (hi > best) best = std::max(best, tridiagonalLargest(d + start, e2 + start, k - start + 1, hi));
        start = k + 1;
    }
    return best * g;
}

// ---- per-element estimators (thesis ch. 4, METHOD.md sec. 3) ----

double r1rLambda(const Model& m, const StiffnessRows& rows, int e) {
    // R1R, Fierz et al. 2012: principal 12x12 submatrix of the assembled K and M at e's DOFs,
    // symmetric form M_r^-1/2 K_r M_r^-1/2; a fixed DOF's row and column are zero.
    Mat12 A;
    double sq[4];  // M_r^-1/2 at the four nodes, once each (this runs for every element of a cut's one-ring)
    for (int a = 0; a < 4; ++a) sq[a] = std::sqrt(m.invMass(m.tets(a, e)));
    for (int a = 0; a < 4; ++a) {
        const int i = m.tets(a, e);
        const double si = sq[a];
        const std::vector<int>& nb = rows.nbr[i];
        for (int b = 0; b < 4; ++b) {
            const int j = m.tets(b, e);
            size_t k = 0;
            while (k < nb.size() && nb[k] != j) ++k;
            A.block<3, 3>(3 * a, 3 * b) = k < nb.size() ? Eigen::Matrix3d(si * sq[b] * rows.block[i][k])
                                                         : Eigen::Matrix3d::Zero();
        }
    }
    return largestEigenvalue(A);
}

namespace {

// D_r = diag(K_r) / M_r at the 12 DOFs of e (0 at a fixed DOF).
Vec12 scaledDiagonal(const Model& m, const Eigen::Matrix3Xd& diag, int e) {
    Vec12 D;
    for (int a = 0; a < 4; ++a) {
        const int i = m.tets(a, e);
        D.segment<3>(3 * a) = diag.col(i) * m.invMass(i);
    }
    return D;
}

} // namespace

double hsLambda(const Model& m, const Eigen::Matrix3Xd& diag, int e) {
    // Hs: lambda ~ max D_r (the thesis's scalar read as 1, METHOD.md sec. 3).
    return scaledDiagonal(m, diag, e).maxCoeff();
}

double hpLambda(const Model& m, const Eigen::Matrix3Xd& diag, int e) {
    // Hp (thesis sec. 4.3, reading of METHOD.md sec. 3): sort D_r descending; j is the first index
    // whose PRECEDING running sum D_r[0] + ... + D_r[j-1] exceeds half of the total; then
    // lambda ~ D_r[0] + D_r[j]. Fixed DOFs count as 0 and sort last, so they never change j.
    Vec12 D = scaledDiagonal(m, diag, e);
    std::sort(D.data(), D.data() + 12, std::greater<double>());
    const double half = 0.5 * D.sum();
    double run = 0;
    for (int j = 0; j < 12; ++j) {
        if (run > half) return D(0) + D(j);
        run += D(j);
    }
    return D(0);  // all zero: nothing free
}

double elementLambda(const Model& m, int e) {
    // Element eigenvalue with own lumped masses rho V / 4: K_e and M_e scale alike with fraction.
    // K_e = V B^T D B (B: 6x12 strain-displacement, D: isotropic elasticity, engineering shear),
    // restricted to free DOFs by P: the nonzero eigenvalues of (4/rho) P B^T D B P are those of the
    // 6x6 (4/rho) S B P B^T S with S = D^1/2 (X^T X and X X^T share them, X = S B P), a sixth of
    // the 12x12 work. D^1/2: normal block a I + b 1 1^T with a^2 = 2 mu, (a + 3b)^2 = 3 lambda + 2 mu;
    // shear block sqrt(mu) I.
    const Mat34 g = shapeGradients(m.dmInv(e));
    Eigen::Matrix<double, 6, 6> G = Eigen::Matrix<double, 6, 6>::Zero();
    for (int a = 0; a < 4; ++a) {
        if (!(m.invMass(m.tets(a, e)) > 0)) continue;
        const double x = g(0, a), y = g(1, a), z = g(2, a);
        Eigen::Matrix<double, 6, 3> Ba;
        Ba << x, 0, 0,  0, y, 0,  0, 0, z,  y, x, 0,  0, z, y,  z, 0, x;
        G.noalias() += Ba * Ba.transpose();
    }
    const double lam = m.material.lambda(), mu = m.material.mu();
    const double sa = std::sqrt(2 * mu), sb = (std::sqrt(3 * lam + 2 * mu) - sa) / 3, ss = std::sqrt(mu);
    Eigen::Matrix<double, 6, 6> S = Eigen::Matrix<double, 6, 6>::Zero();
    S.topLeftCorner<3, 3>().setConstant(sb);
    S.topLeftCorner<3, 3>().diagonal().array() += sa;
    S.bottomRightCorner<3, 3>().diagonal().setConstant(ss);
    const Eigen::Matrix<double, 6, 6> A = (4.0 / m.material.rho) * (S * G * S);
    return Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(A, Eigen::EigenvaluesOnly).eigenvalues()(5);
}

double characteristicLength(const Model& m, int e) {
    // Le = 3V / max face area (thesis Table 4.1): the smallest height of the tet.
    static constexpr int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    double amax = 0;
    for (const auto& f : faces) {
        const Eigen::Vector3d p = m.X.col(m.tets(f[0], e)), q = m.X.col(m.tets(f[1], e)), r = m.X.col(m.tets(f[2], e));
        amax = std::max(amax, 0.5 * (q - p).cross(r - p).norm());
    }
    return amax > 0 ? 3 * m.volume(e) / amax : 0.0;
}

void estimateElements(const Model& m, const StiffnessRows& rows, const Eigen::Matrix3Xd& diag,
                      const std::vector<int>* elements, ElementEstimates& out) {
    if (out.r1r.size() != m.elements()) out.resize(m.elements());
    const int n = elements ? static_cast<int>(elements->size()) : m.elements();
    const double cp = m.material.pWaveSpeed();
#pragma omp parallel for schedule(static) if (n > 256)
    for (int k = 0; k < n; ++k) {
        const int e = elements ? (*elements)[k] : k;
        out.r1r(e) = dtFromLambda(r1rLambda(m, rows, e));
        out.hs(e) = dtFromLambda(hsLambda(m, diag, e));
        out.hp(e) = dtFromLambda(hpLambda(m, diag, e));
        out.le(e) = characteristicLength(m, e) / cp;
        out.element(e) = dtFromLambda(elementLambda(m, e));
    }
}

ElementEstimates estimateElements(const Model& m) {
    ElementEstimates out;
    estimateElements(m, assembleStiffnessRows(m), assembleStiffnessDiagonal(m), nullptr, out);
    return out;
}

} // namespace cutsim
