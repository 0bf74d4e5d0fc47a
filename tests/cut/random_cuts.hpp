// Random cut sequences run at 0.9 of the current exact dt: the numerical-stability stress of
// cutting. Shared by the short CI test and the long stress run.
#pragma once

#include "cut/xfem.hpp"
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "mesh/io.hpp"
#include "test_support.hpp"
#include "timestep/analyzer.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace cutsim::test {

inline constexpr double kBlowUpSpeed = 50;   // [m/s]

struct RandomCutStats {
    int runs = 0, cuts = 0;
    int failures = 0;       // runs that blew up: a non-finite value or a speed above kBlowUpSpeed
    int invertedRuns = 0;   // runs in which some element had det F <= 0, even for a step
    int invertedAtEnd = 0;  // of those, runs with an element still inverted at their last step
    double maxSpeed = 0;    // [m/s]
    long steps = 0;
    double minDtRatio = 1;   // smallest exact dt after a cut over the uncut one
    std::string firstFailure;
};

// The liver (clamped over its back, gravity) or a bar (clamped at one end), as a model.
inline Model randomCutModel(bool liver) {
    Model m;
    if (liver) {
        ReadOptions ro;
        ro.scale = 0.0254;
        m = buildModel(readTetMesh(data("tet/sofa_liver.msh"), ro), Material{});
        m.gravity = Eigen::Vector3d(0, -9.81, 0);
        // Clamped over its back quarter (28 nodes), not at the 10 lowest nodes: a clamp on a few
        // nodes is a point support, whose stress grows without bound under refinement; it left the
        // uncut liver at 37% compression (smallest principal stretch 0.63) and most inversions of
        // the stress run at the clamp. Over the region: 11.5% (0.885), and cuts still cross it.
        for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(2, i) < -0.015;
    } else {
        m = buildModel(boxMesh(0.1, 0.02, 0.02, 10, 2, 2), Material{});
        m.gravity = Eigen::Vector3d(0, 0, -9.81);
        for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(0, i) < 1e-9;
    }
    m.massDamping = 5;
    updateMasses(m);
    return m;
}

// What one random cut sequence saw, and where its first inversion happened.
struct RandomCutRun {
    int cuts = 0;
    long steps = 0;
    bool failed = false;     // a non-finite value or a speed above kBlowUpSpeed
    bool inverted = false;   // some element had det F <= 0
    bool invertedAtEnd = false; // an element still had det F <= 0 at the last step
    double maxSpeed = 0;     // [m/s]
    double minDtRatio = 1;   // smallest exact dt after a cut over the uncut one
    std::string failure;     // where it blew up
    // The first inverted element: after which cut (0: before any), at which step after it, its
    // fraction, its prescribed corners, and the piece it belongs to (elements, volume share of
    // the object, prescribed nodes).
    int invCut = -1, invStep = -1, invElem = -1, invFixedCorners = 0, pieceElems = 0, pieceFixed = 0;
    double invFraction = 0, pieceVolume = 0;
};

