// The input mesh's boundary as the improver keeps it (docs/method.md sec. 4): moved boundary nodes
// slide on their original faces or crease segments and stay within a distance of the old surface.
#pragma once

#include "mesh/mesh.hpp"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace cutsim {

struct ReferenceBoundary {
    std::vector<std::array<int, 3>> faces;             // boundary triangles (node indices)
    std::vector<std::array<Eigen::Vector3d, 3>> tris;  // their original corners [m]
    std::vector<std::vector<int>> ring;                // faces around each node
    std::vector<std::vector<int>> crease;              // feature-edge neighbours of each node
    std::vector<char> onBoundary, movable;             // per node: movable on a disk, a crease, or inside

    // Faces, rings and feature edges (faces turning by more than featureAngleDeg) of `mesh`; a
    // boundary node moves when moveBoundary, on a manifold disk, not at a corner of creases.
    void build(const TetMesh& mesh, double featureAngleDeg, bool moveBoundary);
    // Distance from p to the nearest original face of `of` [m].
    double distance(const Eigen::Vector3d& p, const std::vector<int>& of) const;
    // distance(p, of) <= tol, stopping at the first face that is near enough.
    bool within(const Eigen::Vector3d& p, const std::vector<int>& of, double tol) const;
    // Distance from p to the nearest of the faces `of` at positions X (the new boundary) [m].
    double distanceMoved(const Eigen::Vector3d& p, const std::vector<int>& of, const Eigen::Matrix3Xd& X) const;
    // distanceMoved(p, of, X) <= tol, stopping at the first face that is near enough.
    bool withinMoved(const Eigen::Vector3d& p, const std::vector<int>& of, const Eigen::Matrix3Xd& X, double tol) const;
    // Where a triangle is sampled against a surface: its corners, edge midpoints and centroid.
    static std::array<Eigen::Vector3d, 7> samples(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                                  const Eigen::Vector3d& c) {
        return {a, b, c, (a + b) / 2, (b + c) / 2, (c + a) / 2, (a + b + c) / 3};
    }
    // Closest point on node i's original crease segments (X0: original positions).
    Eigen::Vector3d projectToCrease(int i, const Eigen::Vector3d& p, const Eigen::Matrix3Xd& X0) const;
    // Closest point on node i's original faces.
    Eigen::Vector3d projectToRing(int i, const Eigen::Vector3d& p) const;
    // Largest distance from a sample of the boundary at positions X (vertices, edge midpoints,
    // centroids) to the old faces around its face's vertices: a bound on the distance to the old
    // surface (X0: original positions). Faces whose vertices did not move are at distance 0.
    // bothWays: also from a sample of each moved face's original to the new faces around it.
    double movedDistance(const Eigen::Matrix3Xd& X, const Eigen::Matrix3Xd& X0, bool bothWays = false) const;
};

}  // namespace cutsim
