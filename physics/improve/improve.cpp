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

#include "embed/clip.hpp"
#include "fem/model.hpp"
#include "fem/tet.hpp"
#include "timestep/timestep.hpp"
#include "util/stopwatch.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

namespace cutsim {
namespace {

using Vec3 = Eigen::Vector3d;
using Tet = std::array<int, 4>;
using Tri = std::array<Vec3, 3>;

constexpr double kPi = 3.14159265358979323846;
// 6 V / l_max^3 of an accepted element: far from flat (the regular tet has 0.71) and far above the
// readers' kMinTetFlatness, so an improved mesh always loads.
constexpr double kMinFlatness = 1e-3;
// Soft maximum exponent: ties between equally bad elements still give a descent direction.
constexpr double kSoftMaxPower = 16;
// Default work: 12x12 problems per element of the input, about 0.1 ms per element on one core,
// with a floor for small meshes.
constexpr long long kEvaluationsPerTet = 200;
constexpr long long kMinEvaluations = 100000;

double minDihedralDeg(const TetMesh& m) {
    static constexpr int kEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2},
                                         {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
    double best = 180;
    for (int e = 0; e < m.elements(); ++e) {
        for (const auto& ed : kEdges) {
            const Vec3 p = m.X.col(m.tets(ed[0], e)), q = m.X.col(m.tets(ed[1], e));
            const Vec3 r = m.X.col(m.tets(ed[2], e)), s = m.X.col(m.tets(ed[3], e));
            const Vec3 axis = (q - p).normalized();
            Vec3 u = r - p, v = s - p;
            u -= axis * axis.dot(u);
            v -= axis * axis.dot(v);
            const double c = u.dot(v) / std::max(u.norm() * v.norm(), 1e-300);
            best = std::min(best, std::acos(std::clamp(c, -1.0, 1.0)) * 180 / kPi);
        }
    }
    return best;
}

class Improver {
public:
    Improver(const TetMesh& mesh, const ImproveOptions& o) : opts_(o), mat_(o.material) {
        lame_ = mat_.lambda();
        mu_ = mat_.mu();
        rq_ = mat_.rho / 4;
        X_ = mesh.X;
        X0_ = mesh.X;
        const int n = mesh.nodes();
        nt_.assign(n, {});
        nbr_.assign(n, {});
        blk_.assign(n, {});
        vs_.assign(n, 0.0);
        stampN_.assign(n, 0);
        for (int e = 0; e < mesh.elements(); ++e) {
            Tet t{mesh.tets(0, e), mesh.tets(1, e), mesh.tets(2, e), mesh.tets(3, e)};
            if (tetSignedVolume(X_.col(t[0]), X_.col(t[1]), X_.col(t[2]), X_.col(t[3])) < 0) std::swap(t[2], t[3]);
            addTet(t);
        }
        elements0_ = mesh.elements();
        volume0_ = volume_;
        const Vec3 lo = X_.rowwise().minCoeff(), hi = X_.rowwise().maxCoeff();
        diag_ = (hi - lo).norm();
        setUpBoundary(mesh);
        for (int i : opts_.fixedNodes)
            if (i >= 0 && i < n) movable_[i] = 0;
    }

    double diagonal() const { return diag_; }
    int moves = 0, flips23 = 0, flips32 = 0, collapses = 0;
    long long evaluations = 0;  // 12x12 eigenvalue problems solved

    // The live mesh, unreferenced nodes dropped.
    TetMesh mesh() const {
        std::vector<int> map(X_.cols(), -1);
        int nNodes = 0, nTets = 0;
        for (size_t e = 0; e < T_.size(); ++e)
            if (alive_[e]) {
                ++nTets;
                for (int a : T_[e])
                    if (map[a] < 0) map[a] = nNodes++;
            }
        // Keep the input's node order.
        nNodes = 0;
        for (auto& m : map)
            if (m >= 0) m = nNodes++;
        TetMesh out;
        out.X.resize(3, nNodes);
        for (int i = 0; i < X_.cols(); ++i)
            if (map[i] >= 0) out.X.col(map[i]) = X_.col(i);
        out.tets.resize(4, nTets);
        int k = 0;
        for (size_t e = 0; e < T_.size(); ++e)
            if (alive_[e]) {
                for (int a = 0; a < 4; ++a) out.tets(a, k) = map[T_[e][a]];
                ++k;
            }
        return out;
    }

