// Inside/outside of a triangle surface by the generalized winding number (Jacobson et al. 2013):
// w(q) = sum over triangles of the signed solid angle / 4 pi (van Oosterom & Strackee 1983). It is 1
// inside and 0 outside a closed oriented surface and degrades gracefully on holes, duplicated or
// self-intersecting faces, where ray parity (thesis Algorithm 2) flips on grazing rays. A bounding
// volume hierarchy evaluates far clusters by their dipole term (Barill et al. 2018, first order).
#pragma once

#include "mesh/mesh.hpp"

#include <Eigen/Core>

#include <vector>

namespace cutsim {

struct WindingTree {
    struct Node {
        Eigen::Vector3d lo, hi;      // bounding box [m]
        Eigen::Vector3d center;      // area-weighted centroid of the node's triangles [m]
        Eigen::Vector3d areaNormal;  // sum of (area x unit normal) of its triangles [m^2]
        double radius = 0;           // max distance from center to a vertex of its triangles [m]
        int first = 0, count = 0;    // range in order (leaf); count = 0 for an inner node
        int left = -1, right = -1;   // children (inner node)
    };
    const SurfaceMesh* surface = nullptr;  // not owned; must outlive the tree
    std::vector<Node> nodes;               // nodes[0] is the root
    std::vector<int> order;                // triangle indices, leaves hold contiguous ranges (nTris)
    double beta = 2.0;                     // a cluster is far when |q - center| > beta * radius [-]
};

// Builds the hierarchy (median split on the longest axis, up to 8 triangles per leaf).
WindingTree buildWindingTree(const SurfaceMesh& s);

// Signed solid angle of triangle (a, b, c) seen from q [sr]; positive when q is behind the
// counter-clockwise side (inside a closed outward surface).
double solidAngle(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  const Eigen::Vector3d& c);

// Winding number at q, summing every triangle exactly (reference, O(nTris)).
double windingNumberExact(const SurfaceMesh& s, const Eigen::Vector3d& q);

// Winding number at q through the hierarchy (exact near q, dipole terms far away).
double windingNumber(const WindingTree& t, const Eigen::Vector3d& q);

// The first point where the segment from a to b meets a triangle of the surface, as a fraction
// of the segment in [0, 1] (Moller & Trumbore 1997, through the tree's boxes); false when it
// meets none.
bool firstCrossing(const WindingTree& t, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double& at);

// Edge health of a surface: a closed oriented surface has every edge used exactly twice, once in each direction.
struct SurfaceCheck {
    int openEdges = 0;         // edges used by one triangle
    int nonManifoldEdges = 0;  // edges used by more than two triangles
    int misorientedEdges = 0;  // edges used twice in the same direction
    int degenerateFaces = 0;   // triangles repeating a vertex
    bool closed() const { return openEdges == 0 && nonManifoldEdges == 0 && misorientedEdges == 0; }
};
SurfaceCheck checkSurface(const SurfaceMesh& s);

}  // namespace cutsim
