// Tool contact: penalty forces against hand-computed depths, the spread to nodes by embedding
// weights, the stable stiffness limit (one point on one free node by hand, a box against a dense
// bisection, the mass scale by hand, explicit steps of an MI slab pressed over its whole top face:
// bounded at the limit, diverging above it), tool paths, and the element broad phase against a scan.
#include "mesh/broadphase.hpp"
#include "contact/collider.hpp"
#include "contact/contact.hpp"
#include "contact/tool.hpp"
#include "embed/mi.hpp"
#include "fem/integrate.hpp"
#include "fem/model.hpp"
#include "mesh/io.hpp"
#include "test_support.hpp"
#include "timestep/timestep.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace cutsim {
namespace {

ToolDef sphereAt(const Eigen::Vector3d& c, double r, double k) {
    ToolDef t;
    t.kind = ToolDef::Kind::Sphere;
    t.radius = r;
    t.stiffness = k;
    t.damping = 0;
    ToolKey key;
    key.pose.position = c;
    t.keys.push_back(key);
    return t;
}

// One surface triangle whose three vertices lie in tet 0 with weights w0, w1, w2.
EmbeddedSurface oneTriangle(const Eigen::Vector4d& w0, const Eigen::Vector4d& w1, const Eigen::Vector4d& w2) {
    EmbeddedSurface es;
    es.triangles.resize(3, 1);
    es.triangles << 0, 1, 2;
    es.element = {0, 0, 0};
    es.weights.resize(4, 3);
    es.weights << w0, w1, w2;
    return es;
}

// A 10 x 10 x 2 cm slab of 1 cm cubes: its top face z = 0.02 has a vertex every centimetre.
struct Slab {
    TetMesh mesh = test::boxMesh(0.1, 0.1, 0.02, 10, 10, 2);
    EmbeddedSurface surf = boundarySurface(mesh.tets, mesh.X);
    Eigen::Matrix3Xd v = Eigen::Matrix3Xd::Zero(3, mesh.X.cols());
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, mesh.X.cols());

    ContactStep press(const ToolDef& tool) {
        ContactWorld w({tool});
        w.setSurface(contactPoints(surf, mesh.tets, mesh.X, 0));
        f.setZero();
        w.addForces(mesh.X, v, 0, 1e-4, f);
        return w.last();
    }
};

TEST(Contact, SpherePressedOnOneVertexGivesKTimesDepth) {
    Slab s;
    const double k = 1000, d = 1e-3, r = 0.005;
    const ContactStep st = s.press(sphereAt({0.05, 0.05, 0.02 + r - d}, r, k));
    ASSERT_EQ(st.contacts, 1);
    EXPECT_NEAR(st.maxDepth, d, 1e-9);
    // the vertex is pushed down out of the sphere; the probe is pushed up
    EXPECT_NEAR(st.reaction[0].z(), k * d, 1e-9);
    EXPECT_NEAR(st.reaction[0].head<2>().norm(), 0, 1e-9);
    EXPECT_NEAR(s.f.rowwise().sum().z(), -k * d, 1e-9);
    EXPECT_NEAR(s.f.cwiseAbs().sum(), k * d, 1e-9);  // all of it on one node
}

TEST(Contact, SphereOverFiveVerticesSumsPenaltyForces) {
    Slab s;
    // centre 11 mm above the surface, radius 15 mm: the vertex below at depth 4 mm and its four
    // neighbours 1 cm away at depth r - sqrt(0.01^2 + 0.011^2), pushed along their radius
    const double k = 500, r = 0.015, h = 0.011;
    const ContactStep st = s.press(sphereAt({0.05, 0.05, 0.02 + h}, r, k));
    ASSERT_EQ(st.contacts, 5);
    const double l = std::sqrt(0.01 * 0.01 + h * h);
    const double expected = k * ((r - h) + 4 * (r - l) * h / l);
    EXPECT_NEAR(st.reaction[0].z(), expected, 1e-9);
    EXPECT_NEAR(st.reaction[0].head<2>().norm(), 0, 1e-9);
    EXPECT_NEAR(st.maxDepth, r - h, 1e-9);
    EXPECT_LT((s.f.rowwise().sum() + st.reaction[0]).norm(), 1e-12);  // action = -reaction
}

