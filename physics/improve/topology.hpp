// The mesh improver's elements as a mesh (improve.cpp): the live mesh, and the link condition of
// an edge collapse.
#pragma once

#include "mesh/mesh.hpp"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace cutsim {

// The alive elements of T at positions X as a mesh, unreferenced nodes dropped, the others in
// their order.
TetMesh liveMesh(const Eigen::Matrix3Xd& X, const std::vector<std::array<int, 4>>& T, const std::vector<char>& alive);

// After replacing the elements `olds` by `news` (node lists), every face around node q is used by
// at most two elements and no element repeats (the link condition, checked on faces). nt: a
// node's alive elements, of T.
bool manifoldAfter(int q, const std::vector<int>& olds, const std::vector<std::array<int, 4>>& news,
                   const std::vector<std::vector<int>>& nt, const std::vector<std::array<int, 4>>& T);

}  // namespace cutsim
