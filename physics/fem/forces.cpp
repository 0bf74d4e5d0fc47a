#include "fem/forces.hpp"
#include "fem/kinematics.hpp"
#include "util/stopwatch.hpp"

#include "fem/lanes.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <type_traits>

namespace cutsim {

// Below this many elements a step is a few tens of microseconds: a fork and barrier would cost
// more than they save, and far more on a loaded machine.
constexpr int kParallelElements = 8192;

namespace {

// Elements per block of the force kernel: kLanes (fem/lanes.hpp), one element per lane; GCC does
// not reliably vectorise the masked Newton loop from plain per-element loops.

// Where the kernel puts an element's nodal forces. Without f, all into state.fe. With f, a node
// whose elements all belong to this thread's range takes them by += into f (already holding its
// gravity and applied force), in element order; a node shared with another thread's range
// (shared[node] != 0) takes its slot in state.fe, summed after the barrier in the same element
// order. Either way a node's sum runs in the order of gatherForces: the forces are bitwise the
// same on any number of threads, and the per-element array (96 bytes an element, against ~100
// read for the element's inputs) is neither written nor read back for the other nodes.
struct ForceOut {
    double* f = nullptr;
    const unsigned char* shared = nullptr;  // null with f: no node is shared
    bool allRotations = true;
};

// state.rot is read back only as the tie-break of invertibleRotation, for an element whose det F
// has come near 0. Without allRotations the kernel stores R only where the lower bound
// 2 det F / |F|^2 of the smallest principal stretch is below 0.4 (it is 2/3 at rest), so every
// element on its way to flat keeps its last rotation fresh, and the other elements' 72 bytes are
// not written. An element that goes from a bound of
// 0.4 to flat in one step (a node crossing ~half its element in one stable step) breaks a tie
// against an older rotation of its own.
constexpr double kKeepRotation = 0.4;

// From this many elements on, computeForces adds into the nodes in the kernel: state.fe (96 bytes
// an element) no longer stays in L2 between the element pass and the node pass. Below it, that
// round trip costs less than the fused stage's node flags and extra barrier (BENCHMARKS.md, step
// throughput).
constexpr int kFusedElements = 32768;

// Lanes of the single-precision kernel: 16 floats, one AVX-512 register; a block of them is two
// 8-double blocks (LaneHalf) converted, so the loads and node adds stay those of the double kernel.
constexpr int kLanesF = 2 * kLanes;
typedef float LaneF __attribute__((vector_size(4 * kLanesF)));
typedef float LaneHalf __attribute__((vector_size(4 * kLanes)));

#ifdef CUTSIM_LANE_TRANSPOSE  // the full-block loads and writes, where the lanes are transposed
inline LaneF joinLanes(Lane lo, Lane hi) {
    const LaneHalf a = __builtin_convertvector(lo, LaneHalf), b = __builtin_convertvector(hi, LaneHalf);
    return __builtin_shufflevector(a, b, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
}
inline Lane lowLanes(LaneF v) {
    return __builtin_convertvector(__builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7), Lane);
}
inline Lane highLanes(LaneF v) {
    return __builtin_convertvector(__builtin_shufflevector(v, v, 8, 9, 10, 11, 12, 13, 14, 15), Lane);
}
#endif

// Lane count and scalar of a lane type.
template <class L>
constexpr int lanesOf = sizeof(L) / sizeof(L{}[0]);
template <class L>
using ScalarOf = std::remove_cvref_t<decltype(L{}[0])>;

// Inputs of a block of elements e0 .. e0 + count - 1, lane l for element e0 + l: the edge matrix
// Ds (differences taken in double), DmInv and the force scale -V fraction alpha; lanes past count
// are padded with an undeformed unit element and scale 0. Matrices are column-major, (r, c) at 3c + r.
template <class L>
inline void copyLanes(const Model& m, const State& s, const double* alpha, int e0, int count, L Ds[9], L Dm[9],
                      L& scale) {
    using S = ScalarOf<L>;
    const double* xs = s.x.data();
    for (int l = 0; l < lanesOf<L>; ++l) {
        if (l < count) {
            const int e = e0 + l;
            const int* n = m.tets.col(e).data();
            const double* p0 = xs + 3 * n[0];
            for (int a = 0; a < 3; ++a) {
                const double* pa = xs + 3 * n[a + 1];
                for (int r = 0; r < 3; ++r) Ds[3 * a + r][l] = static_cast<S>(pa[r] - p0[r]);
            }
            const double* dm = m.DmInv.col(e).data();
            for (int k = 0; k < 9; ++k) Dm[k][l] = static_cast<S>(dm[k]);
            scale[l] = static_cast<S>(-m.volume(e) * m.fraction(e) * (alpha ? alpha[e] : 1.0));
        } else {
            for (int k = 0; k < 9; ++k) Dm[k][l] = Ds[k][l] = (k % 4 == 0) ? 1 : 0;
            scale[l] = 0;
        }
    }
}

#ifdef CUTSIM_LANE_TRANSPOSE
// A full block of kLanes doubles: each lane's 3-vectors (node positions, DmInv columns) read
// whole and transposed in registers; the same values as copyLanes, bitwise.
inline void loadFullBlock(const Model& m, const State& s, const double* alpha, int e0, Lane Ds[9], Lane Dm[9],
                          Lane& scale) {
    const double* xs = s.x.data();
    const double* p[kLanes];
    Lane node[4][3];
    for (int a = 0; a < 4; ++a) {
        for (int l = 0; l < kLanes; ++l) p[l] = xs + 3 * m.tets(a, e0 + l);
        transposeLanes3(p, node[a]);
    }
    for (int a = 0; a < 3; ++a)
        for (int r = 0; r < 3; ++r) Ds[3 * a + r] = node[a + 1][r] - node[0][r];
    for (int c = 0; c < 3; ++c) {
        for (int l = 0; l < kLanes; ++l) p[l] = m.DmInv.col(e0 + l).data() + 3 * c;
        transposeLanes3(p, Dm + 3 * c);
    }
    scale = -loadLanes(m.volume.data() + e0) * loadLanes(m.fraction.data() + e0);
    if (alpha) scale *= loadLanes(alpha + e0);
}

// Adds a full block's forces P (12 rows: nodes 0..3) into the nodes, or stores them to state.fe.
// Each lane's force on each node as one 3-vector: stored to state.fe by a masked 4-wide store;
// added into a node by three scalar adds, since a masked 4-wide add made the step dearer (likely
// because the next element's load of the same node then waits for the masked store to retire
// instead of taking it forwarded).
inline void writeFullBlock(const Model& m, State& s, int e0, const Lane P[12], const ForceOut& out) {
    __m256d fa[4][kLanes];
    for (int a = 0; a < 4; ++a) untransposeLanes3(P + 3 * a, fa[a]);
    for (int l = 0; l < kLanes; ++l) {
        double* fe = s.fe.col(e0 + l).data();
        const int* n = m.tets.col(e0 + l).data();
        for (int a = 0; a < 4; ++a) {
            if (out.f && !(out.shared && out.shared[n[a]])) {
                double* fn = out.f + 3 * n[a];
                fn[0] += fa[a][l][0];
                fn[1] += fa[a][l][1];
                fn[2] += fa[a][l][2];
            } else {
                _mm256_mask_storeu_pd(fe + 3 * a, 0x7, fa[a][l]);
            }
        }
    }
}
#endif

// copyLanes's inverse for the forces P of lanes 0 .. count - 1.
template <class L>
inline void writeLanes(const Model& m, State& s, int e0, int count, const L P[12], const ForceOut& out) {
    for (int l = 0; l < count; ++l) {
        double* fe = s.fe.col(e0 + l).data();
        if (out.f) {
            const int* n = m.tets.col(e0 + l).data();
            for (int a = 0; a < 4; ++a) {
                if (out.shared && out.shared[n[a]]) {
                    for (int r = 0; r < 3; ++r) fe[3 * a + r] = P[3 * a + r][l];
                } else {
                    for (int r = 0; r < 3; ++r) out.f[3 * n[a] + r] += P[3 * a + r][l];
                }
            }
        } else {
            for (int k = 0; k < 12; ++k) fe[k] = P[k][l];
        }
    }
}

constexpr double kWatchStretch2 = kMaxStretch * kMaxStretch;

// Forces P (rows 3a .. 3a + 2: node a) of a block from its inputs, in L's arithmetic; X gets each
// lane's rotation (I for the linear model). Returns the inverted elements among the first count.
template <class L>
inline int blockForces(const State& s, int e0, int count, const L Ds[9], const L Dm[9], L scale, double lam, double mu,
                       bool corot, double watch, int* nearFlat, L P[12], L X[9], L& det, L& f2) {
    using S = ScalarOf<L>;
    L F[9];  // F = Ds DmInv
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
            F[3 * c + r] = Ds[r] * Dm[3 * c] + Ds[3 + r] * Dm[3 * c + 1] + Ds[6 + r] * Dm[3 * c + 2];
    det = F[0] * (F[4] * F[8] - F[7] * F[5]) - F[3] * (F[1] * F[8] - F[7] * F[2]) + F[6] * (F[1] * F[5] - F[4] * F[2]);
    // watch: the lower bound 2 det F / |F|^2 of the smallest principal stretch (limitStretch)
    f2 = F[0] * F[0];
    for (int k = 1; k < 9; ++k) f2 += F[k] * F[k];
    int inv = 0, near = 0;
    for (int l = 0; l < count; ++l) {
        inv += det[l] <= 0;
        near += 2 * double(det[l]) < watch * double(f2[l]) || (watch > 0 && double(f2[l]) > kWatchStretch2);
    }
    *nearFlat += near;
    if (corot) {
        for (int k = 0; k < 9; ++k) X[k] = F[k];
        const L sc = f2 / S(3);
        // Newton needs det F well away from 0 (its first step divides by it): det > 1e-6 sc^1.5
        auto active = (det > 0) & (det * det > S(1e-12) * sc * sc * sc);
        for (int l = 0; l < count; ++l) {
            if (active[l]) continue;
            // degenerate or inverted (rare): the invertible-FEM rotation, per element
            Eigen::Matrix3d Fl;
            for (int k = 0; k < 9; ++k) Fl(k % 3, k / 3) = F[k][l];
            const Eigen::Matrix3d R =
                invertibleRotation(Fl, Eigen::Map<const Eigen::Matrix3d>(s.rot.col(e0 + l).data()));
            for (int k = 0; k < 9; ++k) X[k][l] = static_cast<S>(R(k % 3, k / 3));
        }
        for (int l = count; l < lanesOf<L>; ++l) active[l] = 0;  // padding: F = I is its own rotation
        // Polar rotation by Newton's iteration X <- (X + X^-T) / 2 (Higham 1986), per lane until
        // that lane's update is below 1e-6 (quadratic convergence: its error is then ~1e-12);
        // converged lanes are frozen, so each lane gets exactly the iterations it would alone.
        for (int it = 0; it < 30; ++it) {
            if (!anyLane(active)) break;
            // X^-T = cof(X) / det X, with the cofactor columns as cross products of X's columns
            const L c0 = X[4] * X[8] - X[5] * X[7], c1 = X[5] * X[6] - X[3] * X[8], c2 = X[3] * X[7] - X[4] * X[6];
            const L c3 = X[7] * X[2] - X[8] * X[1], c4 = X[8] * X[0] - X[6] * X[2], c5 = X[6] * X[1] - X[7] * X[0];
            const L c6 = X[1] * X[5] - X[2] * X[4], c7 = X[2] * X[3] - X[0] * X[5], c8 = X[0] * X[4] - X[1] * X[3];
            const L h = S(0.5) / (X[0] * c0 + X[1] * c1 + X[2] * c2);
            const L C[9] = {c0, c1, c2, c3, c4, c5, c6, c7, c8};
            L d = L{};
            for (int k = 0; k < 9; ++k) {
                const L xn = S(0.5) * X[k] + h * C[k];
                d += (xn - X[k]) * (xn - X[k]);
                X[k] = active ? xn : X[k];
            }
            active = active & ~(d < S(1e-12));
        }
    } else {
        for (int k = 0; k < 9; ++k) X[k] = L{} + S((k % 4 == 0) ? 1 : 0);
    }
    // Linear stress of the unrotated displacement gradient H = R^T F - I; f_a = -V R sigma g_a
    // equals -R K_e (R^T x - X) of eq. 2.41 without forming K_e.
    L H[9], sig[9], RS[9];
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
            H[3 * c + r] =
                X[3 * r] * F[3 * c] + X[3 * r + 1] * F[3 * c + 1] + X[3 * r + 2] * F[3 * c + 2] - S(r == c ? 1 : 0);
    const L tr = S(lam) * (H[0] + H[4] + H[8]);
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) sig[3 * c + r] = S(mu) * (H[3 * c + r] + H[3 * r + c]) + (r == c ? tr : L{});
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
            RS[3 * c + r] = X[r] * sig[3 * c] + X[3 + r] * sig[3 * c + 1] + X[6 + r] * sig[3 * c + 2];
    // P = scale (R sigma) DmInv^T: columns are the forces on nodes 1..3; node 0 takes minus their sum
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
            P[3 + 3 * c + r] = scale * (RS[r] * Dm[c] + RS[3 + r] * Dm[3 + c] + RS[6 + r] * Dm[6 + c]);
    for (int r = 0; r < 3; ++r) P[r] = -(P[3 + r] + P[6 + r] + P[9 + r]);
    return inv;
}

// The rotations the kernel keeps (ForceOut::allRotations, kKeepRotation).
template <class L>
inline void keepRotations(State& s, int e0, int count, const L X[9], const L& det, const L& f2, const ForceOut& out) {
    for (int l = 0; l < count; ++l)
        if (out.allRotations || 2 * double(det[l]) < kKeepRotation * double(f2[l])) {
            double* rot = s.rot.col(e0 + l).data();
            for (int k = 0; k < 9; ++k) rot[k] = X[k][l];
        }
}

// Each element's stretch bound 2 det F / |F|^2 for limitStretch, rounded down to 1/255 (255: at
// least 1; 0: at most 0, or stretched past kMaxStretch's flag), so that the limiting pass
// picks each element's own watch without recomputing F (no other thread writes these bytes).
template <class L>
inline void markNearFlat(State& s, int e0, int count, double watch, const L& det, const L& f2) {
    if (!(watch > 0)) return;
    for (int l = 0; l < count; ++l) {
        const double bound = 2 * double(det[l]) / double(f2[l]);
        s.nearFlat[static_cast<size_t>(e0 + l)] =
            double(f2[l]) > kWatchStretch2 || !(bound > 0)
                ? 0
                : static_cast<unsigned char>(std::min(255.0, std::floor(255 * bound)));
    }
}

// Forces of the elements e0 .. e0 + count - 1 (count <= kLanes) in double.
inline int elementBlock(const Model& m, State& s, const double* alpha, int e0, int count, double lam, double mu,
                        bool corot, double watch, int* nearFlat, const ForceOut& out) {
    Lane Ds[9], Dm[9], scale, P[12], X[9], det, f2;
#ifdef CUTSIM_LANE_TRANSPOSE
    if (count == kLanes)
        loadFullBlock(m, s, alpha, e0, Ds, Dm, scale);
    else
#endif
        copyLanes(m, s, alpha, e0, count, Ds, Dm, scale);
    const int inv = blockForces(s, e0, count, Ds, Dm, scale, lam, mu, corot, watch, nearFlat, P, X, det, f2);
    markNearFlat(s, e0, count, watch, det, f2);
#ifdef CUTSIM_LANE_TRANSPOSE
    if (count == kLanes)
        writeFullBlock(m, s, e0, P, out);
    else
#endif
        writeLanes(m, s, e0, count, P, out);
    if (corot) keepRotations(s, e0, count, X, det, f2, out);
    return inv;
}

// The same for count <= kLanesF elements in float (ForcePrecision::Single): a full block loads and
// writes as two double blocks, converted.
inline int elementBlockF(const Model& m, State& s, const double* alpha, int e0, int count, double lam, double mu,
                         bool corot, double watch, int* nearFlat, const ForceOut& out) {
    LaneF Ds[9], Dm[9], scale, P[12], X[9], det, f2;
#ifdef CUTSIM_LANE_TRANSPOSE
    const bool full = count == kLanesF;
    if (full) {
        Lane lo[19], hi[19];  // Ds, Dm, scale of each half
        loadFullBlock(m, s, alpha, e0, lo, lo + 9, lo[18]);
        loadFullBlock(m, s, alpha, e0 + kLanes, hi, hi + 9, hi[18]);
        for (int k = 0; k < 9; ++k) {
            Ds[k] = joinLanes(lo[k], hi[k]);
            Dm[k] = joinLanes(lo[9 + k], hi[9 + k]);
        }
        scale = joinLanes(lo[18], hi[18]);
    } else
#endif
        copyLanes(m, s, alpha, e0, count, Ds, Dm, scale);
    const int inv = blockForces(s, e0, count, Ds, Dm, scale, lam, mu, corot, watch, nearFlat, P, X, det, f2);
    markNearFlat(s, e0, count, watch, det, f2);
#ifdef CUTSIM_LANE_TRANSPOSE
    if (full) {
        Lane lo[12], hi[12];
        for (int k = 0; k < 12; ++k) {
            lo[k] = lowLanes(P[k]);
            hi[k] = highLanes(P[k]);
        }
        writeFullBlock(m, s, e0, lo, out);
        writeFullBlock(m, s, e0 + kLanes, hi, out);
    } else
#endif
        writeLanes(m, s, e0, count, P, out);
    if (corot) keepRotations(s, e0, count, X, det, f2, out);
    return inv;
}

void elementBlocks(const Model& m, State& s, const double* alpha, int begin, int end, int* inverted, double watch,
                   int* nearFlat, const ForceOut& out) {
    const double lam = m.material.lambda(), mu = m.material.mu();
    const bool corot = m.elementModel == ElementModel::Corotational;
    int inv = 0, near = 0;
    if (m.precision == ForcePrecision::Single)
        for (int e = begin; e < end; e += kLanesF)
            inv += elementBlockF(m, s, alpha, e, std::min(kLanesF, end - e), lam, mu, corot, watch, &near, out);
    else
        for (int e = begin; e < end; e += kLanes)
            inv += elementBlock(m, s, alpha, e, std::min(kLanes, end - e), lam, mu, corot, watch, &near, out);
    if (inverted) *inverted += inv;
    if (nearFlat) *nearFlat += near;
}

// Gravity and applied force of node i: where every node's sum starts.
inline Eigen::Vector3d nodeLoad(const Model& m, const State& s, int i) { return s.fExt.col(i) + m.mass(i) * m.gravity; }

// Node i's load plus its element slots in state.fe, in element order.
inline void gatherNode(const Model& m, State& s, int i) {
    Eigen::Vector3d f = nodeLoad(m, s, i);
    for (int k = m.nodeSlotStart[i]; k < m.nodeSlotEnd[i]; ++k) {
        const int slot = m.nodeSlots[k];
        f += Eigen::Map<const Eigen::Vector3d>(s.fe.col(slot >> 2).data() + 3 * (slot & 3));
    }
    s.f.col(i) = f;
}

}  // namespace