// A blade does not touch the faces of its own cut (ContactWorld::ignoreCut): the five vertices of
// the test above, with every face around the middle one made by cut 2. Ignoring cut 2, the middle
// vertex (on cut faces only) is not touched and its four neighbours (also on other faces) are;
// ignoring another cut, or none, all five are.
TEST(Contact, ToolIgnoresTheFacesOfItsCut) {
    Slab s;
    const double k = 500, r = 0.015, h = 0.011;
    const Eigen::Vector3d mid(0.05, 0.05, 0.02);
    Eigen::Matrix3Xd rest;
    embeddedPositions(s.surf, s.mesh.tets, s.mesh.X, rest);
    int centre = -1;
    for (int i = 0; i < rest.cols(); ++i)
        if ((rest.col(i) - mid).norm() < 1e-9) centre = i;
    ASSERT_GE(centre, 0);
    int node = -1;  // the mesh node under it
    for (int i = 0; i < s.mesh.X.cols(); ++i)
        if ((s.mesh.X.col(i) - mid).norm() < 1e-9) node = i;
    ASSERT_GE(node, 0);
    s.surf.cutId.assign(static_cast<size_t>(s.surf.faces()), -1);
    int tagged = 0;
    for (int t = 0; t < s.surf.faces(); ++t)
        if ((s.surf.triangles.col(t).array() == centre).any()) s.surf.cutId[static_cast<size_t>(t)] = 2, ++tagged;
    ASSERT_GE(tagged, 4);
    const double l = std::sqrt(0.01 * 0.01 + h * h);
    const double ring = 4 * k * (r - l) * h / l;
    for (const int ignored : {-1, 5, 2}) {
        ContactWorld w({sphereAt(mid + Eigen::Vector3d(0, 0, h), r, k)});
        w.setSurface(contactPoints(s.surf, s.mesh.tets, s.mesh.X, 0));
        w.ignoreCut(0, ignored);
        s.f.setZero();
        w.addForces(s.mesh.X, s.v, 0, 1e-4, s.f);
        EXPECT_EQ(w.last().contacts, ignored == 2 ? 4 : 5) << ignored;
        EXPECT_NEAR(w.last().reaction[0].z(), ring + (ignored == 2 ? 0 : k * (r - h)), 1e-9) << ignored;
        EXPECT_NEAR(s.f.col(node).norm(), ignored == 2 ? 0 : k * (r - h), 1e-9) << ignored;
    }
}

// A blade slides in the slot it has cut (ContactWorld::setSlot): the points within its half
// width of the slot's plane whose projection lies in the swept area are not touched. The sphere
// of ToolIgnoresTheFacesOfItsCut presses five vertices; a slot over the centre one alone leaves the
// four of the ring (4 k (r - l) h / l), one beside it or too thin to reach the surface, all five.
TEST(Contact, ToolSlidesInItsSlot) {
    Slab s;
    const double k = 500, r = 0.015, h = 0.011;
    const Eigen::Vector3d mid(0.05, 0.05, 0.02);
    const double l = std::sqrt(0.01 * 0.01 + h * h);
    const double ring = 4 * k * (r - l) * h / l;
    const std::vector<Eigen::Vector2d> square{{-0.005, -0.005}, {0.005, -0.005}, {0.005, 0.005}, {-0.005, 0.005}};
    struct Case {
        Eigen::Vector3d origin;
        double halfWidth;
        int contacts;
    };
    // the plane through mid spanned by x and z: the surface (z = 0.02) crosses it along the x axis
    for (const Case& c : {Case{mid, 1e-3, 4}, Case{mid + Eigen::Vector3d(0.02, 0, 0), 1e-3, 5},
                          Case{mid + Eigen::Vector3d(0, 2e-3, 0), 1e-3, 5}}) {
        ContactWorld w({sphereAt(mid + Eigen::Vector3d(0, 0, h), r, k)});
        w.setSurface(contactPoints(s.surf, s.mesh.tets, s.mesh.X, 0));
        ContactWorld::Slot slot;
        slot.origin = c.origin;
        slot.u = Eigen::Vector3d::UnitX();
        slot.v = Eigen::Vector3d::UnitZ();
        slot.halfWidth = c.halfWidth;
        slot.polygons = {square};
        EXPECT_EQ(slot.contains(mid), c.contacts == 4);
        w.setSlot(0, slot);
        s.f.setZero();
        w.addForces(s.mesh.X, s.v, 0, 1e-4, s.f);
        EXPECT_EQ(w.last().contacts, c.contacts);
        EXPECT_NEAR(w.last().reaction[0].z(), ring + (c.contacts == 4 ? 0 : k * (r - h)), 1e-9);
    }
}

TEST(Contact, BoxAndCapsuleDepthsComeFromGjkEpa) {
    Slab s;
    const double k = 2000, d = 4e-4;
    ToolDef blade;
    blade.kind = ToolDef::Kind::Blade;
    blade.size << 0.008, 0.008, 0.004;  // half extents 4, 4, 2 mm: only the vertex below is inside
    blade.stiffness = k;
    blade.damping = 0;
    blade.keys.push_back({0, {Eigen::Vector3d(0.05, 0.05, 0.02 + 0.002 - d), Eigen::Quaterniond::Identity()}, 0});
    ContactStep st = s.press(blade);
    ASSERT_EQ(st.contacts, 1);
    EXPECT_NEAR(st.reaction[0].z(), k * d, 1e-9);
    EXPECT_NEAR(st.reaction[0].head<2>().norm(), 0, 1e-9);

    ToolDef cap;
    cap.kind = ToolDef::Kind::Capsule;
    cap.radius = 0.003;
    cap.length = 0.004;  // lying along x (local z turned onto x)
    cap.stiffness = k;
    cap.damping = 0;
    cap.keys.push_back({0,
                        {Eigen::Vector3d(0.05, 0.05, 0.02 + 0.003 - d),
                         Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitY()))},
                        0});
    st = s.press(cap);
    ASSERT_EQ(st.contacts, 1);
    EXPECT_NEAR(st.reaction[0].z(), k * d, 1e-9);
}