    // Largest distance from a sample of the boundary at positions X (vertices, edge midpoints,
    // centroids) to the old faces around its face's vertices: a bound on the distance to the old
    // surface. Faces whose vertices did not move are at distance 0.
    double boundaryDistance(const Eigen::Matrix3Xd& X) const {
        double worst = 0;
        std::vector<int> patch;
        for (int f = 0; f < static_cast<int>(bf_.size()); ++f) {
            const auto& t = bf_[f];
            if (X.col(t[0]) == X0_.col(t[0]) && X.col(t[1]) == X0_.col(t[1]) && X.col(t[2]) == X0_.col(t[2])) continue;
            patch.clear();
            for (int v : t)
                for (int g : ringFaces_[v]) patch.push_back(g);
            const Vec3 p0 = X.col(t[0]), p1 = X.col(t[1]), p2 = X.col(t[2]);
            const Vec3 samples[7] = {p0, p1, p2, (p0 + p1) / 2, (p1 + p2) / 2, (p2 + p0) / 2, (p0 + p1 + p2) / 3};
            for (const Vec3& s : samples) worst = std::max(worst, distanceToFaces(s, patch));
        }
        return worst;
    }
    const Eigen::Matrix3Xd& positions() const { return X_; }

    // Work budget (12x12 problems solved) and wall-clock deadline.
    void setLimits(long long budget, WallClock::time_point deadline) {
        budget_ = budget;
        deadline_ = deadline;
    }
    bool outOfTime() const { return evaluations >= budget_ || WallClock::now() > deadline_; }

    bool round(double& tSmooth, double& tTopo) {
        std::vector<int> bad = criticalElements();
        if (bad.empty()) return false;
        bool changed = false;
        auto t0 = WallClock::now();
        if (opts_.smooth) {
            ++stamp_;
            for (int e : bad) {
                if (!alive_[e]) continue;
                for (int a : T_[e]) {
                    if (stampN_[a] == stamp_) continue;
                    stampN_[a] = stamp_;
                    if (smoothNode(a)) changed = true;
                }
                if (outOfTime()) break;
            }
        }
        tSmooth += secondsSince(t0);
        t0 = WallClock::now();
        if (opts_.flips || opts_.collapse) {
            for (int e : bad) {
                if (outOfTime()) break;
                if (!alive_[e]) continue;
                if (opts_.flips && (flipFaces(e) || flipEdges(e))) {
                    changed = true;
                    continue;
                }
                if (opts_.collapse && collapseShortest(e)) changed = true;
            }
        }
        tTopo += secondsSince(t0);
        return changed;
    }

private:
    // ---- assembled rows -------------------------------------------------------------------------

    Eigen::Matrix3d& block(int i, int j) {
        auto& nb = nbr_[i];
        for (size_t k = 0; k < nb.size(); ++k)
            if (nb[k] == j) return blk_[i][k];
        nb.push_back(j);
        blk_[i].push_back(Eigen::Matrix3d::Zero());
        return blk_[i].back();
    }
    const Eigen::Matrix3d& blockOf(int i, int j) const {
        const auto& nb = nbr_[i];
        for (size_t k = 0; k < nb.size(); ++k)
            if (nb[k] == j) return blk_[i][k];
        static const Eigen::Matrix3d zero = Eigen::Matrix3d::Zero();
        return zero;
    }

    void geometry(int e) {
        const Tet& t = T_[e];
        Eigen::Matrix3d Dm;
        for (int k = 0; k < 3; ++k) Dm.col(k) = X_.col(t[k + 1]) - X_.col(t[0]);
        V_[e] = Dm.determinant() / 6;
        g_[e] = shapeGradients(Dm.inverse());
    }

    // Adds (sign 1) or removes (-1) element e's share of the rows and masses; K_ab of
    // fem/tet.hpp: V [lambda g_a g_b^T + mu g_b g_a^T + mu (g_a.g_b) I].
    void scatter(int e, double sign) {
        const Tet& t = T_[e];
        const Mat34& g = g_[e];
        const double V = sign * V_[e];
        volume_ += V;
        for (int a = 0; a < 4; ++a) {
            vs_[t[a]] += V;
            for (int b = 0; b < 4; ++b) {
                const Vec3 ga = g.col(a), gb = g.col(b);
                Eigen::Matrix3d k = lame_ * ga * gb.transpose() + mu_ * gb * ga.transpose();
                k.diagonal().array() += mu_ * ga.dot(gb);
                block(t[a], t[b]) += V * k;
            }
        }
    }

