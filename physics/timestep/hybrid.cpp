#include "timestep/hybrid.hpp"

#include "util/stopwatch.hpp"

#include <algorithm>

namespace cutsim {

namespace {

// One marking pass over `scan` at threshold dtThr; returns the elements it matched.
std::vector<int> markUnder(Model& m, const TimestepAnalyzer& ta, const std::vector<int>& scan, double dtThr) {
    std::vector<int> added;
    const Eigen::VectorXd& r1r = ta.estimates().r1r;
    if (m.matched.size() < static_cast<size_t>(m.elements())) m.matched.resize(static_cast<size_t>(m.elements()), 0);
    for (const int e : scan)
        if (!m.matched[static_cast<size_t>(e)] && r1r(e) < dtThr) {
            m.matched[static_cast<size_t>(e)] = 1;
            added.push_back(e);
        }
    if (!added.empty()) {
        m.matchedList.insert(m.matchedList.end(), added.begin(), added.end());
        std::sort(m.matchedList.begin(), m.matchedList.end());
    }
    return added;
}

std::vector<int> allElements(const Model& m) {
    std::vector<int> all(static_cast<size_t>(m.elements()));
    for (int e = 0; e < m.elements(); ++e) all[static_cast<size_t>(e)] = e;
    return all;
}

// Marks and re-estimates until nothing under dtThr is left among what each update re-estimated.
void markRounds(Model& m, TimestepAnalyzer& ta, std::vector<int> scan, double dtThr, int maxRounds, HybridResult& res) {
    for (int round = 0; round < maxRounds; ++round) {
        const std::vector<int> added = markUnder(m, ta, scan, dtThr);
        if (added.empty()) break;
        ++res.rounds;
        res.added += static_cast<int>(added.size());
        ta.update(m, added);  // their stiffness left the rows of their nodes
        scan = ta.lastElements();
    }
}

}  // namespace

HybridResult matchCritical(Model& m, TimestepAnalyzer& ta, double dtSim, const HybridOptions& opts, bool all) {
    Stopwatch sw;
    HybridResult res;
    markRounds(m, ta, all ? allElements(m) : ta.lastElements(), opts.threshold * dtSim, opts.maxRounds, res);
    res.matched = static_cast<int>(m.matchedList.size());
    res.seconds = sw.seconds();
    return res;
}

HybridResult matchCriticalCertified(Model& m, TimestepAnalyzer& ta, double dtSim, const HybridOptions& opts, bool all) {
    Stopwatch sw;
    HybridResult res = matchCritical(m, ta, dtSim, opts, all);
    double factor = opts.threshold;
    for (;;) {
        res.dtExact = ta.exact(m).dt;
        ++res.certifyRounds;
        if (res.dtExact >= dtSim || res.certifyRounds > opts.maxRounds) break;
        factor *= 1.05;
        const int before = res.added;
        markRounds(m, ta, allElements(m), factor * dtSim, opts.maxRounds, res);
        if (res.added == before) break;  // nothing left to match: the step is what it is
    }
    res.matched = static_cast<int>(m.matchedList.size());
    res.seconds = sw.seconds();
    return res;
}

}  // namespace cutsim
