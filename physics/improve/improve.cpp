// Mesh improvement for a larger stable step (docs/method.md sec. 4, thesis sec. 5.1).
//
// The objective is the one the thesis keeps its best mesh by, the exact step, through its sharpest
// local form: the reduced-one-ring eigenvalue lambda_R1R(e) = lambda_max(M_r^-1/2 K_r M_r^-1/2) of
// each element (K_r the assembled 12x12 rows of its 4 nodes, M_r their lumped masses; Fierz et al.
// 2012). K_r is a principal submatrix of the assembled K, so every lambda_R1R bounds the global
// lambda_max from below, and on the data meshes their maximum is within 1% of it (0.1% on the
// thesis's liver and armadillo; docs/method.md sec. 3). Moving a node or flipping changes the rows
// of a few nodes only, so each trial re-solves the 12x12 problems of the elements touching them.
#include "improve/improve.hpp"
#include "improve/boundary.hpp"
#include "improve/partition.hpp"
#include "improve/rows.hpp"
#include "improve/stats.hpp"
#include "improve/topology.hpp"

#include "embed/clip.hpp"
#include "fem/model.hpp"
#include "fem/tet.hpp"
#include "timestep/timestep.hpp"
#include "util/stopwatch.hpp"

#include <Eigen/Dense>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <exception>
#include <future>
#include <map>
#include <numeric>
#include <optional>
#include <thread>

namespace cutsim {
namespace {

using Vec3 = Eigen::Vector3d;
using Tet = std::array<int, 4>;
using Tri = std::array<Vec3, 3>;

// 6 V / l_max^3 of an accepted element: far from flat (the regular tet has 0.71) and far above the
// readers' kMinTetFlatness, so an improved mesh always loads.
constexpr double kMinFlatness = 1e-3;
// Soft maximum exponent: ties between equally bad elements still give a descent direction.
constexpr int kSoftMaxPower = 16;
// x^kSoftMaxPower by squaring (std::pow costs more than it).
inline double softTerm(double x) {
    static_assert(kSoftMaxPower == 16);
    x *= x;
    x *= x;
    x *= x;
    return x * x;
}
// Default work: 12x12 problems per element of the input, with a floor for small meshes.
constexpr long long kEvaluationsPerTet = 140;
constexpr long long kMinEvaluations = 100000;
// A node's descent watches the elements within this factor of its local maximum (and its own).
constexpr double kWatched = 0.35;
// Lean descent: probes solve the elements within this factor of the local maximum.
constexpr double kProbe = 0.6;
// 12x12 problems assembled and solved together, one per vector lane (largestEigenvaluesInterleaved).
constexpr int kChunk = 8;
// Fewer nodes to smooth than this per thread: one thread does them (threads cost more than they save).
constexpr int kMinNodesPerThread = 12;
// Times the waiting nodes of a smoothing pass are cut again before one thread does the rest.
constexpr int kCutLevels = 2;

// What one thread of a smoothing pass owns: scratch, and the volume change, work and moves it
// made, folded into the improver's after the pass in thread order, so that a result depends on
// the thread count but not on timing.
struct Worker {
    std::vector<unsigned> stampE;  // touching()'s marks, per element
    unsigned stampT = 0;
    std::vector<double> floor;
    std::vector<int> patch, ring, elems, watched, probed, rest, stale;
    double ref = 1;             // the soft maximum's unit
    double dV = 0;              // enclosed volume change [m^3]
    long long evaluations = 0;  // 12x12 problems solved
    int moves = 0;
    int share = 1;  // threads in the pass: each may use 1/share of the volume change and work left
};

class Improver {
public:
    Improver(const TetMesh& mesh, const ImproveOptions& o, int threads) : opts_(o), mat_(o.material) {
        rows_.lame = mat_.lambda();
        rows_.mu = mat_.mu();
        rq_ = mat_.rho / 4;
        X_ = mesh.X;
        X0_ = mesh.X;
        const int n = mesh.nodes();
        nt_.assign(n, {});
        rows_.resize(n);
        stampN_.assign(n, 0);
        workers_.resize(static_cast<size_t>(std::max(1, threads)));
        for (int e = 0; e < mesh.elements(); ++e) {
            Tet t{mesh.tets(0, e), mesh.tets(1, e), mesh.tets(2, e), mesh.tets(3, e)};
            if (tetSignedVolume(X_.col(t[0]), X_.col(t[1]), X_.col(t[2]), X_.col(t[3])) < 0) std::swap(t[2], t[3]);
            addTet(t);
        }
        elements0_ = mesh.elements();
        volume0_ = volume_;
        const Vec3 lo = X_.rowwise().minCoeff(), hi = X_.rowwise().maxCoeff();
        diag_ = (hi - lo).norm();
        b0_.build(mesh, opts_.featureAngleDeg, opts_.moveBoundary);
        for (int i : opts_.fixedNodes)
            if (i >= 0 && i < n) b0_.movable[i] = 0;
    }

