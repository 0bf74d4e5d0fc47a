#include "timestep/timestep.hpp"

#include "fem/lanes.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
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
    // The neighbour list and each corner's place in it first, then the row sized exactly once: a
    // growing pair of vectors per node cost more in allocation than the blocks themselves. Per
    // thread scratch: the list, the places, and each node's place in the list (-1 when not in
    // it; reset after use), so no search.
    thread_local std::vector<int> list, place, where;
    if (where.size() < static_cast<size_t>(m.nodes())) where.resize(static_cast<size_t>(m.nodes()), -1);
    const int s0 = m.nodeSlotStart[i], s1 = m.nodeSlotEnd[i];
    list.assign(1, i);
    where[static_cast<size_t>(i)] = 0;
    place.resize(static_cast<size_t>(4 * (s1 - s0)));
    for (int s = s0; s < s1; ++s) {
        const int e = m.nodeSlots[s] / 4;
        for (int b = 0; b < 4; ++b) {
            int& w = where[static_cast<size_t>(m.tets(b, e))];
            if (w < 0) w = static_cast<int>(list.size()), list.push_back(m.tets(b, e));
            place[static_cast<size_t>(4 * (s - s0) + b)] = w;
        }
    }
    for (int j : list) where[static_cast<size_t>(j)] = -1;
    nbr.assign(list.begin(), list.end());
    block.assign(nbr.size(), Eigen::Matrix3d::Zero());
    const double lam = m.material.lambda(), mu = m.material.mu();
    for (int s = s0; s < s1; ++s) {
        const int e = m.nodeSlots[s] / 4, a = m.nodeSlots[s] % 4;
        const double V = m.stiffnessVolume(e);
        const Mat34 g = shapeGradients(m.dmInv(e));
        const Eigen::Vector3d la = V * lam * g.col(a), ma = V * mu * g.col(a);
        for (int b = 0; b < 4; ++b) {
            // Block (a,b) of the element stiffness, V [lambda g_a g_b^T + mu g_b g_a^T + mu (g_a.g_b) I]
            // (docs/method.md sec. 1).
            const Eigen::Vector3d gb = g.col(b);
            Eigen::Matrix3d& K = block[static_cast<size_t>(place[static_cast<size_t>(4 * (s - s0) + b)])];
            const double d = ma.dot(gb);
            for (int c = 0; c < 3; ++c)
                for (int r = 0; r < 3; ++r) K(r, c) += la(r) * gb(c) + gb(r) * ma(c) + (r == c ? d : 0.0);
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
    const double eh = m.material.pWaveModulus(), mu = m.material.mu();
    for (int s = m.nodeSlotStart[i]; s < m.nodeSlotEnd[i]; ++s) {
        const int e = m.nodeSlots[s] / 4, a = m.nodeSlots[s] % 4;
        // Eqs. 4.3-4.10: the diagonal of K_e needs only the shape gradients; here node a's three
        // entries (as elementStiffnessDiagonal), from g_a alone.
        const double* dm = m.DmInv.col(e).data();  // column-major: rows of Dm^-1 are g_1 .. g_3
        Eigen::Vector3d ga;
        for (int k = 0; k < 3; ++k) ga(k) = a > 0 ? dm[3 * k + a - 1] : -(dm[3 * k] + dm[3 * k + 1] + dm[3 * k + 2]);
        const Eigen::Vector3d sq = ga.cwiseAbs2();
        const double sum = sq.sum(), V = m.stiffnessVolume(e);
        for (int k = 0; k < 3; ++k) d(k) += V * (eh * sq(k) + mu * (sum - sq(k)));
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

// ---- largest eigenvalue of small symmetric matrices ----

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

// Off-diagonals at or below this (of a matrix scaled into [-1, 1]) split the tridiagonal form.
constexpr double kSplit = 1e-15;

// Largest eigenvalue of a symmetric tridiagonal matrix (diagonal d, off-diagonal e, size n <= 12),
// split at negligible off-diagonals: each unreduced block has simple eigenvalues.
double tridiagonalMax(const double* d, const double* e, int n) {
    double e2[12];
    for (int k = 0; k + 1 < n; ++k) e2[k] = e[k] * e[k];
    double best = -std::numeric_limits<double>::infinity();
    int start = 0;
    for (int k = 0; k < n; ++k) {
        if (k + 1 < n && std::abs(e[k]) > kSplit) continue;
        double hi = -std::numeric_limits<double>::infinity();
        for (int r = start; r <= k; ++r) {
            const double off = (r > start ? std::abs(e[r - 1]) : 0.0) + (r < k ? std::abs(e[r]) : 0.0);
            hi = std::max(hi, d[r] + off);
        }
        if (hi > best) best = std::max(best, tridiagonalLargest(d + start, e2 + start, k - start + 1, hi));
        start = k + 1;
    }
    return best;
}

// Householder reduction of a symmetric NxN matrix (full storage, overwritten) to tridiagonal
// form: diagonal d, off-diagonal e. Fixed size and plain loops: Eigen's general version costs
// several times more here.
template <int N>
void tridiagonalize(double (&a)[N][N], double (&d)[N], double (&e)[N - 1]) {
    for (int k = 0; k < N - 2; ++k) {
        const int m = N - k - 1;   // length of the column below the diagonal
        double* x = &a[k][k + 1];  // row k == column k (symmetric)
        double tail = 0;
        for (int i = 1; i < m; ++i) tail += x[i] * x[i];
        if (tail == 0) {
            e[k] = x[0];
            continue;
        }
        const double norm = std::sqrt(x[0] * x[0] + tail);
        const double alpha = x[0] > 0 ? -norm : norm;
        double v[N];
        v[0] = x[0] - alpha;
        for (int i = 1; i < m; ++i) v[i] = x[i];
        const double beta = 2 / (v[0] * v[0] + tail);
        // p = beta A22 v, w = p - (beta/2)(v.p) v, A22 -= v w^T + w v^T.
        double p[N], vp = 0;
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
    e[N - 2] = a[N - 2][N - 1];
    for (int i = 0; i < N; ++i) d[i] = a[i][i];
}

// The same on blocks of matrices, one per lane of an AVX-512 register of doubles, as the force
// kernel (fem/forces.cpp): every estimator element runs the same fixed-size arithmetic, so 8 of
// them go through it together. GCC/Clang vector extensions; lanes take exactly the scalar steps
// (masked where the scalar code branches), so they agree with it to rounding. Only the upper
// triangle is read and updated: the update keeps a symmetric matrix symmetric to the bit (its two
// products swap places), so this equals the full update for the symmetric matrices it is given.
template <int N>
void tridiagonalizeLanes(Lane (&a)[N][N], Lane (&d)[N], Lane (&e)[N - 1]) {
    for (int k = 0; k < N - 2; ++k) {
        const int m = N - k - 1;
        Lane* x = &a[k][k + 1];
        Lane tail = Lane{};
        for (int i = 1; i < m; ++i) tail += x[i] * x[i];
        // tail == 0: the column is reduced already; beta = 0 leaves A22 as it is.
        const LaneMask reduced = tail == 0;
        const Lane norm = sqrtLanes(x[0] * x[0] + tail);
        const Lane alpha = x[0] > 0 ? -norm : norm;
        Lane v[N];
        v[0] = x[0] - alpha;
        for (int i = 1; i < m; ++i) v[i] = x[i];
        const Lane beta = reduced ? Lane{} : 2 / (v[0] * v[0] + tail);
        Lane p[N], vp = Lane{};
        for (int i = 0; i < m; ++i) {
            Lane s = Lane{};
            for (int j = 0; j < i; ++j) s += a[k + 1 + j][k + 1 + i] * v[j];
            for (int j = i; j < m; ++j) s += a[k + 1 + i][k + 1 + j] * v[j];
            p[i] = beta * s;
            vp += v[i] * p[i];
        }
        const Lane K = 0.5 * beta * vp;
        for (int i = 0; i < m; ++i) p[i] -= K * v[i];
        for (int i = 0; i < m; ++i)
            for (int j = i; j < m; ++j) a[k + 1 + i][k + 1 + j] -= v[i] * p[j] + p[i] * v[j];
        e[k] = reduced ? x[0] : alpha;
    }
    e[N - 2] = a[N - 2][N - 1];
    for (int i = 0; i < N; ++i) d[i] = a[i][i];
}

// tridiagonalLargest for unreduced N x N blocks in the active lanes; a lane stops where the
// scalar loop would, so each lane gets exactly its own iterations.
template <int N>
Lane tridiagonalLargestLanes(const Lane (&d)[N], const Lane (&e2)[N - 1], Lane x, LaneMask active) {
    for (int it = 0; it < 200 && anyLane(active); ++it) {
        Lane p0 = Lane{} + 1.0, p1 = x - d[0], dp0 = Lane{}, dp1 = Lane{} + 1.0, ddp0 = Lane{}, ddp1 = Lane{};
        for (int k = 1; k < N; ++k) {
            const Lane t = x - d[k];
            const Lane p2 = t * p1 - e2[k - 1] * p0;
            const Lane dp2 = p1 + t * dp1 - e2[k - 1] * dp0;
            const Lane ddp2 = 2 * dp1 + t * ddp1 - e2[k - 1] * ddp0;
            p0 = p1, p1 = p2, dp0 = dp1, dp1 = dp2, ddp0 = ddp1, ddp1 = ddp2;
        }
        const Lane G = dp1 / p1, H = G * G - ddp1 / p1;
        Lane disc = (N - 1) * (N * H - G * G);
        disc = disc > 0 ? disc : Lane{};
        const Lane sq = sqrtLanes(disc);
        const Lane step = N / (G >= 0 ? G + sq : G - sq);
        const LaneMask move = active & (p1 != 0) & (step > 0);
        x = move ? x - step : x;
        active = move & ~(step <= 1e-15 * absLanes(x));
    }
    return x;
}

// Largest eigenvalues of kLanes symmetric N x N matrices (a, overwritten), lanes 0 .. count-1
// into out; the other lanes must hold finite values. As largestEigenvalue: scaled into [-1, 1],
// tridiagonalised, Laguerre from the Gershgorin bound; a lane whose tridiagonal form splits (a
// fixed DOF, repeated eigenvalues) finishes on the scalar path, block by block.
template <int N>
void largestEigenvaluesLanes(Lane (&a)[N][N], int count, double* out) {
    Lane g = Lane{};
    for (int i = 0; i < N; ++i) {
        Lane r = absLanes(a[i][0]);
        for (int j = 1; j < N; ++j) r += absLanes(a[i][j]);
        g = r > g ? r : g;
    }
    const LaneMask nonzero = g > 0;
    const Lane inv = nonzero ? 1 / g : Lane{};
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) a[i][j] *= inv;
    Lane d[N], e[N - 1], e2[N - 1];
    tridiagonalizeLanes<N>(a, d, e);
    LaneMask split = LaneMask{};
    for (int k = 0; k < N - 1; ++k) {
        split |= absLanes(e[k]) <= kSplit;
        e2[k] = e[k] * e[k];
    }
    Lane hi = d[0] + absLanes(e[0]);
    for (int r = 1; r < N; ++r) {
        const Lane h = d[r] + (absLanes(e[r - 1]) + (r < N - 1 ? absLanes(e[r]) : Lane{}));
        hi = h > hi ? h : hi;
    }
    const Lane x = tridiagonalLargestLanes<N>(d, e2, hi, nonzero & ~split);
    for (int l = 0; l < count; ++l) {
        if (!nonzero[l]) {
            out[l] = 0;
        } else if (split[l]) {
            double dl[N], el[N - 1];
            for (int i = 0; i < N; ++i) dl[i] = d[i][l];
            for (int i = 0; i < N - 1; ++i) el[i] = e[i][l];
            out[l] = tridiagonalMax(dl, el, N) * g[l];
        } else {
            out[l] = x[l] * g[l];
        }
    }
}

}  // namespace

double largestEigenvalue(const Mat12& A) {
    // Scale so every eigenvalue lies in [-1, 1]: the recurrences then stay far from overflow.
    const double g = A.cwiseAbs().rowwise().sum().maxCoeff();
    if (!(g > 0)) return 0;
    double a[12][12], d[12], e[11];
    const double inv = 1 / g;
    for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) a[i][j] = A(i, j) * inv;
    tridiagonalize<12>(a, d, e);
    return tridiagonalMax(d, e, 12) * g;
}

void largestEigenvalues(const Mat12* A, int n, double* lambda) {
    for (int b = 0; b < n; b += kLanes) {
        const int count = std::min(kLanes, n - b);
        Lane a[12][12];
        for (int l = 0; l < kLanes; ++l) {
            const Mat12& M = A[b + (l < count ? l : 0)];  // padding lanes repeat the first
            for (int i = 0; i < 12; ++i)
                for (int j = 0; j < 12; ++j) a[i][j][l] = M(i, j);
        }
        largestEigenvaluesLanes<12>(a, count, lambda + b);
    }
}

void largestEigenvaluesInterleaved(const double* a, int count, double* lambda) {
    Lane A[12][12];
    std::memcpy(A, a, sizeof A);
    largestEigenvaluesLanes<12>(A, count, lambda);
}

// ---- per-element estimators (thesis ch. 4, docs/method.md sec. 3) ----

namespace {

// Position of node j in row i's neighbour list nb (nb[0] == i), or -1.
inline int rowSlot(const std::vector<int>& nb, int j) {
    const int n = static_cast<int>(nb.size());
    for (int k = 0; k < n; ++k)
        if (nb[k] == j) return k;
    return -1;
}

// R1R lambdas of elems[0 .. count-1], count <= kLanes, one element per lane.
void r1rBlock(const Model& m, const StiffnessRows& rows, const int* elems, int count, double* lambda) {
    // R1R, Fierz et al. 2012: principal 12x12 submatrix of the assembled K and M at e's DOFs,
    // symmetric form M_r^-1/2 K_r M_r^-1/2; a fixed DOF's row and column are zero. The upper
    // blocks are mirrored, so the matrix is symmetric to the bit.
    Lane A[12][12];
    for (int l = 0; l < kLanes; ++l) {
        const int e = elems[l < count ? l : 0];  // padding lanes repeat the first element
        int n[4];
        double sq[4];  // M_r^-1/2 at the four nodes
        for (int a = 0; a < 4; ++a) n[a] = m.tets(a, e), sq[a] = std::sqrt(m.invMass(n[a]));
        for (int a = 0; a < 4; ++a) {
            const std::vector<int>& nb = rows.nbr[n[a]];
            for (int b = a; b < 4; ++b) {
                const int k = b == a ? 0 : rowSlot(nb, n[b]);
                const double s = sq[a] * sq[b];
                const double* K = k >= 0 ? rows.block[n[a]][k].data() : nullptr;  // column-major
                for (int r = 0; r < 3; ++r)
                    for (int c = b == a ? r : 0; c < 3; ++c) {
                        const double v = K ? s * K[3 * c + r] : 0.0;
                        A[3 * a + r][3 * b + c][l] = v;
                        A[3 * b + c][3 * a + r][l] = v;
                    }
            }
        }
    }
    largestEigenvaluesLanes<12>(A, count, lambda);
}

// Element eigenvalues of elems[0 .. count-1], count <= kLanes, one element per lane.
void elementBlock(const Model& m, const int* elems, int count, double* lambda) {
    // With own lumped masses rho V / 4, K_e and M_e scale alike with fraction. K_e = V B^T D B
    // (B: 6x12 strain-displacement, D: isotropic elasticity, engineering shear), restricted to the
    // free DOFs by P: the nonzero eigenvalues of (4/rho) P B^T D B P are those of the 6x6
    // (4/rho) S G S, G = B P B^T, S = D^1/2 (X^T X and X X^T share them, X = S B P), a sixth of
    // the 12x12 work. G needs only the sums Q = sum_a g_a g_a^T over the free nodes:
    // B_a's rows are (x,0,0), (0,y,0), (0,0,z), (y,x,0), (0,z,y), (z,0,x) for g_a = (x,y,z).
    Lane Q[3][3] = {};
    for (int l = 0; l < kLanes; ++l) {
        const int e = elems[l < count ? l : 0];
        const double* dm = m.DmInv.col(e).data();  // column-major: rows of Dm^-1 are g_1 .. g_3
        double g[4][3];
        for (int a = 1; a < 4; ++a)
            for (int k = 0; k < 3; ++k) g[a][k] = dm[3 * k + a - 1];
        for (int k = 0; k < 3; ++k) g[0][k] = -(g[1][k] + g[2][k] + g[3][k]);
        for (int a = 0; a < 4; ++a)
            if (!(m.invMass(m.tets(a, e)) > 0)) g[a][0] = g[a][1] = g[a][2] = 0;  // fixed: no DOFs
        for (int r = 0; r < 3; ++r)
            for (int c = r; c < 3; ++c)
                Q[r][c][l] = g[0][r] * g[0][c] + g[1][r] * g[1][c] + g[2][r] * g[2][c] + g[3][r] * g[3][c];
    }
    const Lane &xx = Q[0][0], &yy = Q[1][1], &zz = Q[2][2], &xy = Q[0][1], &yz = Q[1][2], &xz = Q[0][2];
    const Lane z = Lane{};
    const Lane G[6][6] = {{xx, z, z, xy, z, xz},        {z, yy, z, xy, yz, z},        {z, z, zz, z, yz, xz},
                          {xy, xy, z, xx + yy, xz, yz}, {z, yz, yz, xz, yy + zz, xy}, {xz, z, xz, yz, xy, xx + zz}};
    // D^1/2: normal block sa I + sb 1 1^T with sa^2 = 2 mu, (sa + 3 sb)^2 = 3 lambda + 2 mu;
    // shear block sqrt(mu) I.
    const double lam = m.material.lambda(), mu = m.material.mu(), c = 4.0 / m.material.rho;
    const double sa = std::sqrt(2 * mu), sb = (std::sqrt(3 * lam + 2 * mu) - sa) / 3, ss = std::sqrt(mu);
    double S[6][6] = {};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) S[i][j] = sb + (i == j ? sa : 0.0);
        S[3 + i][3 + i] = ss;
    }
    Lane GS[6][6], A[6][6];
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) {
            Lane s = Lane{};
            for (int k = 0; k < 6; ++k) s += G[i][k] * S[k][j];
            GS[i][j] = s;
        }
    for (int i = 0; i < 6; ++i)
        for (int j = i; j < 6; ++j) {
            Lane s = Lane{};
            for (int k = 0; k < 6; ++k) s += S[i][k] * GS[k][j];
            A[i][j] = A[j][i] = c * s;
        }
    largestEigenvaluesLanes<6>(A, count, lambda);
}

