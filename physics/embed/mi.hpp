// Mesh intersection, MI (thesis ch. 6, Algorithms 1-4; docs/method.md sec. 5): an object given only by
// its closed surface is simulated on a regular background tet lattice, whose time step is the best
// a mesh of that resolution can have. Lattice tets cut by the surface become virtual elements
// (XFEM, thesis 2.3) with stiffness and mass scaled by their inside volume share, so an isolated one
// keeps the parent's eigenvalues; the assembled model can still fall a little below the lattice's
// step, which keepLatticeStep restores by adding mass (timestep.hpp keepStep).
//
// Lattice: cubes split into 6 Kuhn tets (mesh/generate.hpp boxMesh): at equal cell size its exact
// dt is 19% larger than the alternating 5-tet split's, and every tet is congruent, so no cube
// parity has to follow the object.
#pragma once

#include "fem/model.hpp"
#include "mesh/embedding.hpp"
#include "mesh/mesh.hpp"
#include "timestep/timestep.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace cutsim {

struct MiOptions {
    int cells = 16;  // lattice cells across the longest side of the surface's box (when h <= 0)
    double h = 0;    // cell edge [m]; > 0 takes precedence over cells
    Eigen::Vector3i latticeCells = Eigen::Vector3i::Zero();  // > 0: use this lattice (with h and latticeOrigin)
    Eigen::Vector3d latticeCellSize =
        Eigen::Vector3d::Zero();  // > 0: the given lattice's cell edges along x, y, z
                                  // (box cells, each split into 6 Kuhn tets) instead of cubes of edge h [m]
    Eigen::Vector3d latticeOrigin = Eigen::Vector3d::Zero();  // its lowest corner [m]
    double boundaryTol = 1e-3;     // a node closer than boundaryTol x the shortest cell edge to the surface
                                   // is a boundary node [-]
    double minFraction = 1e-6;     // inside share below it: outside; above 1 - it: inside (share 1) [-]
    int refineLevels = 0;          // also estimate interface shares by this many refinement levels (0: skip)
    bool fixOutsideNodes = false;  // the thesis's literal reading: outside corners of interface tets fixed
                                   // (removes DOFs, so the step can only grow; pins the boundary layer)
    bool keepLatticeStep = false;  // add mass where needed (timestep.hpp keepStep) so the embedded model's
                                   // exact step is at least the whole lattice's; costs eigen-solves of both
    long maxTets = 20'000'000;     // refuse larger lattices (InputError)
    std::string sizeKey;           // where cells or h were given ("scene.json: object.surface.h"): errors of
                                   // the lattice's size name it (else the surface file)
};

enum class NodeClass : std::uint8_t { Outside = 0, Inside = 1, Boundary = 2 };
enum class ElementClass : std::uint8_t { Outside = 0, Interface = 1, Inside = 2 };

// Seconds per stage of buildMi [s].
struct MiTimings {
    double lattice = 0, hash = 0, nodes = 0, volumes = 0, refine = 0, model = 0, embed = 0;
    double keepStep = 0;  // MiOptions::keepLatticeStep: the lattice's exact step and the mass scaling
    double total() const { return lattice + hash + nodes + volumes + refine + model + embed + keepStep; }
};

struct MiResult {
    // Background lattice: cube (i, j, k) = i + nx (j + ny k) holds tets 6c .. 6c + 5 (Kuhn split).
    TetMesh lattice;                                     // the whole lattice (rest positions) [m]
    double h = 0;                                        // cell edge [m]; the longest one when the cells are boxes
    Eigen::Vector3d cellSize = Eigen::Vector3d::Zero();  // cell edges along x, y, z [m] (all h for cubes)
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();    // lowest lattice corner [m]
    Eigen::Vector3i cells = Eigen::Vector3i::Zero();     // cubes along x, y, z

