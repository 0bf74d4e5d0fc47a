// Mesh containers; the readers throw InputError (util/input_error.hpp).
#pragma once

#include "util/input_error.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <stdexcept>
#include <string>
#include <vector>

namespace cutsim {

// Documented bounds on geometry read from files and scenes: beyond them volumes, stiffness rows or
// their eigenvalues leave the range of a double.
constexpr double kMaxCoordinate = 1e6;     // |coordinate| after scaling [m]
constexpr double kMinExtent = 1e-6;        // smallest object span [m]
constexpr double kMinTetFlatness = 1e-10;  // |volume| / (longest edge)^3 of any tet

// A tetrahedral volume mesh.
struct TetMesh {
    Eigen::Matrix3Xd X;         // node positions (3 x nNodes) [m]
    Eigen::Matrix4Xi tets;      // node indices of each tet, 0-based (4 x nTets)
    std::vector<long> nodeIds;  // id of each node in the source file (nNodes); empty if implicit
    std::string source;         // file it was read from, for messages

    int nodes() const { return static_cast<int>(X.cols()); }
    int elements() const { return static_cast<int>(tets.cols()); }
};

// A triangle surface mesh.
struct SurfaceMesh {
    Eigen::Matrix3Xd V;  // vertex positions (3 x nVerts) [m]
    Eigen::Matrix3Xi F;  // vertex indices of each triangle, 0-based (3 x nTris)
    std::string source;

    int vertices() const { return static_cast<int>(V.cols()); }
    int faces() const { return static_cast<int>(F.cols()); }
};

// What cleanSurface removed.
struct SurfaceCleanup {
    int weldedVertices = 0;   // vertices merged into an earlier one at exactly the same position
    int duplicateFaces = 0;   // triangles over the same three vertices as an earlier one
    int degenerateFaces = 0;  // triangles repeating a vertex or with area <= minArea
    int total() const { return duplicateFaces + degenerateFaces; }
};

// Welds exactly coincident vertices, then drops degenerate and duplicated triangles, so work that
// follows the triangles (spatial hashing, clipping, winding numbers) grows with the surface and not
// with its defects. Unreferenced vertices stay.
SurfaceCleanup cleanSurface(SurfaceMesh& s, double minArea);

// Signed volume of tet (a,b,c,d): det[b-a, c-a, d-a] / 6, positive when d sees abc counter-clockwise.
double tetSignedVolume(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                       const Eigen::Vector3d& d);
double tetSignedVolume(const TetMesh& m, int e);

// Boundary faces: faces used by exactly one tet, oriented outward (3 x nFaces).
Eigen::Matrix3Xi boundaryFaces(const TetMesh& m);

// Sum of tet volumes [m^3].
double totalVolume(const TetMesh& m);

// The elements `elements` of m as a mesh of their own, their nodes numbered in order of first use;
// nodeOf gets each new node's index in m.
TetMesh subMesh(const TetMesh& m, const std::vector<int>& elements, std::vector<int>& nodeOf);

// Volume enclosed by a closed, consistently oriented surface (divergence theorem) [m^3].
double enclosedVolume(const SurfaceMesh& s);

}  // namespace cutsim