    int addTet(const Tet& t) {
        const int e = static_cast<int>(T_.size());
        T_.push_back(t);
        alive_.push_back(1);
        V_.push_back(0);
        g_.emplace_back();
        lam_.push_back(0);
        stampE_.push_back(0);
        geometry(e);
        scatter(e, 1);
        for (int a : t) nt_[a].push_back(e);
        ++aliveCount_;
        return e;
    }
    void killTet(int e) {
        scatter(e, -1);
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
        scatter(e, 1);
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

    // lambda_R1R of elems into lam_ (docs/method.md sec. 3).
    void evaluate(const std::vector<int>& elems) {
        const int n = static_cast<int>(elems.size());
        mats_.resize(n);
        out_.resize(n);
        for (int k = 0; k < n; ++k) {
            const Tet& t = T_[elems[k]];
            double s[4];
            for (int a = 0; a < 4; ++a) s[a] = 1 / std::sqrt(rq_ * vs_[t[a]]);
            Mat12& A = mats_[k];
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b) A.block<3, 3>(3 * a, 3 * b) = blockOf(t[a], t[b]) * (s[a] * s[b]);
        }
        if (n) largestEigenvalues(mats_.data(), n, out_.data());
        evaluations += n;
        for (int k = 0; k < n; ++k) lam_[elems[k]] = out_[k];
    }

    struct Score {
        double max = 0, soft = 0;
        bool better(const Score& o) const {
            return max < o.max * (1 - 1e-12) || (max <= o.max && soft < o.soft * (1 - 1e-12));
        }
    };
    // Solves elems' problems and scores them; `reference` first makes their maximum the soft
    // maximum's unit (the start of a node's descent or of a flip).
    Score score(const std::vector<int>& elems, bool reference = false) {
        evaluate(elems);
        Score s;
        for (int e : elems) s.max = std::max(s.max, lam_[e]);
        if (reference) ref_ = s.max;
        for (int e : elems) s.soft += std::pow(lam_[e] / ref_, kSoftMaxPower);
        return s;
    }

    // Alive elements with a node among `nodes` (rows changed there).
    void touching(const std::vector<int>& nodes, std::vector<int>& out) {
        out.clear();
        ++stampT_;
        for (int a : nodes)
            for (int f : nt_[a])
                if (stampE_[f] != stampT_) {
                    stampE_[f] = stampT_;
                    out.push_back(f);
                }
    }

    // Elements whose R1R step is within a factor of the worst, worst first.
    std::vector<int> criticalElements() {
        std::vector<int> all;
        for (int e = 0; e < static_cast<int>(T_.size()); ++e)
            if (alive_[e]) all.push_back(e);
        evaluate(all);
        double top = 0;
        for (int e : all) top = std::max(top, lam_[e]);
        std::vector<int> bad;
        for (int e : all)
            if (lam_[e] > 0.5 * top) bad.push_back(e);
        std::sort(bad.begin(), bad.end(),
                  [&](int a, int b) { return lam_[a] > lam_[b] || (lam_[a] == lam_[b] && a < b); });
        const size_t cap = std::max<size_t>(64, all.size() / 10);
        if (bad.size() > cap) bad.resize(cap);
        return bad;
    }

    // ---- boundary -------------------------------------------------------------------------------

