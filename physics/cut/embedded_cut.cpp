// The drawn and touched surface of a cut object given by its surface (mesh intersection, thesis
// ch. 6, with XFEM cuts, sec. 2.3; docs/method.md sec. 5). The lattice faces of a cut element are not
// the object's boundary: the embedded surface is, split where the cuts separate it, plus the cut
// faces inside the original surface.
#include "cut/split_cache.hpp"

#include "mesh/mesh.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <unordered_map>
#include <string>
#include <utility>

namespace cutsim {

namespace {

// A label per element, equal for elements joined through shared nodes (the model's pieces).
std::vector<int> pieceLabels(const Model& m) {
    std::vector<int> root(static_cast<size_t>(m.nodes()));
    for (size_t i = 0; i < root.size(); ++i) root[i] = static_cast<int>(i);
    auto find = [&](int a) {
        while (root[static_cast<size_t>(a)] != a)
            a = root[static_cast<size_t>(a)] = root[static_cast<size_t>(root[static_cast<size_t>(a)])];
        return a;
    };
    for (int e = 0; e < m.elements(); ++e)
        for (int k = 1; k < 4; ++k) {
            const int a = find(m.tets(0, e)), b = find(m.tets(k, e));
            if (a != b) root[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
        }
    std::vector<int> label(static_cast<size_t>(m.elements()));
    for (int e = 0; e < m.elements(); ++e) label[static_cast<size_t>(e)] = find(m.tets(0, e));
    return label;
}

}  // namespace

int CutEngine::carrierOnSide(const Model& m, int p, const std::vector<const Halfspace*>& planes,
                             const Eigen::Vector4d& at, int& carrierParent) const {
    // Each plane's level set is affine in the rest position: its value at a point of another
    // parent is the same weights' dot product, extrapolated from p.
    auto inP = [&](const Eigen::Vector3d& y) {
        return barycentric(y, m.X.col(tets0_(0, p)), m.X.col(tets0_(1, p)), m.X.col(tets0_(2, p)),
                           m.X.col(tets0_(3, p)));
    };
    auto sameSide = [&](const Eigen::Vector4d& w) {
        for (const Halfspace* h : planes)
            if ((w.dot(h->s) >= 0) != (at.dot(h->s) >= 0)) return false;
        return true;
    };
    int best = -1, bestShared = -1;
    for (int c = 0; c < 4; ++c) {
        const int o = tets0_(c, p);
        for (int i = ringStart_[static_cast<size_t>(o)]; i < ringStart_[static_cast<size_t>(o) + 1]; ++i) {
            const int q = ring_[static_cast<size_t>(i)];
            if (q == p) continue;
            int shared = 0;  // corners q shares with p: the more, the closer the extrapolation
            for (int a = 0; a < 4; ++a)
                for (int b = 0; b < 4; ++b) shared += tets0_(a, q) == tets0_(b, p);
            for (int g : virtualsOf(q)) {
                if (shared < bestShared || (shared == bestShared && g >= best)) continue;
                const Virtual* gv = findVirtual(g);
                Eigen::Vector4d mid = Eigen::Vector4d::Constant(0.25);  // an uncut element: its parent's centre
                if (gv) {
                    mid.setZero();
                    for (const auto& xi : gv->piece.xi) mid += weightsOf(xi);
                    mid /= static_cast<double>(gv->piece.xi.size());
                }
                if (!sameSide(inP(restOf(m, q, mid)))) continue;
                best = g;
                bestShared = shared;
                carrierParent = q;
            }
        }
    }
    return best;
}

CutEngine::SplitCache& CutEngine::splitCache(const Model& m, const EmbeddedSurface& original) const {
    constexpr size_t kKept = 4;  // surfaces an engine serves: an MI object's own and a visual one
    auto& caches = split_.items;
    for (auto& k : caches)
        if (k->original == &original && k->vertices == original.vertices() && k->faces == original.faces()) return *k;
    if (caches.size() >= kKept) caches.erase(caches.begin());
    caches.push_back(std::make_shared<SplitCache>());
    SplitCache* c = caches.back().get();
    c->original = &original;
    c->vertices = original.vertices();
    c->faces = original.faces();
    const int nParents = static_cast<int>(tets0_.cols());
    const int nv = original.vertices();
    SurfaceMesh& rs = c->rest;
    rs.V.resize(3, nv);
    rs.F = original.triangles;
    for (int v = 0; v < nv; ++v) {
        const int p = original.element[static_cast<size_t>(v)];
        if (p < 0 || p >= nParents)
            throw InputError("embedded surface: vertex " + std::to_string(v) + " rides element " + std::to_string(p) +
                             ", not an element of the uncut model");
        rs.V.col(v) = restOf(m, p, original.weights.col(v));
    }
    const double diag = nv > 0 ? (rs.V.rowwise().maxCoeff() - rs.V.rowwise().minCoeff()).norm() : 0;
    c->tinyArea = 1e-14 * diag * diag;  // [m^2] parts below it are slivers of round-off
    if (nv > 0) c->tree = buildWindingTree(rs);
    c->holdsVertex.assign(static_cast<size_t>(nParents), 0);
    c->pastVertex.assign(static_cast<size_t>(nv), 0);
    for (int v = 0; v < nv; ++v) {
        const Eigen::Vector4d w = original.weights.col(v);
        const int p = original.element[static_cast<size_t>(v)];
        if (w.minCoeff() >= 0) {
            c->holdsVertex[static_cast<size_t>(p)] = 1;
        } else if (w.minCoeff() < -1e-9) {
            c->outside = true;
            c->pastVertex[static_cast<size_t>(v)] = 1;
            // at most its distance to the element's point at the clamped weights
            const Eigen::Vector4d in = w.cwiseMax(0.0) / w.cwiseMax(0.0).sum();
            c->reach = std::max(c->reach, (rs.V.col(v) - restOf(m, p, in)).norm());
        }
    }
    c->cornerWinding.assign(static_cast<size_t>(m.X.cols()), std::nan(""));
    // Each triangle is clipped to each parent it crosses (flood fill over face neighbours from its
    // vertices' parents); not at boundary faces: a visual surface on a
    // tet mesh crosses them (the MI lattice's boundary lies outside its surface).
    std::vector<int> queue, visited;
    c->partStart.assign(1, 0);
    for (int t = 0; t < original.faces(); ++t) {
        std::array<int, 3> v{}, p{};
        for (size_t i = 0; i < 3; ++i) {
            v[i] = original.triangles(static_cast<int>(i), t);
            p[i] = original.element[static_cast<size_t>(v[i])];
        }
        queue.clear();
        visited.clear();
        for (int q : p)
            if (std::find(visited.begin(), visited.end(), q) == visited.end()) {
                visited.push_back(q);
                queue.push_back(q);
            }
        while (!queue.empty()) {
            const int q = queue.back();
            queue.pop_back();
            Poly poly(3);
            for (size_t i = 0; i < 3; ++i)
                poly[i] = barycentric(rs.V.col(v[i]), m.X.col(tets0_(0, q)), m.X.col(tets0_(1, q)),
                                      m.X.col(tets0_(2, q)), m.X.col(tets0_(3, q)));
            for (int a = 0; a < 4 && !poly.empty(); ++a)
                if (adj_(a, q) >= 0) poly = clipBy(poly, [a](const Eigen::Vector4d& w) { return w[a]; });
            if (poly.empty()) continue;
            for (int k = 0; k < 4; ++k) {
                const int n = adj_(k, q);
                if (n < 0 || std::find(visited.begin(), visited.end(), n) != visited.end()) continue;
                if (std::any_of(poly.begin(), poly.end(),
                                [k](const Eigen::Vector4d& w) { return std::abs(w[k]) < 1e-9; })) {
                    visited.push_back(n);
                    queue.push_back(n);
                }
            }
            c->parts.emplace_back(q, std::move(poly));
        }
        c->partStart.push_back(static_cast<int>(c->parts.size()));
    }
    // Each parent's triangles: those with a vertex or a part in it.
    std::vector<std::pair<int, int>> pairs;  // (parent, triangle)
    std::vector<int> ps;
    for (int t = 0; t < original.faces(); ++t) {
        ps.clear();
        for (int i = 0; i < 3; ++i) ps.push_back(original.element[static_cast<size_t>(original.triangles(i, t))]);
        for (int k = c->partStart[static_cast<size_t>(t)]; k < c->partStart[static_cast<size_t>(t) + 1]; ++k)
            ps.push_back(c->parts[static_cast<size_t>(k)].first);
        std::sort(ps.begin(), ps.end());
        ps.erase(std::unique(ps.begin(), ps.end()), ps.end());
        for (int q : ps) pairs.emplace_back(q, t);
    }
    std::sort(pairs.begin(), pairs.end());
    c->overStart.assign(static_cast<size_t>(nParents) + 1, 0);
    for (const auto& [q, t] : pairs) ++c->overStart[static_cast<size_t>(q) + 1];
    for (size_t q = 0; q < static_cast<size_t>(nParents); ++q) c->overStart[q + 1] += c->overStart[q];
    c->over.reserve(pairs.size());
    for (const auto& [q, t] : pairs) c->over.push_back(t);
    c->scratch.nodes = static_cast<size_t>(tets0_.maxCoeff()) + 1;
    c->drawnTri.resize(static_cast<size_t>(original.faces()));
    c->drawnCap.resize(static_cast<size_t>(nParents));
    return *c;
}

// surface(m, original)'s work: the drawn surface as it is built, and its two phases. Each
// original triangle and each cut parent's cut faces is drawn into its SplitCache::Drawn, or kept
// from the last call when the parents it reads are as they were then; the output welds them in order.
struct CutEngine::SurfaceBuild {
    using Drawn = SplitCache::Drawn;
    const CutEngine& eng;
    const Model& m;
    const EmbeddedSurface& original;
    SplitCache& cache;
    std::vector<int> elem;
    std::vector<Eigen::Vector4d> weights;
    std::vector<Eigen::Vector3i> tris;
    std::vector<int> cutId;
    std::vector<int> kept;              // output index of an original vertex kept as is
    Drawn* into = nullptr;              // what is being drawn
    std::vector<int> ids;               // scratch of append: a Drawn's vertices in the output
    std::vector<int> piece;             // connected piece of each element, once asked for
    std::vector<char> nearChanged;      // parent shares a corner with one changed since the last call
    std::vector<char> moved;            // element's nodes changed since the last call (none: empty)
    std::vector<Eigen::Vector4d> grid;  // scratch of cap: sample weights and winding numbers - 1/2
    std::vector<double> wind;

