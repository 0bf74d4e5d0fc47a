// From a closed surface to a simulation-ready tet mesh (`cutsim tetra`, scene key object.tetra):
// the surface checked, filled by Gmsh (remeshed at a target edge length, the volume by HXT) or by
// TetGen (the surface kept), improved for the stable step (improve/improve.hpp), put in spatial
// order (mesh/generate.hpp spatialOrder).
#pragma once

#include "fem/material.hpp"
#include "mesh/mesh.hpp"

#include <string>
#include <utility>
#include <vector>

namespace cutsim {

// Which mesher fills the surface. Gmsh remeshes the surface at the target edge (its points on the
// input's triangles, creases kept), so the input's slivers and tiny triangles do not reach the tets;
// it runs in a program of its own, cutsim-gmsh-tetra (gmshTetraProgram). TetGen keeps every input
// triangle. Auto: Gmsh when its program is there and its mesh keeps the volume and boundary bounds,
// else TetGen (the report says why).
enum class Mesher { Auto, Gmsh, TetGen };

struct TetraOptions {
    double size = 0;  // target edge length [m]: Gmsh's largest element size; TetGen's volume bound is
                      // twice the regular tet of this edge
    bool improve = true;
    Material material;    // for the exact step (the improver's measure)
    int threads = 1;      // the improver's threads (its result depends on the count)
    std::string sizeKey;  // where size was given ("scene.json: object.tetra.size"): the errors of the
                          // mesh's size name it (else the surface file and --size)
    Mesher mesher = Mesher::Auto;
};

struct TetraReport {
    int surfaceTriangles = 0;
    int degenerateTriangles = 0;   // of zero area, dropped before meshing
    std::string mesher;            // "gmsh" or "tetgen": which one made the mesh
    std::string mesherNote;        // Auto: why TetGen ran (Gmsh absent, failed or out of bounds); empty else
    double creaseAngle = 0;        // Gmsh: edges turning by more than this were kept as creases [deg]
    int gmshRefinements = 0;       // Gmsh: times its mesh was made again with smaller elements where
                                   // the surface lay past its share of the boundary bound
    double meshedVolume = 0;       // Gmsh: the volume of its mesh, before the improver [m^3]
    double meshedDistance = 0;     // Gmsh: its boundary's Hausdorff distance to the surface [m]
    double improverCreases = 180;  // the improver kept edges turning more than this as creases [deg]
                                   // (180: none; Gmsh's mesh improved again with creases kept when
                                   // the first pass left the boundary bound)
    int tetsMeshed = 0;            // the mesher's tets
    int nodes = 0, tets = 0;       // the result's
    double dtBefore = 0;           // exact step of the mesher's mesh [s]
    double dtAfter = 0;            // exact step of the result [s]
    double regularEdge = 0;        // a: edge of the regular tet of the result's median element volume [m]
    double dtScale = 0;            // a / c_p [s]: the result's exact step over it is the step quality
    double volumeSurface = 0;      // enclosed by the surface [m^3]
    double volumeMesh = 0;         // of the result [m^3]
    double boundaryDistance = 0;   // the Hausdorff distance between the result's boundary and the
                                   // surface (both ways; TetGen's: the improver's bound from the
                                   // surface, which TetGen's boundary is) [m]
    double diagonal = 0;           // the surface's bounding-box diagonal [m]
    double minVolume = 0;          // smallest element volume of the result [m^3]
    int inverted = 0;              // elements of the result with volume <= 0
    std::vector<std::pair<std::string, double>> seconds;  // per phase: check, gmsh or tetgen, measure,
                                                          // improve, order [s]
    std::string cacheError;  // tetraCached: why the built mesh could not be cached (empty: cached)
};

struct TetraResult {
    TetMesh mesh;
    TetraReport report;
};

// The cutsim-gmsh-tetra program: $CUTSIM_GMSH_TETRA, else beside the running program, else in the
// install's and the build's program folders; empty when none is there.
std::string gmshTetraProgram();

const char* mesherName(Mesher m);  // "auto", "gmsh", "tetgen"

// Refuses (InputError naming the file and the defect) a surface that does not close a volume:
// open, non-manifold or inconsistently oriented edges, duplicated triangles; TetGen refuses a
// self-intersecting one (the message says so). Unreferenced vertices are dropped.
TetraResult tetraFromSurface(SurfaceMesh surface, const TetraOptions& opts);

// object.tetra: the mesh of surface file `path` at `scale` built by tetraFromSurface, or read from
// the cache when built before with the same file content and options. The cache folder is
// $CUTSIM_CACHE, else $XDG_CACHE_HOME/cutsim, else ~/.cache/cutsim (files tetra-<hash>.msh,
// written through a temporary file and a rename). `cached` tells which; `report` is filled when
// built. scaleKey as ReadOptions::scaleKey.
TetMesh tetraCached(const std::string& path, double scale, const TetraOptions& opts, bool& cached, TetraReport& report,
                    std::string& cacheFile, const std::string& scaleKey = {});

}  // namespace cutsim
