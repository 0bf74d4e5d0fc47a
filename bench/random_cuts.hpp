// Random cut sequences at a fraction of the current exact dt: the numerical-stability stress of
// cutting (the liver and a bar, fixed at one side, under gravity). Used by the CI test, the long
// stress run and `cutsim bench stability`.
#pragma once

#include "cut/xfem.hpp"
#include "fem/integrate.hpp"
#include "fem/model.hpp"
#include "mesh/mesh.hpp"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace cutsim {

inline constexpr double kBlowUpSpeed = 50;  // a node faster than this has blown up [m/s]

struct RandomCutStats {
    int runs = 0, cuts = 0;
    int failures = 0;       // runs that blew up: a non-finite value or a speed above kBlowUpSpeed
    int invertedRuns = 0;   // runs in which some element had det F <= 0, even for one step
    int invertedAtEnd = 0;  // of those, runs with an element still inverted at their last step
    int limitedRuns = 0;    // runs in which stretch limiting corrected an element
    long limitedSteps = 0;  // steps in which it did
    double maxSpeed = 0;    // [m/s]
    long steps = 0;
    double minDtRatio = 1;      // smallest exact dt after a cut over the uncut one [-]
    double maxVolumeError = 0;  // largest |volume after - before| / before of a cut [-]
    double maxMassError = 0;    // largest |mass after - before| / before of a cut [-]
    // With a step floor (RandomCutOptions::stepFloor):
    double maxAddedMass = 0;     // largest mass added over a sequence, over the object's mass [-]
    double maxFloorSeconds = 0;  // slowest floor update of a cut [s]
    double floorSeconds = 0;     // all floor updates [s]
    int cutsBelowFloor = 0;      // cuts whose exact step stayed under the floor after it
    int toppedUp = 0;            // cuts the certified floor topped up globally
    double maxMatchedShare = 0;  // most elements the hybrid matched in a sequence, over the elements [-]
    std::string firstFailure;
};

// What one random cut sequence saw, and where its first inversion happened.
struct RandomCutRun {
    int cuts = 0;
    long steps = 0;
    bool failed = false;                           // a non-finite value or a speed above kBlowUpSpeed
    bool inverted = false;                         // some element had det F <= 0
    bool invertedAtEnd = false;                    // an element still had det F <= 0 at the last step
    long limitedSteps = 0;                         // steps in which stretch limiting corrected an element
    int maxLimited = 0;                            // most elements it corrected in one step
    double maxSpeed = 0;                           // [m/s]
    double minDtRatio = 1;                         // smallest exact dt after a cut over the uncut one [-]
    double maxVolumeError = 0, maxMassError = 0;   // relative, over the cuts [-]
    double addedMass = 0;                          // mass the floor added, over the object's mass [-]
    double floorSeconds = 0, maxFloorSeconds = 0;  // the floor's updates: all, slowest [s]
    int cutsBelowFloor = 0;                        // cuts whose exact step stayed under the floor
    int toppedUp = 0;                              // cuts the certified floor topped up globally
    double matchedShare = 0;                       // elements the hybrid matched, over the elements [-]
    std::string failure;                           // where it blew up
    // The first inverted element: after which cut (0: before any), at which step after it, its
    // fraction, its prescribed corners, and the piece it belongs to (elements, volume share of
    // the object, prescribed nodes).
    int invCut = -1, invStep = -1, invElem = -1, invFixedCorners = 0, pieceElems = 0, pieceFixed = 0;
    double invFraction = 0, pieceVolume = 0;
};

// The liver's clamp in the shipped scenes (demo.json, liver_cuts.json) and the benchmarks that
// follow them: the 10 nodes behind this plane.
inline constexpr double kSceneLiverClampZ = -0.028;  // [m]
// The liver's clamp for the stress: its back quarter (28 nodes). The scenes' clamp of 10 nodes is
// nearly a point support, which strains the hanging liver far more and inverts elements.
inline constexpr double kStressLiverClampZ = -0.015;  // [m]

// The SOFA liver (inches, scaled to m; fixed behind z = clampZ, gravity -y) and the bar
// 10 x 2 x 2 cm (10x2x2 cubes, fixed at x = 0, gravity -z); default material, mass damping 5 1/s.
Model randomCutLiverModel(const TetMesh& liverInches, double clampZ = kStressLiverClampZ);
Model randomCutBarModel();

// How the sequences step: the lumping of the cuts, the step as a fraction of the current exact
// limit, and the stretch limiting of the scenes (0: off, inversions only counted).
struct RandomCutOptions {
    MassLumping lumping = MassLumping::Enrichment;
    double dtFactor = 0.9;                      // step / exact dt of the current model [-]
    double minStretch = 0;                      // StepOptions::minStretch, 0: off [-]
    double fuseReach = CutOptions{}.fuseReach;  // CutOptions::fuseReach [-]
    // Step floor after each cut, as a fraction of the uncut exact step (0: none), held by
    // holdStepFloor (local) or keepStep (global selective mass scaling, an eigen-solve per round).
    double stepFloor = 0;
    enum class Floor : std::uint8_t { Local, Certified, Global, HybridCertified } floor = Floor::Local;
    // HybridCertified: before the certified floor, the elements whose R1R step is under this share
    // of the floor are matched (timestep/hybrid.hpp), so mass goes to the rest only. [-]
    double hybridShare = 1.0;
};

// One sequence of 1-4 random planes through the model's box, the generator seeded with
// (seed, run) so any run replays alone: `stepsBetween` symplectic Euler steps at 0.9 x the uncut
// exact dt0 before the first cut and opt.dtFactor x the cut model's exact dt after each.
// A random plane through the box [lo, hi]: a point uniform in its middle 70% on each axis, a
// direction uniform in a cube (6 draws of U(0, 1) from rng, in that order).
CutSurface randomCutPlane(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::mt19937& rng);

RandomCutRun runRandomCutSequence(const Model& base, double dt0, unsigned seed, int run, int stepsBetween,
                                  const RandomCutOptions& opt = {});

// One line for a run that blew up, inverted or was limited.
std::string describeRun(int run, const RandomCutRun& r);

// The counts as the results of `cutsim bench stability` and the stress test write them:
// {runs, cuts, steps, failures, inverted_runs, inverted_at_end, limited_runs, limited_steps, max_speed,
// min_dt_ratio, max_volume_error, max_mass_error, cuts_below_floor, cuts_topped_up, max_matched_share,
// max_added_mass, mean_floor_seconds, max_floor_seconds, first_failure}.
nlohmann::json randomCutStatsJson(const RandomCutStats& st);

// Runs 0 .. runs-1 of runRandomCutSequence; `log`, when given, gets describeRun of each run that
// blew up, inverted or was limited.
RandomCutStats runRandomCuts(const Model& base, int runs, int stepsBetween, unsigned seed,
                             const RandomCutOptions& opt = {}, std::vector<std::string>* log = nullptr);

}  // namespace cutsim