    SurfaceBuild(const CutEngine& e, const Model& model, const EmbeddedSurface& o, SplitCache& c)
        : eng(e), m(model), original(o), cache(c), kept(static_cast<size_t>(o.vertices()), -1) {}
    int parents() const { return static_cast<int>(eng.tets0_.cols()); }
    // Rest position of parent weights: the parent's original corners (their rest positions never change).
    Eigen::Vector3d rest(int p, const Eigen::Vector4d& w) const { return eng.restOf(m, p, w); }
    double area(int p, const Poly& poly) const {
        Eigen::Vector3d a = Eigen::Vector3d::Zero();
        const Eigen::Vector3d y0 = rest(p, poly[0]);
        for (size_t k = 1; k + 1 < poly.size(); ++k) a += (rest(p, poly[k]) - y0).cross(rest(p, poly[k + 1]) - y0);
        return 0.5 * a.norm();
    }
    // A crossed parent has a piece even when one side was merged (it then has no other virtual element).
    bool isCut(int p) const { return eng.findVirtual(p) != nullptr; }
    // `poly` (weights in p) in the weights of parent q, extrapolated.
    Poly inParent(int p, const Poly& poly, int q) const {
        const auto& t = eng.tets0_;
        Poly out;
        for (const auto& w : poly)
            out.push_back(
                barycentric(rest(p, w), m.X.col(t(0, q)), m.X.col(t(1, q)), m.X.col(t(2, q)), m.X.col(t(3, q))));
        return out;
    }
    bool samePiece(int a, int b) {
        if (piece.empty()) piece = pieceLabels(m);
        return piece[static_cast<size_t>(a)] == piece[static_cast<size_t>(b)];
    }
    // Slivers by parent (CSR), for their cut faces.
    std::vector<int> sliverStart, sliverOf;
    void indexSlivers();
    // The parents whose elements or slivers changed since the last call: those sharing a corner
    // with them are marked in nearChanged (all at the first call).
    void findChanged();
    // Drawn d into the output: its vertices welded to those before (cut/vertex_key.hpp: new
    // vertices at one place on the same nodes are one, shared across elements, so a piece's cut
    // face is connected and shades smoothly), its triangles without those welding collapsed.
    int keptVertex(int v) {
        int& k = kept[static_cast<size_t>(v)];
        if (k < 0) {
            k = static_cast<int>(elem.size());
            elem.push_back(original.element[static_cast<size_t>(v)]);
            weights.push_back(original.weights.col(v));
        }
        return k;
    }
    void append(const Drawn& d, int t = -1) {
        if (d.whole) {  // numbered from the last corner, as the output always was
            const int c = keptVertex(original.triangles(2, t)), b = keptVertex(original.triangles(1, t));
            tris.emplace_back(keptVertex(original.triangles(0, t)), b, c);
            cutId.push_back(-1);
            return;
        }
        ids.resize(d.elem.size());
        for (size_t i = 0; i < d.elem.size(); ++i) {
            auto [it, added] = cache.welded.emplace(d.key[i], static_cast<int>(elem.size()));
            if (added) {
                elem.push_back(d.elem[i]);
                weights.push_back(d.w[i]);
            }
            ids[i] = it->second;
        }
        for (const auto& tri : d.tris) {
            const int a = ids[static_cast<size_t>(tri[0])], b = ids[static_cast<size_t>(tri[1])],
                      c = ids[static_cast<size_t>(tri[2])];
            if (a == b || b == c || a == c) continue;
            tris.emplace_back(a, b, c);
            cutId.push_back(tri[3]);
        }
    }
    int vertex(int p, int e, const Eigen::Vector4d& w, bool inside) {
        // Clipped to the parent's inner faces: only round-off is negative there; beyond a boundary
        // face a visual surface's weights are extrapolated, as are a carrier's (inside false).
        Eigen::Vector4d c = w;
        if (inside)
            for (int a = 0; a < 4; ++a)
                if (eng.adj_(a, p) >= 0) c[a] = std::max(c[a], 0.0);
        return into->add(e, c, vertexKey(m.tets, e, c));
    }
    // A vertex of element e at weights w, one per key in what is being drawn (splitPastBoundary
    // compares them).
    int vertexOnce(int e, const Eigen::Vector4d& w) {
        into->welds = true;
        const VertexKey k = vertexKey(m.tets, e, w);
        for (size_t i = 0; i < into->key.size(); ++i)
            if (into->key[i] == k) {
                if (into->elem[i] != e) into->alsoRide.push_back(e);
                return static_cast<int>(i);
            }
        return into->add(e, w, k);
    }
    // Drawn d as it would be drawn now, its keys named again for the elements relinked since: false
    // when it must be drawn again (vertices made one by keys that changed).
    bool current(Drawn& d) const {
        if (!d.valid) return false;
        if (moved.empty()) return true;
        for (int e : d.alsoRide)
            if (moved[static_cast<size_t>(e)]) return false;
        for (size_t i = 0; i < d.elem.size(); ++i) {
            const int e = d.elem[i];
            if (!moved[static_cast<size_t>(e)]) continue;
            if (d.welds) return false;
            d.key[i] = vertexKey(m.tets, e, d.w[i]);
        }
        return true;
    }
    // cut: the cut making it, or -1. inside: the polygon's weights lie in e's parent (else
    // extrapolated from it). Collapsed triangles are dropped in append.
    void emit(int p, int e, const Poly& poly, int cut, bool inside = true) {
        if (poly.size() < 3 || area(p, poly) <= cache.tinyArea) return;
        const int v0 = vertex(p, e, poly[0], inside);
        int v1 = vertex(p, e, poly[1], inside);
        for (size_t k = 1; k + 1 < poly.size(); ++k) {
            const int v2 = vertex(p, e, poly[k + 1], inside);
            into->tris.push_back({v0, v1, v2, cut});
            v1 = v2;
        }
    }
    void emitInCutParent(int p, const Poly& poly);
    void drawTriangle(int t, const std::vector<char>& near);
    void drawOriginal();
    // The cut faces
    bool cornerOutside(int p) const;
    double windingAt(int p, const Eigen::Vector4d& w) const;
    double crossingAt(int p, const Eigen::Vector4d& a, const Eigen::Vector4d& b) const;
    bool atBoundary(int p) const { return cache.outside && eng.adj_.col(p).minCoeff() < 0; }
    Poly pastBoundary(int p, const Virtual& ve, int cut, const Poly& face) const;
    // Polygon `poly` (weights in p) riding element e, of parent q: p itself, or a carrier whose
    // weights are extrapolated.
    void put(int p, const Poly& poly, int e, int q, int cut) {
        if (q == p) return emit(p, e, poly, cut);
        emit(q, e, inParent(p, poly, q), cut, false);
    }
    void cap(int p, bool inside, const Poly& poly, int e, int q, int cut, int capLevels);
    void drawCutFaces(int capLevels);
    void drawCutFacesOf(int p, int capLevels);
};

// A polygon in cut parent p: split by each cut of p, each cell to the virtual element whose
// sides it is on (a merged sliver's cell, on no element's sides, to the one it violates least).
void CutEngine::SurfaceBuild::emitInCutParent(int p, const Poly& poly) {
    const std::vector<int> ves = eng.virtualsOf(p);  // copy: virtualsOf reuses scratch
    std::vector<const Halfspace*> planes;            // one per cut
    for (int e : ves)
        for (const Halfspace& h : eng.findVirtual(e)->hs)
            if (std::none_of(planes.begin(), planes.end(), [&](const Halfspace* g) { return g->cut == h.cut; }))
                planes.push_back(&h);
    std::vector<Poly> cells{poly}, next;
    for (const Halfspace* h : planes) {
        next.clear();
        for (const Poly& c : cells) {
            Poly pos = clipBy(c, [&](const Eigen::Vector4d& w) { return w.dot(h->s); });
            Poly neg = clipBy(c, [&](const Eigen::Vector4d& w) { return -w.dot(h->s); });
            if (!pos.empty()) next.push_back(std::move(pos));
            if (!neg.empty()) next.push_back(std::move(neg));
        }
        std::swap(cells, next);
    }
    for (const Poly& c : cells) {
        Eigen::Vector4d mid = Eigen::Vector4d::Zero();
        for (const auto& w : c) mid += w;
        mid /= static_cast<double>(c.size());
        int best = ves[0], fewest = 1 << 30;
        for (int e : ves) {
            int bad = 0;
            for (const Halfspace& h : eng.findVirtual(e)->hs) bad += (mid.dot(h.s) >= 0) != h.positive;
            if (bad < fewest) {
                fewest = bad;
                best = e;
            }
        }
        // A cell on a side p dropped (a sliver below minFraction) has no element of p on its
        // side: riding the other side, it would stretch across the opening cut as a shard.
        // It rides an element of a neighbouring parent on its side instead, its weights
        // extrapolated from that parent (the sliver is a few percent of an element).
        int q = -1;
        const int g = fewest > 0 ? eng.carrierOnSide(m, p, planes, mid, q) : -1;
        if (g < 0)
            emit(p, best, c, -1);
        else
            emit(q, g, inParent(p, c, q), -1, false);
    }
}

// 1. The original triangles. One whose parents are all uncut stays as it is; one past the
// boundary is split by the cuts near it (splitPastBoundary); any other is split by the cuts of
// each parent it crosses. Each is drawn again only when a parent sharing a corner with one it
// lies over changed, or when the pieces it asked about were parted or joined.
void CutEngine::SurfaceBuild::drawOriginal() {
    // Parents sharing a corner with a cut parent: a triangle past the boundary near them may be
    // crossed by a cut beyond the parents it lies over.
    std::vector<char> near;
    for (int t = 0; t < original.faces(); ++t) {
        Drawn& d = cache.drawnTri[static_cast<size_t>(t)];
        bool keep = d.valid;
        for (int k = cache.partStart[static_cast<size_t>(t)]; k < cache.partStart[static_cast<size_t>(t) + 1] && keep;
             ++k)
            keep = !nearChanged[static_cast<size_t>(cache.parts[static_cast<size_t>(k)].first)];
        for (int i = 0; i < 3 && keep; ++i)
            keep = !nearChanged[static_cast<size_t>(original.element[static_cast<size_t>(original.triangles(i, t))])];
        for (size_t k = 0; k < d.joined.size() && keep; ++k)
            keep = samePiece(d.joined[k][0], d.joined[k][1]) == (d.joined[k][2] != 0);
        if (!keep || !current(d)) {
            if (near.empty() && cache.outside) {
                near.assign(static_cast<size_t>(parents()), 0);
                for (int p = 0; p < parents(); ++p) {
                    if (!isCut(p)) continue;
                    for (int a = 0; a < 4; ++a) {
                        const int o = eng.tets0_(a, p);
                        for (int i = eng.ringStart_[static_cast<size_t>(o)];
                             i < eng.ringStart_[static_cast<size_t>(o) + 1]; ++i)
                            near[static_cast<size_t>(eng.ring_[static_cast<size_t>(i)])] = 1;
                    }
                }
            }
            d.clear();
            into = &d;
            drawTriangle(t, near);
            d.valid = true;
        }
        append(d, t);
    }
}

void CutEngine::SurfaceBuild::drawTriangle(int t, const std::vector<char>& near) {
    std::array<int, 3> v{};
    bool touchesCut = false;
    for (size_t i = 0; i < 3; ++i) {
        v[i] = original.triangles(static_cast<int>(i), t);
        touchesCut = touchesCut || isCut(original.element[static_cast<size_t>(v[i])]);
    }
    const int b = cache.partStart[static_cast<size_t>(t)], e = cache.partStart[static_cast<size_t>(t) + 1];
    for (int k = b; k < e && !touchesCut; ++k) touchesCut = isCut(cache.parts[static_cast<size_t>(k)].first);
    const bool past = cache.pastVertex[static_cast<size_t>(v[0])] || cache.pastVertex[static_cast<size_t>(v[1])] ||
                      cache.pastVertex[static_cast<size_t>(v[2])];
    const bool nearCut = past && std::any_of(v.begin(), v.end(), [&](int i) {
                             return near[static_cast<size_t>(original.element[static_cast<size_t>(i)])] != 0;
                         });
    if (past && (touchesCut || nearCut)) {
        eng.splitPastBoundary(
            m, cache, original, t,
            [&](int g, int h) {
                const bool same = samePiece(g, h);
                into->joined.push_back({g, h, same ? 1 : 0});
                return same;
            },
            [&](int g, const Eigen::Vector4d& w) { return vertexOnce(g, w); },
            [&](int a, int b2, int c2) {
                into->tris.push_back({a, b2, c2, -1});
            });
        return;
    }
    if (!touchesCut) {
        into->whole = true;
        return;
    }
    for (int k = b; k < e; ++k) {
        const auto& [q, poly] = cache.parts[static_cast<size_t>(k)];
        if (isCut(q))
            emitInCutParent(q, poly);
        else
            emit(q, q, poly, -1);
    }
}

// A whole element (share 1) may still reach past the surface when it is a tet mesh's and the
// surface a visual one: then a corner lies outside the surface or a surface vertex inside it.
bool CutEngine::SurfaceBuild::cornerOutside(int p) const {
    for (int a = 0; a < 4; ++a) {
        double& w = cache.cornerWinding[static_cast<size_t>(eng.tets0_(a, p))];
        if (std::isnan(w)) w = windingNumber(cache.tree, m.X.col(eng.tets0_(a, p)));
        if (w < 0.5) return true;
    }
    return false;
}

double CutEngine::SurfaceBuild::windingAt(int p, const Eigen::Vector4d& w) const {
    const auto [it, added] = cache.winding.try_emplace({p, {w[0], w[1], w[2], w[3]}}, 0.0);
    if (added) it->second = windingNumber(cache.tree, rest(p, w));
    return it->second;
}

// Where the surface crosses the segment from a to b (their sides differ), as a fraction of it,
// so a cap's rim follows the surface instead of the staircase a linear interpolant of the
// (step-like) winding number draws: the first triangle the segment meets, or where none does
// (a hole, a gap in a self-intersecting surface) bisection on the winding number to 2^-12.
double CutEngine::SurfaceBuild::crossingAt(int p, const Eigen::Vector4d& a, const Eigen::Vector4d& b) const {
    const bool flip = std::lexicographical_compare(b.data(), b.data() + 4, a.data(), a.data() + 4);
    const Eigen::Vector4d& u = flip ? b : a;
    const Eigen::Vector4d& v = flip ? a : b;
    const auto [it, added] = cache.crossing.try_emplace({p, {u[0], u[1], u[2], u[3], v[0], v[1], v[2], v[3]}}, 0.0);
    if (added && firstCrossing(cache.tree, rest(p, u), rest(p, v), it->second))
        return flip ? 1 - it->second : it->second;
    if (added) {
        const bool in = windingAt(p, u) >= 0.5;
        double lo = 0, hi = 1;
        for (int i = 0; i < 12; ++i) {
            const double mid = 0.5 * (lo + hi);
            ((windingNumber(cache.tree, rest(p, u + mid * (v - u))) >= 0.5) == in ? lo : hi) = mid;
        }
        it->second = 0.5 * (lo + hi);
    }
    return flip ? 1 - it->second : it->second;
}

// A surface that bulges past the tet boundary (a visual one) would show its inside between its
// rim and a cut face that ends at the boundary: a boundary element's cut face reaches past its
// boundary faces (weights extrapolated), and the winding number clips it to the surface as it
// does inside. A square in the face's plane, wide enough for the grown element, clipped to it
// and to the element's other cuts.
Poly CutEngine::SurfaceBuild::pastBoundary(int p, const Virtual& ve, int cut, const Poly& face) const {
    constexpr double kPast = 0.5;  // of the element's height, at least
    const auto& t = eng.tets0_;
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), nrm = Eigen::Vector3d::Zero();
    const Eigen::Vector3d y0 = rest(p, face[0]);
    for (size_t k = 0; k < face.size(); ++k) {
        c += rest(p, face[k]);
        if (k + 2 < face.size()) nrm += (rest(p, face[k + 1]) - y0).cross(rest(p, face[k + 2]) - y0);
    }
    c /= static_cast<double>(face.size());
    if (!(nrm.norm() > 0)) return face;
    nrm.normalize();
    const Eigen::Vector3d u = nrm.unitOrthogonal(), v = nrm.cross(u);
    double size = 0;
    for (int a = 0; a < 4; ++a) size = std::max(size, (m.X.col(t(a, p)) - c).norm());
    // past each boundary face: kPast, or farther to reach the farthest surface vertex (in
    // weights: distance over the element's height above that face)
    Eigen::Vector4d past = Eigen::Vector4d::Zero();
    for (int a = 0; a < 4; ++a) {
        if (eng.adj_(a, p) >= 0) continue;
        const Eigen::Vector3d y1 = m.X.col(t((a + 1) % 4, p)), y2 = m.X.col(t((a + 2) % 4, p)),
                              y3 = m.X.col(t((a + 3) % 4, p));
        const Eigen::Vector3d nf = (y2 - y1).cross(y3 - y1);
        const double height = std::abs(nf.dot(m.X.col(t(a, p)) - y1)) / nf.norm();
        past[a] = std::max(kPast, 1.25 * cache.reach / height);
    }
    const double half = 2 * (1 + 4 * past.maxCoeff()) * size;
    Poly sq;
    for (const auto& [du, dv] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}})  // counter-clockwise about nrm
        sq.push_back(barycentric(c + half * (du * u + dv * v), m.X.col(t(0, p)), m.X.col(t(1, p)), m.X.col(t(2, p)),
                                 m.X.col(t(3, p))));
    for (int a = 0; a < 4 && !sq.empty(); ++a)
        sq = clipBy(sq, [a, pa = past[a]](const Eigen::Vector4d& w) { return w[a] + pa; });
    for (const Halfspace& h : ve.hs) {
        if (h.cut == cut || sq.empty()) continue;
        sq = clipBy(sq, [&h](const Eigen::Vector4d& w) { return h.positive ? w.dot(h.s) : -w.dot(h.s); });
    }
    return sq.size() >= 3 ? sq : face;
}