// The closed-form distances of spheres, capsules and boxes agree with Bullet's GJK/EPA on the same
// shape, inside and outside, in a turned frame.
TEST(Contact, ClosedFormDistancesMatchGjkEpa) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    ToolDef tool;
    Pose frame;
    frame.position << 0.01, -0.02, 0.03;
    frame.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
    ToolPart parts[3];
    parts[0].shape = ToolShape::Kind::Sphere;
    parts[0].size << 0.01, 0, 0;
    parts[1].shape = ToolShape::Kind::Capsule;
    parts[1].size << 0.004, 0.01, 0;
    parts[2].shape = ToolShape::Kind::Box;
    parts[2].size << 0.02, 0.01, 0.002;
    int inside = 0;
    const Eigen::Vector3d reach[3] = {{0.015, 0.015, 0.015}, {0.006, 0.006, 0.021}, {0.03, 0.015, 0.004}};
    for (int k = 0; k < 3; ++k)
        for (int i = 0; i < 400; ++i) {
            const ToolPart& part = parts[k];
            const Eigen::Vector3d x = frame.apply(reach[k].cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng))));
            Eigen::Vector3d n1, n2;
            const double d1 = partSignedDistance(part, tool, frame, x, n1, true);
            const double d2 = partSignedDistance(part, tool, frame, x, n2, false);
            inside += d1 < 0;
            ASSERT_NEAR(d1, d2, 1e-7) << static_cast<int>(part.shape) << " at " << x.transpose();
            ASSERT_NEAR(n1.norm(), 1, 1e-12);
            if (std::abs(d1) > 1e-4) {
                EXPECT_GT(n1.dot(n2), 0.999) << static_cast<int>(part.shape);
            }
            // the point moved along n by -d lies on the surface
            Eigen::Vector3d n3;
            EXPECT_NEAR(partSignedDistance(part, tool, frame, x - d1 * n1, n3), 0, 1e-12);
        }
    EXPECT_GT(inside, 150);  // both sides were sampled
    EXPECT_LT(inside, 900);
}

// A tool away from the surface computes no distance; the tree follows a surface moved far beyond
// its boxes' margin (a translation of 5 cm in small steps and in one jump), so the contact found
// equals a fresh world's.
TEST(Contact, FarToolTestsNothingAndMovedSurfaceIsFollowed) {
    Slab s;
    const double k = 1000, r = 0.005;
    ContactWorld far({sphereAt({0.05, 0.05, 0.2}, r, k)});
    far.setSurface(contactPoints(s.surf, s.mesh.tets, s.mesh.X, 0.002));
    far.addForces(s.mesh.X, s.v, 0, 1e-4, s.f);
    EXPECT_EQ(far.last().tested, 0);
    EXPECT_EQ(far.last().contacts, 0);
    for (const int stepsToMove : {50, 1}) {
        ContactWorld w({sphereAt({0.05 + 0.05, 0.05, 0.02 + r - 1e-3}, r, k)});
        w.setSurface(contactPoints(s.surf, s.mesh.tets, s.mesh.X, 0.002));
        Eigen::Matrix3Xd x = s.mesh.X;
        for (int i = 0; i <= stepsToMove; ++i) {
            x = s.mesh.X;
            x.row(0).array() += 0.05 * i / stepsToMove;
            s.f.setZero();
            w.addForces(x, s.v, 0, 1e-4, s.f);
        }
        ContactWorld fresh({sphereAt({0.05 + 0.05, 0.05, 0.02 + r - 1e-3}, r, k)});
        fresh.setSurface(contactPoints(s.surf, s.mesh.tets, s.mesh.X, 0.002));
        Eigen::Matrix3Xd f2 = Eigen::Matrix3Xd::Zero(3, x.cols());
        fresh.addForces(x, s.v, 0, 1e-4, f2);
        EXPECT_GT(w.last().contacts, 1) << stepsToMove;
        EXPECT_EQ(w.last().contacts, fresh.last().contacts) << stepsToMove;
        EXPECT_NEAR((w.last().reaction[0] - fresh.last().reaction[0]).norm(), 0, 1e-9) << stepsToMove;
    }
}