// Elements, volume share and prescribed nodes of the piece (nodes joined by elements) holding element e.
inline void pieceOf(const Model& m, int e, RandomCutRun& r) {
    std::vector<int> p(static_cast<size_t>(m.nodes()));
    for (int i = 0; i < m.nodes(); ++i) p[static_cast<size_t>(i)] = i;
    auto find = [&](int i) {
        while (p[static_cast<size_t>(i)] != i) i = p[static_cast<size_t>(i)] = p[static_cast<size_t>(p[static_cast<size_t>(i)])];
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

// One sequence of 1-4 random planes through the object's box (the generator seeded with
// (seed, run), so any run replays alone): `stepsBetween` steps at 0.9 x the uncut exact dt before
// the first cut and dtFactor x the cut mesh's exact dt after each.
inline RandomCutRun runRandomCutSequence(const Model& base, double dt0, unsigned seed, int run, int stepsBetween,
                                         MassLumping lumping = MassLumping::Enrichment, double dtFactor = 0.9) {
    std::seed_seq seq{seed, static_cast<unsigned>(run)};
    std::mt19937 rng(seq);
    std::uniform_real_distribution<double> uni(0, 1);
    const Eigen::Vector3d lo = base.X.rowwise().minCoeff(), hi = base.X.rowwise().maxCoeff();
    RandomCutRun out;
    Model m = base;
    State s = makeState(m);
    TimestepAnalyzer ta(m);
    CutOptions co;
    co.lumping = lumping;
    CutEngine eng(co);
    Stepper stepper;
    StepOptions opt;
    opt.dt = 0.9 * dt0;
    const int nCuts = 1 + static_cast<int>(uni(rng) * 4);
    for (int c = 0; c <= nCuts; ++c) {
        for (int k = 0; k < stepsBetween; ++k) {
            stepper.step(m, s, opt);
            ++out.steps;
            // Blow-up: a non-finite value, or a speed no fall or elastic recoil of this scene
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
            if (s.flags.nonFinite > 0 || !(vmax < kBlowUpSpeed)) {
                out.failed = true;
                out.failure = "cut " + std::to_string(c) + ", step " + std::to_string(k) + " after it: " +
                              std::to_string(s.flags.nonFinite) + " non-finite nodes, max speed " +
                              std::to_string(vmax) + " m/s";
                return out;
            }
        }
        if (c == nCuts) break;
        CutSurface cs;
        for (int k = 0; k < 3; ++k) cs.point[k] = lo[k] + (0.15 + 0.7 * uni(rng)) * (hi[k] - lo[k]);
        cs.normal = Eigen::Vector3d(uni(rng) - 0.5, uni(rng) - 0.5, uni(rng) - 0.5).normalized();
        const CutResult r = eng.cut(m, s, cs);
        ++out.cuts;
        EXPECT_NEAR(r.volumeAfter, r.volumeBefore, 1e-9 * r.volumeBefore);
        EXPECT_NEAR(r.massAfter, r.massBefore, 1e-9 * r.massBefore);
        ta.update(m, r.changedElements, r.changedNodes);
        const double dt = ta.exact(m).dt;
        out.minDtRatio = std::min(out.minDtRatio, dt / dt0);
        opt.dt = dtFactor * dt;
        stepper.reset();
    }
    return out;
}

// One line per run that blew up or inverted, for the stress log.
inline std::string describeRun(int run, const RandomCutRun& r) {
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "run %d: %d cuts%s%s%s; first inversion after cut %d step %d: element %d fraction %.3g, %d prescribed "
                  "corners, piece of %d elements (%.3g of the volume) with %d prescribed nodes",
                  run, r.cuts, r.failed ? ", blew up at " : "", r.failed ? r.failure.c_str() : "",
                  r.invertedAtEnd ? ", still inverted at the end" : ", recovered", r.invCut, r.invStep,
                  r.invElem, r.invFraction, r.invFixedCorners, r.pieceElems, r.pieceVolume, r.pieceFixed);
    return buf;
}

// `runs` sequences (runRandomCutSequence with runs 0 .. runs-1 of `seed`).
inline RandomCutStats runRandomCuts(bool liver, int runs, int stepsBetween, unsigned seed,
                                    MassLumping lumping = MassLumping::Enrichment, double dtFactor = 0.9,
                                    bool verbose = false) {
    RandomCutStats st;
    const Model base = randomCutModel(liver);
    const double dt0 = TimestepAnalyzer(base).exact(base).dt;
    for (int run = 0; run < runs; ++run) {
        const RandomCutRun r = runRandomCutSequence(base, dt0, seed, run, stepsBetween, lumping, dtFactor);
        st.cuts += r.cuts;
        st.steps += r.steps;
        st.maxSpeed = std::max(st.maxSpeed, r.maxSpeed);
        st.minDtRatio = std::min(st.minDtRatio, r.minDtRatio);
        st.failures += r.failed;
        st.invertedRuns += r.inverted;
        st.invertedAtEnd += r.invertedAtEnd;
        if (r.failed && st.firstFailure.empty()) st.firstFailure = "run " + std::to_string(run) + " " + r.failure;
        if (verbose && (r.failed || r.inverted)) std::printf("%s\n", describeRun(run, r).c_str());
        ++st.runs;
    }
    return st;
}

inline void printRandomCuts(const char* name, const RandomCutStats& st) {
    std::printf("%s: %d runs, %d cuts, %ld steps, %d blew up, %d with an inverted element (%d still at the end), "
                "max speed %.3g m/s, min dt ratio %.4f\n", name, st.runs, st.cuts, st.steps, st.failures,
                st.invertedRuns, st.invertedAtEnd, st.maxSpeed, st.minDtRatio);
}

} // namespace cutsim::test