    double diagonal() const { return diag_; }
    int moves = 0, flips23 = 0, flips32 = 0, collapses = 0;
    long long evaluations = 0;  // 12x12 eigenvalue problems solved

    // The live mesh, unreferenced nodes dropped.
    TetMesh mesh() const { return liveMesh(X_, T_, alive_); }

    // How far the boundary at positions X is from the old surface, at most (boundary.hpp).
    double boundaryDistance(const Eigen::Matrix3Xd& X) const {
        return b0_.movedDistance(X, X0_, opts_.boundaryBothWays);
    }
    const Eigen::Matrix3Xd& positions() const { return X_; }
    // The live mesh's M^-1/2 K M^-1/2 from the kept rows: what the mesh's model would assemble,
    // to round-off, without assembling it.
    void scaledStiffness(ScaledStiffness& op) const { rows_.scaled(nt_, T_, rq_, op); }

    // The largest lambda_R1R of the live mesh, the stale elements solved again.
    double largestLambda() {
        std::vector<int> stale;
        double top = 0;
        for (int e = 0; e < static_cast<int>(T_.size()); ++e)
            if (alive_[e] && dirty_[e]) stale.push_back(e);
        evaluate(stale.data(), static_cast<int>(stale.size()), workers_[0]);
        fold();
        for (int e = 0; e < static_cast<int>(T_.size()); ++e)
            if (alive_[e]) top = std::max(top, lam_[e]);
        return top;
    }
    double volume() const { return volume_; }

    // Work budget (12x12 problems solved) and wall-clock deadline.
    void setLimits(long long budget, WallClock::time_point deadline) {
        budget_ = budget;
        deadline_ = deadline;
    }
    bool outOfTime() const { return outOfTime(workers_[0]); }

    bool round(double& tSmooth, double& tTopo) {
        std::vector<int> bad = criticalElements();
        if (bad.empty()) return false;
        bool changed = false;
        auto t0 = WallClock::now();
        if (opts_.smooth) changed = smoothPass(bad);
        tSmooth += secondsSince(t0);
        t0 = WallClock::now();
        if (opts_.flips || opts_.collapse) {
            Worker& w = workers_[0];
            for (int e : bad) {
                if (outOfTime(w)) break;
                if (!alive_[e]) continue;
                if (opts_.flips && (flipFaces(e, w) || flipEdges(e, w))) {
                    changed = true;
                    continue;
                }
                if (opts_.collapse && collapseShortest(e, w)) changed = true;
            }
            fold();
        }
        tTopo += secondsSince(t0);
        return changed;
    }

private:
    // ---- smoothing pass -------------------------------------------------------------------------

    // Smooths each node of the bad elements once, worst element first. With k threads the nodes
    // are cut into k slabs along the longest axis of their box. A node whose re-solved elements
    // (those touching its one ring) meet another slab's waits; the waiting nodes are cut again
    // (they lie along the cuts, so along another axis), and what still waits is done on one
    // thread. The threads' nodes neither read nor write each other's rows, so each part runs as
    // if alone and a result depends on the thread count only.
    bool smoothPass(const std::vector<int>& bad) {
        std::vector<int> nodes;
        ++stamp_;
        for (int e : bad) {
            if (!alive_[e]) continue;
            for (int a : T_[e]) {
                if (stampN_[a] == stamp_) continue;
                stampN_[a] = stamp_;
                if (b0_.movable[a] && !nt_[a].empty()) nodes.push_back(a);
            }
        }
        bool changed = false;
        for (int level = 0; level < kCutLevels && !nodes.empty(); ++level) {
            const int k =
                std::min(static_cast<int>(workers_.size()), static_cast<int>(nodes.size()) / kMinNodesPerThread);
            if (k <= 1) break;
            std::vector<std::vector<int>> parts(k);
            std::vector<int> later;
            partitionNodes(nodes, X_, T_, nt_, parts, later);
            std::vector<char> moved(k, 0);
            std::vector<std::exception_ptr> error(k);
            auto run = [&](int p) {
                try {
                    workers_[p].share = k;
                    moved[p] = smoothNodes(parts[p], workers_[p]);
                } catch (...) {
                    error[p] = std::current_exception();
                }
            };
            std::vector<std::thread> pool;
            for (int p = 1; p < k; ++p) pool.emplace_back(run, p);
            run(0);
            for (auto& t : pool) t.join();
            fold();
            for (int p = 0; p < k; ++p) {
                if (error[p]) std::rethrow_exception(error[p]);
                changed = changed || moved[p];
            }
            nodes = std::move(later);
        }
        changed = smoothNodes(nodes, workers_[0]) || changed;
        fold();
        return changed;
    }

