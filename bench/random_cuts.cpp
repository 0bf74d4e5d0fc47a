#include "bench/random_cuts.hpp"

#include "fem/integrate.hpp"
#include "mesh/generate.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/cut_response.hpp"
#include "timestep/floor.hpp"
#include "timestep/hybrid.hpp"
#include "util/stopwatch.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace cutsim {

Model randomCutLiverModel(const TetMesh& liverInches, double clampZ) {
    TetMesh mesh = liverInches;
    mesh.X *= 0.0254;
    Model m = buildModel(mesh, Material{});
    m.gravity = Eigen::Vector3d(0, -9.81, 0);
    for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(2, i) < clampZ;
    m.massDamping = 5;
    updateMasses(m);
    return m;
}

Model randomCutBarModel() {
    Model m = buildModel(boxMesh(0.1, 0.02, 0.02, 10, 2, 2), Material{});
    m.gravity = Eigen::Vector3d(0, 0, -9.81);
    for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(0, i) < 1e-9;
    m.massDamping = 5;
    updateMasses(m);
    return m;
}

namespace {

// Elements, volume share and prescribed nodes of the piece (nodes joined by elements) holding e.
void pieceOf(const Model& m, int e, RandomCutRun& r) {
    std::vector<int> p(static_cast<size_t>(m.nodes()));
    for (int i = 0; i < m.nodes(); ++i) p[static_cast<size_t>(i)] = i;
    auto find = [&](int i) {
        while (p[static_cast<size_t>(i)] != i)
            i = p[static_cast<size_t>(i)] = p[static_cast<size_t>(p[static_cast<size_t>(i)])];
        return i;
    };
    for (int k = 0; k < m.elements(); ++k)
        for (int a = 1; a < 4; ++a) p[static_cast<size_t>(find(m.tets(a, k)))] = find(m.tets(0, k));
    const int root = find(m.tets(0, e));
    double vol = 0;
    r.pieceElems = 0;
    for (int k = 0; k < m.elements(); ++k)
        if (find(m.tets(0, k)) == root) {
            ++r.pieceElems;
            vol += m.volume(k) * m.fraction(k);
        }
    r.pieceVolume = vol / m.volume.dot(m.fraction);
    r.pieceFixed = 0;
    for (int i = 0; i < m.nodes(); ++i) r.pieceFixed += m.fixed[static_cast<size_t>(i)] && find(i) == root;
}

}  // namespace

CutSurface randomCutPlane(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::mt19937& rng) {
    std::uniform_real_distribution<double> uni(0, 1);
    CutSurface cs;
    for (int k = 0; k < 3; ++k) cs.point[k] = lo[k] + (0.15 + 0.7 * uni(rng)) * (hi[k] - lo[k]);
    cs.normal = Eigen::Vector3d(uni(rng) - 0.5, uni(rng) - 0.5, uni(rng) - 0.5).normalized();
    return cs;
}

