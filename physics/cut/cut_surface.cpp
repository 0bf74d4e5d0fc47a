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

EmbeddedSurface CutEngine::surface(const Model& m) const {
    if (!prepared_) return boundarySurface(m.tets, m.X);
    static const ConvexPiece whole = referenceTet();
    std::vector<int> elem;
    std::vector<Eigen::Vector4d> weights;
    std::vector<Eigen::Vector3i> tris;
    std::vector<int> cutId;
    std::unordered_map<VertexKey, int, VertexKeyHash> welded;  // one vertex per place and node set

    auto vertex = [&](int e, const Eigen::Vector4d& w) {
        auto [it, added] = welded.emplace(vertexKey(m.tets, e, w), static_cast<int>(elem.size()));
        if (added) {
            elem.push_back(e);
            weights.push_back(w);
        }
        return it->second;
    };
    auto emit = [&](const std::vector<int>& vs, int cut) {
        for (size_t k = 1; k + 1 < vs.size(); ++k) {
            if (vs[0] == vs[k] || vs[k] == vs[k + 1] || vs[0] == vs[k + 1]) continue;  // collapsed by welding
            tris.emplace_back(vs[0], vs[k], vs[k + 1]);
            cutId.push_back(cut);
        }
    };
    // Slivers by parent, for the faces they cover.
    std::unordered_multimap<int, const Sliver*> sliversIn;
    for (const Sliver& sl : slivers_)
        if (sl.element >= 0 && sl.element < m.elements())
            sliversIn.emplace(parent_[static_cast<size_t>(sl.element)], &sl);
    // Element e is on a sliver's side at original node o when its node there is not the one of the
    // element that kept the other side.
    auto onSliverSide = [&](int e, int p, const Sliver& sl, int q) {
        for (size_t vi = 0; vi < sl.piece.xi.size(); ++vi) {
            const int c = sl.piece.corner[vi];
            if (c < 0) continue;
            const int o = tets0_(c, q);
            for (int a = 0; a < 4; ++a)
                if (tets0_(a, p) == o && m.tets(a, e) != m.tets(c, sl.element)) return true;
        }
        return false;
    };
    // A face of an element is inside the body when a virtual element across it uses the same three
    // nodes, or when a sliver dropped across it on its side covers it (the sliver's faces are drawn).
    auto exposed = [&](int e, int p, int k) {
        const int q = adj_(k, p);
        if (q < 0) return true;
        const auto range = sliversIn.equal_range(q);
        for (auto it = range.first; it != range.second; ++it)
            if (onSliverSide(e, p, *it->second, q)) return false;
        std::array<int, 3> mine{};
        for (int a = 0, j = 0; a < 4; ++a)
            if (a != k) mine[static_cast<size_t>(j++)] = m.tets(a, e);
        std::sort(mine.begin(), mine.end());
        for (int g : virtualsOf(q)) {
            std::array<int, 3> theirs{};
            int j = 0;
            for (int a = 0; a < 4 && j < 3; ++a) {
                const int orig = tets0_(a, q);
                if (orig == tets0_(0, p) || orig == tets0_(1, p) || orig == tets0_(2, p) || orig == tets0_(3, p))
                    theirs[static_cast<size_t>(j++)] = m.tets(a, g);
            }
            std::sort(theirs.begin(), theirs.end());
            if (theirs == mine) return false;
        }
        return true;
    };

    const int nParents = static_cast<int>(tets0_.cols());
    std::vector<int> vs;
    for (int p = 0; p < nParents; ++p) {
        const std::vector<int> ves = virtualsOf(p);  // copy: virtualsOf reuses scratch
        for (int e : ves) {
            const auto it = virt_.find(e);
            const ConvexPiece& piece = it != virt_.end() ? it->second.piece : whole;
            for (const PolyFace& f : piece.faces) {
                const bool cap = f.tag >= 4;
                if (!cap && !exposed(e, p, f.tag)) continue;
                vs.clear();
                for (int vi : f.v) vs.push_back(vertex(e, weightsOf(piece.xi[static_cast<size_t>(vi)])));
                emit(vs, cap ? f.tag - 4 : -1);
            }
        }
    }

    // Dropped slivers: the side that lost one would show a hole in its cut face (and in its
    // boundary, at the object's surface), with the inner faces around it in view. Each vertex of
    // their faces rides an element on that side whose parent holds the parent corners the vertex
    // depends on, so it is the vertex that element's own faces use (shared edges); failing that,
    // an element on that side holding one of the sliver's corners carries it at weights
    // extrapolated from its parent: the sliver is a few percent of an element, so that stays close.
    auto sideOf = [&](int g, int q, const Sliver& sl, int p) {  // g on the sliver's side?
        const auto gv = virt_.find(g);
        if (gv != virt_.end())
            for (const Halfspace& h : gv->second.hs)
                if (h.cut == sl.cut) return h.positive == sl.positive;
        // Not crossed by that cut: its node at a shared corner tells (the kept element's is the other side).
        for (int c = 0; c < 4; ++c)
            for (int cq = 0; cq < 4; ++cq)
                if (tets0_(cq, q) == tets0_(c, p)) return m.tets(cq, g) != m.tets(c, sl.element);
        return false;
    };
    for (const Sliver& sl : slivers_) {
        const int e = sl.element;
        if (e < 0 || e >= m.elements()) continue;
        const int p = parent_[static_cast<size_t>(e)];
        // The vertex at weights w (in p) on the sliver's side, or -1.
        auto onSide = [&](const Eigen::Vector4d& w) {
            int c0 = 0;
            while (c0 < 4 && std::abs(w[c0]) <= 1e-12) ++c0;
            if (c0 == 4) return -1;
            const int o = tets0_(c0, p);
            for (int i = ringStart_[static_cast<size_t>(o)]; i < ringStart_[static_cast<size_t>(o) + 1]; ++i) {
                const int q = ring_[static_cast<size_t>(i)];
                if (q == p) continue;
                Eigen::Vector4d wq = Eigen::Vector4d::Zero();
                bool holds = true;
                for (int c = 0; c < 4 && holds; ++c) {
                    if (std::abs(w[c]) <= 1e-12) continue;
                    int cq = 0;
                    while (cq < 4 && tets0_(cq, q) != tets0_(c, p)) ++cq;
                    holds = cq < 4;
                    if (holds) wq[cq] = w[c];
                }
                if (!holds) continue;
                for (int g : virtualsOf(q))
                    if (g != e && sideOf(g, q, sl, p)) return vertex(g, wq);
            }
            return -1;
        };
        // Otherwise the element on the sliver's side with the lowest index around the vertex's
        // heaviest corner: a vertex two slivers share gets one carrier, so one vertex.
        auto extrapolated = [&](const Eigen::Vector4d& w) {
            std::array<int, 4> order{0, 1, 2, 3};
            std::sort(order.begin(), order.end(), [&](int a, int b) { return w[a] > w[b]; });
            for (int c : order) {
                if (w[c] <= 1e-12) break;
                const int o = tets0_(c, p);
                int best = -1, bestParent = -1;
                for (int i = ringStart_[static_cast<size_t>(o)]; i < ringStart_[static_cast<size_t>(o) + 1]; ++i) {
                    const int q = ring_[static_cast<size_t>(i)];
                    for (int g : virtualsOf(q))
                        if (g != e && (best < 0 || g < best) && sideOf(g, q, sl, p)) {
                            best = g;
                            bestParent = q;
                        }
                }
                if (best < 0) continue;
                const int q = bestParent;
                return vertex(best, barycentric(restOf(m, p, w), m.X.col(tets0_(0, q)), m.X.col(tets0_(1, q)),
                                                m.X.col(tets0_(2, q)), m.X.col(tets0_(3, q))));
            }
            return -1;
        };
        for (const PolyFace& f : sl.piece.faces) {
            const bool cap = f.tag >= 4;
            if (cap ? f.tag - 4 != sl.cut : adj_(f.tag, p) >= 0) continue;  // its cut face, or the object's boundary
            vs.clear();
            for (int vi : f.v) {
                const Eigen::Vector4d w = weightsOf(sl.piece.xi[static_cast<size_t>(vi)]);
                int v = onSide(w);
                if (v < 0) v = extrapolated(w);
                if (v < 0) break;  // a sliver severed alone: nothing on its side to ride
                vs.push_back(v);
            }
            if (vs.size() == f.v.size()) emit(vs, cap ? sl.cut : -1);
        }
    }

    return makeEmbeddedSurface(std::move(elem), weights, tris, std::move(cutId));
}

}  // namespace cutsim
