// Remeshing baseline (thesis sec. 6.2, Table 6.1 "remesh"): after a plane cut, each piece is
// tetrahedralized from scratch by TetGen (Si 2015, library API) from its closed boundary surface.
// The surface comes from the conforming cut without snapping (cut/conforming.hpp), so cross
// sections with several loops (the liver) need no special case.
#pragma once

#include "cut/conforming.hpp"
#include "mesh/mesh.hpp"

#include <stdexcept>
#include <string>

namespace cutsim {

// TetGen refused the surface or failed; the message names the reason TetGen gave.
class RemeshError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// True when this build links TetGen; without it the functions below throw RemeshError.
bool haveTetGen();

// TetGen's own improvement of an existing tet mesh (switches e.g. "rO10/7zQ": reconstruct the
// mesh, then flips, smoothing and vertex insertion/deletion at optimisation level 10), the
// baseline of `cutsim bench improve`. Throws RemeshError when TetGen fails or is absent.
TetMesh tetgenOptimize(const TetMesh& mesh, const std::string& switches);

// TetGen on a closed surface (switches e.g. "pq1.4a1e-7zQ"): the tets that fill it. Throws
// RemeshError when TetGen refuses the surface or is absent.
TetMesh tetgenSurface(const SurfaceMesh& s, const std::string& switches);

struct RemeshOptions {
    // TetGen switches: p = the input is a piecewise linear complex (our closed surface),
    // q1.414 = radius-edge ratio bound sqrt(2) (TetGen's quality default, well shaped tets),
    // a = volume bound (maxVolume below). "zQ" (0-based, quiet) and the volume are appended.
    std::string switches = "pq1.414";
    double maxVolume = 0;             // largest tet volume [m^3]; 0: the mean tet volume of the input,
                                      // so the new mesh has the input's resolution
    double coplanarTolerance = 1e-9;  // facets closer than this * piece diagonal to one plane are
                                      // merged into one polygon, so TetGen sees the cut as one face [-]
    KeepSide keep = KeepSide::Both;
};

struct RemeshReport {
    int nodes = 0;             // nodes of the result
    int tets = 0;              // tets of the result
    int pieces = 0;            // connected pieces remeshed one by one
    int surfaceTriangles = 0;  // boundary triangles handed over, summed over pieces
    int facets = 0;            // TetGen facets after merging coplanar triangles
    double minVolume = 0;      // smallest tet volume [m^3]
    double volumeBefore = 0;   // volume of the kept input pieces [m^3]
    double volumeAfter = 0;    // volume of the result [m^3]
    std::string switches;      // the full TetGen switch string of the last call
};

struct RemeshResult {
    TetMesh mesh;
    RemeshReport report;
};

// Tetrahedralizes each connected piece of mesh again from its boundary surface.
RemeshResult remeshPieces(const TetMesh& mesh, const RemeshOptions& opts = {});

// Cuts mesh by the plane (conforming split, no snapping), keeps opts.keep and remeshes each piece.
RemeshResult remeshCut(const TetMesh& mesh, const CutPlane& plane, const RemeshOptions& opts = {});

}  // namespace cutsim
