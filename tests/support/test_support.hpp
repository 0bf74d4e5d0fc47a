// Shared helpers for tests: paths to data and small generated meshes.
#pragma once

#include "fem/model.hpp"
#include "mesh/mesh.hpp"

#include <string>

namespace cutsim::test {

// Path of a file in the third-party data folder, e.g. data("tet/sofa_liver.msh").
std::string data(const std::string& rel);
// Path of a file in the source tree, e.g. source("assets/scenes/demo.json").
std::string source(const std::string& rel);
// A fresh empty temporary directory for this test.
std::string tempDir();
// A fresh empty folder named after the running test, apart from tempDir() (which runCutsim wipes),
// for scenes and output folders that commands read and write.
std::string workDir();

// The unit right tet: corners 0, e_x, e_y, e_z.
TetMesh unitTet();

// Regular box [0,lx]x[0,ly]x[0,lz] split into nx*ny*nz cubes of 6 tets each (Kuhn split,
// conforming across cubes), all positively oriented.
TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz);

// Total area of the boundary faces (faces used by one tet).
double boundaryArea(const TetMesh& m);

// Writes text (binary-exact) to path and returns path; reads a whole file back.
std::string writeText(const std::string& path, const std::string& text);
std::string readText(const std::string& path);

// Reference lambda_max(M^-1 K) over the free DOFs by a dense eigen-solve of M^-1/2 K M^-1/2,
// independent of physics/timestep; for small models only.
double denseLambdaMax(const Model& m);

// Fixes the nodes whose rest coordinate `axis` is below `value` (a clamp on a plane).
void fixBelow(Model& m, int axis, double value);

// Runs the cutsim executable with the given arguments; returns its exit code, fills out/err.
int runCutsim(const std::string& args, std::string* out = nullptr, std::string* err = nullptr);

}  // namespace cutsim::test
