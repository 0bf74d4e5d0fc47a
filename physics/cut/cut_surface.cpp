// The drawn and touched surface of a cut tet-mesh object (docs/method.md sec. 5): each virtual
// element's exposed faces and cut faces, as one connected surface per piece.
#include "cut/xfem.hpp"

#include "cut/vertex_key.hpp"

#include "mesh/embedding.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <unordered_map>
#include <utility>

namespace cutsim {

std::vector<std::uint8_t> CutEngine::virtualNodes(const Model& m) const {
    if (!cuts()) return {};
    std::vector<std::uint8_t> v = partialNodes(m);
    for (size_t i = 0; i < v.size(); ++i) v[i] &= originalNode(static_cast<int>(i)) != static_cast<int>(i);
    return v;
}

bool CutEngine::isVirtualNode(const Model& m, int n) const {
    if (!cuts() || originalNode(n) == n) return false;
    const std::span<const int> slots = m.slotsOf(n);
    return !slots.empty() &&
           std::all_of(slots.begin(), slots.end(), [&](int s) { return m.fraction(s / 4) < 1; });  // as partialNodes
}

// surface(m)'s work: the drawn surface as it is built, the faces of the pieces and the slivers'.
struct CutEngine::MeshSurfaceBuild {
    const CutEngine& eng;
    const Model& m;
    std::vector<int> elem;
    std::vector<Eigen::Vector4d> weights;
    std::vector<Eigen::Vector3i> tris;
    std::vector<int> cutId;
    std::unordered_map<VertexKey, int, VertexKeyHash> welded;  // one vertex per place and node set
    std::unordered_multimap<int, const Sliver*> sliversIn;     // slivers by parent, for the faces they cover
    std::vector<int> vs;                                       // scratch: a face's vertices

