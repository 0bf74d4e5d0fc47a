// Generated meshes: reference geometries for scenes, tests and benchmarks.
#pragma once

#include "mesh/mesh.hpp"

namespace cutsim {

// How boxMesh splits its cubes, 6 tets each, conforming across cubes.
enum class BoxSplit {
    Kuhn,      // every cube along the same diagonal (0,0,0)-(1,1,1): the mesh has a preferred
               // diagonal, so a bar bends more easily about one skew axis than about the other
    Mirrored,  // each cube the mirror image of its neighbours (Kuhn split reflected in every axis
               // whose cube index is odd): with even counts the mesh has the box's mirror
               // symmetries, and a square bar bends alike about y and z
};

// Box [0,lx]x[0,ly]x[0,lz] split into nx*ny*nz cubes of 6 tets each, all positively oriented.
TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz, BoxSplit split = BoxSplit::Kuhn);

// Red refinement (Bey 1995): each tet split into 8 at its edge midpoints (4 corner tets and 4 from
// the octahedron, cut along the diagonal x02-x13), all positively oriented. The input's nodes keep
// their indices (midpoints are appended), so values on the coarse nodes compare directly.
TetMesh refineTets(const TetMesh& mesh);

// The same mesh with its elements in Z-order (Morton) of their centroids and its nodes in the order
// the elements first use them: elements near in memory are near in space, so a thread's range of
// elements shares few nodes with another's, and their nodes share cache lines. A mesher's output
// order (TetGen's) is arbitrary. nodeIds follow their nodes. nodeFrom and elementFrom, when given,
// get the input index of each output node and element.
TetMesh spatialOrder(const TetMesh& mesh, std::vector<int>* nodeFrom = nullptr,
                     std::vector<int>* elementFrom = nullptr);

}  // namespace cutsim