// Static colliders keep the points near them between queries (Piece::near): a slab bobbing 3 mm
// above and 0.2 mm into a floor plane, and into and out of a box over its top face, shaken each
// step by up to 0.05 mm at random (so the kept points serve on some steps and are queried again on
// others), gets bitwise the contacts and the projection of a world made afresh each step, which
// queries its trees every time.
TEST(Contact, CollidersKeepTheirNearPointsExactly) {
    Slab s;
    auto colliders = [] {
        ColliderDef floor;  // under the slab's bottom face (z = 0)
        ColliderDef box;    // over a corner of its top face (z = 0.02), 2.5 mm above it
        box.kind = ColliderDef::Kind::Box;
        box.size << 0.02, 0.02, 0.01;
        box.pose.position = {0.0, 0.0, 0.0325};
        return std::vector<ColliderDef>{floor, box};
    };
    ContactWorld kept({}, colliders());
    kept.setSurface(contactPoints(s.surf, s.mesh.tets, s.mesh.X, 0.004));
    const Eigen::VectorXd invMass = Eigen::VectorXd::Ones(s.mesh.X.cols());
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    int contacts = 0, touching = 0;
    // then a slow steady descent onto the floor, which finds any slack in the bound on the move
    for (int step = 0; step < 700; ++step) {
        // the slab's height: from 0.2 mm into the floor to 0.5 mm into the box, then down from 5 mm
        const bool bobbing = step < 200;
        const double h = bobbing ? -2e-4 + 3.2e-3 * (0.5 - 0.5 * std::cos(0.1 * step)) : 5e-3 - 1e-5 * (step - 200);
        Eigen::Matrix3Xd x = s.mesh.X;
        x.row(2).array() += h;
        if (bobbing)
            for (Eigen::Index i = 0; i < x.cols(); ++i) x.col(i) += 5e-5 * Eigen::Vector3d(u(rng), u(rng), u(rng));
        Eigen::Matrix3Xd v = Eigen::Matrix3Xd::Zero(3, x.cols());
        v.row(2).setConstant(-5);  // 0.5 mm a step: speculative contacts hold it
        Eigen::Matrix3Xd x2 = x, v2 = v;
        kept.project(invMass, step * 1e-4, 1e-4, x, v);
        ContactWorld fresh({}, colliders());
        fresh.setSurface(contactPoints(s.surf, s.mesh.tets, s.mesh.X, 0.004));
        fresh.project(invMass, step * 1e-4, 1e-4, x2, v2);
        ASSERT_EQ(kept.last().colliderContacts, fresh.last().colliderContacts) << step;
        ASSERT_EQ(kept.last().colliderDepth, fresh.last().colliderDepth) << step;
        ASSERT_TRUE(x == x2 && v == v2) << step;
        contacts += kept.last().colliderContacts;
        touching += kept.last().colliderContacts > 0;
    }
    EXPECT_GT(contacts, 2000);
    EXPECT_GT(touching, 100);  // the slab touched the floor, the box, or neither, in turns
    EXPECT_LT(touching, 600);
}

TEST(Contact, HullFromObjActsLikeItsShape) {
    // an 8 x 8 x 4 mm cube written as OBJ (in mm, scale 0.001): the same depth as the box blade
    std::string obj;
    for (int i = 0; i < 8; ++i)
        obj += "v " + std::to_string(i & 1 ? 4 : -4) + " " + std::to_string(i & 2 ? 4 : -4) + " " +
               std::to_string(i & 4 ? 2 : -2) + "\n";
    obj += "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n";
    const std::string path = test::writeText(test::tempDir() + "/cube.obj", obj);
    ToolDef hull;
    hull.kind = ToolDef::Kind::Hull;
    hull.hull = readSurfaceMesh(path, 0.001).V;
    const double k = 2000, d = 3e-4;
    hull.stiffness = k;
    hull.damping = 0;
    hull.keys.push_back({0, {Eigen::Vector3d(0.05, 0.05, 0.02 + 0.002 - d), Eigen::Quaterniond::Identity()}, 0});
    Slab s;
    const ContactStep st = s.press(hull);
    ASSERT_EQ(st.contacts, 1);
    EXPECT_NEAR(st.reaction[0].z(), k * d, 1e-9);
    EXPECT_NEAR(st.reaction[0].head<2>().norm(), 0, 1e-9);
}

TEST(Contact, GrasperJawsPushAVertexTowardTheGap) {
    // jaws 4 mm cubes facing each other across y, 2 mm apart, centred 1.5 mm beside the vertex:
    // the vertex sits 0.5 mm inside the lower jaw and is pushed into the gap (+y)
    Slab s;
    const double k = 1000;
    ToolDef g;
    g.kind = ToolDef::Kind::Grasper;
    g.size << 0.004, 0.004, 0.004;
    g.stiffness = k;
    g.damping = 0;
    g.keys.push_back({0, {Eigen::Vector3d(0.05, 0.05 + 0.0015, 0.02), Eigen::Quaterniond::Identity()}, 0.002});
    ContactStep st = s.press(g);
    ASSERT_EQ(st.contacts, 1);
    EXPECT_NEAR(st.reaction[0].y(), -k * 5e-4, 1e-9);
    EXPECT_NEAR(s.f.rowwise().sum().y(), k * 5e-4, 1e-9);
    // centred on the vertex, it sits in the gap: no contact
    g.keys[0].pose.position.y() = 0.05;
    st = s.press(g);
    EXPECT_EQ(st.contacts, 0);
}

TEST(Contact, DampingOpposesApproachOnly) {
    Slab s;
    const double k = 1000, c = 2, d = 1e-3, r = 0.005;
    ToolDef t = sphereAt({0.05, 0.05, 0.02 + r - d}, r, k);
    t.damping = c;
    // the surface moves up into the probe at 0.1 m/s: the penalty grows by c * 0.1
    s.v.row(2).setConstant(0.1);
    ContactStep st = s.press(t);
    EXPECT_NEAR(st.reaction[0].z(), k * d + c * 0.1, 1e-9);
    // moving away fast enough, the force would pull: it is cut at zero
    s.v.row(2).setConstant(-10);
    st = s.press(t);
    EXPECT_EQ(st.reaction[0].norm(), 0);
}

