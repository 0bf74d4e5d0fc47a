// Tool and collider shapes as Bullet convex shapes, and the signed distance of a point to a tool
// part (closed form where the shape has one, GJK/EPA otherwise).
#include "contact/contact.hpp"
#include "contact/shapes.hpp"

#include <BulletCollision/NarrowPhaseCollision/btGjkEpa2.h>

#include <cmath>
#include <memory>

namespace cutsim {

btTransform bt(const Pose& p) {
    const Eigen::Quaterniond& q = p.orientation;
    return btTransform(btQuaternion(q.x(), q.y(), q.z(), q.w()), bt(p.position));
}

std::unique_ptr<btConvexShape> makeShape(const ToolPart& p, const Eigen::Matrix3Xd* hull) {
    std::unique_ptr<btConvexShape> s;
    if (p.hull) {
        auto h = std::make_unique<btConvexHullShape>();
        for (int i = 0; i < hull->cols(); ++i) h->addPoint(bt(Eigen::Vector3d(hull->col(i))), false);
        h->recalcLocalAabb();
        s = std::move(h);
        s->setMargin(0);
    } else if (p.shape == ToolShape::Kind::Sphere) {
        s = std::make_unique<btSphereShape>(p.size.x());
    } else if (p.shape == ToolShape::Kind::Capsule) {
        s = std::make_unique<btCapsuleShapeZ>(p.size.x(), 2 * p.size.y());
    } else {
        s = std::make_unique<btBoxShape>(bt(p.size));
        s->setMargin(0);
    }
    return s;
}

bool closedFormDistance(const ToolPart& part, const btTransform& frame, const btVector3& x, double& d,
                        Eigen::Vector3d& n) {
    if (part.hull) return false;
    const btVector3 l = frame.invXform(x);
    const Eigen::Vector3d q = eig(l);
    Eigen::Vector3d nl;
    if (part.shape == ToolShape::Kind::Sphere || part.shape == ToolShape::Kind::Capsule) {
        // the core is a point or the segment z in [-size.y, size.y]; the radius is size.x
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        if (part.shape == ToolShape::Kind::Capsule) c.z() = std::clamp(q.z(), -part.size.y(), part.size.y());
        const Eigen::Vector3d r = q - c;
        const double len = r.norm();
        d = len - part.size.x();
        nl = len > 0 ? Eigen::Vector3d(r / len) : Eigen::Vector3d::UnitZ();
    } else {
        const Eigen::Vector3d h = part.size;  // half extents
        const Eigen::Vector3d e = q.cwiseAbs() - h;
        const Eigen::Vector3d sgn = q.unaryExpr([](double v) { return v < 0 ? -1.0 : 1.0; });
        if ((e.array() > 0).any()) {
            const Eigen::Vector3d o = e.cwiseMax(0.0);
            d = o.norm();
            nl = sgn.cwiseProduct(o) / d;
        } else {
            Eigen::Index k = 0;
            d = e.maxCoeff(&k);  // nearest face
            nl = Eigen::Vector3d::Zero();
            nl(k) = sgn(k);
        }
    }
    n = eig(frame.getBasis() * bt(nl));
    return true;
}

double partSignedDistance(const ToolPart& part, const ToolDef& tool, const Pose& frame, const Eigen::Vector3d& x,
                          Eigen::Vector3d& n, bool closedForm) {
    const btTransform tr = bt(frame);
    double d = 0;
    if (closedForm && closedFormDistance(part, tr, bt(x), d, n)) return d;
    const std::unique_ptr<btConvexShape> shape = makeShape(part, &tool.hull);
    btGjkEpaSolver2::sResults res;
    d = btGjkEpaSolver2::SignedDistance(bt(x), 0, shape.get(), tr, res);
    n = eig(res.normal);
    return d;
}

}  // namespace cutsim
