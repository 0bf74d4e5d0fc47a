// The two cut baselines the XFEM/MI path is compared against, measured by the exact critical time
// step (thesis sec. 5.2 and Table 6.1, docs/method.md sec. 5): conforming subdivision with node
// snapping (cut/conforming.hpp) and remeshing with TetGen (cut/remesh.hpp).
#pragma once

#include "cut/conforming.hpp"
#include "fem/material.hpp"
#include "mesh/mesh.hpp"

#include <string>
#include <vector>

namespace cutsim {

// SubdivisionImproved: subdivision, then the elements near the plane improved (improveNearPlane).
enum class CutMethod { Subdivision, Remesh, SubdivisionImproved };
const char* cutMethodName(CutMethod m);             // "subdivision", "remesh", "subdivision_improve"
CutMethod parseCutMethod(const std::string& name);  // the names above; throws InputError

// One row of Table 6.1 for one method.
struct BaselineRow {
    double kept = 1;     // share of the bar's length kept (top part) [-]
    std::string method;  // "subdivision" or "remesh"
    int nodes = 0;       // nodes of the kept mesh
    int elements = 0;    // tets of the kept mesh
    double dtExact = 0;  // exact critical time step, 2 / sqrt(lambda_max(M^-1 K)) [s]
};

// The Table 6.1 bar: [0,1]x[0,1]x[0,10] in units of `unit`, a box mesh of nx*ny*nz Kuhn cubes.
// 2x2x9 cubes give the thesis's 90 nodes (216 tets against its 210, whose mesh is not given);
// unit = 1 cm puts the uncut step at the thesis's order (0.638 ms).
struct BarOptions {
    double unit = 0.01;                              // bar length unit [m]
    int nx = 2, ny = 2, nz = 9;                      // cubes along x, y, z
    std::vector<double> kept{1.0, 0.75, 0.5, 0.25};  // kept shares of the length, 1 = uncut
    Material material;                               // thesis sec. 6.2: E 30 kPa, nu 0.3, rho 1000
    ConformingOptions subdivision;                   // snapping 0.1 as in the thesis; keep is forced to Positive
    bool remesh = true;                              // also the TetGen rows (the slow ones)
};

// For each kept share and each method (subdivision, then remesh): cut the bar by the plane
// z = (1 - kept) * 10 unit, keep the top part, report its size and exact step. kept = 1 is the
// uncut bar for both methods (as in the table).
std::vector<BaselineRow> barCutBaselines(const BarOptions& opts = {});

// The bar mesh of opts (no cut).
TetMesh barMesh(const BarOptions& opts = {});

// Exact critical step of a mesh with no fixed nodes [s] (timestep/timestep.hpp exactCriticalDt).
double exactDtOf(const TetMesh& mesh, const Material& material = {});

// How improveNearPlane works and how much. The defaults are the full setting; budgeted() keeps up
// with cutting.
struct NearPlaneOptions {
    double dtCritical = 0;           // work on the band's elements whose R1R step is under it (0: all) [s]
    double reach = 2.0;              // band: elements with a node within this many mean edge lengths
    bool rankAround = false;         // rank with the elements around the band's nodes: the whole
                                     // mesh's R1R steps (false: the band's, approximate at its rim)
    int rounds = 4;                  // improver rounds
    long long problemsPerTet = 100;  // work: R1R problems per element of the region (at least 2000)
    long long maxProblems = 0;       // and at most this many in all, ranking the band included (0: no cap)
    int maxFreeNodes = 0;            // the worst critical elements' nodes, at most about this many (0: all)
    int descentSteps = 3;            // ImproveOptions::descentSteps
    bool lean = false;               // ImproveOptions::lean
    bool exactSteps = true;          // ImproveOptions::exactSteps
    double maxSeconds = 10;          // wall-time limit [s]
    // Keeps up with cutting: the cut's own elements (a node on the plane) ranked, the nodes of the
    // worst, about 40, free; one lean gradient step per node and round, rounds judged by the R1R
    // step, 5000 problems in all (a few ms a cut, `cutsim bench cutstep`).
    static NearPlaneOptions budgeted(double dtCritical);
};

// What improveNearPlane did.
struct NearPlaneReport {
    int band = 0;                      // elements near the plane
    int critical = 0;                  // of them under dtCritical (with dtCritical > 0)
    int freeNodes = 0;                 // nodes that were free to move
    long long problems = 0;            // R1R problems solved, ranking and improver [-]
    double dtBefore = 0, dtAfter = 0;  // the region's smallest R1R step before and after [s]
    double seconds = 0;
};

// The thesis's local improvement after a conforming cut (sec. 5.2), with the improver of sec. 5.1,
// on the elements within `reach` mean edge lengths of the plane (the band). With dtCritical > 0
// only the band's critical elements are worked on: those whose R1R step (of the band as a mesh of
// its own) is under dtCritical, worst first, their nodes free and their one-ring the region; else
// every band node is free. The region is improved as a mesh of its own (improve/region.hpp).
NearPlaneReport improveNearPlane(TetMesh& mesh, const CutPlane& plane, const Material& material,
                                 const NearPlaneOptions& opts = {});

// Applies the planes in sequence with the method (both sides kept and separated) and returns the
// exact critical step after each cut [s] (planes.size() values).
std::vector<double> dtAfterPlaneCuts(const TetMesh& mesh, const std::vector<CutPlane>& planes, CutMethod method,
                                     const Material& material = {});

}  // namespace cutsim
