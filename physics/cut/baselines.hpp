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

// The thesis's local improvement after a conforming cut (sec. 5.2), with the improver of sec. 5.1,
// on the elements within `reach` mean edge lengths of the plane (the band). With dtCritical > 0
// only the band's critical elements are worked on: those whose R1R step (of the band as a mesh of
// its own) is under dtCritical, their nodes free and their one-ring the region; else every band
// node is free. The region is improved as a mesh of its own (improve/region.hpp), for `rounds`
// rounds of 100 one-ring problems per element of it. Returns the seconds it took.
double improveNearPlane(TetMesh& mesh, const CutPlane& plane, const Material& material, double dtCritical = 0,
                        double reach = 2.0, int rounds = 4, double maxSeconds = 10);

// Applies the planes in sequence with the method (both sides kept and separated) and returns the
// exact critical step after each cut [s] (planes.size() values).
std::vector<double> dtAfterPlaneCuts(const TetMesh& mesh, const std::vector<CutPlane>& planes, CutMethod method,
                                     const Material& material = {});

}  // namespace cutsim
