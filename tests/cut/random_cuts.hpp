// Random cut sequences (cut/random_cuts.hpp) for the short CI test and the long stress run: the
// two objects by name, and the conservation checks every cut must pass.
#pragma once

#include "bench/random_cuts.hpp"
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/analyzer.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace cutsim::test {

using cutsim::describeRun;
using cutsim::kBlowUpSpeed;
using cutsim::RandomCutOptions;
using cutsim::RandomCutRun;
using cutsim::RandomCutStats;
using cutsim::runRandomCutSequence;

// The liver (clamped over its back, gravity) or a bar (clamped at one end), as a model.
inline Model randomCutModel(bool liver) {
    return liver ? randomCutLiverModel(readTetMesh(data("tet/sofa_liver.msh"), ReadOptions{})) : randomCutBarModel();
}

// As cutsim::runRandomCuts on randomCutModel(liver); every cut keeps volume and mass. verbose
// prints each run that blew up or inverted.
inline RandomCutStats runRandomCuts(bool liver, int runs, int stepsBetween, unsigned seed,
                                    const RandomCutOptions& opt = {}, bool verbose = false) {
    std::vector<std::string> log;
    const RandomCutStats st =
        cutsim::runRandomCuts(randomCutModel(liver), runs, stepsBetween, seed, opt, verbose ? &log : nullptr);
    for (const auto& line : log) std::printf("%s\n", line.c_str());
    EXPECT_LT(st.maxVolumeError, 1e-9);
    EXPECT_LT(st.maxMassError, 1e-9);
    return st;
}

inline void printRandomCuts(const char* name, const RandomCutStats& st) {
    std::printf("%s: %d runs, %d cuts, %ld steps, %d blew up, %d with an inverted element (%d still at the end), "
                "%d limited (%ld steps), max speed %.3g m/s, min dt ratio %.4f\n",
                name, st.runs, st.cuts, st.steps, st.failures, st.invertedRuns, st.invertedAtEnd, st.limitedRuns,
                st.limitedSteps, st.maxSpeed, st.minDtRatio);
}

}  // namespace cutsim::test
