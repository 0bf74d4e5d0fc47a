// Mesh readers and writers. Every reader throws InputError naming the file and line on bad input.
#pragma once

#include "mesh/mesh.hpp"

#include <string>
#include <vector>

namespace cutsim {

struct ReadOptions {
    double scale = 1.0;      // multiplies every coordinate (thesis meshes need it, docs/method.md sec. 3)
    bool reorient = false;   // swap two nodes of inverted tets instead of rejecting them
    double minVolume = 0.0;  // |V| <= minVolume * (mean |V|) counts as zero volume: rejected
    std::string scaleKey;    // where scale was given ("scene.json: object.scale"): the coordinate-range
                             // errors a scale other than 1 causes name it beside the file
};

// What a reader saw and fixed; filled when a pointer is given.
struct ReadReport {
    std::vector<int> inverted;  // tets with negative volume (reoriented when asked)
    int skippedElements = 0;    // non-tet elements ignored (lines, triangles, ...)
    int unreferencedNodes = 0;  // nodes no tet uses (kept, they carry no mass)
};

// Volume meshes, by extension: .msh (Gmsh v1, 2.2 ASCII, 4.1 ASCII), .node/.ele (TetGen, either
// name), .mesh (MEDIT), .vtu (VTK XML ASCII). Inverted tets are an error unless opts.reorient.
TetMesh readTetMesh(const std::string& path, const ReadOptions& opts = {}, ReadReport* report = nullptr);

// Surface meshes, by extension: .obj, .off, .stl (ASCII or binary). Polygons are fanned into triangles.
// scaleKey as ReadOptions::scaleKey.
SurfaceMesh readSurfaceMesh(const std::string& path, double scale = 1.0, const std::string& scaleKey = {});

// A per-element or per-node scalar field for ParaView.
struct Field {
    std::string name;
    std::vector<double> values;  // components values per element (cell field) or per node (point field)
    int components = 1;          // 3: a vector, x y z per element or node
};

// VTK XML unstructured grid, ASCII. Written to a temporary file and renamed.
void writeVtu(const std::string& path, const TetMesh& mesh, const std::vector<Field>& cellFields = {},
              const std::vector<Field>& pointFields = {});

// Gmsh 2.2 ASCII, node ids 1..n, element type 4. Written to a temporary file and renamed.
void writeMsh22(const std::string& path, const TetMesh& mesh);

}  // namespace cutsim
