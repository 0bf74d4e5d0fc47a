// The surface's contact points (vertices, edge and face points), their mass scaling, and the
// penalty stiffness that keeps the explicit step stable (contact/contact.hpp).
#include "contact/contact.hpp"

#include "timestep/timestep.hpp"

#include <Eigen/SparseCore>
#include <Spectra/MatOp/SparseCholesky.h>
#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymGEigsSolver.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace cutsim {

namespace {

// The surface's edges, each once: `side[3 t + k]` is the edge of triangle t from corner k to k + 1,
// `ends` its two vertices (sorted pairs, not a map: this runs after every cut).
struct SurfaceEdges {
    std::vector<int> side;                  // (3 nTris)
    std::vector<std::pair<int, int>> ends;  // (nEdges)
};
SurfaceEdges surfaceEdges(const EmbeddedSurface& s) {
    // the sides bucketed by their lower vertex, then ordered by the other within each bucket: the
    // edges come out in (lower, upper) order, in linear time
    const int nt = s.faces();
    const auto nv = static_cast<size_t>(s.vertices());
    std::vector<int> start(nv + 1, 0);
    for (int t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k)
            ++start[static_cast<size_t>(std::min(s.triangles(k, t), s.triangles((k + 1) % 3, t))) + 1];
    for (size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
    std::vector<std::pair<int, int>> upper(3 * static_cast<size_t>(nt));  // (upper vertex, side)
    {
        std::vector<int> fill(start.begin(), start.end() - 1);
        for (int t = 0; t < nt; ++t)
            for (int k = 0; k < 3; ++k) {
                const auto [lo, hi] = std::minmax(s.triangles(k, t), s.triangles((k + 1) % 3, t));
                upper[static_cast<size_t>(fill[static_cast<size_t>(lo)]++)] = {hi, 3 * t + k};
            }
    }
    SurfaceEdges e;
    e.side.resize(upper.size());
    for (size_t v = 0; v < nv; ++v) {
        const auto b = upper.begin() + start[v], en = upper.begin() + start[v + 1];
        std::sort(b, en);
        for (auto it = b; it != en; ++it) {
            if (it == b || it->first != (it - 1)->first) e.ends.emplace_back(static_cast<int>(v), it->first);
            e.side[static_cast<size_t>(it->second)] = static_cast<int>(e.ends.size()) - 1;
        }
    }
    return e;
}

// Pieces an edge of rest length `len` is split into so that points are at most `spacing` apart.
double edgePieces(double len, double spacing) { return spacing > 0 ? std::max(1.0, std::ceil(len / spacing)) : 1.0; }

}  // namespace

double contactPointCount(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                         double spacing) {
    Eigen::Matrix3Xd rest;
    embeddedPositions(s, tets, X, rest);
    // in doubles: a tiny spacing must not overflow
    const SurfaceEdges e = surfaceEdges(s);
    std::vector<double> pieces(e.ends.size());
    double n = s.vertices();
    for (size_t i = 0; i < e.ends.size(); ++i) {
        pieces[i] = edgePieces((rest.col(e.ends[i].first) - rest.col(e.ends[i].second)).norm(), spacing);
        n += pieces[i] - 1;
    }
    for (int t = 0; t < s.faces(); ++t) {
        double longest = 1;
        for (int k = 0; k < 3; ++k) longest = std::max(longest, pieces[static_cast<size_t>(e.side[3 * t + k])]);
        n += (longest - 1) * (longest - 2) / 2;
    }
    return n;
}

ContactPoints contactPoints(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                            double spacing) {
    Eigen::Matrix3Xd rest;
    embeddedPositions(s, tets, X, rest);
    const int nv = s.vertices(), nt = s.faces();
    const SurfaceEdges e = surfaceEdges(s);
    const auto ne = e.ends.size();
    // how many points: vertices, then each edge's inner points, then each face's inner points
    std::vector<int> pieces(ne), edgeStart(ne + 1), faceN(static_cast<size_t>(nt));
    edgeStart[0] = nv;
    for (size_t i = 0; i < ne; ++i) {
        pieces[i] =
            static_cast<int>(edgePieces((rest.col(e.ends[i].first) - rest.col(e.ends[i].second)).norm(), spacing));
        edgeStart[i + 1] = edgeStart[i] + pieces[i] - 1;
    }
    long total = edgeStart[ne];
    for (int t = 0; t < nt; ++t) {
        int n = 1;
        for (int k = 0; k < 3; ++k) n = std::max(n, pieces[static_cast<size_t>(e.side[3 * t + k])]);
        faceN[static_cast<size_t>(t)] = n;
        total += static_cast<long>(n - 1) * (n - 2) / 2;
    }
    ContactPoints out;
    const auto np = static_cast<Eigen::Index>(total);
    out.nodes.setZero(ContactPoints::kMaxNodes, np);
    out.weights.setZero(ContactPoints::kMaxNodes, np);
    out.count.assign(static_cast<size_t>(total), 0);
    out.scale = Eigen::VectorXd::Ones(np);
    out.triangles = s.triangles;
    if (s.cutId.size() == static_cast<size_t>(nt)) out.triCut = s.cutId;
    // a point = sum of b_j x vertex j, its nodes merged (written in place, column p)
    auto addVertex = [&](Eigen::Index p, int v, double b) {
        auto& c = out.count[static_cast<size_t>(p)];
        const int el = s.element[static_cast<size_t>(v)];
        for (int k = 0; k < 4; ++k) {
            const double w = s.weights(k, v);
            if (w == 0) continue;
            const int node = tets(k, el);
            int i = 0;
            while (i < c && out.nodes(i, p) != node) ++i;
            if (i == c) out.nodes(c++, p) = node;
            out.weights(i, p) += b * w;
        }
    };
    for (int v = 0; v < nv; ++v) addVertex(v, v, 1.0);
    for (size_t i = 0; i < ne; ++i) {
        const int n = pieces[i];
        for (int j = 1; j < n; ++j) {
            const Eigen::Index p = edgeStart[i] + j - 1;
            addVertex(p, e.ends[i].first, 1.0 - double(j) / n);
            addVertex(p, e.ends[i].second, double(j) / n);
        }
    }
    // per triangle: its vertices, its edges' points, and interior points on a barycentric grid as
    // fine as its longest edge needs
    out.triStart.resize(static_cast<size_t>(nt) + 1);
    out.triStart[0] = 0;
    for (int t = 0; t < nt; ++t) {
        const int n = faceN[static_cast<size_t>(t)];
        int count = 3 + (n - 1) * (n - 2) / 2;
        for (int k = 0; k < 3; ++k) count += pieces[static_cast<size_t>(e.side[3 * t + k])] - 1;
        out.triStart[static_cast<size_t>(t) + 1] = out.triStart[static_cast<size_t>(t)] + count;
    }
    out.triPoints.resize(static_cast<size_t>(out.triStart.back()));
    Eigen::Index next = edgeStart[ne];
    for (int t = 0; t < nt; ++t) {
        int* q = out.triPoints.data() + out.triStart[static_cast<size_t>(t)];
        const int a = s.triangles(0, t), b = s.triangles(1, t), c = s.triangles(2, t);
        *q++ = a, *q++ = b, *q++ = c;
        for (int k = 0; k < 3; ++k) {
            const auto ed = static_cast<size_t>(e.side[3 * t + k]);
            for (int j = edgeStart[ed]; j < edgeStart[ed + 1]; ++j) *q++ = j;
        }
        const int n = faceN[static_cast<size_t>(t)];
        for (int i = 1; i < n; ++i)
            for (int j = 1; i + j < n; ++j) {
                addVertex(next, a, double(i) / n);
                addVertex(next, b, double(j) / n);
                addVertex(next, c, double(n - i - j) / n);
                *q++ = static_cast<int>(next++);
            }
    }
    return out;
}

namespace {
// 1 / (w_p^T M^-1 w_p) over the free nodes [kg]; infinity when the point moves no free node
double effectiveMass(const ContactPoints& pts, const Eigen::VectorXd& invMass, int p) {
    double s = 0;
    for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i)
        s += pts.weights(i, p) * pts.weights(i, p) * invMass(pts.nodes(i, p));
    return s > 0 ? 1.0 / s : std::numeric_limits<double>::infinity();
}
}  // namespace