    void setUpBoundary(const TetMesh& mesh) {
        const int n = mesh.nodes();
        movable_.assign(n, 1);
        boundary_.assign(n, 0);
        ringFaces_.assign(n, {});
        const Eigen::Matrix3Xi F = boundaryFaces(mesh);
        for (int f = 0; f < F.cols(); ++f) {
            bf_.push_back({F(0, f), F(1, f), F(2, f)});
            faces0_.push_back({X_.col(F(0, f)), X_.col(F(1, f)), X_.col(F(2, f))});
            for (int k = 0; k < 3; ++k) {
                boundary_[F(k, f)] = 1;
                ringFaces_[F(k, f)].push_back(f);
            }
        }
        // Feature edges: boundary edges whose two faces turn by more than the feature angle.
        const double cosFeature = std::cos(opts_.featureAngleDeg * kPi / 180);
        std::map<std::pair<int, int>, std::vector<int>> edgeFaces;
        for (int f = 0; f < static_cast<int>(bf_.size()); ++f)
            for (int k = 0; k < 3; ++k) {
                const int u = bf_[f][k], v = bf_[f][(k + 1) % 3];
                edgeFaces[{std::min(u, v), std::max(u, v)}].push_back(f);
            }
        creaseNbr_.assign(n, {});
        std::vector<char> nonManifold(n, 0);
        for (const auto& [edge, fs] : edgeFaces) {
            if (fs.size() != 2) {
                nonManifold[edge.first] = nonManifold[edge.second] = 1;
                continue;
            }
            if (faceNormal(faces0_[fs[0]]).normalized().dot(faceNormal(faces0_[fs[1]]).normalized()) < cosFeature) {
                creaseNbr_[edge.first].push_back(edge.second);
                creaseNbr_[edge.second].push_back(edge.first);
            }
        }
        for (int i = 0; i < n; ++i) {
            if (!boundary_[i]) continue;
            if (!opts_.moveBoundary || nonManifold[i]) {
                movable_[i] = 0;
                continue;
            }
            // A disk: every edge from i is on exactly two of its faces.
            std::map<int, int> edgeUse;
            for (int f : ringFaces_[i])
                for (int v : bf_[f])
                    if (v != i) ++edgeUse[v];
            bool disk = true;
            for (const auto& [v, c] : edgeUse) disk = disk && c == 2;
            // Free on a smooth patch, along the crease between two feature edges, fixed at a corner.
            const size_t creases = creaseNbr_[i].size();
            movable_[i] = disk && (creases == 0 || creases == 2);
        }
    }
    static Vec3 faceNormal(const Tri& t) { return (t[1] - t[0]).cross(t[2] - t[0]); }

    double distanceToFaces(const Vec3& p, const std::vector<int>& faces) const {
        double best = std::numeric_limits<double>::infinity();
        for (int f : faces) {
            const Tri& t = faces0_[f];
            best = std::min(best, (closestPointOnTriangle(p, t[0], t[1], t[2]) - p).squaredNorm());
        }
        return std::sqrt(best);
    }
    // Closest point on the node's two original crease segments.
    Vec3 projectToCrease(int i, const Vec3& p) const {
        Vec3 best = p;
        double bd = std::numeric_limits<double>::infinity();
        const Vec3 o = X0_.col(i);
        for (int k : creaseNbr_[i]) {
            const Vec3 q = X0_.col(k), d = q - o;
            const Vec3 c = o + d * std::clamp((p - o).dot(d) / d.squaredNorm(), 0.0, 1.0);
            if ((c - p).squaredNorm() < bd) bd = (c - p).squaredNorm(), best = c;
        }
        return best;
    }
    Vec3 projectToRing(int i, const Vec3& p) const {
        Vec3 best = p;
        double bd = std::numeric_limits<double>::infinity();
        for (int f : ringFaces_[i]) {
            const Tri& t = faces0_[f];
            const Vec3 c = closestPointOnTriangle(p, t[0], t[1], t[2]);
            const double d = (c - p).squaredNorm();
            if (d < bd) bd = d, best = c;
        }
        return best;
    }
    // The boundary around node i stays within the distance bound of the old surface.
    bool boundaryKept(int i) {
        const double tol = opts_.maxBoundaryDistance * diag_;
        if (distanceToFaces(X_.col(i), ringFaces_[i]) > tol) return false;
        std::vector<int>& patch = patch_;
        for (int f : ringFaces_[i]) {
            patch.clear();
            for (int v : bf_[f])
                for (int g : ringFaces_[v]) patch.push_back(g);
            const Vec3 p0 = X_.col(bf_[f][0]), p1 = X_.col(bf_[f][1]), p2 = X_.col(bf_[f][2]);
            const Vec3 samples[4] = {(p0 + p1) / 2, (p1 + p2) / 2, (p2 + p0) / 2, (p0 + p1 + p2) / 3};
            for (const Vec3& s : samples)
                if (distanceToFaces(s, patch) > tol) return false;
        }
        return std::abs(volume_ - volume0_) <= opts_.maxVolumeChange * volume0_;
    }

    // ---- smoothing ------------------------------------------------------------------------------

    // Puts node i at p, unless an element would get flatter than kMinFlatness or than it was
    // (floor_, per element of nt_[i], set by smoothNode): then nothing changes and false.
    bool place(int i, const Vec3& p) {
        const Vec3 old = X_.col(i);
        X_.col(i) = p;
        bool ok = true;
        for (size_t k = 0; k < nt_[i].size() && ok; ++k) ok = flatness(T_[nt_[i][k]]) >= floor_[k];
        X_.col(i) = old;
        if (!ok) return false;
        for (int e : nt_[i]) scatter(e, -1);
        X_.col(i) = p;
        for (int e : nt_[i]) {
            geometry(e);
            scatter(e, 1);
        }
        return true;
    }