    MeshSurfaceBuild(const CutEngine& e, const Model& model) : eng(e), m(model) {
        for (const Sliver& sl : eng.slivers_)
            if (sl.element >= 0 && sl.element < m.elements())
                sliversIn.emplace(eng.parent_[static_cast<size_t>(sl.element)], &sl);
    }
    int vertex(int e, const Eigen::Vector4d& w) {
        auto [it, added] = welded.emplace(vertexKey(m.tets, e, w), static_cast<int>(elem.size()));
        if (added) {
            elem.push_back(e);
            weights.push_back(w);
        }
        return it->second;
    }
    void emit(int cut) {
        for (size_t k = 1; k + 1 < vs.size(); ++k) {
            if (vs[0] == vs[k] || vs[k] == vs[k + 1] || vs[0] == vs[k + 1]) continue;  // collapsed by welding
            tris.emplace_back(vs[0], vs[k], vs[k + 1]);
            cutId.push_back(cut);
        }
    }
    // Element e is on a sliver's side at original node o when its node there is not the one of the
    // element that kept the other side.
    bool onSliverSide(int e, int p, const Sliver& sl, int q) const {
        for (size_t vi = 0; vi < sl.piece.xi.size(); ++vi) {
            const int c = sl.piece.corner[vi];
            if (c < 0) continue;
            const int o = eng.tets0_(c, q);
            for (int a = 0; a < 4; ++a)
                if (eng.tets0_(a, p) == o && m.tets(a, e) != m.tets(c, sl.element)) return true;
        }
        return false;
    }
    bool exposed(int e, int p, int k) const;
    void drawPieces();
    // Is element g (of parent q) on the side sliver sl (of parent p) dropped?
    bool sliverSide(int g, int q, const Sliver& sl, int p) const {
        const auto gv = eng.virt_.find(g);
        if (gv != eng.virt_.end())
            for (const Halfspace& h : gv->second.hs)
                if (h.cut == sl.cut) return h.positive == sl.positive;
        // Not crossed by that cut: its node at a shared corner tells (the kept element's is the other side).
        for (int c = 0; c < 4; ++c)
            for (int cq = 0; cq < 4; ++cq)
                if (eng.tets0_(cq, q) == eng.tets0_(c, p)) return m.tets(cq, g) != m.tets(c, sl.element);
        return false;
    }
    int onSide(const Sliver& sl, int p, const Eigen::Vector4d& w);
    int extrapolated(const Sliver& sl, int p, const Eigen::Vector4d& w);
    void drawSlivers();
};

// A face of an element is inside the body when a virtual element across it uses the same three
// nodes, or when a sliver dropped across it on its side covers it (the sliver's faces are drawn).
bool CutEngine::MeshSurfaceBuild::exposed(int e, int p, int k) const {
    const int q = eng.adj_(k, p);
    if (q < 0) return true;
    const auto range = sliversIn.equal_range(q);
    for (auto it = range.first; it != range.second; ++it)
        if (onSliverSide(e, p, *it->second, q)) return false;
    std::array<int, 3> mine{};
    for (int a = 0, j = 0; a < 4; ++a)
        if (a != k) mine[static_cast<size_t>(j++)] = m.tets(a, e);
    std::sort(mine.begin(), mine.end());
    const auto& t = eng.tets0_;
    for (int g : eng.virtualsOf(q)) {
        std::array<int, 3> theirs{};
        int j = 0;
        for (int a = 0; a < 4 && j < 3; ++a) {
            const int orig = t(a, q);
            if (orig == t(0, p) || orig == t(1, p) || orig == t(2, p) || orig == t(3, p))
                theirs[static_cast<size_t>(j++)] = m.tets(a, g);
        }
        std::sort(theirs.begin(), theirs.end());
        if (theirs == mine) return false;
    }
    return true;
}

// The exposed faces and cut faces of every element's piece.
void CutEngine::MeshSurfaceBuild::drawPieces() {
    static const ConvexPiece whole = referenceTet();
    const int nParents = static_cast<int>(eng.tets0_.cols());
    for (int p = 0; p < nParents; ++p) {
        const std::vector<int> ves = eng.virtualsOf(p);  // copy: virtualsOf reuses scratch
        for (int e : ves) {
            const auto it = eng.virt_.find(e);
            const ConvexPiece& piece = it != eng.virt_.end() ? it->second.piece : whole;
            for (const PolyFace& f : piece.faces) {
                const bool cap = f.tag >= 4;
                if (!cap && !exposed(e, p, f.tag)) continue;
                vs.clear();
                for (int vi : f.v) vs.push_back(vertex(e, weightsOf(piece.xi[static_cast<size_t>(vi)])));
                emit(cap ? f.tag - 4 : -1);
            }
        }
    }
}

// The vertex at weights w (in sliver sl's parent p) on the sliver's side: the vertex an element
// on that side uses there, its parent holding the parent corners w depends on; or -1.
int CutEngine::MeshSurfaceBuild::onSide(const Sliver& sl, int p, const Eigen::Vector4d& w) {
    int c0 = 0;
    while (c0 < 4 && std::abs(w[c0]) <= 1e-12) ++c0;
    if (c0 == 4) return -1;
    const auto& t = eng.tets0_;
    const int o = t(c0, p);
    for (int i = eng.ringStart_[static_cast<size_t>(o)]; i < eng.ringStart_[static_cast<size_t>(o) + 1]; ++i) {
        const int q = eng.ring_[static_cast<size_t>(i)];
        if (q == p) continue;
        Eigen::Vector4d wq = Eigen::Vector4d::Zero();
        bool holds = true;
        for (int c = 0; c < 4 && holds; ++c) {
            if (std::abs(w[c]) <= 1e-12) continue;
            int cq = 0;
            while (cq < 4 && t(cq, q) != t(c, p)) ++cq;
            holds = cq < 4;
            if (holds) wq[cq] = w[c];
        }
        if (!holds) continue;
        for (int g : eng.virtualsOf(q))
            if (g != sl.element && sliverSide(g, q, sl, p)) return vertex(g, wq);
    }
    return -1;
}

// Otherwise the element on the sliver's side with the lowest index around the vertex's
// heaviest corner, at weights extrapolated from its parent: a vertex two slivers share gets one
// carrier, so one vertex. -1 when none is.
int CutEngine::MeshSurfaceBuild::extrapolated(const Sliver& sl, int p, const Eigen::Vector4d& w) {
    const auto& t = eng.tets0_;
    std::array<int, 4> order{0, 1, 2, 3};
    std::sort(order.begin(), order.end(), [&](int a, int b) { return w[a] > w[b]; });
    for (int c : order) {
        if (w[c] <= 1e-12) break;
        const int o = t(c, p);
        int best = -1, bestParent = -1;
        for (int i = eng.ringStart_[static_cast<size_t>(o)]; i < eng.ringStart_[static_cast<size_t>(o) + 1]; ++i) {
            const int q = eng.ring_[static_cast<size_t>(i)];
            for (int g : eng.virtualsOf(q))
                if (g != sl.element && (best < 0 || g < best) && sliverSide(g, q, sl, p)) {
                    best = g;
                    bestParent = q;
                }
        }
        if (best < 0) continue;
        const int q = bestParent;
        return vertex(best, barycentric(eng.restOf(m, p, w), m.X.col(t(0, q)), m.X.col(t(1, q)), m.X.col(t(2, q)),
                                        m.X.col(t(3, q))));
    }
    return -1;
}

// Dropped slivers: the side that lost one would show a hole in its cut face (and in its
// boundary, at the object's surface), with the inner faces around it in view. Each vertex of
// their faces rides an element on that side whose parent holds the parent corners the vertex
// depends on, so it is the vertex that element's own faces use (shared edges); failing that,
// an element on that side holding one of the sliver's corners carries it at weights
// extrapolated from its parent: the sliver is a few percent of an element, so that stays close.
void CutEngine::MeshSurfaceBuild::drawSlivers() {
    for (const Sliver& sl : eng.slivers_) {
        const int e = sl.element;
        if (e < 0 || e >= m.elements()) continue;
        const int p = eng.parent_[static_cast<size_t>(e)];
        for (const PolyFace& f : sl.piece.faces) {
            const bool cap = f.tag >= 4;
            if (cap ? f.tag - 4 != sl.cut : eng.adj_(f.tag, p) >= 0)
                continue;  // its cut face, or the object's boundary
            vs.clear();
            for (int vi : f.v) {
                const Eigen::Vector4d w = weightsOf(sl.piece.xi[static_cast<size_t>(vi)]);
                int v = onSide(sl, p, w);
                if (v < 0) v = extrapolated(sl, p, w);
                if (v < 0) break;  // a sliver severed alone: nothing on its side to ride
                vs.push_back(v);
            }
            if (vs.size() == f.v.size()) emit(cap ? sl.cut : -1);
        }
    }
}

EmbeddedSurface CutEngine::surface(const Model& m) const {
    if (!prepared_) return boundarySurface(m.tets, m.X);
    MeshSurfaceBuild b(*this, m);
    b.drawPieces();
    b.drawSlivers();
    return makeEmbeddedSurface(std::move(b.elem), b.weights, b.tris, std::move(b.cutId));
}

}  // namespace cutsim
