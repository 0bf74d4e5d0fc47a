// Convex pieces of a tetrahedron in its reference coordinates, for the exact volumes and faces of
// XFEM virtual elements (thesis sec. 2.3, Algorithm 5: a virtual element is its parent restricted
// to one side of the cut, weighted by that side's volume fraction).
//
// A point is xi = (l1, l2, l3), the barycentric weights of corners 1..3 (l0 = 1 - l1 - l2 - l3), so
// the parent is the reference tet (0, e1, e2, e3) of volume 1/6 and every volume below is a fraction
// of the parent's, whatever its shape. A cutting plane is given by its signed distances at the four
// corners; it is linear in xi. Ties go to the positive side (s >= 0), the same rule for every
// element, so a plane through a node, an edge or a face splits the mesh consistently.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace cutsim {

// A side of a cutting plane inside one parent tet: s(xi) = sum_a l_a(xi) s_a.
struct Halfspace {
    Eigen::Vector4d s = Eigen::Vector4d::Zero();  // signed distance at the parent's corners [m]
    bool positive = false;                        // keeps s >= 0 (true) or s < 0 (false)
    int cut = 0;                                  // id of the cut that made it

    // Value at a point; exact at a corner (corner >= 0) so ties at nodes are decided identically
    // by every element sharing the node.
    double at(const Eigen::Vector3d& xi, int corner) const;
};

struct PolyFace {
    std::vector<int> v;  // vertex indices, counter-clockwise seen from outside
    int tag = 0;         // 0..3: on the parent's face opposite that corner; 4 + cut id: a cut face
};

struct ConvexPiece {
    std::vector<Eigen::Vector3d> xi;  // vertices in reference coordinates
    std::vector<int> corner;          // parent corner a vertex is, or -1 (one per vertex)
    std::vector<PolyFace> faces;

    bool empty() const { return faces.empty(); }
};

// The whole reference tet.
ConvexPiece referenceTet();

// The part of piece on h's side. The cut face gets tag 4 + h.cut.
ConvexPiece clip(const ConvexPiece& piece, const Halfspace& h);

// Volume as a fraction of the parent's (divergence theorem, exact for planar faces) [-].
double volumeFraction(const ConvexPiece& piece);

// Integrals over the piece of the barycentric weights, as fractions of the parent's volume:
// first[a] = int l_a / V, second[a] = int l_a^2 / V (for the lumping options of thesis sec. 2.3.3).
void weightIntegrals(const ConvexPiece& piece, Eigen::Vector4d& first, Eigen::Vector4d& second);

// A side of a plane on one triangle: signed distances at its three corners.
struct FaceSide {
    Eigen::Vector3d s = Eigen::Vector3d::Zero();  // [m]
    bool positive = false;
};

// Area of a triangle clipped by sides, as a fraction of the triangle's. Two virtual elements that
// share a face are one body across it when their sides leave some of it to both (virtual node
// algorithm, Molino et al. 2004).
double faceAreaFraction(const std::vector<FaceSide>& sides);

// Barycentric weights of a reference point.
inline Eigen::Vector4d weightsOf(const Eigen::Vector3d& xi) { return {1.0 - xi.sum(), xi[0], xi[1], xi[2]}; }

}  // namespace cutsim
