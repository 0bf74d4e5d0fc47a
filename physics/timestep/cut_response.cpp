#include "timestep/cut_response.hpp"

#include "util/stopwatch.hpp"

#include <cmath>

namespace cutsim {

CutResponseResult CutResponse::apply(Model& m, TimestepAnalyzer& ta, const std::vector<int>& changedElements,
                                     const std::vector<int>& changedNodes, bool defer) {
    Stopwatch sw;
    CutResponseResult r;
    const bool solveNow = o_.exact && !defer;
    // a deferred change leaves the estimates no step reads for settle()
    ta.update(m, changedElements, changedNodes, defer);
    // the rows the change may have raised (the floor and the hybrid below only lower rows)
    if (!solveNow && !o_.hybrid && o_.dtCertified > 0) raised_ = ta.lastNodes();
    const bool holdFloor = !o_.hybrid && o_.dtFloor > 0 && std::isfinite(o_.dtFloor);
    if (holdFloor && o_.floorHybrid)
        r.floorMatched = matchCritical(m, ta, o_.dtFloor, HybridOptions{o_.floorHybridThreshold});
    if (holdFloor) r.floor = holdStepFloor(m, ta, o_.dtFloor);
    if (o_.hybrid && !solveNow) r.hybrid = matchCritical(m, ta, o_.hybridDtSim, HybridOptions{o_.hybridThreshold});
    // Until an exact solve, the certified step is the step's only backing: hold it where the change
    // reached (the rows the updates above recomputed; mass only lowers the rows around it).
    if (!solveNow && !o_.hybrid && o_.dtCertified > 0) r.certified = holdCertifiedFloor(m, ta, o_.dtCertified, raised_);
    r.updateSeconds = sw.seconds();
    if (!solveNow) {
        r.deferred = o_.exact;
        owed_ = owed_ || o_.exact;
        return r;
    }
    return solve(m, ta, r);
}

CutResponseResult CutResponse::settle(Model& m, TimestepAnalyzer& ta) {
    if (ta.ownPending()) ta.refreshOwn(m);
    if (!owed_) return {};
    return solve(m, ta, {});
}

CutResponseResult CutResponse::solve(Model& m, TimestepAnalyzer& ta, CutResponseResult r) {
    Stopwatch sw;
    owed_ = false;
    if (o_.hybrid) {
        r.hybrid = matchCriticalCertified(m, ta, o_.hybridDtSim, HybridOptions{o_.hybridThreshold});
        r.exact = r.hybrid.dtExact;
    } else if (o_.dtFloor > 0 && std::isfinite(o_.dtFloor)) {
        r.topUp = topUpStepFloor(m, ta, o_.dtFloor);
        r.exact = r.topUp.dtAfter;
    } else {
        r.exact = ta.exact(m).dt;
    }
    r.exactSeconds = sw.seconds();
    return r;
}

}  // namespace cutsim
