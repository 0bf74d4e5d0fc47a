// Generated meshes: reference geometries for scenes, tests and benchmarks.
#pragma once

#include "mesh/mesh.hpp"

namespace cutsim {

// Box [0,lx]x[0,ly]x[0,lz] split into nx*ny*nz cubes of 6 tets each (Kuhn split along the cube
// diagonal, conforming across cubes), all positively oriented.
TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz);

} // namespace cutsim