TEST(Contact, ForceOnEmbeddedVertexSpreadsByItsWeights) {
    // one tet; three surface vertices inside it, only the first under the probe
    Eigen::Matrix3Xd X(3, 4);
    X << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
    Eigen::Matrix4Xi tets(4, 1);
    tets << 0, 1, 2, 3;
    const EmbeddedSurface es = oneTriangle({0.1, 0.2, 0.3, 0.4}, {0.7, 0.1, 0.1, 0.1}, {0.1, 0.1, 0.7, 0.1});
    Eigen::Matrix3Xd p;
    embeddedPositions(es, tets, X, p);  // vertex 0 at (0.2, 0.3, 0.4)
    const double k = 100, d = 0.01, r = 0.05;
    ContactWorld w({sphereAt(Eigen::Vector3d(p.col(0)) + Eigen::Vector3d(0, 0, r - d), r, k)});
    w.setSurface(contactPoints(es, tets, X, 0));
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 4), v = Eigen::Matrix3Xd::Zero(3, 4);
    w.addForces(X, v, 0, 1e-3, f);
    ASSERT_EQ(w.last().contacts, 1);
    const Eigen::Vector3d fv(0, 0, -k * d);
    for (int a = 0; a < 4; ++a) EXPECT_NEAR((f.col(a) - es.weights(a, 0) * fv).norm(), 0, 1e-12) << a;
    EXPECT_NEAR((f.rowwise().sum() - fv).norm(), 0, 1e-12);
}

TEST(Contact, PointsOnEdgesAndFacesAtMostSpacingApart) {
    // right triangle with legs 1: spacing 0.5 splits the legs in 2, the hypotenuse (1.41) in 3,
    // and the face grid (3 divisions) has one interior point: 3 + 1 + 1 + 2 + 1 = 8 points
    Eigen::Matrix3Xd X(3, 4);
    X << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
    Eigen::Matrix4Xi tets(4, 1);
    tets << 0, 1, 2, 3;
    EmbeddedSurface es;
    es.triangles.resize(3, 1);
    es.triangles << 0, 1, 2;
    es.element = {0, 0, 0};
    es.weights = Eigen::Matrix4Xd::Zero(4, 3);
    es.weights(0, 0) = es.weights(1, 1) = es.weights(2, 2) = 1;
    const ContactPoints pts = contactPoints(es, tets, X, 0.5);
    ASSERT_EQ(pts.points(), 8);
    for (int p = 0; p < pts.points(); ++p) {
        EXPECT_NEAR(pts.weights.col(p).sum(), 1, 1e-12);
        Eigen::Vector3d x = Eigen::Vector3d::Zero();
        for (int i = 0; i < pts.count[p]; ++i) x += pts.weights(i, p) * X.col(pts.nodes(i, p));
        EXPECT_NEAR(x.z(), 0, 1e-12);  // on the face z = 0
        EXPECT_LE(x.x() + x.y(), 1 + 1e-12);
    }
}

TEST(ContactStiffness, OnePointOnOneFreeNodeIsHeadroomOverItsInverseMass) {
    // One tet, nodes 1-3 fixed: the free DOFs are node 0's. The surface's vertices 1 and 2 sit on
    // fixed nodes; vertex 0 has weight w0 = 0.4 on node 0, so C = (w0^2 / m0) I and
    // lambda_max(K_00 / m0 + k C) = (2 / dtCrit)^2 + k w0^2 / m0 = (2 / dt)^2 at
    // k = ((2/dt)^2 - (2/dtCrit)^2) m0 / w0^2.
    TetMesh mesh;
    mesh.X.resize(3, 4);
    mesh.X << 0, 0.01, 0, 0, 0, 0, 0.01, 0, 0, 0, 0, 0.01;
    mesh.tets.resize(4, 1);
    mesh.tets << 0, 1, 2, 3;
    Model m = buildModel(mesh, Material{});
    fixNodes(m, {1, 2, 3});
    const double dtc = exactCriticalDt(m).dt, dt = 0.9 * dtc;
    const EmbeddedSurface es = oneTriangle({0.4, 0.2, 0.2, 0.2}, {0, 1, 0, 0}, {0, 0, 1, 0});
    const ContactPoints pts = contactPoints(es, mesh.tets, mesh.X, 0);
    const double expected = (4 / (dt * dt) - 4 / (dtc * dtc)) * m.mass(0) / (0.4 * 0.4);
    EXPECT_NEAR(stableStiffness(pts, m, dt, dtc), expected, 1e-6 * expected);
    EXPECT_EQ(stableStiffness(pts, m, dtc, dtc), 0);
}

TEST(ContactStiffness, BoxLimitIsTheDenseBisection) {
    // 2 x 2 x 2 cubes, bottom fixed, points on edges and faces: the largest k with
    // lambda_max(M^-1/2 (K + k sum_p w_p w_p^T (x) I) M^-1/2) <= (2/dt)^2, by bisection on dense
    // eigenvalues, against the pencil solved by Lanczos.
    Model m = buildModel(test::boxMesh(0.02, 0.02, 0.02, 2, 2, 2), Material{});
    test::fixBelow(m, 2, 1e-9);
    const ContactPoints pts = contactPoints(boundarySurface(m.tets, m.X), m.tets, m.X, 0.006);
    const double dtc = exactCriticalDt(m).dt, dt = 0.8 * dtc;
    const int n = 3 * m.nodes();
    const Eigen::MatrixXd K(assembleStiffness(m));
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n, n);
    for (int p = 0; p < pts.points(); ++p)
        for (int i = 0; i < pts.count[p]; ++i)
            for (int j = 0; j < pts.count[p]; ++j)
                for (int d = 0; d < 3; ++d)
                    C(3 * pts.nodes(i, p) + d, 3 * pts.nodes(j, p) + d) += pts.weights(i, p) * pts.weights(j, p);
    Eigen::VectorXd s(n);
    for (int i = 0; i < n; ++i) s(i) = std::sqrt(m.invMass(i / 3));  // fixed DOFs drop out
    const Eigen::MatrixXd A = s.asDiagonal() * K * s.asDiagonal(), Cs = s.asDiagonal() * C * s.asDiagonal();
    auto lambdaMax = [](const Eigen::MatrixXd& S) {
        return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(S, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
    };
    double lo = 0, hi = 1e9;
    for (int it = 0; it < 100 && hi - lo > 1e-7 * hi; ++it) {
        const double k = 0.5 * (lo + hi);
        (lambdaMax(A + k * Cs) <= 4 / (dt * dt) ? lo : hi) = k;
    }
    EXPECT_NEAR(stableStiffness(pts, m, dt, dtc), lo, 1e-5 * lo);
}