    bool smoothNodes(const std::vector<int>& nodes, Worker& w) {
        bool changed = false;
        for (int i : nodes) {
            if (outOfTime(w)) break;
            if (smoothNode(i, w)) changed = true;
        }
        return changed;
    }

    // ---- assembled rows -------------------------------------------------------------------------

    void geometry(int e) {
        const Tet& t = T_[e];
        Eigen::Matrix3d Dm;
        for (int k = 0; k < 3; ++k) Dm.col(k) = X_.col(t[k + 1]) - X_.col(t[0]);
        V_[e] = Dm.determinant() / 6;
        g_[e] = shapeGradients(Dm.inverse());
    }

    // Adds (sign 1) or removes (-1) element e's share of the rows and masses, its volume to `volume`.
    void scatter(int e, double sign, double& volume) {
        volume += sign * V_[e];
        rows_.scatter(T_[e], g_[e], sign * V_[e], slot_[e]);
    }

    int addTet(const Tet& t) {
        const int e = static_cast<int>(T_.size());
        T_.push_back(t);
        alive_.push_back(1);
        dirty_.push_back(1);
        V_.push_back(0);
        g_.emplace_back();
        lam_.push_back(0);
        std::array<int, 16> slot;
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b) slot[4 * a + b] = rows_.slotOf(t[a], t[b]);
        slot_.push_back(slot);
        geometry(e);
        scatter(e, 1, volume_);
        for (int a : t) nt_[a].push_back(e);
        ++aliveCount_;
        return e;
    }
    void killTet(int e) {
        scatter(e, -1, volume_);
        alive_[e] = 0;
        --aliveCount_;
        for (int a : T_[e]) {
            auto& v = nt_[a];
            v.erase(std::find(v.begin(), v.end(), e));
        }
    }
    void reviveTet(int e) {
        alive_[e] = 1;
        ++aliveCount_;
        geometry(e);
        scatter(e, 1, volume_);
        for (int a : T_[e]) nt_[a].push_back(e);
    }

    // 6 V / l_max^3 of a node quadruple at the current positions (negative when inverted).
    double flatness(const Tet& t) const {
        double l2 = 0;
        for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b) l2 = std::max(l2, (X_.col(t[a]) - X_.col(t[b])).squaredNorm());
        return 6 * tetSignedVolume(X_.col(t[0]), X_.col(t[1]), X_.col(t[2]), X_.col(t[3])) / (l2 * std::sqrt(l2));
    }

    // ---- the objective --------------------------------------------------------------------------

    // lambda_R1R of elems[0 .. n-1] into lam_ (docs/method.md sec. 3), assembled straight into
    // the eigen-solver's lanes, kChunk at a time. Block (b, a) is taken as block (a, b)
    // transposed, so the matrix is symmetric to the bit (the kept rows are to round-off).
    void evaluate(const int* elems, int n, Worker& w) {
        alignas(64) double A[144 * kChunk];
        double out[kChunk], s[4][kChunk];
        const double* K[16][kChunk];
        for (int c = 0; c < n; c += kChunk) {
            const int m = std::min(kChunk, n - c);
            for (int l = 0; l < kChunk; ++l) {
                const int e = elems[c + (l < m ? l : 0)];  // padding lanes repeat the first
                const Tet& t = T_[e];
                for (int a = 0; a < 4; ++a) {
                    s[a][l] = 1 / std::sqrt(rq_ * rows_.vs[t[a]]);
                    for (int b = a; b < 4; ++b) K[4 * a + b][l] = rows_.blk[t[a]][slot_[e][4 * a + b]].data();
                }
            }
            for (int a = 0; a < 4; ++a)
                for (int b = a; b < 4; ++b) {
                    double sab[kChunk];
                    for (int l = 0; l < kChunk; ++l) sab[l] = s[a][l] * s[b][l];
                    for (int i = 0; i < 3; ++i)
                        for (int j = a == b ? i : 0; j < 3; ++j) {
                            double* up = A + kChunk * (12 * (3 * a + i) + 3 * b + j);
                            double* low = A + kChunk * (12 * (3 * b + j) + 3 * a + i);
                            for (int l = 0; l < kChunk; ++l) up[l] = K[4 * a + b][l][3 * j + i] * sab[l];
                            if (up != low)
                                for (int l = 0; l < kChunk; ++l) low[l] = up[l];
                        }
                }
            largestEigenvaluesInterleaved(A, m, out);
            for (int k = 0; k < m; ++k) {
                lam_[elems[c + k]] = out[k];
                dirty_[elems[c + k]] = 0;
            }
        }
        w.evaluations += n;
    }

