#include "cut/conforming.hpp"
#include "util/union_find.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>
#include <utility>

namespace cutsim {
namespace {

// A snap may shrink an incident tet to this share of its volume, no further (a flatter tet would
// be a worse sliver than the cut it avoids).
constexpr double kMinSnapVolumeRatio = 1e-3;

// Builds the tets of the result: positively oriented, each tagged with its side.
struct TetSink {
    const std::vector<Eigen::Vector3d>* X;
    std::vector<Eigen::Vector4i> tets;
    std::vector<std::int8_t> side;

    void tet(int a, int b, int c, int d, std::int8_t s) {
        const auto& P = *X;
        if (tetSignedVolume(P[a], P[b], P[c], P[d]) < 0) std::swap(c, d);
        tets.emplace_back(a, b, c, d);
        side.push_back(s);
    }
    // Pyramid over the cyclic quad q, its diagonal through the quad's smallest node index, so the
    // tet across the shared quad face picks the same diagonal (conformity).
    void pyramid(int apex, const int q[4], std::int8_t s) {
        const int k = static_cast<int>(std::min_element(q, q + 4) - q);
        const int q0 = q[k], q1 = q[(k + 1) % 4], q2 = q[(k + 2) % 4], q3 = q[(k + 3) % 4];
        tet(apex, q0, q1, q2, s);
        tet(apex, q0, q2, q3, s);
    }
    // Prism with triangles (v0 v1 v2), (v3 v4 v5) and laterals vi-v(i+3), split into 3 tets with
    // every quad's diagonal through its smallest node index (Dompierre et al. 1999: this rule always
    // admits a split and makes neighbours agree).
    void prism(const int v[6], std::int8_t s) {
        const int k = static_cast<int>(std::min_element(v, v + 6) - v);
        // Relabel so the smallest node is w0: rotate the triangles, swap them if it is on top.
        const int r = k % 3, top = k / 3;
        int w[6];
        for (int i = 0; i < 3; ++i) {
            w[i] = v[(i + r) % 3 + 3 * top];
            w[i + 3] = v[(i + r) % 3 + 3 * (1 - top)];
        }
        if (std::min(w[1], w[5]) < std::min(w[2], w[4])) {  // quad w1 w2 w5 w4 split by w1-w5
            tet(w[0], w[1], w[2], w[5], s);
            tet(w[0], w[1], w[5], w[4], s);
        } else {  // split by w2-w4
            tet(w[0], w[1], w[2], w[4], s);
            tet(w[0], w[4], w[2], w[5], s);
        }
        tet(w[0], w[4], w[5], w[3], s);
    }
};

// The working state of one plane cut: the nodes (grown by the cut points), their signed distances
// to the plane and their sides; the phases run in the order of the members below.
struct ConformingBuild {
    const TetMesh& mesh;
    const CutPlane& plane;
    const ConformingOptions& opts;
    ConformingReport& rep;
    Eigen::Vector3d n;                           // unit plane normal
    int nn = 0, ne = 0;                          // input nodes and tets
    double tol = 0;                              // on-plane distance [m]
    std::vector<Eigen::Vector3d> X;              // node positions, then cut points [m]
    std::vector<double> dist;                    // signed distance of each input node to the plane [m]
    std::vector<std::int8_t> sign;               // side of each node: +1, -1, 0 on the plane
    std::unordered_map<long long, int> cutNode;  // edge (i * nn + j, i < j) -> its cut point

