// The hybrid method (thesis sec. 5.2.1; Fierz et al. 2012): the elements whose reduced-one-ring
// step is below a threshold over the simulation step are moved by shape matching (Model::matched,
// fem/shape_matching.hpp) instead of corotational FEM, so they no longer limit the explicit step.
// Identified on load and, locally, after every cut.
#pragma once

#include "fem/model.hpp"
#include "timestep/analyzer.hpp"

#include <vector>

namespace cutsim {

struct HybridOptions {
    double threshold = 1.1;  // an element with an R1R step under threshold * dtSim is matched (thesis: 1.1) [-]
    int maxRounds = 16;      // rounds of marking and local re-estimation
};

struct HybridResult {
    int matched = 0;        // matched elements after the call
    int added = 0;          // elements this call matched
    int rounds = 0;         // rounds of marking
    double dtExact = 0;     // exact step of the FEM part after the call (certified form only) [s]
    int certifyRounds = 0;  // exact solves (certified form only)
    double seconds = 0;     // wall time [s]
};

// Matches the elements under threshold * dtSim among those the last ta.update re-estimated (all
// elements when `all`). A matched element's stiffness leaves K, which changes its neighbours'
// R1R problems: they are re-estimated (ta kept current) and the marking repeats until no element
// is left under. Elements already matched stay matched.
HybridResult matchCritical(Model& m, TimestepAnalyzer& ta, double dtSim, const HybridOptions& opts = {},
                           bool all = false);

// matchCritical, then the exact step of the FEM part; R1R bounds lambda_max from below, so when
// the exact step is still under dtSim the threshold grows by 5% and every element is scanned
// again, until it is not. Throws EigenSolveError when an eigen-solve fails.
HybridResult matchCriticalCertified(Model& m, TimestepAnalyzer& ta, double dtSim, const HybridOptions& opts = {},
                                    bool all = false);

}  // namespace cutsim