    struct Score {
        double max = 0, soft = 0;
        bool better(const Score& o) const {
            return max < o.max * (1 - 1e-12) || (max <= o.max && soft < o.soft * (1 - 1e-12));
        }
    };
    // Solves elems' problems and scores them; `reference` first makes their maximum the soft
    // maximum's unit (the start of a node's descent or of a flip).
    Score score(const std::vector<int>& elems, Worker& w, bool reference = false) {
        evaluate(elems.data(), static_cast<int>(elems.size()), w);
        return scored(elems, w, reference);
    }
    // The same from the problems as last solved.
    Score scored(const std::vector<int>& elems, Worker& w, bool reference = false) {
        Score s;
        for (int e : elems) s.max = std::max(s.max, lam_[e]);
        if (reference) w.ref = s.max;
        for (int e : elems) s.soft += softTerm(lam_[e] / w.ref);
        return s;
    }

    // Alive elements with a node among `nodes` (rows changed there).
    void touching(const std::vector<int>& nodes, std::vector<int>& out, Worker& w) const {
        out.clear();
        if (w.stampE.size() < T_.size()) w.stampE.resize(T_.size(), 0);
        ++w.stampT;
        for (int a : nodes)
            for (int f : nt_[a])
                if (w.stampE[f] != w.stampT) {
                    w.stampE[f] = w.stampT;
                    out.push_back(f);
                }
    }

    // Elements whose R1R step is within a factor of the worst, worst first. Only elements whose
    // rows changed since their last solve are solved again.
    std::vector<int> criticalElements() {
        const double top = largestLambda();
        std::vector<int> bad;
        for (int e = 0; e < static_cast<int>(T_.size()); ++e)
            if (alive_[e] && lam_[e] > 0.5 * top) bad.push_back(e);
        std::sort(bad.begin(), bad.end(),
                  [&](int a, int b) { return lam_[a] > lam_[b] || (lam_[a] == lam_[b] && a < b); });
        const size_t cap = std::max<size_t>(64, static_cast<size_t>(aliveCount_) / 10);
        if (bad.size() > cap) bad.resize(cap);
        return bad;
    }

    // The workers' volume changes, work and moves into the improver's, in thread order.
    void fold() {
        for (Worker& w : workers_) {
            volume_ += w.dV;
            evaluations += w.evaluations;
            moves += w.moves;
            w.dV = 0;
            w.evaluations = 0;
            w.moves = 0;
            w.share = 1;
        }
    }
    bool outOfTime(const Worker& w) const {
        return evaluations + w.share * w.evaluations >= budget_ || WallClock::now() > deadline_;
    }

    // ---- boundary -------------------------------------------------------------------------------

    // The boundary around node i stays within the distance bound of the old surface.
    bool boundaryKept(int i, Worker& w) const {
        const double tol = opts_.maxBoundaryDistance * diag_;
        if (!b0_.within(X_.col(i), b0_.ring[i], tol)) return false;
        std::vector<int>& patch = w.patch;
        for (int f : b0_.ring[i]) {
            patch.assign(1, f);  // a sample of face f is most often near its own old face
            for (int v : b0_.faces[f])
                for (int g : b0_.ring[v]) patch.push_back(g);
            const Vec3 p0 = X_.col(b0_.faces[f][0]), p1 = X_.col(b0_.faces[f][1]), p2 = X_.col(b0_.faces[f][2]);
            const Vec3 samples[4] = {(p0 + p1) / 2, (p1 + p2) / 2, (p2 + p0) / 2, (p0 + p1 + p2) / 3};
            for (const Vec3& s : samples)
                if (!b0_.within(s, patch, tol)) return false;
            // Both ways: the old face near the new boundary too. A node sliding off a crease or a
            // tip keeps the new boundary on the old surface but cuts the old one away.
            if (!opts_.boundaryBothWays) continue;
            const auto& o = b0_.tris[f];
            for (const Vec3& s : ReferenceBoundary::samples(o[0], o[1], o[2]))
                if (!b0_.withinMoved(s, patch, X_, tol)) return false;
        }
        // Each of k threads may use 1/k of what is left (then all of them together stay within).
        return std::abs(volume_ + w.share * w.dV - volume0_) <= opts_.maxVolumeChange * volume0_;
    }

    // ---- smoothing ------------------------------------------------------------------------------

    // Puts node i at p, unless an element would get flatter than kMinFlatness or than it was
    // (w.floor, per element of nt_[i], set by smoothNode): then nothing changes and false.
    bool place(int i, const Vec3& p, Worker& w) {
        const Vec3 old = X_.col(i);
        X_.col(i) = p;
        bool ok = true;
        for (size_t k = 0; k < nt_[i].size() && ok; ++k) ok = flatness(T_[nt_[i][k]]) >= w.floor[k];
        X_.col(i) = old;
        if (!ok) return false;
        X_.col(i) = p;
        for (int e : nt_[i]) {
            const Mat34 g0 = g_[e];
            const double v0 = V_[e];
            geometry(e);
            w.dV += V_[e] - v0;
            rows_.rescatter(T_[e], g0, v0, g_[e], V_[e], slot_[e]);
        }
        return true;
    }

