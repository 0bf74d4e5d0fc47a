// Random cut sequences at a fraction of the current exact dt: the numerical-stability stress of
// cutting (the liver and a bar, fixed at one side, under gravity). Used by the CI test, the long
// stress run and `cutsim bench stability`.
#pragma once

#include "cut/xfem.hpp"
#include "fem/model.hpp"
#include "mesh/mesh.hpp"

#include <string>

namespace cutsim {

inline constexpr double kBlowUpSpeed = 50;   // a node faster than this has blown up [m/s]

struct RandomCutStats {
    int runs = 0, cuts = 0;
    int failures = 0;        // runs that blew up: a non-finite value or a speed above kBlowUpSpeed
    int invertedRuns = 0;    // runs in which some element inverted (reported; large strain, not instability)
    double maxSpeed = 0;     // [m/s]
    long steps = 0;
    double minDtRatio = 1;   // smallest exact dt after a cut over the uncut one [-]
    double maxVolumeError = 0; // largest |volume after - before| / before of a cut [-]
    double maxMassError = 0;   // largest |mass after - before| / before of a cut [-]
    std::string firstFailure;
};

// The SOFA liver (inches, scaled to m; fixed behind z = -0.028 m, gravity -y) and the bar
// 10 x 2 x 2 cm (10x2x2 cubes, fixed at x = 0, gravity -z); default material, mass damping 5 1/s.
Model randomCutLiverModel(const TetMesh& liverInches);
Model randomCutBarModel();

// `runs` sequences of 1-4 random planes through the model's box, `stepsBetween` symplectic Euler
// steps at 0.9 x the uncut exact dt before the first cut and dtFactor x the cut model's exact dt
// after each. The sequence of planes depends only on seed.
RandomCutStats runRandomCuts(const Model& base, int runs, int stepsBetween, unsigned seed,
                             MassLumping lumping = MassLumping::Enrichment, double dtFactor = 0.9);

} // namespace cutsim