    // Descends the soft maximum of lambda_R1R over the elements node i influences, along its
    // finite-difference gradient (in the tangent plane for a boundary node, then back onto the
    // node's original faces), accepting a step only when the local maximum does not rise.
    bool smoothNode(int i) {
        if (!movable_[i] || nt_[i].empty()) return false;
        std::vector<int> ring;
        for (int e : nt_[i])
            for (int b : T_[e]) ring.push_back(b);
        std::sort(ring.begin(), ring.end());
        ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
        std::vector<int> elems;
        touching(ring, elems);
        double len = 0;
        for (int b : ring)
            if (b != i) len += (X_.col(b) - X_.col(i)).norm();
        len /= std::max<size_t>(1, ring.size() - 1);

        const bool onBoundary = boundary_[i];
        Vec3 t1 = Vec3::UnitX(), t2 = Vec3::UnitY(), t3 = Vec3::UnitZ(), normal = Vec3::Zero();
        double ringArea = 0;
        if (onBoundary) {
            for (int f : ringFaces_[i]) {
                const Vec3 c = (X_.col(bf_[f][1]) - X_.col(bf_[f][0])).cross(X_.col(bf_[f][2]) - X_.col(bf_[f][0]));
                normal += c;
                ringArea += 0.5 * c.norm();
            }
            normal.normalize();
            t1 = normal.unitOrthogonal();
            t2 = normal.cross(t1);
        }
        const bool onCrease = onBoundary && !creaseNbr_[i].empty();
        if (onCrease) t1 = (X0_.col(creaseNbr_[i][0]) - X0_.col(creaseNbr_[i][1])).normalized();
        floor_.clear();
        for (int e : nt_[i]) floor_.push_back(std::min(kMinFlatness, flatness(T_[e])));
        Score best = score(elems, true);
        bool moved = false;
        for (int iter = 0; iter < 3; ++iter) {
            const Vec3 x = X_.col(i);
            const double h = 1e-4 * len;
            Vec3 grad = Vec3::Zero();
            const Vec3 dirs[3] = {t1, t2, t3};
            const int nd = onCrease ? 1 : onBoundary ? 2 : 3;
            bool probeOk = true;
            for (int k = 0; k < nd && probeOk; ++k) {
                probeOk = place(i, x + h * dirs[k]);
                grad += dirs[k] * (score(elems).soft - best.soft) / h;
            }
            place(i, x);
            if (!probeOk || grad.squaredNorm() == 0) break;
            const Vec3 d = -grad.normalized();
            bool accepted = false;
            const double volume = volume_;
            for (double step = 0.3 * len; step > 1e-3 * len; step *= 0.5) {
                Vec3 p = x + step * d;
                if (onCrease) {
                    p = projectToCrease(i, p);
                } else if (onBoundary) {
                    // Slide within the old faces, then along the normal by what gives the volume
                    // back: dV = offset x (ring area / 3) to first order.
                    p = projectToRing(i, p);
                    if (!place(i, p)) continue;
                    const double dV = volume_ - volume;
                    p += normal * (-dV / (ringArea / 3));
                }
                if (!place(i, p) || (onBoundary && !boundaryKept(i))) continue;
                const Score s = score(elems);
                if (s.better(best)) {
                    best = s;
                    accepted = true;
                    break;
                }
            }
            if (!accepted) {
                place(i, x);
                break;
            }
            moved = true;
        }
        if (moved) ++moves;
        return moved;
    }

    // ---- flips and collapses --------------------------------------------------------------------

    // Replaces the elements `olds` by `news` (node lists) when that lowers the local objective;
    // otherwise restores them.
    bool tryReplace(const std::vector<int>& olds, std::vector<Tet> news) {
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
        touching(nodes, elems);
        const Score before = score(elems, true);
        for (int e : olds) killTet(e);
        std::vector<int> added;
        for (const Tet& t : news) added.push_back(addTet(t));
        touching(nodes, elems);
        if (score(elems).better(before)) return true;
        for (int e : added) killTet(e);
        for (int e : olds) reviveTet(e);
        return false;
    }

