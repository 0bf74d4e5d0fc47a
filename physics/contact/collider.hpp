// Static colliders a scene declares (a floor, boxes, spheres, triangle meshes): fixed in the world,
// touched by the object's surface as tools are (contact/contact.hpp), with Coulomb friction.
// Plain data, no Bullet types.
#pragma once

#include "contact/tool.hpp"

#include <Eigen/Core>

#include <string>

namespace cutsim {

// How contact acts (scene key contact.model; contact/contact.hpp).
enum class ContactModel { Projection, Penalty };

struct ColliderDef {
    enum class Kind { Plane, Box, Sphere, Mesh } kind = Kind::Plane;
    std::string name;
    Pose pose;  // plane: a point on it (position), its normal the local +z; box, sphere, mesh: frame
    Eigen::Vector3d size = Eigen::Vector3d::Zero();  // box: half extents [m]; sphere: x = radius [m]
    Eigen::Matrix3Xd vertices;                       // mesh: local vertices (3 x nVerts) [m]
    Eigen::Matrix3Xi triangles;                      // mesh: closed, outward-facing triangles (3 x nTris)
    double friction = 0;                             // Coulomb coefficient with the tissue [-]

    // The plane's unit normal, pointing out of the solid half-space (world).
    Eigen::Vector3d normal() const { return pose.orientation * Eigen::Vector3d::UnitZ(); }
};

}  // namespace cutsim