// Hs and Hp lambdas of elems[0 .. count-1], count <= kLanes, from D_r = diag(K_r) / M_r at the
// 12 DOFs (0 at a fixed DOF), one element per lane.
void heuristicBlock(const Model& m, const Eigen::Matrix3Xd& diag, const int* elems, int count, double* hs, double* hp) {
    Lane D[12];
    for (int l = 0; l < kLanes; ++l) {
        const int e = elems[l < count ? l : 0];
        for (int a = 0; a < 4; ++a) {
            const int i = m.tets(a, e);
            for (int k = 0; k < 3; ++k) D[3 * a + k][l] = diag(k, i) * m.invMass(i);
        }
    }
    // Descending by odd-even transposition: 12 rounds sort 12 values, with no branches.
    for (int round = 0; round < 12; ++round)
        for (int k = round % 2; k + 1 < 12; k += 2) {
            const Lane hi = D[k] > D[k + 1] ? D[k] : D[k + 1], lo = D[k] > D[k + 1] ? D[k + 1] : D[k];
            D[k] = hi, D[k + 1] = lo;
        }
    // Hs: lambda ~ max D_r (the thesis's scalar read as 1, docs/method.md sec. 3).
    // Hp (thesis sec. 4.3, reading of docs/method.md sec. 3): j is the first index whose PRECEDING
    // running sum D_r[0] + ... + D_r[j-1] exceeds half of the total; then lambda ~ D_r[0] + D_r[j].
    // Fixed DOFs count as 0 and sort last, so they never change j; all zero gives D_r[0] = 0.
    Lane total = D[0];
    for (int k = 1; k < 12; ++k) total += D[k];
    const Lane half = 0.5 * total;
    Lane run = Lane{}, lambda = D[0];
    LaneMask found = LaneMask{};
    for (int j = 0; j < 12; ++j) {
        const LaneMask take = ~found & (run > half);
        lambda = take ? D[0] + D[j] : lambda;
        found |= take;
        run += D[j];
    }
    for (int l = 0; l < count; ++l) hs[l] = D[0][l], hp[l] = lambda[l];
}

}  // namespace

