// What follows a topology change (docs/method.md, "After a cut"): the one sequence that the
// simulation loop, the benchmarks and the stress tests run, so that what they measure is the
// product's path.
//
//   1. local update of the estimators and the Gershgorin rows around the change (no solve)
//   2. the hybrid's matching, or the step floor's local mass scaling (R1R problems)
//   3. either the exact step now (Lanczos; the floor topped up with global modes when still under
//      it, the hybrid's threshold raised) or, for a deferred change, the certified floor: the
//      changed Gershgorin rows held under the aim, so the certified step backs the step taken
//      until the owed exact solve runs (settle(): a blade's stroke ends).
#pragma once

#include "fem/model.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/floor.hpp"
#include "timestep/hybrid.hpp"

#include <limits>
#include <vector>

namespace cutsim {

struct CutResponseOptions {
    double dtFloor = 0;                 // step floor [s] (0: none; the hybrid holds none)
    bool floorHybrid = false;           // under the floor, match by shape matching before adding mass
    double floorHybridThreshold = 1.0;  // ... the elements under this x dtFloor
    bool hybrid = false;                // the hybrid method: critical elements matched, no mass added
    double hybridDtSim = 0;             // the hybrid's simulation step [s]
    double hybridThreshold = 1.1;
    bool exact = true;  // solve the exact step (now, or at settle() for deferred changes); false: never
    // Aim of the certified floor for changes whose exact step is not solved now [s]: the smaller of
    // the step floor and the uncut object's certified step, so the certified step never falls
    // below what it was before the cut or under the floor (0: none).
    double dtCertified = 0;
};

struct CutResponseResult {
    StepFloorResult floor;      // R1R mass scaling
    StepFloorResult certified;  // Gershgorin rows held (deferred or unsolved changes)
    HybridResult floorMatched;  // cutting.floor_method "hybrid"
    HybridResult hybrid;
    KeepStepResult topUp;                                     // the floor's global top-up after the exact solve
    double exact = std::numeric_limits<double>::quiet_NaN();  // exact step after [s]; NaN: not solved
    double updateSeconds = 0;                                 // steps 1-2 and the certified floor [s]
    double exactSeconds = 0;                                  // the exact solve and what it topped up [s]
    bool deferred = false;                                    // the exact step is owed (settle())
    double addedMass() const { return floor.addedMass + certified.addedMass + topUp.addedMass; }
};

class CutResponse {
public:
    CutResponse() = default;
    explicit CutResponse(const CutResponseOptions& o) : o_(o) {}
    const CutResponseOptions& options() const { return o_; }

    // After the caller changed the model (the cut engine's changed elements and nodes). With
    // `defer` the exact solve waits for settle() and the certified floor backs the step meanwhile.
    // Throws EigenSolveError when an eigen-solve fails.
    CutResponseResult apply(Model& m, TimestepAnalyzer& ta, const std::vector<int>& changedElements,
                            const std::vector<int>& changedNodes, bool defer = false);
    // The exact solve owed by deferred changes, with the floor's top-up or the hybrid's
    // certification; an empty result (exact NaN) when nothing is owed. Brings the estimates
    // deferred changes left waiting up to date (TimestepAnalyzer::refreshOwn) either way.
    CutResponseResult settle(Model& m, TimestepAnalyzer& ta);
    bool owed() const { return owed_; }

private:
    CutResponseResult solve(Model& m, TimestepAnalyzer& ta, CutResponseResult r);

    CutResponseOptions o_;
    bool owed_ = false;
    std::vector<int> raised_;  // scratch: nodes whose rows the last change may have raised
};

}  // namespace cutsim