void elementForces(const Model& m, State& s, const double* alpha, int begin, int end, int* inverted, double watch,
                   int* nearFlat) {
    elementBlocks(m, s, alpha, begin, end, inverted, watch, nearFlat, ForceOut{});
}

void gatherForces(const Model& m, State& s, int begin, int end) {
    for (int i = begin; i < end; ++i) gatherNode(m, s, i);
}

namespace {

// Inside the force stage's region, once nodes [begin, end) hold their sums: their NodeUpdate (if
// any), the first thread closing the node phase on its clock. Returns how many are not finite.
int updateNodes(const Model& m, State& s, const NodeUpdate* up, int begin, int end, int t, ForceStageSeconds* times,
                WallClock::time_point& t0) {
    if (!up) return 0;
    if (times && t == 0) {
        times->nodes += secondsSince(t0);
        t0 = WallClock::now();
    }
    const NodeUpdate& u = *up;
    int bad = 0;
    for (int i = begin; i < end; ++i) {
        const double w = m.invMass(i);
        if (w == 0)
            s.v.col(i).setZero();
        else {
            s.v.col(i) = (u.a * s.v.col(i) + u.h * w * s.f.col(i)) * u.b;
            s.x.col(i) += u.dt * s.v.col(i);
        }
        bad += nonFiniteNode(s, i);
    }
    return bad;
}

// Thread t's share [split(n, t), split(n, t + 1)) of n items.
struct Split {
    int nt;
    int operator()(int n, int k) const { return static_cast<int>(static_cast<long>(n) * k / nt); }
};

// Small meshes: every element into state.fe, one barrier, then each node's sum.
void forcesViaSlots(const Model& m, State& s, const double* alpha, double watch, bool allRotations,
                    ForceStageSeconds* times, NodeUpdate* up, int& inverted, int& nearFlat) {
    const int ne = m.elements(), nn = m.nodes();
    const ForceOut out{nullptr, nullptr, allRotations};
    WallClock::time_point t0 = times ? WallClock::now() : WallClock::time_point{};
    int inv = 0, near = 0, bad = 0;
#pragma omp parallel reduction(+ : inv, near, bad) if (ne >= kParallelElements)
    {
        const int t = omp_get_thread_num();
        const Split split{omp_get_num_threads()};
        elementBlocks(m, s, alpha, split(ne, t), split(ne, t + 1), &inv, watch, &near, out);
#pragma omp barrier
        if (times && t == 0) {
            times->elements += secondsSince(t0);
            t0 = WallClock::now();
        }
        gatherForces(m, s, split(nn, t), split(nn, t + 1));
        bad += updateNodes(m, s, up, split(nn, t), split(nn, t + 1), t, times, t0);
    }
    if (times) (up ? times->update : times->nodes) += secondsSince(t0);
    if (up) up->nonFinite = bad;
    inverted = inv;
    nearFlat = near;
}

// Large meshes: each node's load first, then the kernel adds into the nodes its thread alone
// touches; the nodes two threads share are summed from their slots after the last barrier.
void forcesFused(const Model& m, State& s, const double* alpha, double watch, bool allRotations,
                 ForceStageSeconds* times, NodeUpdate* up, int& inverted, int& nearFlat) {
    const int ne = m.elements(), nn = m.nodes();
    s.sharedNode.resize(static_cast<size_t>(nn));
    WallClock::time_point t0 = times ? WallClock::now() : WallClock::time_point{};
    int inv = 0, near = 0, bad = 0;
#pragma omp parallel reduction(+ : inv, near, bad) if (ne >= kParallelElements)
    {
        const int nt = omp_get_num_threads(), t = omp_get_thread_num();
        const Split split{nt};
        // Element ranges are contiguous and a node's slots are in element order, so its elements
        // span two ranges exactly when its first and last lie on two sides of a range boundary.
        for (int i = split(nn, t); i < split(nn, t + 1); ++i) {
            s.f.col(i) = nodeLoad(m, s, i);
            const int k0 = m.nodeSlotStart[i], k1 = m.nodeSlotEnd[i];
            bool shared = false;
            for (int b = 1; b < nt && k1 > k0; ++b)
                shared =
                    shared || ((m.nodeSlots[k0] >> 2) < split(ne, b) && (m.nodeSlots[k1 - 1] >> 2) >= split(ne, b));
            s.sharedNode[static_cast<size_t>(i)] = shared;
        }
#pragma omp barrier
        // phase times: the first thread's clock at the barriers that end the phases
        if (times && t == 0) {
            times->nodes += secondsSince(t0);
            t0 = WallClock::now();
        }
        // one thread shares no node: no flags to read
        const ForceOut out{s.f.data(), nt > 1 ? s.sharedNode.data() : nullptr, allRotations};
        elementBlocks(m, s, alpha, split(ne, t), split(ne, t + 1), &inv, watch, &near, out);
#pragma omp barrier
        if (times && t == 0) {
            times->elements += secondsSince(t0);
            t0 = WallClock::now();
        }
        for (int i = split(nn, t); i < split(nn, t + 1) && nt > 1; ++i)
            if (s.sharedNode[static_cast<size_t>(i)]) gatherNode(m, s, i);
        // this thread's nodes now hold their sums: the other threads add only into their own
        bad += updateNodes(m, s, up, split(nn, t), split(nn, t + 1), t, times, t0);
    }
    if (times) (up ? times->update : times->nodes) += secondsSince(t0);
    if (up) up->nonFinite = bad;
    inverted = inv;
    nearFlat = near;
}

}  // namespace