    // 2-3 flips across the faces of element e.
    bool flipFaces(int e) {
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
            if (tryReplace({e, e2}, news)) {
                ++flips23;
                return true;
            }
        }
        return false;
    }

    // 3-2 flips of the interior edges of element e that have exactly three elements around them.
    bool flipEdges(int e) {
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
                if (tryReplace(around, {{r[0], r[1], r[2], p}, {r[0], r[1], r[2], q}})) {
                    ++flips32;
                    return true;
                }
            }
        return false;
    }

    // Collapses the shortest edge of element e that has an interior, movable end into its other end.
    bool collapseShortest(int e) {
        std::array<std::pair<double, std::pair<int, int>>, 12> cand;
        int nc = 0;
        for (int a = 0; a < 4; ++a)
            for (int b = 0; b < 4; ++b) {
                if (a == b) continue;
                const int p = T_[e][a], q = T_[e][b];
                if (boundary_[p] || !movable_[p]) continue;
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
            if (!manifoldAfter(q, olds, news)) continue;
            if (tryReplace(olds, news)) {
                ++collapses;
                return true;
            }
        }
        return false;
    }

    // After replacing `olds` by `news`, every face around q is used by at most two elements and no
    // element repeats (the link condition, checked on faces).
    bool manifoldAfter(int q, const std::vector<int>& olds, const std::vector<Tet>& news) const {
        std::map<std::array<int, 3>, int> faceUse;
        std::vector<std::array<int, 4>> sets;
        auto add = [&](Tet t) {
            std::sort(t.begin(), t.end());
            sets.push_back(t);
            for (int o = 0; o < 4; ++o) {
                std::array<int, 3> f;
                int k = 0;
                for (int a = 0; a < 4; ++a)
                    if (a != o) f[k++] = t[a];
                ++faceUse[f];
            }
        };
        for (int f : nt_[q])
            if (std::find(olds.begin(), olds.end(), f) == olds.end()) add(T_[f]);
        for (const Tet& t : news) add(t);
        for (const auto& [f, c] : faceUse)
            if (c > 2) return false;
        std::sort(sets.begin(), sets.end());
        return std::adjacent_find(sets.begin(), sets.end()) == sets.end();
    }

    const ImproveOptions& opts_;
    Material mat_;
    double lame_ = 0, mu_ = 0, rq_ = 0;
    Eigen::Matrix3Xd X_, X0_;                  // current and original positions
    std::vector<std::vector<int>> creaseNbr_;  // feature-edge neighbours of a boundary node
    std::vector<Tet> T_;
    std::vector<char> alive_;
    std::vector<double> V_, lam_;
    std::vector<Mat34, Eigen::aligned_allocator<Mat34>> g_;
    std::vector<std::vector<int>> nt_, nbr_;
    std::vector<std::vector<Eigen::Matrix3d, Eigen::aligned_allocator<Eigen::Matrix3d>>> blk_;
    std::vector<double> vs_;
    double volume_ = 0, volume0_ = 0, diag_ = 0, ref_ = 1;
    int elements0_ = 0, aliveCount_ = 0;
    long long budget_ = 0;
    WallClock::time_point deadline_;
    std::vector<char> movable_, boundary_;
    std::vector<std::array<int, 3>> bf_;
    std::vector<Tri> faces0_;
    std::vector<std::vector<int>> ringFaces_;
    std::vector<int> patch_;
    std::vector<double> floor_;
    std::vector<unsigned> stampN_, stampE_;
    unsigned stamp_ = 0, stampT_ = 0;
    std::vector<Mat12, Eigen::aligned_allocator<Mat12>> mats_;
    std::vector<double> out_;
};

}  // namespace

MeshStepStats meshStepStats(const TetMesh& mesh, const Material& material) {
    MeshStepStats s;
    const Model m = buildModel(mesh, material);
    const StiffnessRows rows = assembleStiffnessRows(m);
    s.nodes = m.nodes();
    s.tets = m.elements();
    s.dtExact = exactCriticalDt(m, rows).dt;
    s.dtCertified = certifiedDt(m, rows);
    ElementEstimates est;
    estimateElements(m, rows, assembleStiffnessDiagonal(m), nullptr, est);
    s.dtR1R = est.r1r.size() ? est.r1r.minCoeff() : 0.0;
    s.minDihedralDeg = minDihedralDeg(mesh);
    s.volume = totalVolume(mesh);
    return s;
}

