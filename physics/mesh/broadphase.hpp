// Broad phase over the elements of a deformed tet mesh: Bullet's btDbvt over element bounding
// boxes. The blade cut asks it for the elements whose boxes overlap the blade's swept box
// (contact/tool.hpp sweptAabb) before the exact swept-surface test.
#pragma once

#include <Eigen/Core>

#include <memory>
#include <vector>

namespace cutsim {

class ElementBroadphase {
public:
    // margin: how far a box is fattened so small motions need no tree update [m].
    explicit ElementBroadphase(double margin = 0);
    ~ElementBroadphase();
    ElementBroadphase(const ElementBroadphase&) = delete;
    ElementBroadphase& operator=(const ElementBroadphase&) = delete;

    // Boxes of elements tets (4 x nElems) at node positions x (3 x nNodes) [m]: builds the tree the
    // first time or when elements were removed, inserts appended ones, and sets the leaves again
    // once a node has drifted a few margins from where it was then (a pass over the nodes, not the
    // elements, per call); until then queries widen by the drift past the margin.
    void refit(const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& x);

    // Elements whose (fattened) box overlaps [lo, hi], ascending: all whose box does, and others
    // near it. Exact boxes when margin = 0.
    void query(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::vector<int>& out) const;

    int elements() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace cutsim
