// A drawn surface's triangles that lie past the object's boundary, split by the cuts near them
// (CutEngine::surface(m, original); docs/method.md sec. 5).
#include "cut/split_cache.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <utility>
#include <vector>

namespace cutsim {

// The cuts near one triangle past the boundary (a plane per cut, from a cut parent near) and
// which elements lie on which of their sides.
struct CutEngine::PastBoundarySplit {
    struct Plane {
        int cut, parent;
        Eigen::Vector4d s;  // signed distance at the parent's corners [m]
    };
    const CutEngine& eng;
    const Model& m;
    SplitCache::Scratch& ws;
    std::vector<Plane> planes;
    mutable std::vector<std::pair<int, std::uint32_t>> sides;  // sidesOf's answers so far, by element

    // The sign of plane c's signed distance at the corners of the cut parents near: the last
    // nonzero one given for each original node (ws.nodeSign[c], current where ws.nodeStamp[c] is ws.stamp).
    void setNode(size_t c, int n, double d) {
        if (d == 0) return;
        ws.nodeStamp[c][static_cast<size_t>(n)] = ws.stamp;
        ws.nodeSign[c][static_cast<size_t>(n)] = d > 0 ? 1 : -1;
    }
    int nodeSign(size_t c, int n) const {
        return ws.nodeStamp[c][static_cast<size_t>(n)] == ws.stamp ? ws.nodeSign[c][static_cast<size_t>(n)] : 0;
    }