void r1rLambdas(const Model& m, const StiffnessRows& rows, const int* elems, int n, double* lambda) {
    for (int b = 0; b < n; b += kLanes) r1rBlock(m, rows, elems + b, std::min(kLanes, n - b), lambda + b);
}

void elementLambdas(const Model& m, const int* elems, int n, double* lambda) {
    for (int b = 0; b < n; b += kLanes) elementBlock(m, elems + b, std::min(kLanes, n - b), lambda + b);
}

double r1rLambda(const Model& m, const StiffnessRows& rows, int e) {
    double lambda;
    r1rBlock(m, rows, &e, 1, &lambda);
    return lambda;
}

double elementLambda(const Model& m, int e) {
    double lambda;
    elementBlock(m, &e, 1, &lambda);
    return lambda;
}

double hsLambda(const Model& m, const Eigen::Matrix3Xd& diag, int e) {
    double hs, hp;
    heuristicBlock(m, diag, &e, 1, &hs, &hp);
    return hs;
}

double hpLambda(const Model& m, const Eigen::Matrix3Xd& diag, int e) {
    double hs, hp;
    heuristicBlock(m, diag, &e, 1, &hs, &hp);
    return hp;
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

void estimateOneRing(const Model& m, const StiffnessRows& rows, const Eigen::Matrix3Xd& diag, const int* elems, int n,
                     ElementEstimates& out) {
    for (int b = 0; b < n; b += kLanes) {
        const int count = std::min(kLanes, n - b);
        double r1r[kLanes], hs[kLanes], hp[kLanes];
        r1rBlock(m, rows, elems + b, count, r1r);
        heuristicBlock(m, diag, elems + b, count, hs, hp);
        for (int l = 0; l < count; ++l) {
            const int e = elems[b + l];
            out.r1r(e) = dtFromLambda(r1r[l]);
            out.hs(e) = dtFromLambda(hs[l]);
            out.hp(e) = dtFromLambda(hp[l]);
        }
    }
}

void estimateOwn(const Model& m, const int* elems, int n, ElementEstimates& out) {
    const double cp = m.material.pWaveSpeed();
    for (int b = 0; b < n; b += kLanes) {
        const int count = std::min(kLanes, n - b);
        double lambda[kLanes];
        elementBlock(m, elems + b, count, lambda);
        for (int l = 0; l < count; ++l) {
            const int e = elems[b + l];
            out.element(e) = dtFromLambda(lambda[l]);
            out.le(e) = characteristicLength(m, e) / cp;
        }
    }
}

void estimateElements(const Model& m, const StiffnessRows& rows, const Eigen::Matrix3Xd& diag,
                      const std::vector<int>* elements, ElementEstimates& out) {
    if (out.r1r.size() != m.elements()) out.resize(m.elements());
    std::vector<int> all;
    if (!elements) {
        all.resize(static_cast<size_t>(m.elements()));
        for (int e = 0; e < m.elements(); ++e) all[static_cast<size_t>(e)] = e;
        elements = &all;
    }
    const int n = static_cast<int>(elements->size());
    const int* list = elements->data();
    constexpr int chunk = 8 * kLanes;
#pragma omp parallel for schedule(dynamic, 4) if (n > 256)
    for (int b = 0; b < n; b += chunk) {
        const int count = std::min(chunk, n - b);
        estimateOneRing(m, rows, diag, list + b, count, out);
        estimateOwn(m, list + b, count, out);
    }
}

ElementEstimates estimateElements(const Model& m) {
    ElementEstimates out;
    estimateElements(m, assembleStiffnessRows(m), assembleStiffnessDiagonal(m), nullptr, out);
    return out;
}

}  // namespace cutsim