void computeForces(const Model& m, State& s, const double* alpha, double watch, bool allRotations,
                   ForceStageSeconds* times, NodeUpdate* update) {
    int inverted = 0, nearFlat = 0;
    const int ne = m.elements();
    if (watch > 0) s.nearFlat.resize(static_cast<size_t>(ne));
    if (ne < kFusedElements)
        forcesViaSlots(m, s, alpha, watch, allRotations, times, update, inverted, nearFlat);
    else
        forcesFused(m, s, alpha, watch, allRotations, times, update, inverted, nearFlat);
    s.flags.inverted = inverted;
    s.flags.nearFlat = nearFlat;
    s.flags.firstInverted = -1;
    // Rare: find one for messages with a scan instead of a shared write in the hot loop.
    for (int e = 0; inverted > 0 && e < ne; ++e) {
        const Eigen::Vector3d x0 = s.x.col(m.tets(0, e));
        Eigen::Matrix3d Ds;
        Ds << s.x.col(m.tets(1, e)) - x0, s.x.col(m.tets(2, e)) - x0, s.x.col(m.tets(3, e)) - x0;
        if ((Ds * m.dmInv(e)).determinant() <= 0) {
            s.flags.firstInverted = e;
            break;
        }
    }
}

void setThreads(int n) { omp_set_num_threads(n > 0 ? n : omp_get_num_procs()); }
int threads() { return omp_get_max_threads(); }

}  // namespace cutsim
