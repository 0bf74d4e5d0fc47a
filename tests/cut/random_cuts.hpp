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

namespace cutsim::test {

inline constexpr double kBlowUpSpeed = 50;   // [m/s]

struct RandomCutStats {
    int runs = 0, cuts = 0;
    int failures = 0;       // runs that blew up: a non-finite value or a speed above kBlowUpSpeed
    int invertedRuns = 0;   // runs in which some element inverted (reported; large strain, not instability)
    double maxSpeed = 0;    // [m/s]
    long steps = 0;
    double minDtRatio = 1;   // smallest exact dt after a cut over the uncut one
    std::string firstFailure;
};

// The liver (fixed at its back, gravity) or a bar (fixed at one end), as a model.
inline Model randomCutModel(bool liver) {
    Model m;
    if (liver) {
        ReadOptions ro;
        ro.scale = 0.0254;
        m = buildModel(readTetMesh(data("tet/sofa_liver.msh"), ro), Material{});
        m.gravity = Eigen::Vector3d(0, -9.81, 0);
        for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(2, i) < -0.028;
    } else {
        m = buildModel(boxMesh(0.1, 0.02, 0.02, 10, 2, 2), Material{});
        m.gravity = Eigen::Vector3d(0, 0, -9.81);
        for (int i = 0; i < m.nodes(); ++i) m.fixed[i] = m.X(0, i) < 1e-9;
    }
    m.massDamping = 5;
    updateMasses(m);
    return m;
}

// `runs` sequences of 1-4 random planes through the object's box, `stepsBetween` steps at
// 0.9 x the uncut exact dt before the first cut and dtFactor x the cut mesh's exact dt after each.
inline RandomCutStats runRandomCuts(bool liver, int runs, int stepsBetween, unsigned seed,
                                    MassLumping lumping = MassLumping::Enrichment, double dtFactor = 0.9) {
    RandomCutStats st;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> uni(0, 1);
    const Model base = randomCutModel(liver);
    const Eigen::Vector3d lo = base.X.rowwise().minCoeff(), hi = base.X.rowwise().maxCoeff();
    const double dt0 = TimestepAnalyzer(base).exact(base).dt;
    for (int run = 0; run < runs; ++run) {
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
        bool failed = false, inverted = false;
        for (int c = 0; c <= nCuts && !failed; ++c) {
            for (int k = 0; k < stepsBetween; ++k) {
                stepper.step(m, s, opt);
                ++st.steps;
                // Blow-up: a non-finite value, or a speed no fall or elastic recoil of this scene
                // reaches (free fall over the object's size gives ~1.5 m/s).
                const double vmax = s.v.colwise().norm().maxCoeff();
                st.maxSpeed = std::max(st.maxSpeed, vmax);
                if (s.flags.inverted > 0 && !inverted) {
                    inverted = true;
                    ++st.invertedRuns;
                }
                if (s.flags.nonFinite > 0 || !(vmax < kBlowUpSpeed)) {
                    failed = true;
                    if (st.firstFailure.empty())
                        st.firstFailure = "run " + std::to_string(run) + " cut " + std::to_string(c) + ", step " +
                                          std::to_string(k) + " after it: " + std::to_string(s.flags.nonFinite) +
                                          " non-finite nodes, max speed " + std::to_string(vmax) + " m/s";
                    break;
                }
            }
            if (c == nCuts || failed) break;
            CutSurface cs;
            for (int k = 0; k < 3; ++k) cs.point[k] = lo[k] + (0.15 + 0.7 * uni(rng)) * (hi[k] - lo[k]);
            cs.normal = Eigen::Vector3d(uni(rng) - 0.5, uni(rng) - 0.5, uni(rng) - 0.5).normalized();
            const CutResult r = eng.cut(m, s, cs);
            ++st.cuts;
            EXPECT_NEAR(r.volumeAfter, r.volumeBefore, 1e-9 * r.volumeBefore);
            EXPECT_NEAR(r.massAfter, r.massBefore, 1e-9 * r.massBefore);
            ta.update(m, r.changedElements, r.changedNodes);
            const double dt = ta.exact(m).dt;
            st.minDtRatio = std::min(st.minDtRatio, dt / dt0);
            opt.dt = dtFactor * dt;
            stepper.reset();
        }
        st.failures += failed;
        ++st.runs;
    }
    return st;
}

inline void printRandomCuts(const char* name, const RandomCutStats& st) {
    std::printf("%s: %d runs, %d cuts, %ld steps, %d blew up, %d with an inverted element, max speed %.3g m/s, "
                "min dt ratio %.4f\n", name, st.runs, st.cuts, st.steps, st.failures, st.invertedRuns, st.maxSpeed,
                st.minDtRatio);
}

} // namespace cutsim::test