TEST(ContactStiffness, MassScaleIsEffectiveMassOverReference) {
    Model m = buildModel(test::boxMesh(0.02, 0.02, 0.02, 2, 2, 2), Material{});
    fixNodes(m, {0});
    // vertices only: each point has weight 1 on its node, so its effective mass is the node's
    ContactPoints pts = contactPoints(boundarySurface(m.tets, m.X), m.tets, m.X, 0);
    std::vector<double> masses;
    for (int p = 0; p < pts.points(); ++p)
        if (m.invMass(pts.nodes(0, p)) > 0) masses.push_back(m.mass(pts.nodes(0, p)));
    std::sort(masses.begin(), masses.end());
    const double ref = masses[static_cast<size_t>(0.9 * static_cast<double>(masses.size() - 1))];
    EXPECT_EQ(referenceMass(pts, m.invMass), ref);
    EXPECT_LT(masses.front(), ref);  // the corners are lighter than the face centres
    scaleByMass(pts, m.invMass, ref);
    for (int p = 0; p < pts.points(); ++p) {
        const int a = pts.nodes(0, p);
        EXPECT_NEAR(pts.scale(p), m.invMass(a) > 0 ? std::min(1.0, m.mass(a) / ref) : 1.0, 1e-15) << p;
    }
    // and the penalty on a scaled point is scaled: one corner vertex under a sphere
    int corner = -1;
    for (int p = 0; p < pts.points(); ++p)
        if ((m.X.col(pts.nodes(0, p)) - Eigen::Vector3d(0.02, 0.02, 0.02)).norm() < 1e-12) corner = p;
    ASSERT_GE(corner, 0);
    const double k = 100, d = 1e-3, r = 0.004;
    ContactWorld w({sphereAt(Eigen::Vector3d(0.02, 0.02, 0.02 + r - d), r, k)});
    w.setSurface(pts);
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, m.nodes()), v = Eigen::Matrix3Xd::Zero(3, m.nodes());
    w.addForces(m.X, v, 0, 1e-4, f);
    ASSERT_EQ(w.last().contacts, 1);
    EXPECT_LT(pts.scale(corner), 1);
    EXPECT_NEAR(w.last().reaction[0].z(), pts.scale(corner) * k * d, 1e-12);
}

// An MI slab whose top face cuts its lattice cells at 15% (light outside nodes above it), bottom
// lattice nodes fixed, contact points on the top face only, pressed 1 mm over all of it by a large
// sphere: every point is in contact with the normal -z, so the limit is nearly reached.
struct PressedMiSlab {
    MiResult mi;
    ContactPoints pts;
    double dt = 0, dtc = 0;

    PressedMiSlab() {
        MiOptions o;
        o.h = 0.01;
        o.latticeCells = Eigen::Vector3i(4, 4, 2);
        o.latticeOrigin = Eigen::Vector3d::Zero();
        mi = buildMi(boxSurface({0.001, 0.001, 0.001}, {0.039, 0.039, 0.0115}), Material{}, o);
        test::fixBelow(mi.model, 2, 1e-9);
        mi.model.elementModel = ElementModel::Linear;
        // the top face: its triangles and their vertices, renumbered
        const EmbeddedSurface& s = mi.surface;
        Eigen::Matrix3Xd rest;
        embeddedPositions(s, mi.model.tets, mi.model.X, rest);
        EmbeddedSurface top;
        std::vector<int> map(static_cast<size_t>(s.vertices()), -1);
        std::vector<int> tris;
        for (int t = 0; t < s.faces(); ++t) {
            bool up = true;
            for (int k = 0; k < 3; ++k) up = up && std::abs(rest(2, s.triangles(k, t)) - 0.0115) < 1e-12;
            if (!up) continue;
            for (int k = 0; k < 3; ++k) {
                const int v = s.triangles(k, t);
                if (map[static_cast<size_t>(v)] < 0) {
                    map[static_cast<size_t>(v)] = top.vertices();
                    top.element.push_back(s.element[static_cast<size_t>(v)]);
                    top.weights.conservativeResize(4, top.vertices());
                    top.weights.col(top.vertices() - 1) = s.weights.col(v);
                }
                tris.push_back(map[static_cast<size_t>(v)]);
            }
        }
        top.triangles = Eigen::Map<Eigen::Matrix3Xi>(tris.data(), 3, static_cast<Eigen::Index>(tris.size() / 3));
        pts = contactPoints(top, mi.model.tets, mi.model.X, 0.004);
        scaleByMass(pts, mi.model.invMass, referenceMass(pts, mi.model.invMass));
        dtc = exactCriticalDt(mi.model).dt;
        dt = 0.9 * dtc;
    }

