// A surface carried by a tet mesh. Each vertex sits at fixed barycentric weights inside one
// element, so it follows the deformation: x_v = sum_a w_a x[tets(a, element_v)]. This is how the
// mesh-intersection method renders a fine surface on a coarse background mesh (thesis ch. 6) and
// how cut faces and clipped boundary faces of virtual elements follow their pieces.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace cutsim {

struct EmbeddedSurface {
    Eigen::Matrix3Xi triangles;  // vertex indices, counter-clockwise seen from outside (3 x nTris)
    std::vector<int> element;    // element holding each vertex (nVerts)
    Eigen::Matrix4Xd weights;    // barycentric weights in that element's rest shape (4 x nVerts) [-]
    std::vector<int> cutId;      // the cut that made each triangle, -1 for none (nTris)

    int vertices() const { return static_cast<int>(element.size()); }
    int faces() const { return static_cast<int>(triangles.cols()); }
    bool cutFace(int t) const { return cutId[static_cast<size_t>(t)] >= 0; }  // made by a cut
};

// An embedded surface from per-vertex lists (element, weights) and per-triangle lists.
EmbeddedSurface makeEmbeddedSurface(std::vector<int> element, const std::vector<Eigen::Vector4d>& weights,
                                    const std::vector<Eigen::Vector3i>& triangles, std::vector<int> cutId);

// Vertex positions (3 x nVerts) [m] for node positions x (3 x nNodes) [m].
void embeddedPositions(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& x,
                       Eigen::Matrix3Xd& out);

// Barycentric weights of point p in the tet with corners X0..X3 (they sum to 1; all >= 0 inside).
Eigen::Vector4d barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& X0, const Eigen::Vector3d& X1,
                            const Eigen::Vector3d& X2, const Eigen::Vector3d& X3);

// The boundary of a tet mesh (faces used by one tet, outward) as an embedded surface: one vertex
// per boundary node, riding the element of its first boundary face with weight 1 on that node.
EmbeddedSurface boundarySurface(const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X);

// The mesh node a vertex follows most (largest weight), e.g. to average element values around it.
int dominantNode(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, int vertex);

}  // namespace cutsim
