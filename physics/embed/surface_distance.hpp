// Distance between two triangle surfaces (the Hausdorff distance, both ways): how far a mesh's
// boundary strays from the surface it was made from, and how far the surface lies from it.
#pragma once

#include "mesh/mesh.hpp"

#include <vector>

namespace cutsim {

// Largest distance from a point of `from` to the surface `to` [m]: an upper bound, at most
// spacing / sqrt(3) above the exact value (triangles of `from` split down to edges of `spacing`
// where the bound needs it).
double farthestDistance(const SurfaceMesh& from, const SurfaceMesh& to, double spacing);

// Distance from each point (a column) to the surface `to` [m].
std::vector<double> pointDistances(const Eigen::Matrix3Xd& points, const SurfaceMesh& to);

// The symmetric Hausdorff distance: the larger of the two one-sided distances above [m].
double hausdorffDistance(const SurfaceMesh& a, const SurfaceMesh& b, double spacing);

}  // namespace cutsim