    // Descends the soft maximum of lambda_R1R over the elements node i influences, along its
    // finite-difference gradient (in the tangent plane for a boundary node, then back onto the
    // node's original faces), accepting a step only when the local maximum does not rise.
    bool smoothNode(int i, Worker& w) {
        if (!b0_.movable[i] || nt_[i].empty()) return false;
        std::vector<int>& ring = w.ring;
        ring.clear();
        for (int e : nt_[i])
            for (int b : T_[e]) ring.push_back(b);
        std::sort(ring.begin(), ring.end());
        ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
        std::vector<int>& elems = w.elems;
        touching(ring, elems, w);
        double len = 0;
        for (int b : ring)
            if (b != i) len += (X_.col(b) - X_.col(i)).norm();
        len /= std::max<size_t>(1, ring.size() - 1);

        const bool onBoundary = b0_.onBoundary[i];
        Vec3 t1 = Vec3::UnitX(), t2 = Vec3::UnitY(), t3 = Vec3::UnitZ(), normal = Vec3::Zero();
        double ringArea = 0;
        if (onBoundary) {
            for (int f : b0_.ring[i]) {
                const Vec3 c = (X_.col(b0_.faces[f][1]) - X_.col(b0_.faces[f][0]))
                                   .cross(X_.col(b0_.faces[f][2]) - X_.col(b0_.faces[f][0]));
                normal += c;
                ringArea += 0.5 * c.norm();
            }
            normal.normalize();
            t1 = normal.unitOrthogonal();
            t2 = normal.cross(t1);
        }
        const bool onCrease = onBoundary && !b0_.crease[i].empty();
        if (onCrease) t1 = (X0_.col(b0_.crease[i][0]) - X0_.col(b0_.crease[i][1])).normalized();
        w.floor.clear();
        for (int e : nt_[i]) w.floor.push_back(std::min(kMinFlatness, flatness(T_[e])));
        Score best;
        if (opts_.lean) {  // the problems solved since their rows last changed still hold
            std::vector<int>& stale = w.stale;
            stale.clear();
            for (int e : elems)
                if (dirty_[e]) stale.push_back(e);
            evaluate(stale.data(), static_cast<int>(stale.size()), w);
            best = scored(elems, w, true);
        } else {
            best = score(elems, w, true);
        }
        // The descent watches the elements that can become critical: those near the local maximum,
        // and those of node i, whose shapes change. The others' problems change through masses and
        // shared edges only, by far less than the factor; their soft maximum terms are < 1e-7.
        std::vector<int>& watched = w.watched;
        watched.clear();
        for (int e : elems) {
            const Tet& t = T_[e];
            if (lam_[e] >= kWatched * w.ref || t[0] == i || t[1] == i || t[2] == i || t[3] == i) watched.push_back(e);
        }
        best.soft = 0;
        for (int e : watched) best.soft += softTerm(lam_[e] / w.ref);
        // Lean: probes solve the near-critical elements alone (the soft maximum's gradient is
        // theirs: an element at kProbe of the maximum weighs kProbe^16 < 3e-4), and a trial solves
        // them first, stopping when their maximum already rises.
        std::vector<int>& probed = w.probed;
        std::vector<int>& rest = w.rest;
        probed.clear();
        rest.clear();
        for (int e : watched) (!opts_.lean || lam_[e] >= kProbe * w.ref ? probed : rest).push_back(e);
        double probedSoft = 0;
        for (int e : probed) probedSoft += softTerm(lam_[e] / w.ref);
        bool moved = false, fresh = true;  // fresh: lam_ of the watched elements is of the current rows
        for (int iter = 0; iter < opts_.descentSteps; ++iter) {
            const Vec3 x = X_.col(i);
            const double h = 1e-4 * len;
            Vec3 grad = Vec3::Zero();
            const Vec3 dirs[3] = {t1, t2, t3};
            const int nd = onCrease ? 1 : onBoundary ? 2 : 3;
            bool probeOk = true;
            for (int k = 0; k < nd && probeOk; ++k) {
                probeOk = place(i, x + h * dirs[k], w);
                if (probeOk) grad += dirs[k] * (score(probed, w).soft - probedSoft) / h;
            }
            place(i, x, w);
            fresh = false;
            if (!probeOk || grad.squaredNorm() == 0) break;
            const Vec3 d = -grad.normalized();
            bool accepted = false;
            const double volume = w.dV;
            for (double step = 0.3 * len; step > 1e-3 * len; step *= 0.5) {
                Vec3 p = x + step * d;
                if (onCrease) {
                    p = b0_.projectToCrease(i, p, X0_);
                } else if (onBoundary) {
                    // Slide within the old faces, then along the normal by what gives the volume
                    // back: dV = offset x (ring area / 3) to first order.
                    p = b0_.projectToRing(i, p);
                    if (!place(i, p, w)) continue;
                    const double dV = w.dV - volume;
                    p += normal * (-dV / (ringArea / 3));
                }
                if (!place(i, p, w) || (onBoundary && !boundaryKept(i, w))) continue;
                if (!rest.empty() && score(probed, w).max > best.max) continue;
                if (!rest.empty()) evaluate(rest.data(), static_cast<int>(rest.size()), w);
                const Score s = rest.empty() ? score(watched, w) : scored(watched, w);
                if (s.better(best)) {
                    best = s;
                    probedSoft = rest.empty() ? s.soft : scored(probed, w).soft;
                    accepted = true;
                    break;
                }
            }
            if (!accepted) {
                place(i, x, w);
                break;
            }
            moved = fresh = true;
        }
        // The rows of elems changed: what was not solved at the final position is solved again
        // by the next round's critical-element search.
        if (!opts_.lean) {
            if (!fresh || watched.size() < elems.size())
                for (int e : elems) dirty_[e] = 1;
        } else if (!moved) {  // the rows are back (to round-off): the solved ones are of trials
            for (int e : watched) dirty_[e] = 1;
        } else {
            for (int e : elems) dirty_[e] = 1;
            if (fresh)
                for (int e : watched) dirty_[e] = 0;
        }
        if (moved) ++w.moves;
        return moved;
    }