    ConformingBuild(const TetMesh& m, const CutPlane& p, const ConformingOptions& o, ConformingReport& r);
    void snap();
    TetSink split();
    void separate(const TetSink& out, ConformingResult& res);

private:
    bool trySnap(int i, const std::vector<int>& start, const std::vector<int>& slots, const std::vector<double>& vol0);
    int cut(int i, int j);
    void splitCrossed(const int P[4], const int N[4], const int Z[4], int np, int nm, TetSink& out);
    std::vector<std::uint8_t> opening() const;
};

void checkCutInput(const CutPlane& plane, const ConformingOptions& opts) {
    const double nNorm = plane.normal.norm();
    if (!(nNorm > 0) || !std::isfinite(nNorm) || !plane.point.allFinite())
        throw InputError("cut plane: the normal must be a finite non-zero vector and the point finite");
    for (const CutPlane& l : opts.limits)
        if (!(l.normal.norm() > 0) || !l.normal.allFinite() || !l.point.allFinite())
            throw InputError("cut limit: the normal must be a finite non-zero vector and the point finite");
    if (!opts.limits.empty() && opts.keep != KeepSide::Both)
        throw InputError("bounded cut: only KeepSide::Both (the sides stay joined beyond the limits)");
}

ConformingBuild::ConformingBuild(const TetMesh& m, const CutPlane& p, const ConformingOptions& o, ConformingReport& r)
    : mesh(m), plane(p), opts(o), rep(r), n(p.normal / p.normal.norm()), nn(m.nodes()), ne(m.elements()) {
    X.resize(static_cast<size_t>(nn));
    dist.resize(static_cast<size_t>(nn));
    for (int i = 0; i < nn; ++i) {
        X[i] = mesh.X.col(i);
        dist[i] = n.dot(X[i] - plane.point);
    }
    double diag = 0;
    if (nn > 0) diag = (mesh.X.rowwise().maxCoeff() - mesh.X.rowwise().minCoeff()).norm();
    tol = opts.onPlaneTolerance * diag;
    sign.resize(static_cast<size_t>(nn));
    for (int i = 0; i < nn; ++i) sign[i] = std::abs(dist[i]) <= tol ? 0 : (dist[i] > 0 ? 1 : -1);
}

// Sum of the unique incident edges' lengths and their count, per node (for the mean edge length).
void incidentEdgeLengths(const TetMesh& mesh, const std::vector<Eigen::Vector3d>& X, std::vector<double>& lenSum,
                         std::vector<int>& deg) {
    std::vector<std::pair<int, int>> edges;
    edges.reserve(6 * static_cast<size_t>(mesh.elements()));
    for (int e = 0; e < mesh.elements(); ++e)
        for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b) {
                const int i = mesh.tets(a, e), j = mesh.tets(b, e);
                edges.emplace_back(std::min(i, j), std::max(i, j));
            }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    lenSum.assign(static_cast<size_t>(mesh.nodes()), 0.0);
    deg.assign(static_cast<size_t>(mesh.nodes()), 0);
    for (const auto& [i, j] : edges) {
        const double l = (X[i] - X[j]).norm();
        lenSum[i] += l, lenSum[j] += l;
        ++deg[i], ++deg[j];
    }
}

// Node -> tets (CSR): node i's tets are slots[start[i] .. start[i + 1]).
void nodeTets(const TetMesh& mesh, std::vector<int>& start, std::vector<int>& slots) {
    const int nn = mesh.nodes(), ne = mesh.elements();
    start.assign(static_cast<size_t>(nn) + 1, 0);
    slots.assign(4 * static_cast<size_t>(ne), 0);
    for (int e = 0; e < ne; ++e)
        for (int a = 0; a < 4; ++a) ++start[mesh.tets(a, e) + 1];
    std::partial_sum(start.begin(), start.end(), start.begin());
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (int e = 0; e < ne; ++e)
        for (int a = 0; a < 4; ++a) slots[fill[mesh.tets(a, e)]++] = e;
}

// (a) Node snapping (thesis sec. 6.2, docs/method.md sec. 5).
void ConformingBuild::snap() {
    if (!(opts.snapFraction > 0) || ne <= 0) return;
    std::vector<double> lenSum;
    std::vector<int> deg, start, slots;
    incidentEdgeLengths(mesh, X, lenSum, deg);
    nodeTets(mesh, start, slots);
    std::vector<double> vol0(static_cast<size_t>(ne));
    for (int e = 0; e < ne; ++e) vol0[e] = tetSignedVolume(mesh, e);

    std::vector<int> cand;
    for (int i = 0; i < nn; ++i)
        if (sign[i] != 0 && deg[i] > 0 && std::abs(dist[i]) < opts.snapFraction * lenSum[i] / deg[i]) cand.push_back(i);
    // Nearest first: they move least and decide the tets around them.
    std::sort(cand.begin(), cand.end(), [&](int a, int b) { return std::abs(dist[a]) < std::abs(dist[b]); });
    for (const int i : cand) {
        if (trySnap(i, start, slots, vol0))
            ++rep.snappedNodes;
        else
            ++rep.rejectedSnaps;
    }
}

// Moves node i onto the plane unless that inverts or flattens one of its tets; false: left in place.
bool ConformingBuild::trySnap(int i, const std::vector<int>& start, const std::vector<int>& slots,
                              const std::vector<double>& vol0) {
    const Eigen::Vector3d moved = X[i] - dist[i] * n;
    const Eigen::Vector3d old = X[i];
    const std::int8_t oldSign = sign[i];
    X[i] = moved;
    sign[i] = 0;
    bool ok = true;
    for (int s = start[i]; s < start[i + 1] && ok; ++s) {
        const int e = slots[s];
        const int a = mesh.tets(0, e), b = mesh.tets(1, e), c = mesh.tets(2, e), d = mesh.tets(3, e);
        // A tet with all four nodes on the plane collapses into the cut: allowed, removed below.
        if (sign[a] == 0 && sign[b] == 0 && sign[c] == 0 && sign[d] == 0) continue;
        const double v = tetSignedVolume(X[a], X[b], X[c], X[d]);
        ok = v * vol0[e] > 0 && std::abs(v) > kMinSnapVolumeRatio * std::abs(vol0[e]);
    }
    if (ok) {
        X[i] += n * -n.dot(X[i] - plane.point);  // round-off left by the projection
        dist[i] = 0;
    } else {
        X[i] = old;
        sign[i] = oldSign;
    }
    return ok;
}

// The cut point on edge (i, j), shared by every tet around the edge.
int ConformingBuild::cut(int i, int j) {
    if (i > j) std::swap(i, j);
    const long long key = static_cast<long long>(i) * nn + j;
    auto [it, inserted] = cutNode.try_emplace(key, static_cast<int>(X.size()));
    if (inserted) {
        const double t = dist[i] / (dist[i] - dist[j]);
        X.push_back(X[i] + t * (X[j] - X[i]));
        sign.push_back(0);
    }
    return it->second;
}

// (b) Conforming split: whole tets keep their side, crossed ones are split, flat ones dropped.
TetSink ConformingBuild::split() {
    TetSink out{&X, {}, {}};
    out.tets.reserve(static_cast<size_t>(ne) + 8);
    for (int e = 0; e < ne; ++e) {
        int P[4], N[4], Z[4], np = 0, nm = 0, nz = 0;
        for (int a = 0; a < 4; ++a) {
            const int v = mesh.tets(a, e);
            (sign[v] > 0 ? P[np++] : sign[v] < 0 ? N[nm++] : Z[nz++]) = v;
        }
        if (np == 0 && nm == 0) {
            ++rep.collapsedTets;
            continue;
        }
        if (np == 0 || nm == 0) {
            out.tet(mesh.tets(0, e), mesh.tets(1, e), mesh.tets(2, e), mesh.tets(3, e), np > 0 ? 1 : -1);
            continue;
        }
        splitCrossed(P, N, Z, np, nm, out);
    }
    rep.cutPoints = static_cast<int>(cutNode.size());
    return out;
}

// A tet with np nodes P on the positive side, nm nodes N on the negative one and the rest Z on the plane.
void ConformingBuild::splitCrossed(const int P[4], const int N[4], const int Z[4], int np, int nm, TetSink& out) {
    ++rep.splitTets;
    // Name the lone node's side "a" so the 1-vs-k cases are written once.
    const bool posLone = np <= nm;
    const int* A = posLone ? P : N;
    const int* B = posLone ? N : P;
    const std::int8_t sa = posLone ? 1 : -1, sb = static_cast<std::int8_t>(-sa);
    const int na = posLone ? np : nm, nb = posLone ? nm : np;
    if (na == 1 && nb == 1) {  // two nodes on the plane: one cut edge, two tets
        const int c = cut(A[0], B[0]);
        out.tet(A[0], c, Z[0], Z[1], sa);
        out.tet(B[0], c, Z[0], Z[1], sb);
    } else if (na == 1 && nb == 2) {  // one node on the plane: tet + pyramid
        const int a = A[0], b = B[0], c = B[1], z = Z[0];
        const int cab = cut(a, b), cac = cut(a, c);
        out.tet(a, cab, cac, z, sa);
        const int quad[4] = {b, c, cac, cab};
        out.pyramid(z, quad, sb);
    } else if (na == 1 && nb == 3) {  // tet + prism -> 1 + 3 tets
        const int a = A[0], b = B[0], c = B[1], d = B[2];
        const int cab = cut(a, b), cac = cut(a, c), cad = cut(a, d);
        out.tet(a, cab, cac, cad, sa);
        const int pr[6] = {b, c, d, cab, cac, cad};
        out.prism(pr, sb);
    } else {  // 2 vs 2: two prisms -> 3 + 3 tets
        const int a = P[0], b = P[1], c = N[0], d = N[1];
        const int cac = cut(a, c), cad = cut(a, d), cbc = cut(b, c), cbd = cut(b, d);
        const int pp[6] = {a, cac, cad, b, cbc, cbd};
        out.prism(pp, 1);
        const int pn[6] = {c, cac, cbc, d, cad, cbd};
        out.prism(pn, -1);
    }
}

// Bounded cut: nodes on a limit or beyond it stay shared (the crack front and the uncut part).
std::vector<std::uint8_t> ConformingBuild::opening() const {
    const int total = static_cast<int>(X.size());
    std::vector<std::uint8_t> opens(static_cast<size_t>(total), 1);
    for (const CutPlane& l : opts.limits) {
        const Eigen::Vector3d ln = l.normal.normalized();
        for (int v = 0; v < total; ++v)
            if (ln.dot(X[v] - l.point) <= tol) opens[v] = 0;
    }
    return opens;
}

// (c) Separate: the kept tets renumbered, the negative side with its own copy of every node on the
// plane that opens.
void ConformingBuild::separate(const TetSink& out, ConformingResult& res) {
    const int total = static_cast<int>(X.size());
    const std::vector<std::uint8_t> opens = opening();
    std::vector<int> copyOf(static_cast<size_t>(total), -1);
    std::vector<int> newId(static_cast<size_t>(total), -1);
    std::vector<Eigen::Vector3d> outX;
    std::vector<Eigen::Vector4i> kept;
    for (size_t t = 0; t < out.tets.size(); ++t) {
        const std::int8_t s = out.side[t];
        if ((opts.keep == KeepSide::Positive && s < 0) || (opts.keep == KeepSide::Negative && s > 0)) continue;
        Eigen::Vector4i tt = out.tets[t];
        for (int a = 0; a < 4; ++a) {
            const int v = tt[a];
            int& id = (opts.keep == KeepSide::Both && s < 0 && sign[v] == 0 && opens[v]) ? copyOf[v] : newId[v];
            if (id < 0) {
                id = static_cast<int>(outX.size());
                outX.push_back(X[v]);
            }
            tt[a] = id;
        }
        kept.push_back(tt);
        res.side.push_back(s);
    }
    for (int v = 0; v < total; ++v) rep.duplicatedNodes += (copyOf[v] >= 0 && newId[v] >= 0);

    TetMesh& m = res.mesh;
    m.source = mesh.source;
    m.X.resize(3, static_cast<Eigen::Index>(outX.size()));
    for (size_t i = 0; i < outX.size(); ++i) m.X.col(static_cast<Eigen::Index>(i)) = outX[i];
    m.tets.resize(4, static_cast<Eigen::Index>(kept.size()));
    for (size_t t = 0; t < kept.size(); ++t) m.tets.col(static_cast<Eigen::Index>(t)) = kept[t];
}

}  // namespace

