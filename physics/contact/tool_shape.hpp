// A tool as drawn: its solid, pose and size. Defined with the tools (contact/tool.hpp makes them
// from a tool's parts); snapshot/snapshot.hpp carries them to the renderer.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>

namespace cutsim {

// A rigid tool, drawn as a solid of its shape.
struct ToolShape {
    enum class Kind : std::uint8_t { Sphere, Capsule, Box };
    Kind kind = Kind::Sphere;
    Eigen::Vector3d position = Eigen::Vector3d::Zero();               // centre [m]
    Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  // local -> world
    Eigen::Vector3d size = Eigen::Vector3d::Constant(0.01);           // [m] sphere: radius in x;
                                                             // capsule: radius in x, half-length of the axis (local z)
                                                             // in y; box: half extents in x, y, z
};

}  // namespace cutsim
