// Rigid tools: their shapes and kinematic paths. A tool is driven, not simulated: its pose at any
// time comes from keyframes (linear position, slerp rotation), and the tissue pushes back on it
// through contact (contact/contact.hpp). Plain data, no Bullet types.
#pragma once

#include "contact/tool_shape.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace cutsim {

// A rigid pose: world point = position + orientation * local point.
struct Pose {
    Eigen::Vector3d position = Eigen::Vector3d::Zero();               // [m]
    Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // local -> world
    Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return position + orientation * p; }
};

struct ToolKey {
    double time = 0;  // [s]
    Pose pose;
    double opening = 0;  // grasper: gap between the jaws [m]
};

struct ToolDef {
    enum class Kind { Sphere, Capsule, Blade, Grasper, Hull } kind = Kind::Sphere;
    std::string name;
    double radius = 0.01;  // sphere and capsule radius [m]
    double length = 0.02;  // capsule: distance between the cap centres, along local z [m]
    Eigen::Vector3d size =
        Eigen::Vector3d(0.04, 0.02, 0.001);  // blade: full extents [m]; the cutting
                                             // edge is the local -y edge, along x; grasper: one jaw's full extents
    Eigen::Matrix3Xd hull;                   // hull: points in local coordinates (3 x nPoints) [m]
    std::vector<ToolKey> keys;               // in time order; the pose is held before the first and after the last
    double stiffness =
        0;  // penalty stiffness per contact point [N/m]; 0 = automatic (penalty model: 0.5 of the stable limit)
    double damping = -1;  // penalty damping per contact point [N s/m]; < 0 = automatic
    double friction = 0;  // Coulomb coefficient with the tissue [-] (projection contact)
};

// One convex piece of a tool in the tool's frame (a grasper has two).
struct ToolPart {
    ToolShape::Kind shape = ToolShape::Kind::Sphere;  // drawn as; a hull is a Box of its bounds
    bool hull = false;                                // convex hull of ToolDef::hull instead of the shape
    Eigen::Vector3d size = Eigen::Vector3d::Zero();   // as ToolShape::size [m]
    Pose local;                                       // part frame in the tool frame
};

// Pose of a tool at time t: linear interpolation of positions, slerp of orientations.
Pose toolPose(const ToolDef& tool, double t);
// Grasper opening at time t [m] (linear between keyframes).
double toolOpening(const ToolDef& tool, double t);
// The keyframe that holds the tool as it is at time t (a copy of a key where the path rests, so a
// path re-keyed through it gives bitwise the same poses).
ToolKey toolKeyAt(const ToolDef& tool, double t);

// Convex parts of a tool at time t (grasper jaws move with the opening).
std::vector<ToolPart> toolParts(const ToolDef& tool, double t);

// The tool as the renderer draws it at time t (one ToolShape per part, in world coordinates).
void appendToolShapes(const ToolDef& tool, double t, std::vector<ToolShape>& out);

// World bounding box of the tool at time t [m].
void toolAabb(const ToolDef& tool, double t, Eigen::Vector3d& lo, Eigen::Vector3d& hi);

// Box holding every position the tool takes in [t0, t1] [m]: the union of the boxes at `samples`+1
// evenly spaced times. Exact for a pure translation between keyframes (the swept volume of a convex
// part is the hull of its two end copies); with rotation the sampling is an approximation, so the
// box is grown by the largest distance a tool point moves between two samples.
void sweptAabb(const ToolDef& tool, double t0, double t1, Eigen::Vector3d& lo, Eigen::Vector3d& hi, int samples = 8);

// The blade's cutting edge (local -y edge along x) at time t: endpoints a, b [m].
void bladeEdge(const ToolDef& tool, double t, Eigen::Vector3d& a, Eigen::Vector3d& b);

}  // namespace cutsim
