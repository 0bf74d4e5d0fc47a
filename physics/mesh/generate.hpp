// Generated meshes: reference geometries for scenes, tests and benchmarks.
#pragma once

#include "mesh/mesh.hpp"

namespace cutsim {

// Box [0,lx]x[0,ly]x[0,lz] split into nx*ny*nz cubes of 6 tets each (Kuhn split along the cube
// diagonal, conforming across cubes), all positively oriented.
TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz);

// Red refinement (Bey 1995): each tet split into 8 at its edge midpoints (4 corner tets and 4 from
// the octahedron, cut along the diagonal x02-x13), all positively oriented. The input's nodes keep
// their indices (midpoints are appended), so values on the coarse nodes compare directly.
TetMesh refineTets(const TetMesh& mesh);

} // namespace cutsim