    // ---- flips and collapses --------------------------------------------------------------------

    // Replaces the elements `olds` by `news` (node lists) when that lowers the local objective;
    // otherwise restores them.
    bool tryReplace(const std::vector<int>& olds, std::vector<Tet> news, Worker& w) {
        // Every new element positive and no flatter than kMinFlatness or the flattest it
        // replaces, and the volume preserved.
        double vOld = 0, vNew = 0, floor = kMinFlatness;
        for (int e : olds) {
            vOld += V_[e];
            floor = std::min(floor, flatness(T_[e]));
        }
        for (Tet& t : news) {
            double v = tetSignedVolume(X_.col(t[0]), X_.col(t[1]), X_.col(t[2]), X_.col(t[3]));
            if (v < 0) {
                std::swap(t[2], t[3]);
                v = -v;
            }
            vNew += v;
            if (flatness(t) < floor) return false;
        }
        if (std::abs(vNew - vOld) > 1e-9 * vOld) return false;
        std::vector<int> nodes;
        for (int e : olds)
            for (int a : T_[e]) nodes.push_back(a);
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
        std::vector<int> elems;
        touching(nodes, elems, w);
        const Score before = score(elems, w, true);
        for (int e : olds) killTet(e);
        std::vector<int> added;
        for (const Tet& t : news) added.push_back(addTet(t));
        touching(nodes, elems, w);
        if (score(elems, w).better(before)) return true;
        for (int e : added) killTet(e);
        for (int e : olds) reviveTet(e);
        touching(nodes, elems, w);
        for (int e : elems) dirty_[e] = 1;
        return false;
    }

    // 2-3 flips across the faces of element e.
    bool flipFaces(int e, Worker& w) {
        for (int o = 0; o < 4; ++o) {
            const Tet& t = T_[e];
            const int d = t[o];
            int face[3], k = 0;
            for (int a = 0; a < 4; ++a)
                if (a != o) face[k++] = t[a];
            // The element across the face.
            int other = -1, e2 = -1;
            for (int f : nt_[face[0]]) {
                if (f == e) continue;
                const Tet& u = T_[f];
                if (std::count(u.begin(), u.end(), face[1]) && std::count(u.begin(), u.end(), face[2])) {
                    e2 = f;
                    for (int b : u)
                        if (b != face[0] && b != face[1] && b != face[2]) other = b;
                }
            }
            if (e2 < 0) continue;
            std::vector<Tet> news = {
                {face[0], face[1], d, other}, {face[1], face[2], d, other}, {face[2], face[0], d, other}};
            if (tryReplace({e, e2}, news, w)) {
                ++flips23;
                return true;
            }
        }
        return false;
    }

