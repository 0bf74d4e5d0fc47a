// Inside volume of a tet cut by a closed surface, exactly and by refinement (thesis ch. 6, Algorithm 3).
#pragma once

#include "mesh/mesh.hpp"

#include <Eigen/Core>

#include <functional>
#include <vector>

namespace cutsim {

// Share of tet (p0, p1, p2, p3) (positively oriented) inside the closed, outward surface s [-],
// from the triangles in `tris` (every triangle that can touch the tet must be listed) and whether
// p3 is inside. Exact up to rounding, not clamped to [0, 1]. Divergence theorem with the apex at p0:
//   vol(T n O) = sum_t cone(p0, t n T) + cone(p0, F0 n O),  F0 the face opposite p0,
// and area(F0 n O), length(E n O) (E = p2p3, the edge of F0 opposite p1) recurse the same way, so
//   fraction = sum_t cone / V + sum_t seg / area(F0) + sum_t pt / |E| + [p3 in O].
// Degenerate contacts (a triangle in a tet face, an edge through a triangle edge) must be avoided by
// the caller (MI shifts the surface by a tiny generic offset).
double tetInsideFraction(const SurfaceMesh& s, const std::vector<int>& tris, const Eigen::Vector3d& p0,
                         const Eigen::Vector3d& p1, const Eigen::Vector3d& p2, const Eigen::Vector3d& p3,
                         bool p3Inside);

// Inside share of a tet by red refinement (Bey: 8 children of V/8 from the edge midpoints), as the
// thesis does with 5 levels: a child that no listed triangle's box touches counts by its corner's
// label, any other is split again; at the last level it counts by its centroid. fractionAtLevel[l]
// receives the estimate after l levels (l = 0..levels; resized). inside(x) classifies a point;
// corner labels of the tet are given.
void refinedInsideFraction(const SurfaceMesh& s, const std::vector<int>& tris, const Eigen::Vector3d (&p)[4],
                           const bool (&cornerInside)[4], int levels,
                           const std::function<bool(const Eigen::Vector3d&)>& inside,
                           std::vector<double>& fractionAtLevel);

// Inside test of x from a point a whose label is known: the parity of the crossings of segment a-x
// with the listed triangles. Local (short segment, few triangles); used inside one lattice cell.
bool insideFromAnchor(const SurfaceMesh& s, const std::vector<int>& tris, const Eigen::Vector3d& a, bool aInside,
                      const Eigen::Vector3d& x);

// The point of triangle (a, b, c) closest to q (Ericson, Real-Time Collision Detection 5.1.5).
Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                       const Eigen::Vector3d& c);
// Closest distance from q to triangle (a, b, c) [m].
double pointTriangleDistance(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c);

}  // namespace cutsim
