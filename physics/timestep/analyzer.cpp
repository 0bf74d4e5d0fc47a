#include "timestep/analyzer.hpp"
#include "util/stopwatch.hpp"

#include <algorithm>
#include <chrono>
#include <limits>

namespace cutsim {

namespace {
// A local update is a latency path: a parallel region on a busy machine can wait a whole
// scheduler slice for its other thread, which costs more than a small update in one. Threads only
// for milliseconds of work (as forces.cpp's kParallelElements).
constexpr int kParallelUpdate = 2048;
constexpr int kChunk = 64;  // elements per task: the estimators run 8 at a time on vector lanes

double minOf(const Eigen::VectorXd& v) { return v.size() ? v.minCoeff() : std::numeric_limits<double>::infinity(); }
}  // namespace

void TimestepAnalyzer::compute(const Model& m) {
    const auto t0 = WallClock::now();
    rows_ = assembleStiffnessRows(m);
    diag_ = assembleStiffnessDiagonal(m);
    est_.resize(m.elements());
    estimateElements(m, rows_, diag_, nullptr, est_);
    shapes_ = shapeMeasures(m);
    nodeBound_.resize(m.nodes());
    double mx = 0;
#pragma omp parallel for schedule(static) reduction(max : mx) if (m.nodes() > 2000)
    for (int i = 0; i < m.nodes(); ++i) {
        nodeBound_(i) = gershgorinNodeBound(m, rows_, i);
        mx = std::max(mx, nodeBound_(i));
    }
    maxBound_ = mx;
    nodeStamp_.assign(m.nodes(), 0);
    elemStamp_.assign(m.elements(), 0);
    geomStamp_.assign(m.elements(), 0);
    stamp_ = 0;
    free_.resize(m.nodes());
    for (int i = 0; i < m.nodes(); ++i) free_[i] = m.invMass(i) > 0;
    elems_.clear();
    nodes_.clear();
    ownPending_.clear();
    ownMark_.assign(m.elements(), 0);
    stats_ = {true, m.nodes(), m.elements(), m.nodes(), secondsSince(t0)};
}

void TimestepAnalyzer::update(const Model& m, const std::vector<int>& changedElements,
                              const std::vector<int>& changedNodes, bool deferOwn) {
    const int oldNodes = static_cast<int>(rows_.nbr.size()), oldElems = static_cast<int>(est_.r1r.size());
    if (m.nodes() < oldNodes || m.elements() < oldElems || oldElems == 0) {
        compute(m);
        return;
    }
    const auto t0 = WallClock::now();
    const bool waitOwn = deferOwn || ownPending();
    // Appended nodes and elements.
    if (m.nodes() > oldNodes) {
        rows_.nbr.resize(m.nodes());
        rows_.block.resize(m.nodes());
        diag_.conservativeResize(3, m.nodes());
        nodeBound_.conservativeResize(m.nodes());
        nodeStamp_.resize(m.nodes(), 0);
        free_.resize(m.nodes(), 0);
    }
    if (m.elements() > oldElems) {
        for (Eigen::VectorXd* v : {&est_.r1r, &est_.hs, &est_.hp}) v->conservativeResize(m.elements());
        elemStamp_.resize(m.elements(), 0);
        geomStamp_.resize(m.elements(), 0);
        ownMark_.resize(m.elements(), 0);
    }
    if (++stamp_ == 0) {  // wrapped: clear the stamps
        std::fill(nodeStamp_.begin(), nodeStamp_.end(), 0);
        std::fill(elemStamp_.begin(), elemStamp_.end(), 0);
        std::fill(geomStamp_.begin(), geomStamp_.end(), 0);
        stamp_ = 1;
    }
    // N: nodes whose row of K, diagonal or mass changed.
    std::vector<int>& nodes = nodes_;
    nodes.clear();
    auto markNode = [&](int i) {
        if (nodeStamp_[i] != stamp_) nodeStamp_[i] = stamp_, nodes.push_back(i);
    };
    // G: elements whose own data changed (rest shape, nodes, or which of their nodes are free).
    std::vector<int>& geom = geomElems_;
    geom.clear();
    auto markGeom = [&](int e) {
        if (geomStamp_[e] != stamp_) geomStamp_[e] = stamp_, geom.push_back(e);
    };
    for (int e : changedElements) {
        markGeom(e);
        for (int a = 0; a < 4; ++a) markNode(m.tets(a, e));
    }
    for (int i : changedNodes) markNode(i);
    for (int i = oldNodes; i < m.nodes(); ++i) markNode(i);
    for (int e = oldElems; e < m.elements(); ++e) markGeom(e);
    const int nChanged = static_cast<int>(nodes.size());
#pragma omp parallel for schedule(dynamic, 16) if (nChanged > kParallelUpdate)
    for (int k = 0; k < nChanged; ++k) {
        const int i = nodes[k];
        assembleStiffnessRow(m, i, rows_.nbr[i], rows_.block[i]);
        diag_.col(i) = nodeStiffnessDiagonal(m, i);
    }
    // Elements with a node in N: their K_r, M_r or D_r changed (R1R, Hs, Hp). A node that became
    // fixed or free also changes the isolated element estimate of its elements.
    std::vector<int>& elems = elems_;
    elems.clear();
    for (int k = 0; k < nChanged; ++k) {
        const int i = nodes[k];
        const std::uint8_t isFree = m.invMass(i) > 0;
        const bool flipped = free_[i] != isFree || i >= oldNodes;
        free_[i] = isFree;
        for (int s = m.nodeSlotStart[i]; s < m.nodeSlotEnd[i]; ++s) {
            const int e = m.nodeSlots[s] / 4;
            if (elemStamp_[e] != stamp_) elemStamp_[e] = stamp_, elems.push_back(e);
            if (flipped) markGeom(e);
        }
    }
    const int nElems = static_cast<int>(elems.size());
#pragma omp parallel for schedule(static) if (nElems > kParallelUpdate)
    for (int b = 0; b < nElems; b += kChunk)
        estimateOneRing(m, rows_, diag_, elems.data() + b, std::min(kChunk, nElems - b), est_);
    // Le, the isolated element estimate and the shape measures see only the element itself (rest
    // positions, volume, DmInv, fixed nodes): the one-ring around it does not change them.
    for (int e : geom)
        if (!ownMark_[static_cast<size_t>(e)]) ownMark_[static_cast<size_t>(e)] = 1, ownPending_.push_back(e);
    if (!waitOwn) refreshOwn(m);
    // Gershgorin rows that see a changed block or mass: the nodes of those elements, plus N.
    for (int e : elems)
        for (int a = 0; a < 4; ++a) markNode(m.tets(a, e));
    const int nBounds = static_cast<int>(nodes.size());
#pragma omp parallel for schedule(static) if (nBounds > kParallelUpdate)
    for (int k = 0; k < nBounds; ++k) nodeBound_(nodes[k]) = gershgorinNodeBound(m, rows_, nodes[k]);
    maxBound_ = nodeBound_.size() ? nodeBound_.maxCoeff() : 0.0;
    stats_ = {false, nChanged, nElems, nBounds, secondsSince(t0)};
}

void TimestepAnalyzer::refreshOwn(const Model& m) {
    if (est_.le.size() < m.elements()) {
        for (Eigen::VectorXd* v :
             {&est_.le, &est_.element, &shapes_.volumeLength, &shapes_.harmonicVolumeLength, &shapes_.minSineDihedral,
              &shapes_.radiusRatio, &shapes_.meanRatio, &shapes_.charLength})
            v->conservativeResize(m.elements());
    }
    const int n = static_cast<int>(ownPending_.size());
#pragma omp parallel for schedule(static) if (n > kParallelUpdate)
    for (int b = 0; b < n; b += kChunk) {
        const int count = std::min(kChunk, n - b);
        estimateOwn(m, ownPending_.data() + b, count, est_);
        for (int k = b; k < b + count; ++k) shapes_.set(ownPending_[k], elementShape(m, ownPending_[k]));
    }
    for (int e : ownPending_) ownMark_[static_cast<size_t>(e)] = 0;
    ownPending_.clear();
}

void TimestepAnalyzer::updateMovedNodes(const Model& m, const std::vector<int>& movedNodes) {
    std::vector<int> elems;
    std::vector<char> seen(m.elements(), 0);
    for (int i : movedNodes)
        for (int s = m.nodeSlotStart[i]; s < m.nodeSlotEnd[i]; ++s) {
            const int e = m.nodeSlots[s] / 4;
            if (!seen[e]) seen[e] = 1, elems.push_back(e);
        }
    update(m, elems, movedNodes);
}

double TimestepAnalyzer::minR1r() const { return minOf(est_.r1r); }

TimestepAnalyzer::Minima TimestepAnalyzer::minDt() const {
    return {minOf(est_.r1r), minOf(est_.hs), minOf(est_.hp), minOf(est_.le), minOf(est_.element)};
}

std::vector<std::pair<std::string, double>> correlationsWithR1R(const ElementEstimates& est,
                                                                const ShapeMeasures& shapes) {
    const Eigen::VectorXd& r = est.r1r;
    return {{"volume_length", pearson(shapes.volumeLength, r)},
            {"harmonic_volume_length", pearson(shapes.harmonicVolumeLength, r)},
            {"min_sine_dihedral", pearson(shapes.minSineDihedral, r)},
            {"radius_ratio", pearson(shapes.radiusRatio, r)},
            {"mean_ratio", pearson(shapes.meanRatio, r)},
            {"char_length", pearson(shapes.charLength, r)},
            {"hs", pearson(est.hs, r)},
            {"hp", pearson(est.hp, r)},
            {"le", pearson(est.le, r)},
            {"element", pearson(est.element, r)}};
}

}  // namespace cutsim