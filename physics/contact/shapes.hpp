// Bullet conversions and shapes shared by the contact world and its signed distances (internal).
#pragma once

#include "contact/tool.hpp"

#include <btBulletCollisionCommon.h>

#include <Eigen/Core>

#include <memory>

namespace cutsim {

// inline: the contact query converts every candidate triangle's box
inline btVector3 bt(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
inline Eigen::Vector3d eig(const btVector3& v) { return {v.x(), v.y(), v.z()}; }
btTransform bt(const Pose& p);

// A Bullet convex shape of one tool part. Margins are zero for boxes and hulls so that their core
// is the shape itself; a sphere's or capsule's radius is its margin, which SignedDistance subtracts.
std::unique_ptr<btConvexShape> makeShape(const ToolPart& p, const Eigen::Matrix3Xd* hull);

// Signed distance of the world point x to a sphere, capsule or box part whose frame is `frame`,
// in closed form (the same as btGjkEpaSolver2::SignedDistance up to rounding, without its
// iterations); n is the way out of the part. False for a hull, which goes to GJK/EPA.
bool closedFormDistance(const ToolPart& part, const btTransform& frame, const btVector3& x, double& d,
                        Eigen::Vector3d& n);

}  // namespace cutsim