ConformingResult conformingCut(const TetMesh& mesh, const CutPlane& plane, const ConformingOptions& opts) {
    checkCutInput(plane, opts);
    ConformingResult res;
    ConformingReport& rep = res.report;
    rep.volumeBefore = totalVolume(mesh);
    ConformingBuild b(mesh, plane, opts, rep);
    b.snap();
    const TetSink out = b.split();
    b.separate(out, res);

    const TetMesh& m = res.mesh;
    rep.nodes = m.nodes();
    rep.tets = m.elements();
    rep.minVolume = m.elements() > 0 ? std::numeric_limits<double>::infinity() : 0;
    for (int e = 0; e < m.elements(); ++e) rep.minVolume = std::min(rep.minVolume, tetSignedVolume(m, e));
    rep.volumeAfter = totalVolume(m);
    return res;
}

ConformingResult conformingCuts(const TetMesh& mesh, const std::vector<CutPlane>& planes,
                                const ConformingOptions& opts) {
    ConformingResult res;
    res.mesh = mesh;
    res.side.assign(static_cast<size_t>(mesh.elements()), 1);
    res.report.nodes = mesh.nodes();
    res.report.tets = mesh.elements();
    res.report.volumeBefore = res.report.volumeAfter = totalVolume(mesh);
    for (const CutPlane& p : planes) {
        ConformingResult next = conformingCut(res.mesh, p, opts);
        ConformingReport& r = next.report;
        r.volumeBefore = res.report.volumeBefore;
        r.snappedNodes += res.report.snappedNodes;
        r.rejectedSnaps += res.report.rejectedSnaps;
        r.collapsedTets += res.report.collapsedTets;
        r.splitTets += res.report.splitTets;
        r.cutPoints += res.report.cutPoints;
        r.duplicatedNodes += res.report.duplicatedNodes;
        res = std::move(next);
    }
    return res;
}

int connectedPieces(const TetMesh& mesh, std::vector<int>* tetPiece) {
    UnionFind uf = elementPieces(mesh.tets, mesh.nodes());
    std::vector<int> label(static_cast<size_t>(mesh.nodes()), -1);
    int pieces = 0;
    if (tetPiece) tetPiece->assign(static_cast<size_t>(mesh.elements()), -1);
    for (int e = 0; e < mesh.elements(); ++e) {
        int& l = label[static_cast<size_t>(uf.find(mesh.tets(0, e)))];
        if (l < 0) l = pieces++;
        if (tetPiece) (*tetPiece)[e] = l;
    }
    return pieces;
}

}  // namespace cutsim