    // Largest displacement of a contact point over `steps` symplectic Euler steps from rest [m]
    // (infinity once non-finite), pressed by a box whose bottom is 1 mm below the face: through
    // the ContactWorld (unilateral), or as the linear spring the limit certifies (bilateral, -z).
    double run(double k, int steps, bool bilateral) const {
        const double zTool = 0.0115 - 1e-3;
        ToolDef box = sphereAt(Eigen::Vector3d::Zero(), 0, k);
        box.kind = ToolDef::Kind::Hull;
        box.hull.resize(3, 8);
        for (int c = 0; c < 8; ++c)
            box.hull.col(c) << (c & 1 ? 0.09 : -0.05), (c & 2 ? 0.09 : -0.05), (c & 4 ? 0.06 : zTool);
        ContactWorld w({box});
        w.setSurface(pts);
        State st = makeState(mi.model);
        Stepper stepper;
        StepOptions so;
        so.dt = dt;
        auto point = [&](const Eigen::Matrix3Xd& x, int p) {
            Eigen::Vector3d xp = Eigen::Vector3d::Zero();
            for (int q = 0; q < pts.count[p]; ++q) xp += pts.weights(q, p) * x.col(pts.nodes(q, p));
            return xp;
        };
        double worst = 0;
        for (int i = 0; i < steps; ++i) {
            st.fExt.setZero();
            if (bilateral) {
                for (int p = 0; p < pts.points(); ++p) {
                    const double fz = -pts.scale(p) * k * (point(st.x, p).z() - zTool);
                    for (int q = 0; q < pts.count[p]; ++q) st.fExt(2, pts.nodes(q, p)) += pts.weights(q, p) * fz;
                }
            } else {
                w.addForces(st.x, st.v, st.time, dt, st.fExt);
                if (i == 0) {
                    EXPECT_EQ(w.last().contacts, pts.points());
                }
            }
            stepper.step(mi.model, st, so);
            for (int p = 0; p < pts.points(); ++p) {
                const double u = (point(st.x, p) - point(mi.model.X, p)).norm();
                if (!std::isfinite(u)) return INFINITY;
                worst = std::max(worst, u);
            }
        }
        return worst;
    }
};

TEST(ContactStiffness, MiSlabPressedAtTheLimitStaysBoundedAndBlowsUpAbove) {
    const PressedMiSlab s;
    ASSERT_GT(s.mi.count(ElementClass::Interface), 0);
    double mMin = 1e300;
    for (int i = 0; i < s.mi.model.nodes(); ++i)
        if (s.mi.model.invMass(i) > 0) mMin = std::min(mMin, s.mi.model.mass(i));
    EXPECT_LT(mMin, 1e-4 * s.mi.model.mass.maxCoeff());  // light outside corners, as on the MI liver
    const double k = stableStiffness(s.pts, s.mi.model, s.dt, s.dtc);
    ASSERT_GT(k, 0);
    // the certified linearisation: released from 1 mm deep the points oscillate within a few mm
    // at the limit; 1.3 x beyond it (the z direction alone has a little slack) the top mode grows
    EXPECT_LT(s.run(0.98 * k, 1500, true), 0.01);
    EXPECT_EQ(s.run(1.3 * k, 1500, true), INFINITY);
    EXPECT_EQ(s.run(2.0 * k, 1500, true), INFINITY);
    // unilateral contact: entering and leaving the tool on alternate steps pumps energy when the
    // contact mode is near the limit (0.54 m at 1.0 x, 9.5 mm at 0.6 x), so tools default to
    // kDefaultStiffnessFraction x the limit: here within 3.1 mm, as the bilateral spring
    EXPECT_LT(s.run(kDefaultStiffnessFraction * k, 1500, false), 0.005);
    EXPECT_GT(s.run(k, 1500, false), 0.05);
}

TEST(Tool, KeyframesInterpolateLinearlyAndSlerp) {
    ToolDef t;
    t.keys.push_back({1.0, {Eigen::Vector3d(0, 0, 0), Eigen::Quaterniond::Identity()}, 0.0});
    t.keys.push_back({3.0,
                      {Eigen::Vector3d(2, 4, 0),
                       Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()))},
                      0.01});
    const Pose mid = toolPose(t, 2.0);
    EXPECT_NEAR((mid.position - Eigen::Vector3d(1, 2, 0)).norm(), 0, 1e-12);
    EXPECT_NEAR(Eigen::AngleAxisd(mid.orientation).angle(), std::numbers::pi / 4, 1e-12);
    EXPECT_NEAR((toolPose(t, 0).position - Eigen::Vector3d(0, 0, 0)).norm(), 0, 1e-12);  // held before
    EXPECT_NEAR((toolPose(t, 9).position - Eigen::Vector3d(2, 4, 0)).norm(), 0, 1e-12);  // and after
    EXPECT_NEAR(toolOpening(t, 2.0), 0.005, 1e-15);
}