    // Classification
    std::vector<NodeClass> nodeClass;        // per lattice node (nLatticeNodes); boundary wins over in/out
    std::vector<std::uint8_t> nodeInside;    // winding number > 1/2, per lattice node (nLatticeNodes)
    std::vector<ElementClass> elementClass;  // per lattice tet (nLatticeTets)
    Eigen::VectorXd fractionExact;           // inside share by clipping, not clamped (nLatticeTets) [-]
    std::vector<Eigen::VectorXd>
        fractionRefined;  // [l] = share after l refinement levels (levels+1 x nLatticeTets) [-]
    bool closed = true;   // the surface is closed and oriented: shares are exact;
                          // otherwise they come from max(2, refineLevels) refinement
                          // levels with winding numbers (the region where w > 1/2)

    // The embedded model: inside and interface lattice tets, nodes no kept tet uses dropped.
    Model model;
    std::vector<int> latticeElement;  // lattice tet of each model element (nElems)
    std::vector<int> latticeNode;     // lattice node of each model node (nNodes)
    EmbeddedSurface surface;          // the input surface riding the model's elements
    double dtLattice = 0;             // exact step of the whole lattice, all nodes free; set when
                                      // keepLatticeStep [s]
    KeepStepResult massScaling;       // what keepLatticeStep added (model.addedMass)

    SurfaceCleanup cleanup;  // what was welded and dropped before classification (mesh.hpp cleanSurface)
    MiTimings seconds;

    int count(ElementClass c) const;
    int count(NodeClass c) const;
    double embeddedVolume() const;  // sum of kept volume x share [m^3]
};

// Builds the MI model of a surface (readSurfaceMesh; already scaled and placed). Throws InputError
// for an empty surface, a non-finite coordinate, a bad resolution or a lattice above maxTets.
MiResult buildMi(const SurfaceMesh& surface, const Material& material, const MiOptions& opts);

// The surface of the box [lo, hi] (12 triangles, outward).
SurfaceMesh boxSurface(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

// Table 6.1 of the thesis, MI column: the bar [0,1]x[0,1]x[0,10] x scale, cut by the plane
// z = 10 (1 - kept) x scale, top part kept, embedded in the uncut bar's lattice.
struct MiBarOptions {
    double scale = 0.01;  // bar of 1 x 1 x 10 cm by default [m per unit]
    int cellsAcross = 3;  // lattice cells across the bar
    int cellsAlong = 0;   // lattice cells along it; 0: miBarCellsAlong(cellsAcross)
    Material material;    // thesis default: E = 30 kPa, nu = 0.3, rho = 1000
};
// Cells along the bar for c across: 10c + 1, odd, so the cuts at 1/4, 1/2 and 3/4 of the length
// fall at 1/4, 1/2 and 3/4 of a cell (every cut crosses cells, as in the thesis's 2 x 2 x 9 bar),
// and the cells stay near cubes (1/c x 1/c x 10/(10c + 1)).
int miBarCellsAlong(int cellsAcross);
struct MiBarRow {
    double kept = 1;                // kept share of the bar [-]
    int nodes = 0;                  // model nodes (all free)
    int freeNodesOutsideFixed = 0;  // nodes left free with the outside corners fixed (fixOutsideNodes)
    int elements = 0;               // model elements (inside + interface)
    int interfaceElements = 0;
    double volume = 0;             // embedded volume [m^3]
    double dtExact = 0;            // exact critical step of the MI model [s]
    double dtCertified = 0;        // certified lower bound [s]
    double dtLattice = 0;          // exact step of the uncut lattice [s]
    double dtOutsideFixed = 0;     // exact step with the outside corners fixed (MiOptions::fixOutsideNodes) [s]
    double dtKept = 0;             // exact step with the lattice's step kept (MiOptions::keepLatticeStep) [s]
    double addedMassFraction = 0;  // the mass that took, over the model's (all nodes free) [-]
};
std::vector<MiBarRow> miBarRows(const MiBarOptions& opts = {},
                                const std::vector<double>& kept = {1.0, 0.75, 0.5, 0.25});

}  // namespace cutsim