RandomCutRun runRandomCutSequence(const Model& base, double dt0, unsigned seed, int run, int stepsBetween,
                                  const RandomCutOptions& ro) {
    std::seed_seq seq{seed, static_cast<unsigned>(run)};
    std::mt19937 rng(seq);
    std::uniform_real_distribution<double> uni(0, 1);
    const Eigen::Vector3d lo = base.X.rowwise().minCoeff(), hi = base.X.rowwise().maxCoeff();
    RandomCutRun out;
    Model m = base;
    const double totalMass = m.mass.sum();
    State s = makeState(m);
    TimestepAnalyzer ta(m);
    CutOptions co;
    co.lumping = ro.lumping;
    co.fuseReach = ro.fuseReach;
    CutEngine eng(co);
    CutResponseOptions rs;  // the routes other than the global baseline, as the scene keys set them
    if (ro.stepFloor > 0) rs.dtFloor = ro.stepFloor * dt0;
    rs.floorHybrid = ro.floor == RandomCutOptions::Floor::HybridCertified;
    rs.floorHybridThreshold = ro.hybridShare;
    rs.exact = ro.stepFloor == 0 || ro.floor != RandomCutOptions::Floor::Local;
    CutResponse response(rs);
    Stepper stepper;
    StepOptions opt;
    opt.dt = 0.9 * dt0;
    opt.minStretch = ro.minStretch;
    const int nCuts = 1 + static_cast<int>(uni(rng) * 4);
    for (int c = 0; c <= nCuts; ++c) {
        for (int k = 0; k < stepsBetween; ++k) {
            stepper.step(m, s, opt);
            ++out.steps;
            // Blow-up: a non-finite value, or a speed no fall or elastic recoil of these objects
            // reaches (free fall over the object's size gives ~1.5 m/s).
            const double vmax = s.v.colwise().norm().maxCoeff();
            out.maxSpeed = std::max(out.maxSpeed, vmax);
            if (s.flags.inverted > 0 && !out.inverted) {
                out.inverted = true;
                out.invCut = c;
                out.invStep = k;
                out.invElem = s.flags.firstInverted;
                out.invFraction = m.fraction(out.invElem);
                for (int a = 0; a < 4; ++a) out.invFixedCorners += m.fixed[static_cast<size_t>(m.tets(a, out.invElem))];
                pieceOf(m, out.invElem, out);
            }
            out.invertedAtEnd = s.flags.inverted > 0;
            out.limitedSteps += s.flags.limited > 0;
            out.maxLimited = std::max(out.maxLimited, s.flags.limited);
            if (s.flags.nonFinite > 0 || !(vmax < kBlowUpSpeed)) {
                out.failed = true;
                out.failure = "cut " + std::to_string(c) + ", step " + std::to_string(k) +
                              " after it: " + std::to_string(s.flags.nonFinite) + " non-finite nodes, max speed " +
                              std::to_string(vmax) + " m/s";
                return out;
            }
        }
        if (c == nCuts) break;
        const CutResult r = eng.cut(m, s, randomCutPlane(lo, hi, rng));
        ++out.cuts;
        out.maxVolumeError = std::max(out.maxVolumeError, std::abs(r.volumeAfter - r.volumeBefore) / r.volumeBefore);
        out.maxMassError = std::max(out.maxMassError, std::abs(r.massAfter - r.massBefore) / r.massBefore);
        Stopwatch sw;
        double dtExact = std::numeric_limits<double>::quiet_NaN();
        if (ro.stepFloor > 0 && ro.floor == RandomCutOptions::Floor::Global) {
            // the baseline: mass from global modes only
            ta.update(m, r.changedElements, r.changedNodes);
            keepStep(m, ta.rows(), ro.stepFloor * dt0);
            ta.compute(m);
        } else {
            // the product's after-cut response (timestep/cut_response.hpp)
            const CutResponseResult res = response.apply(m, ta, r.changedElements, r.changedNodes);
            out.toppedUp += res.topUp.addedMass > 0;
            dtExact = res.exact;
            if (ro.floor == RandomCutOptions::Floor::HybridCertified)
                out.matchedShare = static_cast<double>(m.matchedList.size()) / m.elements();
        }
        if (ro.stepFloor > 0) {
            const double sec = sw.seconds();
            out.floorSeconds += sec;
            out.maxFloorSeconds = std::max(out.maxFloorSeconds, sec);
            out.addedMass = m.addedMass.size() ? m.addedMass.sum() / totalMass : 0.0;
        }
        const double dt = std::isnan(dtExact) ? ta.exact(m).dt : dtExact;
        out.minDtRatio = std::min(out.minDtRatio, dt / dt0);
        if (ro.stepFloor > 0 && dt < ro.stepFloor * dt0 * (1 - 1e-6)) ++out.cutsBelowFloor;
        opt.dt = ro.dtFactor * dt;
        stepper.reset();
    }
    return out;
}

