#include "cut/xfem.hpp"
#include "util/union_find.hpp"

#include "fem/forces.hpp"
#include "mesh/mesh.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <numeric>
#include <tuple>

namespace cutsim {

MassLumping parseLumping(const std::string& name) {
    if (name == "row_sum") return MassLumping::RowSum;
    if (name == "weighted_diagonal") return MassLumping::WeightedDiagonal;
    if (name == "enrichment") return MassLumping::Enrichment;
    throw InputError("unknown mass lumping '" + name + "' (row_sum, weighted_diagonal, enrichment)");
}

const char* lumpingName(MassLumping l) {
    switch (l) {
    case MassLumping::RowSum: return "row_sum";
    case MassLumping::WeightedDiagonal: return "weighted_diagonal";
    case MassLumping::Enrichment: return "enrichment";
    }
    return "?";
}

void planeAxes(const Eigen::Vector3d& normal, Eigen::Vector3d& u, Eigen::Vector3d& v) {
    u = normal.unitOrthogonal();
    v = normal.cross(u);
}

namespace {

using Clock = std::chrono::steady_clock;

const ConvexPiece& wholeTet() {
    static const ConvexPiece t = referenceTet();
    return t;
}

// Point in a convex polygon of either orientation, boundary included (tolerance tol) [m].
bool insideConvex(const std::vector<Eigen::Vector2d>& poly, const Eigen::Vector2d& p, double tol) {
    const size_t n = poly.size();
    if (n < 3) return false;
    double area2 = 0;
    for (size_t k = 0; k < n; ++k) {
        const Eigen::Vector2d& a = poly[k];
        const Eigen::Vector2d& b = poly[(k + 1) % n];
        area2 += a[0] * b[1] - a[1] * b[0];
    }
    const double sgn = area2 >= 0 ? 1.0 : -1.0;
    for (size_t k = 0; k < n; ++k) {
        const Eigen::Vector2d e = poly[(k + 1) % n] - poly[k];
        const double len = e.norm();
        if (len == 0) continue;
        const Eigen::Vector2d d = p - poly[k];
        if (sgn * (e[0] * d[1] - e[1] * d[0]) / len < -tol) return false;
    }
    return true;
}

// Convex hull (counter-clockwise) of a few points, Andrew's monotone chain.
std::vector<Eigen::Vector2d> convexHull(std::vector<Eigen::Vector2d> p) {
    std::sort(p.begin(), p.end(),
              [](const auto& a, const auto& b) { return a[0] < b[0] || (a[0] == b[0] && a[1] < b[1]); });
    if (p.size() < 3) return p;
    std::vector<Eigen::Vector2d> h(2 * p.size());
    size_t k = 0;
    auto turn = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    };
    for (size_t i = 0; i < p.size(); ++i) {
        while (k >= 2 && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    for (size_t i = p.size() - 1, t = k + 1; i-- > 0;) {
        while (k >= t && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    h.resize(k - 1);
    return h;
}

int localIndex(const Eigen::Matrix4Xi& tets, int e, int node) {
    for (int a = 0; a < 4; ++a)
        if (tets(a, e) == node) return a;
    return -1;
}

}  // namespace

const std::vector<int>& CutEngine::virtualsOf(int parent) const {
    if (marked(parent, kChildren)) return children_[static_cast<size_t>(parent)];
    single_.assign(1, parent);
    return single_;
}

void CutEngine::prepare(const Model& m) {
    if (prepared_) return;
    tets0_ = m.tets;
    const int ne = m.elements(), nn = m.nodes();
    fraction0_ = m.fraction;
    fixed0_ = m.fixed;
    mass0_ = wholeMass(m);  // an MI lattice node's light share is of its whole cells' mass
    volume0_ = m.volume.dot(m.fraction);
    massRef_ = m.mass.sum();

    // Face adjacency: sort (face key, element, corner) and pair equal keys.
    std::vector<std::tuple<std::array<int, 3>, int, int>> faces;
    faces.reserve(4 * static_cast<size_t>(ne));
    for (int e = 0; e < ne; ++e)
        for (int k = 0; k < 4; ++k) {
            std::array<int, 3> f{};
            for (int a = 0, j = 0; a < 4; ++a)
                if (a != k) f[j++] = m.tets(a, e);
            std::sort(f.begin(), f.end());
            faces.emplace_back(f, e, k);
        }
    std::sort(faces.begin(), faces.end());
    adj_ = Eigen::Matrix4Xi::Constant(4, ne, -1);
    children_.assign(static_cast<size_t>(ne), {});
    ringPos_.assign(static_cast<size_t>(ne), -1);
    for (size_t i = 0; i + 1 < faces.size(); ++i)
        if (std::get<0>(faces[i]) == std::get<0>(faces[i + 1])) {
            adj_(std::get<2>(faces[i]), std::get<1>(faces[i])) = std::get<1>(faces[i + 1]);
            adj_(std::get<2>(faces[i + 1]), std::get<1>(faces[i + 1])) = std::get<1>(faces[i]);
            ++i;
        }

    // Original node -> parents.
    ringStart_.assign(static_cast<size_t>(nn) + 1, 0);
    for (int e = 0; e < ne; ++e)
        for (int a = 0; a < 4; ++a) ++ringStart_[static_cast<size_t>(m.tets(a, e)) + 1];
    for (int i = 0; i < nn; ++i) ringStart_[i + 1] += ringStart_[i];
    ring_.resize(4 * static_cast<size_t>(ne));
    std::vector<int> fill(ringStart_.begin(), ringStart_.end() - 1);
    for (int e = 0; e < ne; ++e)
        for (int a = 0; a < 4; ++a) ring_[static_cast<size_t>(fill[m.tets(a, e)]++)] = e;

    parent_.resize(static_cast<size_t>(ne));
    std::iota(parent_.begin(), parent_.end(), 0);
    origNode_.resize(static_cast<size_t>(nn));
    std::iota(origNode_.begin(), origNode_.end(), 0);
    // Room for a stroke's elements and nodes now: grown during a cut, these would copy (and
    // rehash) the whole mesh's worth in one blade step.
    const size_t roomE = static_cast<size_t>(ne) + ne / 4 + 16, roomN = static_cast<size_t>(nn) + nn / 4 + 16;
    parent_.reserve(roomE);
    origNode_.reserve(roomN);
    gluedOf_.reserve(roomE);
    virt_.reserve(static_cast<size_t>(ne / 8 + 64));
    prepared_ = true;
}

void CutEngine::setMassShare(Model& m, int e) const {
    if (m.massShare.cols() != m.elements()) return;  // enrichment lumping: fraction / 4 by default
    const Virtual* it = findVirtual(e);
    const double f = m.fraction(e);
    if (!it || opts_.lumping == MassLumping::Enrichment) {
        m.massShare.col(e).setConstant(f / 4.0);
        return;
    }
    // Shares of the side's integrals, scaled to the side's mass (f, with the parent's own
    // fraction f0 for an embedded element).
    Eigen::Vector4d first, second;
    weightIntegrals(it->piece, first, second);
    const Eigen::Vector4d w = opts_.lumping == MassLumping::RowSum ? first : second;
    const double sum = w.sum();
    if (sum > 0)
        m.massShare.col(e) = f * w / sum;
    else
        m.massShare.col(e).setConstant(f / 4.0);
}

CutResult CutEngine::cut(Model& m, State& s, const CutSurface& surface) {
    NodeValues nodeS;
    return apply(m, s, surface, nextCut_++, nullptr, nullptr, nodeS);
}

void CutEngine::endStroke() { stroke_ = Stroke{}; }

CutResult CutEngine::sweep(Model& m, State& s, const BladeEdge& from, const BladeEdge& to,
                           const std::vector<int>* candidates) {
    const Eigen::Vector3d motion = 0.5 * (to.a + to.b) - 0.5 * (from.a + from.b);
    const Eigen::Vector3d edge = from.b - from.a;
    // A blade at rest sweeps nothing new (keyframe interpolation leaves rounding-level motion).
    if (std::max((to.a - from.a).norm(), (to.b - from.b).norm()) <= 1e-12 * edge.norm()) return {};
    if (!stroke_.active) {
        const Eigen::Vector3d n = edge.cross(motion);
        if (!(n.norm() > 1e-12 * std::max(1e-300, edge.norm() * motion.norm())) || n.norm() == 0) return {};
        stroke_ = Stroke{};
        stroke_.active = true;
        stroke_.cut = nextCut_++;
        stroke_.surface.point = from.a;
        stroke_.surface.normal = n.normalized();
    }
    // The swept quad, projected onto the stroke's plane.
    Eigen::Vector3d u, v;
    planeAxes(stroke_.surface.normal, u, v);
    std::vector<Eigen::Vector2d> q;
    for (const Eigen::Vector3d& p : {from.a, from.b, to.b, to.a}) {
        const Eigen::Vector3d d = p - stroke_.surface.point;
        q.emplace_back(d.dot(u), d.dot(v));
    }
    q = convexHull(q);
    if (q.size() < 3) return {};
    // A translation that continues the previous one (same edge, same direction, starting where
    // it ended) extends the previous parallelogram: their union is the hull of both, exactly. One
    // region per straight stretch keeps the coverage test from growing with the step count.
    const double tol = 1e-9 * std::max({edge.norm(), motion.norm(), stroke_.lastMotion.norm()});
    const bool translation = ((to.b - to.a) - edge).norm() <= tol;
    const bool continues = translation && stroke_.lastTranslation && !stroke_.surface.regions.empty() &&
                           (from.a - stroke_.last.a).norm() <= tol && (from.b - stroke_.last.b).norm() <= tol &&
                           motion.dot(stroke_.lastMotion) > 0 &&
                           motion.cross(stroke_.lastMotion).norm() <= 1e-9 * motion.norm() * stroke_.lastMotion.norm();
    if (continues) {
        auto& prev = stroke_.surface.regions.back();
        prev.insert(prev.end(), q.begin(), q.end());
        prev = convexHull(prev);
    } else {
        stroke_.surface.regions.push_back(std::move(q));
    }
    stroke_.last = to;
    stroke_.lastMotion = motion;
    stroke_.lastTranslation = translation;

    // Elements to test: the candidates and the stroke's watch list from earlier sweeps.
    std::vector<int> cand;
    const std::vector<int>* candPtr = nullptr;
    if (candidates) {
        cand = *candidates;
        cand.insert(cand.end(), stroke_.watch.begin(), stroke_.watch.end());
        std::sort(cand.begin(), cand.end());
        cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
        candPtr = &cand;
    }
    std::vector<int> watch;
    CutResult r = apply(m, s, stroke_.surface, stroke_.cut, candPtr, &watch, stroke_.nodeS, &stroke_.sections);
    stroke_.watch = std::move(watch);
    stroke_.pending = r.pending;
    return r;
}

// One application of a cut surface: the plane's frame, the node distances frozen for the stroke,
// and what the pass found so far.
struct CutEngine::Pass {
    Pass(const CutSurface& surf, int id, NodeValues& distances, std::vector<int>* watch, CutResult& result,
         std::unordered_map<int, Section>* secs)
        : surface(surf), cutId(id), nodeS(distances), watchOut(watch), r(result), sections(secs) {}
    const CutSurface& surface;
    int cutId;
    NodeValues& nodeS;           // signed distance of each node met so far [m]
    std::vector<int>* watchOut;  // elements met but not yet covered (a stroke's), or null
    CutResult& r;
    std::unordered_map<int, Section>* sections;  // the stroke's clipped sides of watched elements, or null
    Eigen::Vector3d n = Eigen::Vector3d::Zero(), u = n, v = n;  // plane normal and in-plane axes
    double d = 0;                                               // plane offset n.x = d [m]
    double tol = 1e-9;                                          // in-polygon tolerance [m]
    int E0 = 0;                                                 // elements before the pass
    struct NewElem {
        int src;
        Virtual virt;
    };
    std::vector<NewElem> fresh;          // the second sides of split elements, to append
    std::vector<int> parents, splitNow;  // parents cut and elements split by this pass

    // Signed distance of a node, frozen for the whole cut (a blade stroke) so that elements cut at
    // different sweeps see the same values at their shared nodes.
    double sAt(const State& s, int node) {
        if (const double* known = nodeS.find(node)) return *known;
        const double val = n.dot(s.x.col(node)) - d;
        nodeS.emplace(node, val);
        return val;
    }

    // A blade step's plane meets elements all across the body, but only those near the swept area
    // can be covered. The cross-section's points are convex combinations of the element's nodes,
    // so when all four nodes, projected, lie beyond one edge line of a region by more than twice
    // insideConvex's tolerance, no point of the section is in that region: skip the two clips.
    bool outsideRegions(const Model& m, const State& s, int e) const {
        Eigen::Vector2d q[4];
        for (int a = 0; a < 4; ++a) {
            const Eigen::Vector3d dx = s.x.col(m.tets(a, e)) - surface.point;
            q[a] = Eigen::Vector2d(dx.dot(u), dx.dot(v));
        }
        for (const auto& poly : surface.regions) {
            const size_t nv = poly.size();
            if (nv < 3) continue;  // never inside
            double area2 = 0;
            for (size_t k = 0; k < nv; ++k)
                area2 += poly[k][0] * poly[(k + 1) % nv][1] - poly[k][1] * poly[(k + 1) % nv][0];
            const double sgn = area2 >= 0 ? 1.0 : -1.0;
            bool separated = false;
            for (size_t k = 0; k < nv && !separated; ++k) {
                const Eigen::Vector2d ed = poly[(k + 1) % nv] - poly[k];
                const double len = ed.norm();
                if (len == 0) continue;
                separated = true;
                for (int a = 0; a < 4 && separated; ++a) {
                    const Eigen::Vector2d dq = q[a] - poly[k];
                    separated = sgn * (ed[0] * dq[1] - ed[1] * dq[0]) / len < -2 * tol;
                }
            }
            if (!separated) return false;
        }
        return true;
    }

    // The side's cross-section (its faces on this cut) as corner weights, into sec.
    void keepSectionPoints(Section& sec) const {
        const ConvexPiece& side = sec.neg.empty() ? sec.pos : sec.neg;
        sec.points = 0;
        for (const PolyFace& f : side.faces) {
            if (f.tag != 4 + cutId) continue;
            for (int vi : f.v) {
                if (sec.points == static_cast<int>(sec.w.size())) {
                    sec.points = -1;
                    return;
                }
                const Eigen::Vector4d w = weightsOf(side.xi[static_cast<size_t>(vi)]);
                for (int a = 0; a < 4; ++a) sec.w[static_cast<size_t>(sec.points)][static_cast<size_t>(a)] = w[a];
                ++sec.points;
            }
        }
    }

    // Coverage: every point of the side's cross-section lies in the cut area. Returns the points
    // inside and the total, or as soon as one is in and one out, (1, 2): partly covered.
    std::pair<int, int> covered(const Model& m, const State& s, int e, const Section& sec) const {
        Eigen::Matrix<double, 3, 4> xe;
        for (int a = 0; a < 4; ++a) xe.col(a) = s.x.col(m.tets(a, e));
        int total = 0, inside = 0;
        auto test = [&](const Eigen::Vector4d& w) {
            Eigen::Vector3d x = Eigen::Vector3d::Zero();
            for (int a = 0; a < 4; ++a) x += w[a] * xe.col(a);
            const Eigen::Vector3d dx = x - surface.point;
            const Eigen::Vector2d p(dx.dot(u), dx.dot(v));
            ++total;
            for (const auto& poly : surface.regions)
                if (insideConvex(poly, p, tol)) {
                    ++inside;
                    break;
                }
            return inside > 0 && inside < total;
        };
        if (sec.points >= 0) {
            for (int k = 0; k < sec.points; ++k)
                if (test(Eigen::Map<const Eigen::Vector4d>(sec.w[static_cast<size_t>(k)].data()))) return {1, 2};
            return {inside, total};
        }
        const ConvexPiece& side = sec.neg.empty() ? sec.pos : sec.neg;
        for (const PolyFace& f : side.faces) {
            if (f.tag != 4 + cutId) continue;
            for (int vi : f.v)
                if (test(weightsOf(side.xi[static_cast<size_t>(vi)]))) return {1, 2};
        }
        return {inside, total};
    }
};

// Element e against the pass's surface: split into two virtual elements when the surface crosses
// it completely (a sliver side merged into the other, CutOptions::minFraction), else left, and
// watched when a bounded surface covers its section only in part.
void CutEngine::visitElement(Model& m, State& s, Pass& pass, int e) {
    if (marked(e, kFused)) return;  // follows its sibling (mergeDebris)
    // done by an earlier sweep of this stroke (most often its last split; a scripted cut may have
    // split it since)
    const int last = lastCutOf(e);
    if (last == pass.cutId) return;
    if (last > pass.cutId)
        for (const Halfspace& hc : findVirtual(e)->hs)
            if (hc.cut == pass.cutId) return;
    CutResult& r = pass.r;
    Halfspace h;
    h.cut = pass.cutId;
    bool anyPos = false, anyNeg = false;
    for (int a = 0; a < 4; ++a) {
        h.s[a] = pass.sAt(s, m.tets(a, e));
        (h.s[a] >= 0 ? anyPos : anyNeg) = true;  // ties go to the positive side
    }
    if (!(anyPos && anyNeg)) return;
    const bool bounded = !pass.surface.regions.empty();
    if (bounded && pass.outsideRegions(m, s, e)) {  // the coverage test below would find nothing
        if (pass.watchOut) pass.watchOut->push_back(e);
        return;
    }
    const Virtual* it = findVirtual(e);
    const ConvexPiece& piece = it ? it->piece : wholeTet();
    Halfspace hn = h, hp = h;
    hn.positive = false;
    hp.positive = true;
    // A stroke's element keeps its sides while it waits to be covered (its piece changes only
    // when this stroke splits it, and its distances are frozen).
    Section local;
    Section* sec = &local;
    const std::array<double, 4> hs{h.s[0], h.s[1], h.s[2], h.s[3]};
    bool clipNow = true;
    if (pass.sections) {
        const auto [at, fresh] = pass.sections->try_emplace(e);
        sec = &at->second;
        clipNow = fresh || sec->s != hs;
    }
    if (clipNow) {
        sec->s = hs;
        sec->neg = clip(piece, hn);
        sec->pos = clip(piece, hp);
        if (bounded) pass.keepSectionPoints(*sec);
    }
    if (sec->neg.empty() && sec->pos.empty()) return;
    if (bounded) {
        const auto [inside, total] = pass.covered(m, s, e, *sec);
        if (inside < total || total == 0) {
            if (pass.watchOut) pass.watchOut->push_back(e);
            r.pending += inside > 0;
            return;
        }
    }
    ConvexPiece neg = std::move(sec->neg), pos = std::move(sec->pos);
    if (sec != &local) pass.sections->erase(e);

    ++r.crossed;
    const int p = parent_[static_cast<size_t>(e)];
    const double fneg = volumeFraction(neg), fpos = volumeFraction(pos);
    Virtual base;
    if (it)
        base = *it;
    else
        base.share = volumeFraction(piece);
    // Shares of the two sides; a sliver side is merged into the other (see CutOptions).
    const double total = base.share, sum = fneg + fpos;
    double sneg = sum > 0 ? total * fneg / sum : 0, spos = total - sneg;
    bool keepNeg = !neg.empty() && sneg >= opts_.minFraction, keepPos = !pos.empty() && spos >= opts_.minFraction;
    if (!keepNeg && !keepPos) (fneg >= fpos ? keepNeg : keepPos) = true;  // never lose a whole element
    r.dropped += (!keepNeg && fneg > 0) + (!keepPos && fpos > 0);
    // The dropped side is no material, but its side of the drawn surface still needs its faces.
    if (!keepNeg && fneg > 0) slivers_.push_back({e, pass.cutId, false, neg});
    if (!keepPos && fpos > 0) slivers_.push_back({e, pass.cutId, true, pos});
    if (!keepNeg) spos = total;
    if (!keepPos) sneg = total;

    const double f0 = fraction0_[p];
    if (keepNeg && keepPos) {
        ++r.split;
        Pass::NewElem ne{e, base};
        ne.virt.piece = std::move(pos);
        ne.virt.share = spos;
        ne.virt.hs.push_back(hp);
        pass.fresh.push_back(std::move(ne));
    }
    Virtual& mine = addVirtual(e);
    mine = std::move(base);
    mine.hs.push_back(keepNeg ? hn : hp);
    setLastCut(e, pass.cutId);
    mine.piece = keepNeg ? std::move(neg) : std::move(pos);
    mine.share = keepNeg ? sneg : spos;
    m.fraction(e) = f0 * mine.share;
    pass.parents.push_back(p);
    pass.splitNow.push_back(e);
}

// The candidates, and each split element's face neighbours in turn until no more split: the cut
// spreads over the covered part of the plane however the body has moved away from the blade. A
// neighbour counts when it shares the face's three nodes (still one body there).
void CutEngine::visitFromCandidates(Model& m, State& s, Pass& pass, const std::vector<int>& candidates) {
    std::vector<int>& queue = visitQueue_;
    queue.clear();
    // elements queued in this pass carry its stamp (no set to build per blade step)
    if (visitMark_.size() < static_cast<size_t>(pass.E0)) visitMark_.resize(static_cast<size_t>(pass.E0), 0);
    if (++visitStamp_ == 0) std::fill(visitMark_.begin(), visitMark_.end(), 0), visitStamp_ = 1;
    auto enqueue = [&](int e) {
        if (e < 0 || e >= pass.E0 || visitMark_[static_cast<size_t>(e)] == visitStamp_) return;
        visitMark_[static_cast<size_t>(e)] = visitStamp_;
        queue.push_back(e);
    };
    for (int e : candidates) enqueue(e);
    size_t done = 0;
    for (size_t head = 0; head < queue.size(); ++head) {
        visitElement(m, s, pass, queue[head]);
        for (; done < pass.splitNow.size(); ++done) {
            const int e = pass.splitNow[done], p = parent_[static_cast<size_t>(e)];
            for (int k = 0; k < 4; ++k) {
                const int q = adj_(k, p);
                if (q < 0) continue;
                for (int g : virtualsOf(q)) {
                    int shared = 0;
                    for (int a = 0; a < 4; ++a)
                        for (int b = 0; b < 4; ++b) shared += m.tets(a, e) == m.tets(b, g);
                    if (shared >= 3) enqueue(g);
                }
            }
        }
    }
    if (pass.watchOut) {
        std::sort(pass.watchOut->begin(), pass.watchOut->end());
        pass.watchOut->erase(std::unique(pass.watchOut->begin(), pass.watchOut->end()), pass.watchOut->end());
    }
}

// Appends the new virtual elements in one go: the parent's rest data, its rotation as warm start.
void CutEngine::appendVirtuals(Model& m, State& s, Pass& pass) {
    if (pass.fresh.empty()) return;
    const int E0 = pass.E0, E1 = E0 + static_cast<int>(pass.fresh.size());
    m.tets.conservativeResize(4, E1);
    m.volume.conservativeResize(E1);
    m.fraction.conservativeResize(E1);
    if (m.massShare.cols() == E0) m.massShare.conservativeResize(4, E1);
    // the widest per-element arrays have room (fem/state.hpp reserveElements), else a quarter more
    if (s.rot.cols() < E1 || s.fe.cols() < E1 || m.DmInv.cols() < E1) reserveElements(m, s, E1 + E1 / 4 + 16);
    for (size_t k = 0; k < pass.fresh.size(); ++k) {
        const int e = E0 + static_cast<int>(k), src = pass.fresh[k].src;
        const int p = parent_[static_cast<size_t>(src)];
        m.tets.col(e) = m.tets.col(src);
        m.DmInv.col(e) = m.DmInv.col(src);
        m.volume(e) = m.volume(src);
        m.fraction(e) = fraction0_[p] * pass.fresh[k].virt.share;
        s.rot.col(e) = s.rot.col(src);
        parent_.push_back(p);
        std::vector<int>& ch = children_[static_cast<size_t>(p)];
        if (!marked(p, kChildren)) ch.assign(1, p), setMark(p, kChildren);
        ch.push_back(e);
        addVirtual(e) = std::move(pass.fresh[k].virt);
        setLastCut(e, pass.cutId);
        pass.r.newElements.push_back(e);
        pass.r.elementSource.push_back(src);
    }
}

CutResult CutEngine::apply(Model& m, State& s, const CutSurface& surface, int cutId, const std::vector<int>* candidates,
                           std::vector<int>* watchOut, NodeValues& nodeS, std::unordered_map<int, Section>* sections) {
    const auto t0 = Clock::now();
    prepare(m);
    CutResult r;
    r.cut = cutId;
    const bool local = candidates != nullptr;  // a blade step: sums over what it touched
    massChange_ = 0;
    r.volumeBefore = local ? volume0_ : m.volume.dot(m.fraction);
    r.massBefore = local ? massRef_ : m.mass.sum();
    if (opts_.lumping != MassLumping::Enrichment && m.massShare.cols() != m.elements()) {
        m.massShare.resize(4, m.elements());
        for (int e = 0; e < m.elements(); ++e) m.massShare.col(e).setConstant(m.fraction(e) / 4.0);
    }
    Pass pass(surface, cutId, nodeS, watchOut, r, sections);
    pass.n = surface.normal.normalized();
    pass.d = pass.n.dot(surface.point);
    planeAxes(pass.n, pass.u, pass.v);
    pass.E0 = m.elements();

    // Split what the surface crosses, append the second sides, then relink the control points.
    if (candidates)
        visitFromCandidates(m, s, pass, *candidates);
    else
        for (int e = 0; e < pass.E0; ++e) visitElement(m, s, pass, e);
    appendVirtuals(m, s, pass);
    std::vector<int>& parents = pass.parents;
    std::sort(parents.begin(), parents.end());
    parents.erase(std::unique(parents.begin(), parents.end()), parents.end());
    if (!parents.empty()) relink(m, s, parents, r, nodeS);
    if (opts_.mergeDebris && r.crossed > 0) mergeDebris(m, s.x, r);
    if (opts_.relaxIterations > 0 && r.crossed > 0) relaxCutNodes(m, s, r);
    if (r.crossed > 0) markLightNodes(m);
    if (local) {
        // every parent cut keeps its material V f0 over its virtual elements
        double before = 0, after = 0;
        for (int p : parents) {
            before += m.volume(p) * fraction0_[p];
            for (int g : virtualsOf(p)) after += m.volume(g) * m.fraction(g);
        }
        r.volumeAfter = r.volumeBefore + (after - before);
        r.massAfter = r.massBefore + massChange_;
    } else {
        r.volumeAfter = m.volume.dot(m.fraction);
        r.massAfter = m.mass.sum();
    }
    r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return r;
}

// Two virtual elements of face-adjacent parents p (face opposite corner k) and q are one body
// across the face when their sides leave part of it to both (Molino et al. 2004).
bool CutEngine::gluedAcross(int e, int p, int k, int g, int q, std::vector<FaceSide>& sides) const {
    const Virtual *ie = findVirtual(e), *ig = findVirtual(g);
    if (!ie && !ig) return true;
    int cp[3], cq[3];
    for (int a = 0, j = 0; a < 4; ++a)
        if (a != k) {
            cp[j] = a;
            cq[j] = localIndex(tets0_, q, tets0_(a, p));
            ++j;
        }
    sides.clear();
    if (ie)
        for (const Halfspace& h : ie->hs) sides.push_back({{h.s[cp[0]], h.s[cp[1]], h.s[cp[2]]}, h.positive});
    if (ig)
        for (const Halfspace& h : ig->hs) sides.push_back({{h.s[cq[0]], h.s[cq[1]], h.s[cq[2]]}, h.positive});
    return faceAreaFraction(sides) > 1e-9;
}

// New nodes: copies of the node they split from, at its rest and current position and velocity.
void CutEngine::appendNodeCopies(Model& m, State& s, const std::vector<NodeCopy>& copies) {
    if (copies.empty()) return;
    const int N0 = m.nodes(), N1 = N0 + static_cast<int>(copies.size());
    m.X.conservativeResize(3, N1);
    for (auto* mat : {&s.x, &s.v, &s.f, &s.a, &s.fExt}) mat->conservativeResize(3, N1);
    m.fixed.resize(static_cast<size_t>(N1), 0);
    // Added mass stays with the node it was put on; a copy starts without.
    if (m.addedMass.size() == N0) {
        m.addedMass.conservativeResize(N1);
        m.addedMass.tail(N1 - N0).setZero();
    }
    for (int k = 0; k < N1 - N0; ++k) {
        const int id = N0 + k, src = copies[static_cast<size_t>(k)].src;
        m.X.col(id) = m.X.col(src);
        s.x.col(id) = s.x.col(src);
        s.v.col(id) = s.v.col(src);
        s.a.col(id) = s.a.col(src);
        s.f.col(id).setZero();
        s.fExt.col(id).setZero();
        origNode_.push_back(copies[static_cast<size_t>(k)].orig);
    }
}

// Masses and incidence of the changed elements. An element of an uncut parent can be re-pointed
// too (its corner's copies were regrouped): its stiffness now couples other nodes, so every row
// it touches is stale, not only the rows of the nodes it left and joined.
void CutEngine::finishRelink(Model& m, const std::vector<int>& parents, const std::vector<int>& repointed,
                             std::vector<int>& changedNodes, CutResult& r) {
    for (int p : parents)
        for (int e : virtualsOf(p)) {
            setMassShare(m, e);
            r.changedElements.push_back(e);
        }
    r.changedElements.insert(r.changedElements.end(), repointed.begin(), repointed.end());
    std::sort(r.changedElements.begin(), r.changedElements.end());
    r.changedElements.erase(std::unique(r.changedElements.begin(), r.changedElements.end()), r.changedElements.end());
    for (int e : r.changedElements)
        for (int a = 0; a < 4; ++a) changedNodes.push_back(m.tets(a, e));
    changedNodes.insert(changedNodes.end(), r.changedNodes.begin(), r.changedNodes.end());  // from followFused
    std::sort(changedNodes.begin(), changedNodes.end());
    changedNodes.erase(std::unique(changedNodes.begin(), changedNodes.end()), changedNodes.end());
    // Only these rows and masses changed: a blade step costs what it cut, not the mesh.
    updateIncidence(m, changedNodes, r.changedElements);
    const Eigen::Index n0 = m.mass.size();
    double before = 0, after = 0;
    for (int i : changedNodes)
        if (i < n0) before += m.mass(i);
    updateMasses(m, changedNodes);
    for (int i : changedNodes) after += m.mass(i);
    for (Eigen::Index i = n0; i < m.nodes(); ++i)  // an appended node no changed element holds
        if (!std::binary_search(changedNodes.begin(), changedNodes.end(), static_cast<int>(i))) after += m.mass(i);
    massChange_ += after - before;
    r.changedNodes = std::move(changedNodes);
}

void CutEngine::relink(Model& m, State& s, const std::vector<int>& parents, CutResult& r, NodeValues& nodeS) {
    // Original nodes whose copies may change: those of the parents the cut touched.
    std::vector<int> nodes;
    for (int p : parents)
        for (int a = 0; a < 4; ++a) nodes.push_back(tets0_(a, p));
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());

    struct Slot {
        int elem, corner, parent;
    };
    std::vector<NodeCopy> copies;
    std::vector<std::pair<int, std::uint8_t>> fixedOf;  // node -> fixed, applied once the arrays have grown
    std::vector<int> changedNodes;
    std::vector<int> repointed;  // elements with a corner moved to another node
    std::vector<Slot> slots;
    std::vector<FaceSide> sides;
    // Scratch reused across the nodes (this runs at every blade step).
    UnionFind uf;
    std::vector<std::vector<int>> comps;
    std::vector<int> rootComp, used, ids, slotStart;
    // A face holds three nodes, and a blade step relinks the rings its earlier steps relinked:
    // each pair of elements across a face is asked about again and again. Whether they are glued
    // depends only on their sides, so the answer is kept, beside the first element, until either
    // element is split again. Two uncut elements are one body (gluedAcross).
    if (gluedOf_.size() < static_cast<size_t>(m.elements())) gluedOf_.resize(static_cast<size_t>(m.elements()));
    auto gluedOnce = [&](int e, int p, int k, int g, int q) {
        if (!marked(e, kVirtual) && !marked(g, kVirtual)) return true;
        const std::uint32_t ve = virtVersion(e), vg = virtVersion(g);
        std::vector<Glued>& kept = gluedOf_[static_cast<size_t>(e)];
        auto it = std::find_if(kept.begin(), kept.end(), [g](const Glued& x) { return x.other == g; });
        if (it == kept.end()) it = kept.insert(kept.end(), Glued{g, 0, 0, false});
        if (it->versionE != ve || it->versionG != vg) *it = {g, ve, vg, gluedAcross(e, p, k, g, q, sides)};
        return it->glued;
    };

    int nextNode = m.nodes();
    for (int N : nodes) {
        slots.clear();
        const int ring0 = ringStart_[N], ring1 = ringStart_[N + 1];
        slotStart.clear();
        for (int i = ring0; i < ring1; ++i) {
            const int p = ring_[static_cast<size_t>(i)];
            const int c = localIndex(tets0_, p, N);
            slotStart.push_back(static_cast<int>(slots.size()));
            ringPos_[static_cast<size_t>(p)] = i - ring0;
            for (int e : virtualsOf(p))
                if (!marked(e, kFused)) slots.push_back({e, c, p});
        }
        slotStart.push_back(static_cast<int>(slots.size()));
        // Sides of one parent are apart by construction; sides of two parents are one body only
        // across a face holding N, so each slot is paired with the slots of its three neighbours
        // there (the earlier slot of a pair asks, as a scan of all pairs would).
        uf.reset(slots.size());
        for (size_t i = 0; i < slots.size(); ++i) {
            const Slot& a = slots[i];
            for (int k = 0; k < 4; ++k) {
                const int q = adj_(k, a.parent);
                if (q < 0 || k == a.corner) continue;
                const int r0 = ringPos_[static_cast<size_t>(q)];
                if (r0 < 0) continue;
                for (int j = std::max(slotStart[r0], static_cast<int>(i) + 1); j < slotStart[r0 + 1]; ++j) {
                    if (uf.find(static_cast<int>(i)) == uf.find(j)) continue;
                    if (gluedOnce(a.elem, a.parent, k, slots[j].elem, q)) uf.join(static_cast<int>(i), j);
                }
            }
        }

        for (int i = ring0; i < ring1; ++i) ringPos_[static_cast<size_t>(ring_[static_cast<size_t>(i)])] = -1;

        // Components; the largest keep existing node ids, the others get new copies of N.
        // (comps keeps its inner vectors between nodes; only the first nComps are this node's.)
        size_t nComps = 0;
        rootComp.assign(slots.size(), -1);
        for (size_t i = 0; i < slots.size(); ++i) {
            const int root = uf.find(static_cast<int>(i));
            if (rootComp[root] < 0) {
                rootComp[root] = static_cast<int>(nComps);
                if (comps.size() <= nComps) comps.emplace_back();
                comps[nComps++].clear();
            }
            comps[rootComp[root]].push_back(static_cast<int>(i));
        }
        const auto compsEnd = comps.begin() + static_cast<std::ptrdiff_t>(nComps);
        std::sort(comps.begin(), compsEnd, [](const auto& a, const auto& b) { return a.size() > b.size(); });
        used.clear();
        for (auto ci = comps.begin(); ci != compsEnd; ++ci) {
            const std::vector<int>& comp = *ci;
            ids.clear();
            for (int i : comp) ids.push_back(m.tets(slots[i].corner, slots[i].elem));
            std::sort(ids.begin(), ids.end());
            int best = -1, bestCount = 0, common = ids.front(), commonCount = 0;
            for (size_t i = 0; i < ids.size();) {
                size_t j = i;
                while (j < ids.size() && ids[j] == ids[i]) ++j;
                const int cnt = static_cast<int>(j - i);
                if (cnt > commonCount) common = ids[i], commonCount = cnt;
                if (cnt > bestCount && std::find(used.begin(), used.end(), ids[i]) == used.end())
                    best = ids[i], bestCount = cnt;
                i = j;
            }
            int id = best;
            if (id < 0) {
                id = nextNode++;
                copies.push_back({common, N});
                r.newNodes.push_back(id);
                if (const double* known = nodeS.find(common)) nodeS.emplace(id, *known);
            }
            used.push_back(id);
            // A copy of a prescribed node stays prescribed when its piece is held: it carries
            // material at that node, or at another prescribed node of its element (a cut through
            // a clamp keeps both sides clamped). A copy serving only pieces that lie away from
            // the support is an enrichment degree of freedom and moves; fixing it would hang a
            // severed piece on the clamp, whose hanging element then inverts (random bar cut
            // sequences, tests/cut).
            bool held = false;
            for (int i : comp) {
                const Virtual* it = findVirtual(slots[i].elem);
                if (!it) {
                    held = true;
                    break;
                }
                for (int a : it->piece.corner)
                    if (a >= 0 && fixed0_[static_cast<size_t>(tets0_(a, slots[i].parent))]) held = true;
                if (held) break;
            }
            fixedOf.emplace_back(id, fixed0_[static_cast<size_t>(N)] && held);
            for (int i : comp) {
                int& cur = m.tets(slots[i].corner, slots[i].elem);
                if (cur != id) {
                    // The element may belong to an uncut parent next to the cut: its nodes
                    // changed, so it is a changed element too (stiffness rows of its other nodes).
                    changedNodes.push_back(cur);
                    changedNodes.push_back(id);
                    repointed.push_back(slots[i].elem);
                    cur = id;
                }
            }
        }
    }

    appendNodeCopies(m, s, copies);
    for (const auto& [id, fx] : fixedOf) m.fixed[static_cast<size_t>(id)] = fx;
    followFused(m, r);

    finishRelink(m, parents, repointed, changedNodes, r);
}

}  // namespace cutsim