// A cap polygon of parent p riding e (of parent q). In an element the surface crosses (inside
// false) only its part inside the surface: each triangle subdivided into 4^capLevels, the
// winding number w of the rest surface sampled at their corners, and each clipped where the
// linear interpolant of w - 1/2 changes sign (Jacobson et al. 2013: w is 1 inside a closed
// surface, 0 outside).
void CutEngine::SurfaceBuild::cap(int p, bool inside, const Poly& poly, int e, int q, int cut, int capLevels) {
    if (inside) return put(p, poly, e, q, cut);
    const int n = 1 << std::max(0, capLevels);
    auto at = [n](int i, int j) { return static_cast<size_t>(i * (n + 1) - i * (i - 1) / 2 + j); };  // i + j <= n
    for (size_t k = 1; k + 1 < poly.size(); ++k) {
        const Eigen::Vector4d A = poly[0], B = poly[k], C = poly[k + 1];
        grid.assign(static_cast<size_t>((n + 1) * (n + 2) / 2), Eigen::Vector4d::Zero());
        wind.assign(grid.size(), 0.0);
        for (int i = 0; i <= n; ++i)
            for (int j = 0; i + j <= n; ++j) {
                const Eigen::Vector4d w = A + (double(i) / n) * (B - A) + (double(j) / n) * (C - A);
                grid[at(i, j)] = w;
                wind[at(i, j)] = windingAt(p, w) - 0.5;
            }
        // inside at every sample: the triangle whole (the same area, 4^capLevels times fewer triangles)
        if (std::all_of(wind.begin(), wind.end(), [](double x) { return x >= 0; })) {
            put(p, {A, B, C}, e, q, cut);
            continue;
        }
        // A sub-triangle the surface crosses is clipped by the line through the two
        // crossings on its edges: values at its corners whose linear interpolant is zero
        // exactly there (the lone corner on its side at +-1).
        auto sub = [&](size_t a, size_t b, size_t c) {
            const std::array<size_t, 3> v{a, b, c};
            const int nIn = (wind[a] >= 0) + (wind[b] >= 0) + (wind[c] >= 0);
            if (nIn == 0) return;
            if (nIn == 3) return put(p, {grid[a], grid[b], grid[c]}, e, q, cut);
            size_t lone = 0;
            for (size_t i = 0; i < 3; ++i)
                if ((wind[v[i]] >= 0) == (nIn == 1)) lone = i;
            std::vector<double> f(3);
            f[lone] = nIn == 1 ? 1 : -1;
            for (size_t i = 0; i < 3; ++i) {
                if (i == lone) continue;
                const double t = std::clamp(crossingAt(p, grid[v[lone]], grid[v[i]]), 1e-6, 1 - 1e-6);
                f[i] = -f[lone] * (1 - t) / t;
            }
            put(p, clipPoly({grid[a], grid[b], grid[c]}, f), e, q, cut);
        };
        for (int i = 0; i < n; ++i)
            for (int j = 0; i + j < n; ++j) {
                sub(at(i, j), at(i + 1, j), at(i, j + 1));
                if (i + j + 1 < n) sub(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            }
    }
}

// Slivers by parent, newest first.
void CutEngine::SurfaceBuild::indexSlivers() {
    sliverStart.assign(static_cast<size_t>(parents()) + 1, 0);
    auto parentOf = [&](const Sliver& sl) {
        return sl.element >= 0 && sl.element < m.elements() ? eng.parent_[static_cast<size_t>(sl.element)] : -1;
    };
    for (const Sliver& sl : eng.slivers_)
        if (const int p = parentOf(sl); p >= 0) ++sliverStart[static_cast<size_t>(p) + 1];
    for (size_t p = 0; p < static_cast<size_t>(parents()); ++p) sliverStart[p + 1] += sliverStart[p];
    sliverOf.resize(static_cast<size_t>(sliverStart.back()));
    std::vector<int> fill(sliverStart.begin() + 1, sliverStart.end());
    for (size_t i = 0; i < eng.slivers_.size(); ++i)
        if (const int p = parentOf(eng.slivers_[i]); p >= 0)
            sliverOf[static_cast<size_t>(--fill[static_cast<size_t>(p)])] = static_cast<int>(i);
}

// What surface() reads of a parent: its elements, the sides set on each (virtVersion), and its
// slivers. A triangle or cut face reads those of the parents sharing a corner with the parents
// it lies over. The elements' nodes only name the vertices (Drawn): `moved` marks those changed.
void CutEngine::SurfaceBuild::findChanged() {
    const int np = parents();
    std::vector<int> start{0}, state;
    start.reserve(static_cast<size_t>(np) + 1);
    for (int p = 0; p < np; ++p) {
        const std::vector<int>& ves = eng.virtualsOf(p);
        state.push_back(static_cast<int>(ves.size()));
        for (int g : ves) {
            state.push_back(g);
            state.push_back(static_cast<int>(eng.virtVersion(g)));
        }
        state.insert(state.end(), sliverOf.begin() + sliverStart[static_cast<size_t>(p)],
                     sliverOf.begin() + sliverStart[static_cast<size_t>(p) + 1]);
        start.push_back(static_cast<int>(state.size()));
    }
    const bool first = cache.stateStart.size() != start.size();
    nearChanged.assign(static_cast<size_t>(np), first ? 1 : 0);
    for (int p = 0; p < np && !first; ++p) {
        const auto was = cache.state.begin() + cache.stateStart[static_cast<size_t>(p)];
        const auto wasEnd = cache.state.begin() + cache.stateStart[static_cast<size_t>(p) + 1];
        if (std::equal(was, wasEnd, state.begin() + start[static_cast<size_t>(p)],
                       state.begin() + start[static_cast<size_t>(p) + 1]))
            continue;
        for (int a = 0; a < 4; ++a) {
            const int o = eng.tets0_(a, p);
            for (int i = eng.ringStart_[static_cast<size_t>(o)]; i < eng.ringStart_[static_cast<size_t>(o) + 1]; ++i)
                nearChanged[static_cast<size_t>(eng.ring_[static_cast<size_t>(i)])] = 1;
        }
    }
    cache.stateStart = std::move(start);
    cache.state = std::move(state);
    // elements made since the last call are in no Drawn kept
    const Eigen::Index before = first ? 0 : std::min(cache.tets.cols(), m.tets.cols());
    moved.clear();
    for (Eigen::Index e = 0; e < before; ++e)
        if (cache.tets.col(e) != m.tets.col(e)) {
            if (moved.empty()) moved.assign(static_cast<size_t>(m.elements()), 0);
            moved[static_cast<size_t>(e)] = 1;
        }
    cache.tets = m.tets;
}

// 2. The cut faces of each cut parent, in parent order (deterministic output); drawn again when a
// parent sharing a corner with it changed.
void CutEngine::SurfaceBuild::drawCutFaces(int capLevels) {
    if (cache.drawnLevels != capLevels)
        for (Drawn& d : cache.drawnCap) d.valid = false;
    cache.drawnLevels = capLevels;
    for (int p = 0; p < parents(); ++p) {
        if (!isCut(p)) continue;
        Drawn& d = cache.drawnCap[static_cast<size_t>(p)];
        if (!d.valid || nearChanged[static_cast<size_t>(p)] || !current(d)) {
            d.clear();
            into = &d;
            drawCutFacesOf(p, capLevels);
            d.valid = true;
        }
        append(d);
    }
}

// The cut faces of the pieces of p, and of its slivers on their side (a hole there otherwise,
// with the inside of the surface in view through it).
void CutEngine::SurfaceBuild::drawCutFacesOf(int p, int capLevels) {
    const bool inside =
        original.vertices() == 0 ||
        (eng.fraction0_[p] >= 1.0 && !cache.holdsVertex[static_cast<size_t>(p)] && !atBoundary(p) && !cornerOutside(p));
    const std::vector<int> ves = eng.virtualsOf(p);  // copy: virtualsOf reuses scratch
    std::vector<const Halfspace*> planes;            // p's cut planes, for carriers
    for (int e : ves) {
        const Virtual& ve = *eng.findVirtual(e);
        for (const Halfspace& h : ve.hs)
            if (std::none_of(planes.begin(), planes.end(), [&](const Halfspace* g) { return g->cut == h.cut; }))
                planes.push_back(&h);
        for (const PolyFace& f : ve.piece.faces) {
            if (f.tag < 4) continue;
            Poly poly;
            for (int vi : f.v) poly.push_back(weightsOf(ve.piece.xi[static_cast<size_t>(vi)]));
            if (!inside && atBoundary(p)) poly = pastBoundary(p, ve, f.tag - 4, poly);
            cap(p, inside, poly, e, p, f.tag - 4, capLevels);
        }
    }
    for (int i = sliverStart[static_cast<size_t>(p)]; i < sliverStart[static_cast<size_t>(p) + 1]; ++i) {
        const Sliver& sl = eng.slivers_[static_cast<size_t>(sliverOf[static_cast<size_t>(i)])];
        Eigen::Vector4d mid = Eigen::Vector4d::Zero();
        for (const auto& xi : sl.piece.xi) mid += weightsOf(xi);
        mid /= static_cast<double>(std::max<size_t>(1, sl.piece.xi.size()));
        int q = -1;
        const int g = eng.carrierOnSide(m, p, planes, mid, q);
        if (g < 0) continue;  // severed alone: nothing on its side to ride
        for (const PolyFace& f : sl.piece.faces) {
            if (f.tag - 4 != sl.cut) continue;
            Poly poly;
            for (int vi : f.v) poly.push_back(weightsOf(sl.piece.xi[static_cast<size_t>(vi)]));
            cap(p, inside, poly, g, q, sl.cut, capLevels);
        }
    }
}

EmbeddedSurface CutEngine::surface(const Model& m, const EmbeddedSurface& original, int capLevels) const {
    if (!prepared_) return original;
    SurfaceBuild b(*this, m, original, splitCache(m, original));
    b.cache.welded.clear();
    b.indexSlivers();
    b.findChanged();
    b.drawOriginal();
    b.drawCutFaces(capLevels);
    return makeEmbeddedSurface(std::move(b.elem), b.weights, b.tris, std::move(b.cutId));
}

}  // namespace cutsim