nlohmann::json randomCutStatsJson(const RandomCutStats& st) {
    return {{"runs", st.runs},
            {"cuts", st.cuts},
            {"steps", st.steps},
            {"failures", st.failures},
            {"inverted_runs", st.invertedRuns},
            {"inverted_at_end", st.invertedAtEnd},
            {"limited_runs", st.limitedRuns},
            {"limited_steps", st.limitedSteps},
            {"max_speed", st.maxSpeed},
            {"min_dt_ratio", st.minDtRatio},
            {"max_volume_error", st.maxVolumeError},
            {"max_mass_error", st.maxMassError},
            {"cuts_below_floor", st.cutsBelowFloor},
            {"cuts_topped_up", st.toppedUp},
            {"max_matched_share", st.maxMatchedShare},
            {"max_added_mass", st.maxAddedMass},
            {"mean_floor_seconds", st.cuts ? st.floorSeconds / st.cuts : 0.0},
            {"max_floor_seconds", st.maxFloorSeconds},
            {"first_failure", st.firstFailure}};
}

std::string describeRun(int run, const RandomCutRun& r) {
    char buf[500];
    if (!r.inverted) {
        std::snprintf(buf, sizeof buf,
                      "run %d: %d cuts%s%s; no inversion; stretch limiting in %ld steps, at most %d elements", run,
                      r.cuts, r.failed ? ", blew up at " : "", r.failed ? r.failure.c_str() : "", r.limitedSteps,
                      r.maxLimited);
        return buf;
    }
    std::snprintf(
        buf, sizeof buf,
        "run %d: %d cuts%s%s%s; first inversion after cut %d step %d: element %d fraction %.3g, %d prescribed "
        "corners, piece of %d elements (%.3g of the volume) with %d prescribed nodes; stretch limiting in %ld steps",
        run, r.cuts, r.failed ? ", blew up at " : "", r.failed ? r.failure.c_str() : "",
        r.invertedAtEnd ? ", still inverted at the end" : ", recovered", r.invCut, r.invStep, r.invElem, r.invFraction,
        r.invFixedCorners, r.pieceElems, r.pieceVolume, r.pieceFixed, r.limitedSteps);
    return buf;
}

RandomCutStats runRandomCuts(const Model& base, int runs, int stepsBetween, unsigned seed, const RandomCutOptions& opt,
                             std::vector<std::string>* log) {
    RandomCutStats st;
    const double dt0 = TimestepAnalyzer(base).exact(base).dt;
    for (int run = 0; run < runs; ++run) {
        const RandomCutRun r = runRandomCutSequence(base, dt0, seed, run, stepsBetween, opt);
        st.cuts += r.cuts;
        st.steps += r.steps;
        st.maxSpeed = std::max(st.maxSpeed, r.maxSpeed);
        st.minDtRatio = std::min(st.minDtRatio, r.minDtRatio);
        st.maxVolumeError = std::max(st.maxVolumeError, r.maxVolumeError);
        st.maxMassError = std::max(st.maxMassError, r.maxMassError);
        st.maxAddedMass = std::max(st.maxAddedMass, r.addedMass);
        st.maxFloorSeconds = std::max(st.maxFloorSeconds, r.maxFloorSeconds);
        st.floorSeconds += r.floorSeconds;
        st.cutsBelowFloor += r.cutsBelowFloor;
        st.toppedUp += r.toppedUp;
        st.maxMatchedShare = std::max(st.maxMatchedShare, r.matchedShare);
        st.failures += r.failed;
        st.invertedRuns += r.inverted;
        st.invertedAtEnd += r.invertedAtEnd;
        st.limitedRuns += r.limitedSteps > 0;
        st.limitedSteps += r.limitedSteps;
        if (r.failed && st.firstFailure.empty()) st.firstFailure = "run " + std::to_string(run) + " " + r.failure;
        if (log && (r.failed || r.inverted || r.limitedSteps > 0)) log->push_back(describeRun(run, r));
        ++st.runs;
    }
    return st;
}

}  // namespace cutsim
