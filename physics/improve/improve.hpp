// Mesh improvement for a larger stable time step (docs/method.md sec. 4, thesis sec. 5.1): node
// smoothing and flips that lower the largest reduced-one-ring eigenvalue of the mesh, keeping the
// mesh whose exact step is best.
#pragma once

#include "fem/material.hpp"
#include "mesh/mesh.hpp"

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace cutsim {

struct ImproveOptions {
    Material material;
    double targetDt = 0;                 // stop once the exact step reaches it (0: no target) [s]
    long long maxEvaluations = 0;        // work budget in reduced-one-ring eigenvalue problems, the
                                         // unit that makes a run deterministic; 0: 140 per element
                                         // (at least 1e5)
    double maxSeconds = 60;              // wall-time limit besides [s]
    int maxRounds = 40;                  // rounds of smoothing then flips
    bool smooth = true;                  // move nodes
    bool flips = true;                   // 2-3 and 3-2 flips
    bool collapse = true;                // collapse the shortest interior edge of a critical element
    bool moveBoundary = true;            // boundary nodes slide within their original boundary faces
    double maxVolumeChange = 0.008;      // |enclosed volume change| / volume, at most [-]
    double maxBoundaryDistance = 0.015;  // new boundary from the old surface, over the bbox diagonal [-]
    bool boundaryBothWays = false;       // the distance bound holds both ways: the old surface also
                                         // stays near the new boundary (a Hausdorff bound; a node
                                         // cannot slide off a crease or a tip and cut it away)
    double featureAngleDeg = 180;        // boundary edges whose faces turn by more than this are
                                         // features: a node between two slides along them, a node on
                                         // one or on three or more (a corner) stays put. 180: none,
                                         // the volume and distance bounds alone keep the shape [deg]
    double maxElementLoss = 0.05;        // collapses may remove at most this share of the elements [-]
    std::vector<int> fixedNodes;         // nodes that must not move (a scene's fixed region)
    int descentSteps = 3;                // gradient steps per node and round, each a line search
    bool lean = false;                   // fewer problems per node, for local improvement on a budget:
                                         // a descent reuses what was solved since the rows last
                                         // changed and probes its near-critical elements alone
    bool exactSteps = true;              // rounds judged by the exact (Lanczos) step; false: by the
                                         // smallest R1R step, which the improver solves anyway (no
                                         // Lanczos: for improvement that has to keep up with cutting);
                                         // the report's before/after then hold the R1R step and volume,
                                         // its boundaryDistance 0 (the bound is kept, not measured)
    int threads = 1;                     // threads that smooth disjoint parts at once; a result depends
                                         // on this count, not on timing (0: one per core)
    // Called after each round with the round, the seconds so far and the exact step of the
    // round's mesh (of a round that cannot beat the best: its R1R step, a bound above); for a
    // progress bar.
    std::function<void(int round, double seconds, double dtExact)> progress;
};

// What a mesh allows, at one material.
struct MeshStepStats {
    int nodes = 0, tets = 0;
    double dtExact = 0;      // Lanczos [s]
    double dtCertified = 0;  // Gershgorin, <= dtExact [s]
    double dtR1R = 0;        // smallest reduced-one-ring estimate [s]
    double minDihedralDeg = 0;
    double volume = 0;  // [m^3]
};
MeshStepStats meshStepStats(const TetMesh& mesh, const Material& material);

struct ImproveReport {
    MeshStepStats before, after;
    double volumeChange = 0;      // (after - before) / before [-]
    double boundaryDistance = 0;  // largest distance of a new boundary point (vertices, edge
                                  // midpoints, face centroids) from the old surface [m]
    double diagonal = 0;          // bounding-box diagonal [m]
    int rounds = 0, bestRound = 0;
    int moves = 0, flips23 = 0, flips32 = 0, collapses = 0;
    long long evaluations = 0;                            // reduced-one-ring eigenvalue problems solved (the work)
    std::vector<std::pair<std::string, double>> seconds;  // per stage [s]
    struct Point {
        double seconds, dtExact;
    };
    std::vector<Point> history;  // exact step after each round (round 0: the input) that could
                                 // beat the best (its R1R step above it); the smallest R1R step
                                 // of every round when !exactSteps
};

// Largest distance from the boundary of `to` (its vertices, edge midpoints and face centroids) to
// the boundary surface of `from` [m]: how far an improver moved the surface.
double surfaceDistance(const TetMesh& from, const TetMesh& to);

// Improves `mesh` in place (rest positions, elements; unreferenced nodes are dropped, so node
// numbers may change when edges were collapsed). Never produces an inverted element.
// Throws EigenSolveError when an exact step cannot be computed.
ImproveReport improveMesh(TetMesh& mesh, const ImproveOptions& opts);

}  // namespace cutsim
