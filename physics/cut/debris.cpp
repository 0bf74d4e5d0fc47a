// The cut engine's clean-up after a split (cut/xfem.hpp): debris fused to the piece it hangs
// from, the new nodes relaxed, the light nodes marked.
#include "cut/xfem.hpp"

#include "fem/forces.hpp"
#include "mesh/mesh.hpp"

#include <algorithm>
#include <vector>

namespace cutsim {
void CutEngine::mergeDebris(Model& m, const Eigen::Matrix3Xd& x, CutResult& r) {
    // Pieces through the changed elements, explored over shared nodes. An exploration stops at a
    // prescribed node or past kMaxElems elements (that piece is not debris); marks are per
    // exploration, so an element reached once is never explored again in this cut.
    constexpr size_t kMaxElems = 64;
    std::vector<int>& mark = pieceMark_;  // stamps above `base` are this cut's (no pass over all elements)
    if (pieceStamp_ > (1 << 30)) std::fill(mark.begin(), mark.end(), 0), pieceStamp_ = 0;
    mark.resize(static_cast<size_t>(m.elements()), 0);
    std::vector<int> piece, sibling;
    const int base = pieceStamp_;
    int& stamp = pieceStamp_;
    for (int start : r.changedElements) {
        if (mark[static_cast<size_t>(start)] > base) continue;
        ++stamp;
        piece.assign(1, start);
        mark[static_cast<size_t>(start)] = stamp;
        bool held = false;
        double vol = 0, vref = 0;  // piece volume; largest parent volume in it [m^3]
        for (size_t k = 0; k < piece.size() && !held && piece.size() <= kMaxElems; ++k) {
            const int e = piece[k];
            vol += m.volume(e) * m.fraction(e);
            vref = std::max(vref, m.volume(e));
            for (int a = 0; a < 4 && !held; ++a) {
                const int node = m.tets(a, e);
                held = m.fixed[static_cast<size_t>(node)] != 0;
                for (int sl = m.nodeSlotStart[node]; sl < m.nodeSlotEnd[node]; ++sl) {
                    const int g = m.nodeSlots[static_cast<size_t>(sl)] / 4;
                    if (mark[static_cast<size_t>(g)] <= base) {
                        mark[static_cast<size_t>(g)] = stamp;
                        piece.push_back(g);
                    }
                }
            }
        }
        if (held || piece.size() > kMaxElems || vol >= vref) continue;
        // Not on an embedded object's interface (parent share < 1): there a piece's volume is the
        // material it holds, its elements carry the object's surface, and gluing it to its sibling
        // would move that surface to the other side.
        bool embedded = false;
        for (int e : piece) embedded = embedded || fraction0_[parent_[static_cast<size_t>(e)]] < 1;
        if (embedded) continue;
        // Each element needs a sibling outside the piece near its place: the other side of this
        // cut shares its corners' positions; a side split off by an earlier cut or sweep may have
        // moved apart since. The nearest within fuseReach element sizes (cbrt V) is taken, the
        // larger on ties; an element fused before follows its sibling.
        sibling.assign(piece.size(), -1);
        bool all = true;
        for (size_t k = 0; k < piece.size() && all; ++k) {
            const int e = piece[k];
            if (marked(e, kFused)) continue;
            const double h = std::cbrt(m.volume(e)), tie = 1e-9 * h;
            double best = std::max(opts_.fuseReach * h, tie);
            for (int g : virtualsOf(parent_[static_cast<size_t>(e)])) {
                if (mark[static_cast<size_t>(g)] == stamp) continue;
                double apart = 0;
                for (int a = 0; a < 4; ++a) apart = std::max(apart, (x.col(m.tets(a, e)) - x.col(m.tets(a, g))).norm());
                const bool nearer = apart < best - tie, equal = std::abs(apart - best) <= tie;
                if (nearer || (equal && sibling[k] >= 0 && m.fraction(g) > m.fraction(sibling[k])) ||
                    (equal && sibling[k] < 0)) {
                    sibling[k] = g;
                    best = std::min(best, apart);
                }
            }
            all = sibling[k] >= 0;
        }
        if (!all) continue;
        for (size_t k = 0; k < piece.size(); ++k)
            if (sibling[k] >= 0) fusedTo_[piece[k]] = sibling[k], setMark(piece[k], kFused);
        ++r.merged;
    }
    if (r.merged == 0) return;
    followFused(m, r);
    const double before = m.mass.sum();
    updateMasses(m);
    massChange_ += m.mass.sum() - before;
    buildIncidence(m);
    std::sort(r.changedElements.begin(), r.changedElements.end());
    r.changedElements.erase(std::unique(r.changedElements.begin(), r.changedElements.end()), r.changedElements.end());
    std::sort(r.changedNodes.begin(), r.changedNodes.end());
    r.changedNodes.erase(std::unique(r.changedNodes.begin(), r.changedNodes.end()), r.changedNodes.end());
}

void CutEngine::relaxCutNodes(const Model& m, State& s, const CutResult& r) const {
    std::vector<int> nodes;
    for (int n : r.changedNodes) {
        if (n >= m.nodes() || m.invMass(n) == 0) continue;
        bool onlyCut = m.nodeSlotStart[n] < m.nodeSlotEnd[n];
        for (int sl = m.nodeSlotStart[n]; sl < m.nodeSlotEnd[n] && onlyCut; ++sl)
            onlyCut = marked(m.nodeSlots[static_cast<size_t>(sl)] / 4, kVirtual);
        if (onlyCut) nodes.push_back(n);
    }
    relaxNodes(m, s, nodes, opts_.relaxIterations);
}

void CutEngine::markLightNodes(Model& m) const { cutsim::markLightNodes(m, mass0_, opts_.lightShare, &origNode_); }

// Points every fused element at the nodes of the sibling it follows (through chains of fusions);
// returns whether any element changed. Changed elements and their old and new nodes go into r.
bool CutEngine::followFused(Model& m, CutResult& r) const {
    bool any = false;
    for (const auto& [e, first] : fusedTo_) {
        int g = first;  // a piece is never fused to itself, so chains end; the cap is a guard
        for (int hop = 0; hop < 64; ++hop) {
            const auto it = fusedTo_.find(g);
            if (it == fusedTo_.end()) break;
            g = it->second;
        }
        if (m.tets.col(e) == m.tets.col(g)) continue;
        for (int a = 0; a < 4; ++a) r.changedNodes.push_back(m.tets(a, e));
        m.tets.col(e) = m.tets.col(g);
        for (int a = 0; a < 4; ++a) r.changedNodes.push_back(m.tets(a, e));
        r.changedElements.push_back(e);
        any = true;
    }
    return any;
}

}  // namespace cutsim
