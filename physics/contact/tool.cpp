#include "contact/tool.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace cutsim {

namespace {

// Keyframe interval [a, b] around t and the blend weight in it.
void bracket(const std::vector<ToolKey>& keys, double t, const ToolKey*& a, const ToolKey*& b, double& w) {
    assert(!keys.empty());
    a = &keys.front();
    b = a;
    w = 0;
    if (t <= keys.front().time) return;
    if (t >= keys.back().time) {
        a = b = &keys.back();
        return;
    }
    const auto it =
        std::upper_bound(keys.begin(), keys.end(), t, [](double x, const ToolKey& k) { return x < k.time; });
    b = &*it;
    a = &*(it - 1);
    w = b->time > a->time ? (t - a->time) / (b->time - a->time) : 1.0;
}

// Distance from the tool origin to its farthest point [m].
double reach(const std::vector<ToolPart>& parts, const ToolDef& tool) {
    double r = 0;
    for (const auto& p : parts) {
        double own = 0;
        if (p.hull) {
            for (int i = 0; i < tool.hull.cols(); ++i) own = std::max(own, tool.hull.col(i).norm());
        } else if (p.shape == ToolShape::Kind::Sphere) {
            own = p.size.x();
        } else if (p.shape == ToolShape::Kind::Capsule) {
            own = p.size.x() + p.size.y();
        } else {
            own = p.size.norm();
        }
        r = std::max(r, p.local.position.norm() + own);
    }
    return r;
}

void partAabb(const ToolPart& p, const ToolDef& tool, const Pose& pose, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
    const Eigen::Quaterniond q = pose.orientation * p.local.orientation;
    const Eigen::Vector3d c = pose.apply(p.local.position);
    if (p.hull) {
        for (int i = 0; i < tool.hull.cols(); ++i) {
            const Eigen::Vector3d w = c + q * tool.hull.col(i);
            lo = lo.cwiseMin(w);
            hi = hi.cwiseMax(w);
        }
        return;
    }
    Eigen::Vector3d half;
    if (p.shape == ToolShape::Kind::Sphere) {
        half.setConstant(p.size.x());
    } else if (p.shape == ToolShape::Kind::Capsule) {
        const Eigen::Vector3d axis = q * Eigen::Vector3d(0, 0, p.size.y());
        half = axis.cwiseAbs() + Eigen::Vector3d::Constant(p.size.x());
    } else {
        half = q.toRotationMatrix().cwiseAbs() * p.size;
    }
    lo = lo.cwiseMin(c - half);
    hi = hi.cwiseMax(c + half);
}

// Keys of the same pose: the pose is held, and w = 0 gives it bitwise as a single key would
// ((1 - w) x + w x is not always x in floating point).
bool samePose(const ToolKey& a, const ToolKey& b) {
    return a.pose.position == b.pose.position && a.pose.orientation.coeffs() == b.pose.orientation.coeffs();
}
}  // namespace

Pose toolPose(const ToolDef& tool, double t) {
    const ToolKey *a, *b;
    double w;
    bracket(tool.keys, t, a, b, w);
    if (samePose(*a, *b)) w = 0;
    Pose p;
    p.position = (1 - w) * a->pose.position + w * b->pose.position;
    p.orientation = a->pose.orientation.slerp(w, b->pose.orientation).normalized();
    return p;
}

double toolOpening(const ToolDef& tool, double t) {
    const ToolKey *a, *b;
    double w;
    bracket(tool.keys, t, a, b, w);
    if (a->opening == b->opening) w = 0;
    return (1 - w) * a->opening + w * b->opening;
}

ToolKey toolKeyAt(const ToolDef& tool, double t) {
    const ToolKey *a, *b;
    double w;
    bracket(tool.keys, t, a, b, w);
    ToolKey k;
    if (samePose(*a, *b) && a->opening == b->opening) {
        k = *a;
    } else {
        k.pose = toolPose(tool, t);
        k.opening = toolOpening(tool, t);
    }
    k.time = t;
    return k;
}