    // 3-2 flips of the interior edges of element e that have exactly three elements around them.
    bool flipEdges(int e, Worker& w) {
        for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b) {
                const int p = T_[e][a], q = T_[e][b];
                std::vector<int> around;
                for (int f : nt_[p]) {
                    const Tet& u = T_[f];
                    if (std::count(u.begin(), u.end(), q)) around.push_back(f);
                }
                if (around.size() != 3) continue;
                std::map<int, int> ringUse;
                for (int f : around)
                    for (int c : T_[f])
                        if (c != p && c != q) ++ringUse[c];
                if (ringUse.size() != 3) continue;  // an open ring: the edge is on the boundary
                std::vector<int> r;
                for (const auto& [c, uses] : ringUse) r.push_back(c);
                if (tryReplace(around, {{r[0], r[1], r[2], p}, {r[0], r[1], r[2], q}}, w)) {
                    ++flips32;
                    return true;
                }
            }
        return false;
    }

    // Collapses the shortest edge of element e that has an interior, movable end into its other end.
    bool collapseShortest(int e, Worker& w) {
        std::array<std::pair<double, std::pair<int, int>>, 12> cand;
        int nc = 0;
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b) {
                if (a == b) continue;
                const int p = T_[e][a], q = T_[e][b];
                if (b0_.onBoundary[p] || !b0_.movable[p]) continue;
                cand[nc++] = {(X_.col(p) - X_.col(q)).squaredNorm(), {p, q}};
            }
        std::sort(cand.begin(), cand.begin() + nc);
        for (int c = 0; c < std::min(nc, 2); ++c) {
            const auto [p, q] = cand[c].second;
            std::vector<int> olds = nt_[p];
            int removed = 0;
            std::vector<Tet> news;
            for (int f : olds) {
                Tet t = T_[f];
                if (std::count(t.begin(), t.end(), q)) {
                    ++removed;
                    continue;
                }
                for (int& v : t)
                    if (v == p) v = q;
                news.push_back(t);
            }
            if (aliveCount_ - removed < (1 - opts_.maxElementLoss) * elements0_) return false;
            if (!manifoldAfter(q, olds, news, nt_, T_)) continue;
            if (tryReplace(olds, news, w)) {
                ++collapses;
                return true;
            }
        }
        return false;
    }

    const ImproveOptions& opts_;
    Material mat_;
    double rq_ = 0;            // rho / 4: a node's lumped mass over its elements' volume
    Eigen::Matrix3Xd X_, X0_;  // current and original positions
    std::vector<Tet> T_;
    std::vector<char> alive_, dirty_;  // dirty: rows changed since lam_ was solved
    std::vector<double> V_, lam_;
    std::vector<KeptRows::Slots> slot_;
    std::vector<Mat34, Eigen::aligned_allocator<Mat34>> g_;
    std::vector<std::vector<int>> nt_;
    KeptRows rows_;
    double volume_ = 0, volume0_ = 0, diag_ = 0;
    int elements0_ = 0, aliveCount_ = 0;
    long long budget_ = 0;
    WallClock::time_point deadline_;
    ReferenceBoundary b0_;  // the input's boundary, which moved nodes must stay near
    std::vector<unsigned> stampN_;
    unsigned stamp_ = 0;
    std::vector<Worker> workers_;  // one per thread; workers_[0] is the calling thread's
};

}  // namespace