    Eigen::Vector4d inP(int p, const Eigen::Vector3d& y) const {
        const auto& t = eng.tets0_;
        return barycentric(y, m.X.col(t(0, p)), m.X.col(t(1, p)), m.X.col(t(2, p)), m.X.col(t(3, p)));
    }
    template <class F>
    void forRing(int p, F&& f) const {  // each parent sharing a corner with p (p too), with repeats
        for (int a = 0; a < 4; ++a) {
            const int o = eng.tets0_(a, p);
            for (int i = eng.ringStart_[static_cast<size_t>(o)]; i < eng.ringStart_[static_cast<size_t>(o) + 1]; ++i)
                f(eng.ring_[static_cast<size_t>(i)]);
        }
    }
    // The planes of the cut parents in `asked` (in that order, with repeats): one per cut, from
    // the first parent that has it, and the signed distances each parent gives its corners, the
    // last one asked winning. A parent asked again gives what it gave before, so only its last
    // time counts for those and its first for the planes.
    void addPlanesOf(const std::vector<int>& asked) {
        const size_t nParents = static_cast<size_t>(eng.tets0_.cols()), nNodes = ws.nodes;
        if (ws.firstMark.size() < nParents) ws.firstMark.assign(nParents, 0), ws.lastMark.assign(nParents, 0);
        ++ws.stamp;
        std::vector<int>& first = ws.first;
        std::vector<int>& last = ws.last;
        first.clear();
        last.clear();
        for (int q : asked)
            if (std::exchange(ws.firstMark[static_cast<size_t>(q)], ws.stamp) != ws.stamp) first.push_back(q);
        for (size_t i = asked.size(); i-- > 0;)
            if (std::exchange(ws.lastMark[static_cast<size_t>(asked[i])], ws.stamp) != ws.stamp)
                last.push_back(asked[i]);
        auto planeOf = [&](int cut) {
            return static_cast<size_t>(
                std::find_if(planes.begin(), planes.end(), [&](const Plane& x) { return x.cut == cut; }) -
                planes.begin());
        };
        for (int q : first)
            for (int g : eng.virtualsOf(q))
                for (const Halfspace& h : eng.findVirtual(g)->hs)
                    if (planeOf(h.cut) == planes.size()) planes.push_back({h.cut, q, h.s});
        while (ws.nodeStamp.size() < planes.size()) {
            ws.nodeStamp.emplace_back(nNodes, 0);
            ws.nodeSign.emplace_back(nNodes, 0);
        }
        for (size_t i = last.size(); i-- > 0;) {
            const int q = last[i];
            for (int g : eng.virtualsOf(q))
                for (const Halfspace& h : eng.findVirtual(g)->hs) {
                    const size_t c = planeOf(h.cut);
                    for (int a = 0; a < 4; ++a) setNode(c, eng.tets0_(a, q), h.s[a]);
                }
        }
    }
    double level(const Plane& pl, const Eigen::Vector3d& x) const { return pl.s.dot(inP(pl.parent, x)); }
    std::uint32_t sideOf(const Eigen::Vector3d& x) const {
        std::uint32_t sig = 0;
        for (size_t c = 0; c < planes.size() && c < 32; ++c) sig |= std::uint32_t(level(planes[c], x) >= 0) << c;
        return sig;
    }
    // The rest centre of element g of parent q: its piece's, or the parent's when uncut.
    Eigen::Vector3d centre(int q, int g) const {
        const Virtual* gv = eng.findVirtual(g);
        if (!gv || gv->piece.xi.empty()) return eng.restOf(m, q, Eigen::Vector4d::Constant(0.25));
        Eigen::Vector4d w = Eigen::Vector4d::Zero();
        for (const auto& xi : gv->piece.xi) w += weightsOf(xi);
        return eng.restOf(m, q, w / static_cast<double>(gv->piece.xi.size()));
    }
    // Sides of element g of parent q: its own halfspace of each cut, else the sign its corners
    // have where a cut parent near gives them (the cut was made in the deformed shape: its rest
    // level set bends, so a plane far from where it was taken may put an element on the wrong
    // side), else its centre's.
    std::uint32_t sidesOf(int q, int g) const {
        for (const auto& [e, sig] : sides)
            if (e == g) return sig;
        std::uint32_t sig = sideOf(centre(q, g));
        const Virtual* gv = eng.findVirtual(g);
        for (size_t c = 0; c < planes.size() && c < 32; ++c) {
            int known = 0;
            if (gv)
                for (const Halfspace& h : gv->hs)
                    if (h.cut == planes[c].cut) known = h.positive ? 1 : -1;
            for (int a = 0; a < 4 && known == 0; ++a) known = nodeSign(c, eng.tets0_(a, q));
            if (known != 0) sig = (sig & ~(std::uint32_t(1) << c)) | (std::uint32_t(known > 0) << c);
        }
        sides.emplace_back(g, sig);
        return sig;
    }
    // An element on side sig: of p, else of a parent sharing the most corners with p; {-1, -1}
    // when none is.
    std::pair<int, int> rideOnSide(int p, std::uint32_t sig) const {
        for (int g : eng.virtualsOf(p))
            if (sidesOf(p, g) == sig) return {g, p};
        std::pair<int, int> best{-1, -1};
        int bestShared = -1;
        forRing(p, [&](int q) {
            int shared = 0;
            for (int b = 0; b < 4; ++b)
                for (int c = 0; c < 4; ++c) shared += eng.tets0_(b, q) == eng.tets0_(c, p);
            if (q == p || shared <= bestShared) return;
            for (int g : eng.virtualsOf(q))
                if (sidesOf(q, g) == sig) {
                    best = {g, q};
                    bestShared = shared;
                    return;
                }
        });
        return best;
    }
    // p's element on the fewest wrong sides (nothing on side sig near p).
    std::pair<int, int> leastWrong(int p, std::uint32_t sig) const {
        std::pair<int, int> ride{p, p};
        int fewest = 1 << 30;
        for (int g : eng.virtualsOf(p))
            if (const int wrong = std::popcount(sidesOf(p, g) ^ sig); wrong < fewest) fewest = wrong, ride = {g, p};
        return ride;
    }
    // The triangle y0 y1 y2 (rest positions in the first three entries) split by each plane.
    std::vector<Poly> cells(const std::array<Eigen::Vector3d, 3>& y) const {
        std::vector<Poly> out{
            {{y[0].x(), y[0].y(), y[0].z(), 0}, {y[1].x(), y[1].y(), y[1].z(), 0}, {y[2].x(), y[2].y(), y[2].z(), 0}}},
            next;
        for (const Plane& pl : planes) {
            next.clear();
            for (const Poly& c : out)
                for (double sign : {1.0, -1.0}) {
                    Poly part = clipBy(c, [&](const Eigen::Vector4d& w) { return sign * level(pl, w.head<3>()); });
                    if (!part.empty()) next.push_back(std::move(part));
                }
            std::swap(out, next);
        }
        return out;
    }
};

void CutEngine::splitPastBoundary(const Model& m, SplitCache& cache, const EmbeddedSurface& original, int t,
                                  const std::function<bool(int, int)>& samePiece,
                                  const std::function<int(int, const Eigen::Vector4d&)>& addVertex,
                                  const std::function<void(int, int, int)>& addTriangle) const {
    // Past the boundary no partition by parents is continuous (neighbours' extrapolations agree
    // only on their shared face's plane), so the triangle stays whole but for the cuts: split by
    // one plane per cut, taken from a cut parent near it, each cell drawn linear between corners
    // that ride elements on its side, as an uncut visual triangle rides its corners' elements.
    std::array<int, 3> parent{};
    std::array<Eigen::Vector3d, 3> y;
    for (size_t i = 0; i < 3; ++i) {
        const int v = original.triangles(static_cast<int>(i), t);
        parent[i] = original.element[static_cast<size_t>(v)];
        y[i] = cache.rest.V.col(v);
    }
    PastBoundarySplit split{*this, m, cache.scratch, {}, {}};
    std::vector<int> asked;  // the cut parents whose planes count: the corners', the parts', those around the corners
    auto ask = [&](int q) {
        if (findVirtual(q)) asked.push_back(q);
    };
    for (int q : parent) ask(q);
    for (int k = cache.partStart[static_cast<size_t>(t)]; k < cache.partStart[static_cast<size_t>(t) + 1]; ++k)
        ask(cache.parts[static_cast<size_t>(k)].first);
    for (int q : parent) split.forRing(q, ask);
    split.addPlanesOf(asked);
    std::vector<int> ids;
    std::vector<std::pair<int, int>> rides;  // (element, parent) of each cell corner
    for (const Poly& c : split.cells(y)) {
        Eigen::Vector3d mid = Eigen::Vector3d::Zero();
        for (const auto& w : c) mid += w.head<3>();
        const std::uint32_t sig = split.sideOf(mid / static_cast<double>(c.size()));
        // the triangle's corners to ride from: those in the cell first, then the nearest
        std::array<size_t, 3> order{0, 1, 2};
        std::array<bool, 3> in{};
        for (size_t i = 0; i < 3; ++i)
            in[i] = std::any_of(c.begin(), c.end(), [&](const Eigen::Vector4d& w) { return w.head<3>() == y[i]; });
        rides.clear();
        size_t anchor = 0;  // a corner of the triangle in the cell, else the first
        for (size_t k = c.size(); k-- > 0;)
            if (std::any_of(y.begin(), y.end(), [&](const Eigen::Vector3d& yi) { return c[k].head<3>() == yi; }))
                anchor = k;
        for (const auto& w : c) {
            std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
                if (in[a] != in[b]) return in[a];
                return (y[a] - w.head<3>()).squaredNorm() < (y[b] - w.head<3>()).squaredNorm();
            });
            std::pair<int, int> ride{-1, -1};
            for (size_t k = 0; k < 3 && ride.first < 0; ++k) ride = split.rideOnSide(parent[order[k]], sig);
            if (ride.first < 0) ride = split.leastWrong(parent[order[0]], sig);
            rides.push_back(ride);
        }
        // One piece per cell: a corner riding an element the cuts have parted from the anchor's
        // would stretch the cell across the opening as a spike; it rides the anchor's instead.
        ids.clear();
        for (size_t k = 0; k < c.size(); ++k) {
            auto ride = rides[k];
            if (!samePiece(ride.first, rides[anchor].first)) ride = rides[anchor];
            ids.push_back(addVertex(ride.first, split.inP(ride.second, c[k].head<3>())));
        }
        for (size_t k = 1; k + 1 < ids.size(); ++k)
            if (ids[0] != ids[k] && ids[k] != ids[k + 1] && ids[0] != ids[k + 1])
                addTriangle(ids[0], ids[k], ids[k + 1]);
    }
}

}  // namespace cutsim