std::vector<ToolPart> toolParts(const ToolDef& tool, double t) {
    std::vector<ToolPart> parts;
    ToolPart p;
    switch (tool.kind) {
    case ToolDef::Kind::Sphere:
        p.shape = ToolShape::Kind::Sphere;
        p.size << tool.radius, 0, 0;
        parts.push_back(p);
        break;
    case ToolDef::Kind::Capsule:
        p.shape = ToolShape::Kind::Capsule;
        p.size << tool.radius, 0.5 * tool.length, 0;
        parts.push_back(p);
        break;
    case ToolDef::Kind::Blade:
        p.shape = ToolShape::Kind::Box;
        p.size = 0.5 * tool.size;
        parts.push_back(p);
        break;
    case ToolDef::Kind::Grasper: {
        // two jaws facing each other across the local y axis, `opening` apart
        p.shape = ToolShape::Kind::Box;
        p.size = 0.5 * tool.size;
        const double off = 0.5 * toolOpening(tool, t) + p.size.y();
        p.local.position << 0, off, 0;
        parts.push_back(p);
        p.local.position << 0, -off, 0;
        parts.push_back(p);
        break;
    }
    case ToolDef::Kind::Hull: {
        p.hull = true;
        p.shape = ToolShape::Kind::Box;
        const Eigen::Vector3d lo = tool.hull.rowwise().minCoeff(), hi = tool.hull.rowwise().maxCoeff();
        p.size = 0.5 * (hi - lo);
        parts.push_back(p);
        break;
    }
    }
    return parts;
}

void appendToolShapes(const ToolDef& tool, double t, std::vector<ToolShape>& out) {
    const Pose pose = toolPose(tool, t);
    for (const auto& p : toolParts(tool, t)) {
        ToolShape s;
        s.kind = p.shape;
        s.size = p.size;
        s.orientation = pose.orientation * p.local.orientation;
        Eigen::Vector3d centre = p.local.position;
        if (p.hull) centre += 0.5 * (tool.hull.rowwise().minCoeff() + tool.hull.rowwise().maxCoeff());
        s.position = pose.apply(centre);
        out.push_back(s);
    }
}

void toolAabb(const ToolDef& tool, double t, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
    lo.setConstant(1e300);
    hi.setConstant(-1e300);
    const Pose pose = toolPose(tool, t);
    for (const auto& p : toolParts(tool, t)) partAabb(p, tool, pose, lo, hi);
}

void sweptAabb(const ToolDef& tool, double t0, double t1, Eigen::Vector3d& lo, Eigen::Vector3d& hi, int samples) {
    samples = std::max(1, samples);
    lo.setConstant(1e300);
    hi.setConstant(-1e300);
    double grow = 0;
    Pose prev = toolPose(tool, t0);
    const double r = reach(toolParts(tool, t0), tool);
    for (int s = 0; s <= samples; ++s) {
        const double t = t0 + (t1 - t0) * s / samples;
        Eigen::Vector3d l, h;
        toolAabb(tool, t, l, h);
        lo = lo.cwiseMin(l);
        hi = hi.cwiseMax(h);
        const Pose p = toolPose(tool, t);
        // a point at distance r from the origin moves at most r * angle between samples beyond the
        // straight line the box union already covers
        grow = std::max(grow, r * p.orientation.angularDistance(prev.orientation));
        prev = p;
    }
    lo.array() -= grow;
    hi.array() += grow;
}

void bladeEdge(const ToolDef& tool, double t, Eigen::Vector3d& a, Eigen::Vector3d& b) {
    const Pose p = toolPose(tool, t);
    const Eigen::Vector3d h = 0.5 * tool.size;
    a = p.apply(Eigen::Vector3d(-h.x(), -h.y(), 0));
    b = p.apply(Eigen::Vector3d(h.x(), -h.y(), 0));
}

}  // namespace cutsim