ImproveReport improveMesh(TetMesh& mesh, const ImproveOptions& opts) {
    const auto start = WallClock::now();
    const auto deadline =
        start + std::chrono::duration_cast<WallClock::duration>(std::chrono::duration<double>(opts.maxSeconds));
    const int threads =
        opts.threads > 0 ? opts.threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    // The Lanczos solves and statistics would otherwise start OpenMP teams of all cores, on top
    // of the improver's own threads.
    struct SerialOpenMP {
        int before = omp_get_max_threads();
        SerialOpenMP() { omp_set_num_threads(1); }
        ~SerialOpenMP() { omp_set_num_threads(before); }
    } serial;
    ImproveReport r;
    double tStats = 0, tSmooth = 0, tTopo = 0, tExact = 0;
    auto t0 = WallClock::now();
    // With a second thread the input's statistics (its Lanczos) run beside the first round, which
    // is judged after them.
    const bool inputBeside = opts.exactSteps && threads > 1;
    std::future<MeshStepStats> input;
    if (inputBeside) {
        input = std::async(std::launch::async, [&mesh, &opts] {
            omp_set_num_threads(1);
            return meshStepStats(mesh, opts.material);
        });
    } else if (opts.exactSteps) {
        r.before = meshStepStats(mesh, opts.material);
    }
    tStats += secondsSince(t0);

    Improver imp(mesh, opts, threads);
    imp.setLimits(opts.maxEvaluations > 0 ? opts.maxEvaluations
                                          : std::max<long long>(kMinEvaluations, kEvaluationsPerTet * mesh.elements()),
                  deadline);
    // Without Lanczos a round is judged by 2 / sqrt(the largest lambda_R1R), solved by the improver.
    auto r1rStep = [&imp] { return 2 / std::sqrt(imp.largestLambda()); };
    if (!opts.exactSteps) r.before = r1rStats(mesh, r1rStep());
    r.diagonal = imp.diagonal();
    TetMesh best;
    Eigen::Matrix3Xd bestX;  // all positions of the best round, before unused nodes are dropped
    double bestDt = 0;
    int stale = 0;
    // A judged round's step: kept when it beats the best (then cur, X: its mesh and positions, or
    // the live ones when null); true when the run ends with it.
    auto judge = [&](int round, double dt, TetMesh* cur, const Eigen::Matrix3Xd* X) {
        r.history.push_back({secondsSince(start), dt});
        if (opts.progress && round > 0) opts.progress(round, secondsSince(start), dt);
        if (!(dt > bestDt * (1 + 1e-9))) return ++stale >= 3;
        bestDt = dt;
        best = cur ? std::move(*cur) : imp.mesh();
        bestX = X ? *X : imp.positions();
        r.bestRound = round;
        stale = 0;
        return opts.targetDt > 0 && bestDt >= opts.targetDt;
    };
    // With a second thread, a round's Lanczos runs beside the next round, whose smoothing seldom
    // keeps both busy (its critical elements are one cluster on the knight). When the solve ends
    // the run, that next round is dropped: the result is the serial order's.
    struct Pending {
        int round;
        TetMesh mesh;
        Eigen::Matrix3Xd X;
        std::future<double> dt;
    };
    ScaledStiffness op;  // a pending solve's: it outlives it, and the next is built after its judgement
    std::optional<Pending> pending;
    auto judgePending = [&] {
        Pending p = std::move(*pending);
        pending.reset();
        return judge(p.round, p.dt.get(), &p.mesh, &p.X);
    };
    // The input is round 0, the step to beat.
    auto judgeInput = [&] {
        const auto t = WallClock::now();
        if (input.valid()) r.before = input.get();
        TetMesh in = mesh;
        const bool end = judge(0, opts.exactSteps ? r.before.dtExact : r.before.dtR1R, &in, &mesh.X);
        tStats += secondsSince(t);
        return end;
    };
    if (!inputBeside) judgeInput();
    for (int round = 1; round <= opts.maxRounds; ++round) {
        if (opts.targetDt > 0 && bestDt >= opts.targetDt) break;
        if (imp.outOfTime()) break;
        const bool changed = imp.round(tSmooth, tTopo);
        if (input.valid() && judgeInput()) break;  // round dropped
        t0 = WallClock::now();
        // The R1R step bounds the exact one from above (sec. 3): a round it puts at or below the
        // best cannot beat it, and Lanczos is skipped (the next round needs these solves anyway).
        const double dtR1R = changed ? r1rStep() : 0;
        if (pending && judgePending()) break;
        r.rounds = round;
        if (!changed) break;
        bool end = false;
        if (!opts.exactSteps) {
            end = judge(round, dtR1R, nullptr, nullptr);
        } else if (!(dtR1R > bestDt * (1 + 1e-9))) {
            if (opts.progress) opts.progress(round, secondsSince(start), dtR1R);
            end = ++stale >= 3;
        } else {
            imp.scaledStiffness(op);
            if (threads > 1) {
                auto solve = [&op] {
                    omp_set_num_threads(1);
                    return exactCriticalDt(op).dt;
                };
                pending = Pending{round, imp.mesh(), imp.positions(), std::async(std::launch::async, std::move(solve))};
            } else {
                end = judge(round, exactCriticalDt(op).dt, nullptr, nullptr);
            }
        }
        tExact += secondsSince(t0);
        if (end) break;
    }
    if (input.valid()) judgeInput();
    t0 = WallClock::now();
    if (pending) judgePending();
    tExact += secondsSince(t0);
    r.moves = imp.moves;
    r.flips23 = imp.flips23;
    r.flips32 = imp.flips32;
    r.collapses = imp.collapses;
    if (opts.exactSteps) r.boundaryDistance = imp.boundaryDistance(bestX);  // else kept, not measured
    r.evaluations = imp.evaluations;
    best.source = mesh.source;
    mesh = std::move(best);
    t0 = WallClock::now();
    if (opts.exactSteps) {
        // The kept mesh's step from its own assembly, as meshStepStats gives it (the kept rows
        // agree to round-off); with a second thread beside the other statistics.
        auto dt = std::async(threads > 1 ? std::launch::async : std::launch::deferred, [&mesh, &opts] {
            omp_set_num_threads(1);
            return exactCriticalDt(buildModel(mesh, opts.material)).dt;
        });
        r.after = stepStats(mesh, opts.material, bestDt);
        r.after.dtExact = dt.get();
    } else {
        r.after = r1rStats(mesh, bestDt);
    }
    tStats += secondsSince(t0);
    r.volumeChange = (r.after.volume - r.before.volume) / r.before.volume;
    r.seconds = {
        {"smooth", tSmooth}, {"flips", tTopo}, {"exact", tExact}, {"stats", tStats}, {"total", secondsSince(start)}};
    return r;
}

}  // namespace cutsim