double surfaceDistance(const TetMesh& from, const TetMesh& to) {
    const Eigen::Matrix3Xi F = boundaryFaces(from), G = boundaryFaces(to);
    // Each old face's bounding sphere prunes the exact point-triangle distances.
    std::vector<Vec3> centre(F.cols());
    std::vector<double> radius(F.cols());
    for (int f = 0; f < F.cols(); ++f) {
        centre[f] = (from.X.col(F(0, f)) + from.X.col(F(1, f)) + from.X.col(F(2, f))) / 3;
        radius[f] = 0;
        for (int k = 0; k < 3; ++k) radius[f] = std::max(radius[f], (from.X.col(F(k, f)) - centre[f]).norm());
    }
    auto distance = [&](const Vec3& p) {
        double best = std::numeric_limits<double>::infinity();
        for (int f = 0; f < F.cols(); ++f) {
            if ((p - centre[f]).norm() - radius[f] >= best) continue;
            const Vec3 c = closestPointOnTriangle(p, from.X.col(F(0, f)), from.X.col(F(1, f)), from.X.col(F(2, f)));
            best = std::min(best, (c - p).norm());
        }
        return best;
    };
    double worst = 0;
    for (int g = 0; g < G.cols(); ++g) {
        const Vec3 p0 = to.X.col(G(0, g)), p1 = to.X.col(G(1, g)), p2 = to.X.col(G(2, g));
        for (const Vec3& s :
             {p0, p1, p2, Vec3((p0 + p1) / 2), Vec3((p1 + p2) / 2), Vec3((p2 + p0) / 2), Vec3((p0 + p1 + p2) / 3)})
            worst = std::max(worst, distance(s));
    }
    return worst;
}

ImproveReport improveMesh(TetMesh& mesh, const ImproveOptions& opts) {
    const auto start = WallClock::now();
    const auto deadline =
        start + std::chrono::duration_cast<WallClock::duration>(std::chrono::duration<double>(opts.maxSeconds));
    ImproveReport r;
    double tStats = 0, tSmooth = 0, tTopo = 0, tExact = 0;
    auto t0 = WallClock::now();
    r.before = meshStepStats(mesh, opts.material);
    tStats += secondsSince(t0);
    r.history.push_back({secondsSince(start), r.before.dtExact});

    Improver imp(mesh, opts);
    imp.setLimits(opts.maxEvaluations > 0 ? opts.maxEvaluations
                                          : std::max<long long>(kMinEvaluations, kEvaluationsPerTet * mesh.elements()),
                  deadline);
    r.diagonal = imp.diagonal();
    TetMesh best = mesh;
    Eigen::Matrix3Xd bestX = mesh.X;  // all positions of the best round, before unused nodes are dropped
    double bestDt = r.before.dtExact;
    int stale = 0;
    for (int round = 1; round <= opts.maxRounds; ++round) {
        if (opts.targetDt > 0 && bestDt >= opts.targetDt) break;
        if (imp.outOfTime()) break;
        const bool changed = imp.round(tSmooth, tTopo);
        r.rounds = round;
        if (!changed) break;
        t0 = WallClock::now();
        TetMesh cur = imp.mesh();
        const double dt = exactCriticalDt(buildModel(cur, opts.material)).dt;
        tExact += secondsSince(t0);
        r.history.push_back({secondsSince(start), dt});
        if (opts.progress) opts.progress(round, secondsSince(start), dt);
        if (dt > bestDt * (1 + 1e-9)) {
            bestDt = dt;
            best = std::move(cur);
            r.bestRound = round;
            bestX = imp.positions();
            stale = 0;
        } else if (++stale >= 3) {
            break;
        }
    }
    r.moves = imp.moves;
    r.flips23 = imp.flips23;
    r.flips32 = imp.flips32;
    r.collapses = imp.collapses;
    r.boundaryDistance = imp.boundaryDistance(bestX);
    r.evaluations = imp.evaluations;
    best.source = mesh.source;
    mesh = std::move(best);
    t0 = WallClock::now();
    r.after = meshStepStats(mesh, opts.material);
    tStats += secondsSince(t0);
    r.volumeChange = (r.after.volume - r.before.volume) / r.before.volume;
    r.seconds = {
        {"smooth", tSmooth}, {"flips", tTopo}, {"exact", tExact}, {"stats", tStats}, {"total", secondsSince(start)}};
    return r;
}

}  // namespace cutsim