TEST(Tool, GrasperJawsAndSweptBox) {
    ToolDef g;
    g.kind = ToolDef::Kind::Grasper;
    g.size << 0.02, 0.004, 0.006;
    g.keys.push_back({0, {}, 0.01});
    const auto parts = toolParts(g, 0);
    ASSERT_EQ(parts.size(), 2u);
    // inner faces of the jaws are `opening` apart
    EXPECT_NEAR((parts[0].local.position.y() - 0.002) - (parts[1].local.position.y() + 0.002), 0.01, 1e-15);

    ToolDef b;
    b.kind = ToolDef::Kind::Blade;
    b.size << 0.04, 0.02, 0.002;
    b.keys.push_back({0, {Eigen::Vector3d(0, 0, 0), Eigen::Quaterniond::Identity()}, 0});
    b.keys.push_back({1, {Eigen::Vector3d(0, 0, 0.1), Eigen::Quaterniond::Identity()}, 0});
    Eigen::Vector3d lo, hi;
    sweptAabb(b, 0, 1, lo, hi);
    // pure translation: exactly the union of the end boxes
    EXPECT_NEAR((lo - Eigen::Vector3d(-0.02, -0.01, -0.001)).norm(), 0, 1e-12);
    EXPECT_NEAR((hi - Eigen::Vector3d(0.02, 0.01, 0.101)).norm(), 0, 1e-12);
    Eigen::Vector3d a, e;
    bladeEdge(b, 0, a, e);
    EXPECT_NEAR((a - Eigen::Vector3d(-0.02, -0.01, 0)).norm(), 0, 1e-15);
    EXPECT_NEAR((e - Eigen::Vector3d(0.02, -0.01, 0)).norm(), 0, 1e-15);
}

std::vector<int> bruteForce(const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& x, const Eigen::Vector3d& lo,
                            const Eigen::Vector3d& hi) {
    std::vector<int> out;
    for (int e = 0; e < tets.cols(); ++e) {
        Eigen::Vector3d a = x.col(tets(0, e)), b = a;
        for (int k = 1; k < 4; ++k) {
            a = a.cwiseMin(x.col(tets(k, e)));
            b = b.cwiseMax(x.col(tets(k, e)));
        }
        if ((a.array() <= hi.array()).all() && (b.array() >= lo.array()).all()) out.push_back(e);
    }
    return out;
}

TEST(ElementBroadphase, EqualsBruteForceBeforeAndAfterRefit) {
    const TetMesh mesh = test::boxMesh(0.06, 0.06, 0.06, 6, 6, 6);
    Eigen::Matrix3Xd x = mesh.X;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.01, 0.07), jitter(-0.003, 0.003), ext(0.001, 0.03);
    ElementBroadphase bp;
    bp.refit(mesh.tets, x);
    EXPECT_EQ(bp.elements(), mesh.tets.cols());
    std::vector<int> got;
    for (int round = 0; round < 3; ++round) {
        for (int q = 0; q < 40; ++q) {
            const Eigen::Vector3d lo(u(rng), u(rng), u(rng));
            const Eigen::Vector3d hi = lo + Eigen::Vector3d(ext(rng), ext(rng), ext(rng));
            bp.query(lo, hi, got);
            EXPECT_EQ(got, bruteForce(mesh.tets, x, lo, hi)) << "round " << round << " query " << q;
        }
        for (int i = 0; i < x.cols(); ++i) x.col(i) += Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
        bp.refit(mesh.tets, x);
    }
    // a fattened tree returns a superset
    ElementBroadphase fat(0.002);
    fat.refit(mesh.tets, x);
    const Eigen::Vector3d lo(0.02, 0.02, 0.02), hi(0.03, 0.03, 0.03);
    fat.query(lo, hi, got);
    for (int e : bruteForce(mesh.tets, x, lo, hi)) EXPECT_TRUE(std::binary_search(got.begin(), got.end(), e)) << e;
}

// A fattened tree whose nodes move past a few margins sets its leaves again in place (inner boxes
// merged bottom up): every element whose box overlaps a query is returned, round after round of
// motions that stretch, shift and shear the mesh.
TEST(ElementBroadphase, FattenedTreeStaysASupersetThroughLargeMotions) {
    const TetMesh mesh = test::boxMesh(0.06, 0.06, 0.06, 6, 6, 6);
    Eigen::Matrix3Xd x = mesh.X;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-0.02, 0.09), jitter(-0.002, 0.002), ext(0.001, 0.03);
    ElementBroadphase fat(0.001);
    fat.refit(mesh.tets, x);
    std::vector<int> got;
    for (int round = 0; round < 8; ++round) {
        for (int i = 0; i < x.cols(); ++i) {  // a shear growing with height, a shift and a jitter
            x(0, i) += 0.1 * mesh.X(2, i) + 0.002;
            x.col(i) += Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
        }
        fat.refit(mesh.tets, x);
        for (int q = 0; q < 40; ++q) {
            const Eigen::Vector3d lo(u(rng), u(rng), u(rng));
            const Eigen::Vector3d hi = lo + Eigen::Vector3d(ext(rng), ext(rng), ext(rng));
            fat.query(lo, hi, got);
            for (int e : bruteForce(mesh.tets, x, lo, hi))
                EXPECT_TRUE(std::binary_search(got.begin(), got.end(), e)) << "round " << round << " element " << e;
        }
    }
}

}  // namespace
}  // namespace cutsim
