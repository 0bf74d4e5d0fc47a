// Time-step analysis of a model kept up to date locally: computed once, then after a cut or a
// mesh improvement only the elements whose one-ring changed are recomputed (docs/method.md sec. 3).
#pragma once

#include "fem/model.hpp"
#include "timestep/quality.hpp"
#include "timestep/timestep.hpp"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace cutsim {

// Pearson r of each shape measure and estimator against the R1R dt, across elements
// (thesis figs. 4.3, 4.12). Names: volume_length, harmonic_volume_length, min_sine_dihedral,
// radius_ratio, mean_ratio, char_length, hs, hp, le, element.
std::vector<std::pair<std::string, double>> correlationsWithR1R(const ElementEstimates& est,
                                                                const ShapeMeasures& shapes);

class TimestepAnalyzer {
public:
    TimestepAnalyzer() = default;
    explicit TimestepAnalyzer(const Model& m) { compute(m); }

    // Everything from scratch: stiffness rows, nodal diagonals, Gershgorin rows, per-element
    // estimates and shape measures. No global eigen-solve (see exact()).
    void compute(const Model& m);

    // Local update after the caller changed the model (volumes, fractions, positions with DmInv,
    // fixed nodes, appended nodes or elements) and refreshed it (updateMasses, buildIncidence).
    // changedElements: elements whose geometry, fraction or nodes changed, or that are new.
    // changedNodes: nodes whose mass or incident elements changed without being in a changed
    // element (e.g. a node an element was re-pointed away from, a node newly fixed).
    // Fewer nodes or elements than before means renumbering: falls back to compute().
    // With deferOwn, what sees only the element itself (Le, the isolated element estimate and the
    // shape measures, which no step depends on) waits for refreshOwn(): a blade step then grows
    // and fills three per-element arrays, not eleven. It waits too while earlier updates left some.
    void update(const Model& m, const std::vector<int>& changedElements, const std::vector<int>& changedNodes = {},
                bool deferOwn = false);
    // Brings Le, the isolated element estimate and the shape measures of the elements updates
    // left waiting up to date (sized to the model's elements).
    void refreshOwn(const Model& m);
    bool ownPending() const { return !ownPending_.empty() || est_.le.size() < est_.r1r.size(); }
    // Nodes moved (rest positions, DmInv and volumes updated by the caller): their elements changed.
    void updateMovedNodes(const Model& m, const std::vector<int>& movedNodes);

    // Exact global value from the current rows (Lanczos; throws EigenSolveError).
    ExactResult exact(const Model& m, const ExactOptions& opts = {}) const { return exactCriticalDt(m, rows_, opts); }

    // r1r, hs and hp are always current; le, element and shapes() after refreshOwn() when an
    // update left some waiting (ownPending()).
    const ElementEstimates& estimates() const { return est_; }
    const ShapeMeasures& shapes() const { return shapes_; }
    const StiffnessRows& rows() const { return rows_; }
    const Eigen::Matrix3Xd& stiffnessDiagonal() const { return diag_; }  // (3 x nNodes) [N/m]
    const Eigen::VectorXd& nodeBounds() const { return nodeBound_; }     // Gershgorin rows [1/s^2]
    double certifiedLambda() const { return maxBound_; }                 // >= lambda_max [1/s^2]
    double certifiedDt() const { return dtFromLambda(maxBound_); }       // <= exact dt [s]

    // Smallest per-element estimate of each kind [s].
    struct Minima {
        double r1r, hs, hp, le, element;
    };
    Minima minDt() const;
    double minR1r() const;  // minDt().r1r alone (after each cut)

    std::vector<std::pair<std::string, double>> correlations() const { return correlationsWithR1R(est_, shapes_); }

    struct UpdateStats {
        bool full = false;   // last call recomputed everything
        int nodes = 0;       // stiffness rows rebuilt
        int elements = 0;    // elements re-estimated
        int bounds = 0;      // Gershgorin rows recomputed
        double seconds = 0;  // wall time
    };
    const UpdateStats& lastUpdate() const { return stats_; }
    // Elements whose one-ring estimates the last update() recomputed (empty after compute()).
    const std::vector<int>& lastElements() const { return elems_; }
    // Nodes whose Gershgorin row the last update() recomputed (empty after compute()).
    const std::vector<int>& lastNodes() const { return nodes_; }

private:
    StiffnessRows rows_;
    Eigen::Matrix3Xd diag_;
    Eigen::VectorXd nodeBound_;
    double maxBound_ = 0;
    ElementEstimates est_;
    ShapeMeasures shapes_;
    UpdateStats stats_;
    // Scratch for the local update: a node / element is marked when its stamp equals stamp_.
    std::vector<unsigned> nodeStamp_, elemStamp_, geomStamp_;
    unsigned stamp_ = 0;
    std::vector<std::uint8_t> free_;              // invMass > 0 when last analysed (nNodes)
    std::vector<int> nodes_, elems_, geomElems_;  // scratch lists, kept to avoid allocating per update
    std::vector<int> ownPending_;                 // elements whose own estimates wait (refreshOwn)
    std::vector<std::uint8_t> ownMark_;           // 1: in ownPending_
};

}  // namespace cutsim