void scaleByMass(ContactPoints& pts, const Eigen::VectorXd& invMass, double mRef) {
    pts.scale.resize(pts.points());
    for (int p = 0; p < pts.points(); ++p) pts.scale(p) = std::min(1.0, effectiveMass(pts, invMass, p) / mRef);
}

double referenceMass(const ContactPoints& pts, const Eigen::VectorXd& invMass) {
    std::vector<double> m;
    for (int p = 0; p < pts.points(); ++p)
        if (const double mp = effectiveMass(pts, invMass, p); std::isfinite(mp)) m.push_back(mp);
    if (m.empty()) return 1;
    const auto q = m.begin() + static_cast<std::ptrdiff_t>(0.9 * static_cast<double>(m.size() - 1));
    std::nth_element(m.begin(), q, m.end());
    return *q;
}

double stableStiffness(const ContactPoints& pts, const Model& model, double dt, double dtCrit) {
    if (!(dt > 0) || !(dt < dtCrit)) return 0;
    const double target = 4.0 / (dt * dt);
    int nf = 0;
    const std::vector<int> map = freeDofMap(model, &nf);
    // B = target I - M^-1/2 K M^-1/2 and C = M^-1/2 (sum_p w_p w_p^T (x) I) M^-1/2 over the free DOFs
    Eigen::SparseMatrix<double> B = -scaledFreeStiffness(model, map, nf);
    for (int d = 0; d < nf; ++d) B.coeffRef(d, d) += target;
    std::vector<Eigen::Triplet<double>> tc;
    for (int p = 0; p < pts.points(); ++p)
        for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i)
            for (int j = 0; j < pts.count[static_cast<size_t>(p)]; ++j) {
                const int ni = pts.nodes(i, p), nj = pts.nodes(j, p);
                if (map[3 * static_cast<size_t>(ni)] < 0 || map[3 * static_cast<size_t>(nj)] < 0) continue;
                const double v = pts.scale(p) * pts.weights(i, p) * pts.weights(j, p) *
                                 std::sqrt(model.invMass(ni) * model.invMass(nj));
                for (int k = 0; k < 3; ++k)
                    tc.emplace_back(map[3 * static_cast<size_t>(ni) + k], map[3 * static_cast<size_t>(nj) + k], v);
            }
    if (tc.empty()) return std::numeric_limits<double>::infinity();
    Eigen::SparseMatrix<double> C(nf, nf);
    C.setFromTriplets(tc.begin(), tc.end());
    // k_max = 1 / nu_max of C x = nu B x: B is positive definite exactly when dt < dtCrit
    using Op = Spectra::SparseSymMatProd<double>;
    using BOp = Spectra::SparseCholesky<double>;
    Op op(C);
    BOp bop(B);
    if (bop.info() != Spectra::CompInfo::Successful) return 0;  // rounding at dt ~ dtCrit: no headroom
    Spectra::SymGEigsSolver<Op, BOp, Spectra::GEigsMode::Cholesky> eigs(op, bop, 1, std::min(24, nf));
    eigs.init();
    computeEigs(eigs, "contact stiffness limit", Spectra::SortRule::LargestAlge, 2000, 1e-10);
    if (eigs.info() != Spectra::CompInfo::Successful)
        throw EigenSolveError("contact stiffness limit: Lanczos did not converge (" + std::to_string(nf) +
                              " free DOFs)");
    const double nu = eigs.eigenvalues()(0);
    return nu > 0 ? 1.0 / nu : std::numeric_limits<double>::infinity();
}

}  // namespace cutsim
