#include "contact/contact.hpp"
#include "contact/shapes.hpp"

#include "util/union_find.hpp"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkEpa2.h>
#include <btBulletCollisionCommon.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace cutsim {

namespace {

std::atomic<int> gLiveWorlds{0};

// Steps of motion a moved leaf is grown by along its velocity (at most 4 fat).
constexpr double kLookahead = 16;
// Depth in the rest shape, as a fraction of the leaf margin, beyond which a point behind a triangle
// of another piece is overlap the cut made (an embedded surface is not split at the cut, so
// triangles of one side reach over the other's), not contact.
constexpr double kMadeOverlap = 0.1;
// Depth below which two pieces touch without pressing: faces a cut made coincide to rounding [m].
constexpr double kSlop = 1e-7;
// Distance outside a shape, as a fraction of the leaf margin, within which a point is a
// speculative contact of the projection.
constexpr double kSpeculative = 0.1;
// Least sum of |w_i| over the free nodes of a contact the projection moves.
constexpr double kMinFreeWeight = 0.1;

struct Collect : btDbvt::ICollide {
    std::vector<int>* out = nullptr;
    void Process(const btDbvtNode* leaf) override { out->push_back(leaf->dataAsInt); }
};

}  // namespace

// ---- ContactWorld ----

// One shape the surface can touch: a part of a tool (moving on its keyframes) or a static collider.
struct Shape {
    int tool = -1;       // owning tool, or -1
    int collider = -1;   // owning collider, or -1
    ToolPart part;       // sphere, capsule, box or hull (a collider's too)
    bool plane = false;  // a collider's half-space: no collision object, its own tree traversal
    double radius = 0;   // of a sphere about the part origin holding the part [m] (not for planes)
    double friction = 0;
};

// One node's share in a contact: the contact's velocity is sum_i w_i v_i (minus a wall's).
struct Term {
    int node = 0;
    double w = 0;
    double im = 0;  // inverse mass the projection moves the node with [1/kg]
};

// A surface point inside a shape, or inside another piece of the object, at the query time.
struct Touch {
    int point = 0;
    int shape = -1;         // the tool part or collider, or -1 for another piece
    int first = 0, n = 0;   // its terms: the point's nodes, then minus the other piece's triangle's
    Eigen::Vector3d n_;     // the way out of the shape
    double depth = 0;       // how far inside [m] (> 0)
    Eigen::Vector3d c0;     // sum_i w_i x_i when detected [m]
    Eigen::Vector3d vWall;  // velocity of the shape's material point there [m/s]
    double mass = 0;        // effective mass, 1 / (sum_i w_i^2 / m_i) [kg]
    double lambda = 0;      // normal impulse accumulated by the projection [N s]
    Eigen::Vector3d tangent = Eigen::Vector3d::Zero();  // friction impulse accumulated [N s]
    double push = 0;                                    // position correction accumulated, as mass x length [kg m]
    double friction = 0;
};

// A connected part of the surface (triangles joined by shared nodes: a piece of the object once
// cuts have separated it). Each has its own tree and drift, so a piece far from every shape (one
// falling away) costs one pass over its nodes and no refit.
struct Piece {
    btDbvt tree;
    std::vector<int> nodes;  // indices into surfNodes
    double drift = 0;        // how far any of its points may be outside its leaf [m]
    bool refitted = false;   // this step
    btDbvtVolume around;     // its root grown by drift
    int facing = 1;          // +1: triangles counter-clockwise from outside; -1: from inside; 0: encloses nothing
};

struct ContactWorld::Impl {
    std::vector<ToolDef> tools;
    std::vector<ColliderDef> colliders;
    // the collision world holds the tool parts and the colliders; its broad phase keeps their boxes
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btCollisionWorld world{&dispatcher, &broadphase, &config};
    std::vector<Shape> shapes;
    std::vector<std::unique_ptr<btConvexShape>> btShapes;     // per shape (null for a plane)
    std::vector<std::unique_ptr<btCollisionObject>> objects;  // per shape (null for a plane)
    std::vector<double> colliderStiffness, colliderDamping;   // penalty on colliders [N/m], [N s/m]
    bool pieceContact = false;
    double pieceFriction = 0.3;

    ContactPoints pts;
    std::vector<int> ignoredCut;  // per tool: the cut whose faces it does not touch, or -1
    std::vector<std::unique_ptr<Piece>> pieces;
    std::vector<int> triPiece;   // piece of each triangle (nTris)
    std::vector<int> nodePiece;  // piece of each surface node (surfNodes)
    std::vector<btDbvtNode*>
        leaves;            // (nTris): each triangle's box in its piece's tree, grown by `margin` at the last refit
    double fat = 1e-3;     // a leaf moved is grown by this [m]
    double margin = 5e-4;  // and kept while its triangle stays `margin` inside it (fat / 2) [m]
    std::vector<int> surfNodes;     // nodes the surface's vertices follow
    Eigen::Matrix3Xd xRef;          // their positions when their triangles were last refitted (3 x surfNodes) [m]
    std::vector<double> moved;      // how far each moved from there, per axis (surfNodes) [m]
    std::vector<int> nodeTriStart;  // CSR: triangles following surface node k (surfNodes + 1)
    std::vector<int> nodeTris;
    double wSum = 1;             // largest sum_i |w_i| of a vertex: it moves at most this x its nodes
    std::vector<int> dirty;      // triangles to refit this step
    std::vector<int> triStamp;   // last refit that queued each triangle (nTris)
    std::vector<int> vertStamp;  // last refit that placed each vertex (nPoints)
    int refits = 0;
    Eigen::Matrix3Xd xp;     // point positions (3 x nPoints) [m], computed for candidates only
    std::vector<int> stamp;  // last query that visited each point (nPoints)
    int query = 0;
    std::vector<int> candidates;  // triangles, then points
    btNodeStack stack;
    std::vector<const btDbvtNode*> walk;     // the plane traversal's stack
    std::vector<std::pair<int, int>> pairs;  // triangles of two pieces whose boxes overlap
    std::vector<btTransform> now, other;     // shape transforms at the query time and at the step's other end
    std::vector<Touch> touches;
    std::vector<Term> terms;
    std::vector<int> interpolateNow;  // points to place for the piece test
    Eigen::Matrix3Xd restPts;         // point positions in the rest shape (3 x nPoints) [m]; empty: no piece contact
    const Eigen::Matrix3Xd* xNow = nullptr;  // positions of this step's query
    ContactStep last;

    void clearTree() {
        for (auto& p : pieces) p->tree.clear();
        leaves.clear();
    }
    void interpolate(const Eigen::Matrix3Xd& x, int p) {
        Eigen::Vector3d s = Eigen::Vector3d::Zero();
        for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i) s += pts.weights(i, p) * x.col(pts.nodes(i, p));
        xp.col(p) = s;
    }
    Eigen::Vector3d pointVelocity(const Eigen::Matrix3Xd& v, int p) const {
        Eigen::Vector3d s = Eigen::Vector3d::Zero();
        for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i) s += pts.weights(i, p) * v.col(pts.nodes(i, p));
        return s;
    }
    Eigen::Vector3d combine(const Eigen::Matrix3Xd& y, const Touch& tc) const {
        Eigen::Vector3d s = Eigen::Vector3d::Zero();
        for (int i = tc.first; i < tc.first + tc.n; ++i)
            s += terms[static_cast<size_t>(i)].w * y.col(terms[static_cast<size_t>(i)].node);
        return s;
    }
    void refitMoved(Piece& piece, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt);
    void build(const Eigen::Matrix3Xd& x);
    void touchPieces();
    void pointsInTriangle(int source, int target);
    void gather(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double tq, double tOther, bool withPieces);
};

namespace {
// Bounds of the triangle of points a, b, c (3 x nPoints columns of xp).
btDbvtVolume triangleBox(const Eigen::Matrix3Xd& xp, const Eigen::Matrix3Xi& tris, int t) {
    const Eigen::Vector3d a = xp.col(tris(0, t)), b = xp.col(tris(1, t)), c = xp.col(tris(2, t));
    return btDbvtVolume::FromMM(bt(Eigen::Vector3d(a.cwiseMin(b).cwiseMin(c))),
                                bt(Eigen::Vector3d(a.cwiseMax(b).cwiseMax(c))));
}
// Smallest n . (x - o) over a box: how far the box reaches below the plane through o.
double belowPlane(const btDbvtVolume& box, const Eigen::Vector3d& n, const Eigen::Vector3d& o) {
    const Eigen::Vector3d c = eig(box.Center()), h = eig(box.Extents());
    return n.dot(c - o) - n.cwiseAbs().dot(h);
}
}  // namespace

ContactWorld::ContactWorld(std::vector<ToolDef> tools, std::vector<ColliderDef> colliders)
    : impl_(std::make_unique<Impl>()) {
    ++gLiveWorlds;
    Impl& m = *impl_;
    m.tools = std::move(tools);
    m.colliders = std::move(colliders);
    double smallest = 1e300;
    auto add = [&](Shape s, const Eigen::Matrix3Xd* hull, const btTransform& at) {
        const ToolPart& q = s.part;
        double rad = q.shape == ToolShape::Kind::Sphere    ? q.size.x()
                     : q.shape == ToolShape::Kind::Capsule ? q.size.x() + q.size.y()
                                                           : q.size.norm();
        if (q.hull) {
            rad = 0;
            for (int k = 0; k < hull->cols(); ++k) rad = std::max(rad, hull->col(k).norm());
        }
        s.radius = rad * (1 + 1e-9);
        auto shape = makeShape(q, hull);
        auto obj = std::make_unique<btCollisionObject>();
        obj->setCollisionShape(shape.get());
        obj->setCollisionFlags(
            obj->getCollisionFlags() | btCollisionObject::CF_NO_CONTACT_RESPONSE |
            (s.tool >= 0 ? btCollisionObject::CF_KINEMATIC_OBJECT : btCollisionObject::CF_STATIC_OBJECT));
        obj->setWorldTransform(at);
        m.world.addCollisionObject(obj.get());
        m.btShapes.push_back(std::move(shape));
        m.objects.push_back(std::move(obj));
        m.shapes.push_back(s);
    };
    for (size_t t = 0; t < m.tools.size(); ++t) {
        const auto parts = toolParts(m.tools[t], 0);
        for (const ToolPart& part : parts) {
            Shape s;
            s.tool = static_cast<int>(t);
            s.part = part;
            s.friction = m.tools[t].friction;
            add(s, &m.tools[t].hull, bt(toolPose(m.tools[t], 0)) * bt(part.local));
            smallest = std::min(smallest, part.size.minCoeff() > 0 ? part.size.minCoeff() : part.size.x());
        }
    }
    for (size_t c = 0; c < m.colliders.size(); ++c) {
        const ColliderDef& cd = m.colliders[c];
        Shape s;
        s.collider = static_cast<int>(c);
        s.friction = cd.friction;
        if (cd.kind == ColliderDef::Kind::Plane) {
            s.plane = true;
            m.shapes.push_back(s);
            m.btShapes.emplace_back();
            m.objects.emplace_back();
            continue;
        }
        s.part.shape = cd.kind == ColliderDef::Kind::Sphere ? ToolShape::Kind::Sphere : ToolShape::Kind::Box;
        s.part.size = cd.size;
        s.part.hull = cd.kind == ColliderDef::Kind::Mesh;
        add(s, &cd.vertices, bt(cd.pose));
    }
    m.colliderStiffness.assign(m.colliders.size(), 0);
    m.colliderDamping.assign(m.colliders.size(), 0);
    // leaves move only when a point leaves a box this much bigger than itself
    m.fat = std::clamp(0.5 * smallest, 1e-5, 1e-2);
    m.margin = 0.5 * m.fat;
    m.last.reaction.assign(m.tools.size(), Eigen::Vector3d::Zero());
}

ContactWorld::~ContactWorld() {
    Impl& m = *impl_;
    m.clearTree();
    for (auto& o : m.objects)
        if (o) m.world.removeCollisionObject(o.get());
    --gLiveWorlds;
}

int ContactWorld::live() { return gLiveWorlds.load(); }
std::vector<ToolDef>& ContactWorld::tools() { return impl_->tools; }
const std::vector<ToolDef>& ContactWorld::tools() const { return impl_->tools; }
const std::vector<ColliderDef>& ContactWorld::colliders() const { return impl_->colliders; }
const ContactPoints& ContactWorld::points() const { return impl_->pts; }
const ContactStep& ContactWorld::last() const { return impl_->last; }

void ContactWorld::setColliderPenalty(double stiffness, double damping) {
    std::fill(impl_->colliderStiffness.begin(), impl_->colliderStiffness.end(), stiffness);
    std::fill(impl_->colliderDamping.begin(), impl_->colliderDamping.end(), damping);
}

void ContactWorld::ignoreCut(int tool, int cut) {
    Impl& m = *impl_;
    m.ignoredCut.resize(m.tools.size(), -1);
    m.ignoredCut.at(static_cast<size_t>(tool)) = cut;
}

void ContactWorld::setSurface(ContactPoints pts, const Eigen::Matrix3Xd* rest) {
    Impl& m = *impl_;
    m.clearTree();
    m.pts = std::move(pts);
    m.xp.resize(3, m.pts.points());
    m.stamp.assign(static_cast<size_t>(m.pts.points()), -1);
    m.query = 0;
    // the nodes each triangle's box depends on: those of its three vertices (edge and face
    // points are combinations of the vertices, inside the triangle)
    const auto nt = static_cast<size_t>(m.pts.triangles.cols());
    std::vector<int> slot;  // node -> index in surfNodes, or -1
    m.surfNodes.clear();
    m.wSum = 0;
    std::vector<std::pair<int, int>> pairs;  // (surface node, triangle)
    for (size_t t = 0; t < nt; ++t) {
        int seen[3 * ContactPoints::kMaxNodes];
        int ns = 0;
        for (int c = 0; c < 3; ++c) {
            const int p = m.pts.triangles(c, static_cast<Eigen::Index>(t));
            double w = 0;
            for (int i = 0; i < m.pts.count[static_cast<size_t>(p)]; ++i) {
                const int node = m.pts.nodes(i, p);
                w += std::abs(m.pts.weights(i, p));
                if (static_cast<size_t>(node) >= slot.size()) slot.resize(static_cast<size_t>(node) + 1, -1);
                int& k = slot[static_cast<size_t>(node)];
                if (k < 0) {
                    k = static_cast<int>(m.surfNodes.size());
                    m.surfNodes.push_back(node);
                }
                if (std::find(seen, seen + ns, k) == seen + ns) seen[ns++] = k;
            }
            m.wSum = std::max(m.wSum, w);
        }
        for (int i = 0; i < ns; ++i) pairs.emplace_back(seen[i], static_cast<int>(t));
    }
    // surface nodes in index order, so the per-step drift pass reads the positions in order
    std::vector<int> order(m.surfNodes.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return m.surfNodes[static_cast<size_t>(a)] < m.surfNodes[static_cast<size_t>(b)]; });
    std::vector<int> rank(order.size());
    for (size_t k = 0; k < order.size(); ++k) rank[static_cast<size_t>(order[k])] = static_cast<int>(k);
    std::sort(m.surfNodes.begin(), m.surfNodes.end());
    for (auto& pr : pairs) pr.first = rank[static_cast<size_t>(pr.first)];
    std::sort(pairs.begin(), pairs.end());
    m.nodeTriStart.assign(m.surfNodes.size() + 1, 0);
    m.nodeTris.resize(pairs.size());
    for (size_t i = 0; i < pairs.size(); ++i) {
        ++m.nodeTriStart[static_cast<size_t>(pairs[i].first) + 1];
        m.nodeTris[i] = pairs[i].second;
    }
    for (size_t k = 0; k < m.surfNodes.size(); ++k) m.nodeTriStart[k + 1] += m.nodeTriStart[k];
    m.xRef.resize(3, static_cast<Eigen::Index>(m.surfNodes.size()));
    m.moved.assign(m.surfNodes.size(), 0);
    m.triStamp.assign(nt, -1);
    m.vertStamp.assign(static_cast<size_t>(m.pts.points()), -1);
    m.refits = 0;
    m.restPts.resize(3, 0);
    if (rest) {
        m.restPts.resize(3, m.pts.points());
        for (int p = 0; p < m.pts.points(); ++p) {
            Eigen::Vector3d q = Eigen::Vector3d::Zero();
            for (int i = 0; i < m.pts.count[static_cast<size_t>(p)]; ++i)
                q += m.pts.weights(i, p) * rest->col(m.pts.nodes(i, p));
            m.restPts.col(p) = q;
        }
    }
    // pieces: triangles joined through the nodes their vertices follow
    UnionFind uf(slot.size());
    for (size_t t = 0; t < nt; ++t) {
        const int p0 = m.pts.triangles(0, static_cast<Eigen::Index>(t));
        const int n0 = m.pts.nodes(0, p0);
        for (int c = 0; c < 3; ++c) {
            const int p = m.pts.triangles(c, static_cast<Eigen::Index>(t));
            for (int i = 0; i < m.pts.count[static_cast<size_t>(p)]; ++i) uf.join(n0, m.pts.nodes(i, p));
        }
    }
    std::vector<int> label(slot.size(), -1);
    m.pieces.clear();
    m.triPiece.resize(nt);
    for (size_t t = 0; t < nt; ++t) {
        int& l = label[static_cast<size_t>(uf.find(m.pts.nodes(0, m.pts.triangles(0, static_cast<Eigen::Index>(t)))))];
        if (l < 0) {
            l = static_cast<int>(m.pieces.size());
            m.pieces.push_back(std::make_unique<Piece>());
        }
        m.triPiece[t] = l;
    }
    m.nodePiece.resize(m.surfNodes.size());
    for (size_t k = 0; k < m.surfNodes.size(); ++k) {
        const int l = label[static_cast<size_t>(uf.find(m.surfNodes[k]))];
        m.nodePiece[k] = l;
        m.pieces[static_cast<size_t>(l)]->nodes.push_back(static_cast<int>(k));
    }
}

int ContactWorld::pieces() const { return static_cast<int>(impl_->pieces.size()); }

void ContactWorld::setPieceContact(bool on, double friction) {
    impl_->pieceContact = on;
    impl_->pieceFriction = friction;
}

// Leaves hold their triangle grown by `margin` when refitted, and a triangle is refitted as soon as
// one of its nodes moved more than margin / (2 wSum) from where it was at its last refit (then each
// vertex moved at most `margin` since, the reference of a node being reset when all its triangles
// are refitted). So the tree is exact where it is used.
void ContactWorld::Impl::build(const Eigen::Matrix3Xd& x) {
    const int nt = static_cast<int>(pts.triangles.cols());
    const int nv = pts.triangles.maxCoeff() + 1;
    for (int p = 0; p < nv; ++p) interpolate(x, p);
    clearTree();
    leaves.resize(static_cast<size_t>(nt));
    for (int t = 0; t < nt; ++t) {
        btDbvtVolume vol = triangleBox(xp, pts.triangles, t);
        vol.Expand(btVector3(fat, fat, fat));
        leaves[static_cast<size_t>(t)] =
            pieces[static_cast<size_t>(triPiece[static_cast<size_t>(t)])]->tree.insert(vol, nullptr);
        leaves[static_cast<size_t>(t)]->dataAsInt = t;
    }
    for (size_t k = 0; k < surfNodes.size(); ++k) xRef.col(static_cast<Eigen::Index>(k)) = x.col(surfNodes[k]);
    std::fill(moved.begin(), moved.end(), 0.0);
    // which way each piece's triangles face: out when its enclosed (signed) volume is positive;
    // a surface that encloses nothing (open, or flat) takes no part in piece contact
    std::vector<double> volume(pieces.size(), 0.0), scale(pieces.size(), 0.0);
    for (int t = 0; t < nt; ++t) {
        const Eigen::Vector3d a = xp.col(pts.triangles(0, t)), b = xp.col(pts.triangles(1, t)),
                              c = xp.col(pts.triangles(2, t));
        const auto k = static_cast<size_t>(triPiece[static_cast<size_t>(t)]);
        volume[k] += a.dot(b.cross(c)) / 6;
        scale[k] += (b - a).cross(c - a).norm() * (a.norm() + b.norm() + c.norm()) / 18;
    }
    for (size_t k = 0; k < pieces.size(); ++k)
        pieces[k]->facing = std::abs(volume[k]) > 1e-3 * scale[k] ? (volume[k] > 0 ? 1 : -1) : 0;
}

void ContactWorld::Impl::refitMoved(Piece& piece, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt) {
    piece.refitted = true;
    const double trigger = margin / (2 * std::max(wSum, 1e-300));
    const int stampNow = ++refits;
    dirty.clear();
    for (const int k : piece.nodes) {
        if (!(moved[static_cast<size_t>(k)] > trigger)) continue;
        for (int i = nodeTriStart[static_cast<size_t>(k)]; i < nodeTriStart[static_cast<size_t>(k) + 1]; ++i) {
            const int t = nodeTris[static_cast<size_t>(i)];
            if (triStamp[static_cast<size_t>(t)] == stampNow) continue;
            triStamp[static_cast<size_t>(t)] = stampNow;
            dirty.push_back(t);
        }
        xRef.col(k) = x.col(surfNodes[static_cast<size_t>(k)]);
        moved[static_cast<size_t>(k)] = 0;
    }
    const btVector3 grow(margin, margin, margin);
    for (int t : dirty) {
        for (int c = 0; c < 3; ++c) {
            const int p = pts.triangles(c, t);
            if (vertStamp[static_cast<size_t>(p)] == stampNow) continue;
            vertStamp[static_cast<size_t>(p)] = stampNow;
            interpolate(x, p);
        }
        btDbvtNode* leaf = leaves[static_cast<size_t>(t)];
        btDbvtVolume vol = triangleBox(xp, pts.triangles, t);
        vol.Expand(grow);
        if (leaf->volume.Contain(vol)) continue;
        vol.Expand(grow);  // margin + margin = fat
        // grown along the triangle's velocity too, so a piece in steady motion (falling, dragged)
        // leaves its boxes less often (as Bullet's broad phase predicts its proxies)
        Eigen::Vector3d vt = Eigen::Vector3d::Zero();
        for (int c = 0; c < 3; ++c) vt += pointVelocity(v, pts.triangles(c, t));
        Eigen::Vector3d ahead = vt * (kLookahead * dt / 3);
        if (const double len = ahead.norm(); len > 4 * fat) ahead *= 4 * fat / len;
        if (ahead.allFinite()) vol.SignedExpand(bt(ahead));
        // in place, the ancestors' boxes refitted up to the first that still holds it: the surface
        // moves continuously, so neighbours stay neighbours and the tree keeps its shape without
        // Bullet's remove and insert per moved leaf
        leaf->volume = vol;
        for (btDbvtNode* n = leaf->parent; n; n = n->parent) {
            const btDbvtVolume before = n->volume;
            Merge(n->childs[0]->volume, n->childs[1]->volume, n->volume);
            if (before.Mins() == n->volume.Mins() && before.Maxs() == n->volume.Maxs()) break;
        }
    }
}

namespace {
struct CollidePairs : btDbvt::ICollide {
    std::vector<std::pair<int, int>>* out = nullptr;
    void Process(const btDbvtNode* a, const btDbvtNode* b) override { out->emplace_back(a->dataAsInt, b->dataAsInt); }
};
}  // namespace

// The points of triangle `source` just inside triangle `target` of another piece: behind its
// plane by less than `margin`, over the triangle. Each becomes a contact of the two pieces whose
// terms are the point's nodes and, negated, the target point's (barycentric in its triangle).
void ContactWorld::Impl::pointsInTriangle(int source, int target) {
    const ContactPoints& P = pts;
    const int ia = P.triangles(0, target), ib = P.triangles(1, target), ic = P.triangles(2, target);
    const Eigen::Vector3d a = xp.col(ia), b = xp.col(ib), c = xp.col(ic);
    const Eigen::Vector3d e1 = b - a, e2 = c - a;
    const int facing = pieces[static_cast<size_t>(triPiece[static_cast<size_t>(target)])]->facing;
    Eigen::Vector3d n = e1.cross(e2);  // counter-clockwise from outside when facing is +1
    const double area2 = n.norm();
    if (!(area2 > 0) || facing == 0) return;
    n *= facing / area2;  // out of the target's piece
    // only faces that face each other press: a source face across the target's (normals within
    // 60 degrees of opposite), which leaves out the side faces met at a cut's rim
    {
        const Eigen::Vector3d sa = xp.col(P.triangles(0, source));
        const Eigen::Vector3d ns = (xp.col(P.triangles(1, source)) - sa).cross(xp.col(P.triangles(2, source)) - sa);
        const int fs = pieces[static_cast<size_t>(triPiece[static_cast<size_t>(source)])]->facing;
        if (!(fs * ns.dot(n) < -0.5 * ns.norm())) return;
    }
    const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), den = d11 * d22 - d12 * d12;
    for (int k = P.triStart[static_cast<size_t>(source)]; k < P.triStart[static_cast<size_t>(source) + 1]; ++k) {
        const int p = P.triPoints[static_cast<size_t>(k)];
        const Eigen::Vector3d r = xp.col(p) - a;
        const double d = n.dot(r);
        if (!(d < -kSlop) || !(d > -margin)) continue;
        const double r1 = r.dot(e1), r2 = r.dot(e2);
        const double u = (d22 * r1 - d12 * r2) / den, w = (d11 * r2 - d12 * r1) / den;
        if (u < 0 || w < 0 || u + w > 1) continue;
        // behind the triangle already in the rest shape: overlap the cut made, not contact
        const Eigen::Vector3d ra = restPts.col(ia), rn = (restPts.col(ib) - ra).cross(restPts.col(ic) - ra);
        if (facing * rn.dot(restPts.col(p) - ra) < -kMadeOverlap * margin * rn.norm()) continue;
        Touch tc;
        tc.point = p;
        tc.n_ = n;
        tc.depth = -d;
        tc.vWall.setZero();
        tc.friction = pieceFriction;
        tc.first = static_cast<int>(terms.size());
        auto add = [&](int q, double scale) {
            for (int i = 0; i < P.count[static_cast<size_t>(q)]; ++i) {
                const int node = P.nodes(i, q);
                const double wq = scale * P.weights(i, q);
                int j = tc.first;
                while (j < static_cast<int>(terms.size()) && terms[static_cast<size_t>(j)].node != node) ++j;
                if (j == static_cast<int>(terms.size()))
                    terms.push_back({node, wq});
                else
                    terms[static_cast<size_t>(j)].w += wq;
            }
        };
        add(p, 1.0);
        add(ia, -(1 - u - w));
        add(ib, -u);
        add(ic, -w);
        tc.n = static_cast<int>(terms.size()) - tc.first;
        tc.c0 = xp.col(p) - ((1 - u - w) * a + u * b + w * c);
        touches.push_back(tc);
    }
}

// Contacts between separated pieces: triangle pairs of two pieces whose leaves overlap.
void ContactWorld::Impl::touchPieces() {
    for (size_t A = 0; A < pieces.size(); ++A)
        for (size_t B = A + 1; B < pieces.size(); ++B) {
            Piece &pa = *pieces[A], &pb = *pieces[B];
            if (!pa.tree.m_root || !pb.tree.m_root || !Intersect(pa.around, pb.around)) continue;
            pairs.clear();
            CollidePairs collide;
            collide.out = &pairs;
            pa.tree.collideTT(pa.tree.m_root, pb.tree.m_root, collide);
            if (pairs.empty()) continue;
            // the vertices of both triangles of each pair, placed now
            if (++query == std::numeric_limits<int>::max()) {
                std::fill(stamp.begin(), stamp.end(), -1);
                query = 0;
            }
            for (const auto& [ta, tb] : pairs)
                for (const int t : {ta, tb})
                    for (int k = pts.triStart[static_cast<size_t>(t)]; k < pts.triStart[static_cast<size_t>(t) + 1];
                         ++k) {
                        const int p = pts.triPoints[static_cast<size_t>(k)];
                        if (stamp[static_cast<size_t>(p)] == query) continue;
                        stamp[static_cast<size_t>(p)] = query;
                        interpolateNow.push_back(p);
                    }
            for (const int p : interpolateNow) interpolate(*xNow, p);
            interpolateNow.clear();
            const size_t first = touches.size();
            for (const auto& [ta, tb] : pairs) {
                pointsInTriangle(ta, tb);
                pointsInTriangle(tb, ta);
            }
            // a point behind several faces of the other piece (at an edge) keeps the shallowest
            std::sort(touches.begin() + static_cast<std::ptrdiff_t>(first), touches.end(),
                      [](const Touch& l, const Touch& r) {
                          return l.point != r.point ? l.point < r.point : l.depth < r.depth;
                      });
            size_t out = first;
            for (size_t i = first; i < touches.size(); ++i)
                if (i == first || touches[i].point != touches[i - 1].point) touches[out++] = touches[i];
            touches.resize(out);
            last.pieceContacts += static_cast<int>(out - first);
        }
}

// The surface points inside any shape at time tq (tools posed at tq), into `touches`; a tool's
// material velocity is taken over [tOther, tq] (either order). With withPieces, also the points of
// one piece inside another.
void ContactWorld::Impl::gather(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double tq, double tOther,
                                bool withPieces) {
    const ContactPoints& P = pts;
    const int nt = static_cast<int>(P.triangles.cols());
    ContactStep& st = last;
    st.reaction.assign(tools.size(), Eigen::Vector3d::Zero());
    st.contacts = 0;
    st.colliderContacts = 0;
    st.pieceContacts = 0;
    st.maxDepth = 0;
    st.colliderDepth = 0;
    st.tested = 0;
    touches.clear();
    terms.clear();
    if (nt == 0) return;
    xNow = &x;
    const double dt = std::abs(tq - tOther);
    // 1. how far each surface node moved since its triangles were refitted; each piece lies in its
    // tree's root box grown by wSum times its farthest (one pass over the surface's nodes)
    if (static_cast<int>(leaves.size()) != nt) {
        build(x);
        for (auto& pc : pieces) pc->drift = 0, pc->refitted = true;
    } else {
        for (auto& pc : pieces) pc->drift = 0, pc->refitted = false;
        for (size_t k = 0; k < surfNodes.size(); ++k) {
            moved[k] = (x.col(surfNodes[k]) - xRef.col(static_cast<Eigen::Index>(k))).cwiseAbs().maxCoeff();
            double& dr = pieces[static_cast<size_t>(nodePiece[k])]->drift;
            dr = std::max(dr, moved[k]);
        }
    }
    for (auto& pc : pieces) {
        pc->drift *= wSum;
        if (!pc->tree.m_root) continue;
        pc->around = pc->tree.m_root->volume;  // a shape away from the whole piece costs no more than this
        pc->around.Expand(btVector3(pc->drift, pc->drift, pc->drift));
    }
    // 2. tool parts at tq and tOther into the collision world; its broad phase updates their boxes
    now.resize(shapes.size());
    other.resize(shapes.size());
    for (size_t t0 = 0, o = 0; t0 < tools.size(); ++t0) {
        const ToolDef& tool = tools[t0];
        const Pose pa = toolPose(tool, tq), pb = toolPose(tool, tOther);
        const auto partsA = toolParts(tool, tq), partsB = toolParts(tool, tOther);
        for (size_t i = 0; i < partsA.size(); ++i, ++o) {
            now[o] = bt(pa) * bt(partsA[i].local);
            other[o] = bt(pb) * bt(partsB[i].local);
            objects[o]->setWorldTransform(now[o]);
        }
    }
    if (!tools.empty()) world.updateAabbs();
    // 3. per shape: the bound-volume test per piece, then candidates from its tree, then signed
    // distances. The projection also takes points just outside (speculative contacts, as Box2D
    // keeps resting contact): they may close the gap in this step but not pass it, so a point
    // resting on a surface keeps its contact, and its friction, from step to step.
    const double speculative = withPieces ? kSpeculative * margin : 0.0;
    Collect collect;
    collect.out = &candidates;
    for (size_t o = 0; o < shapes.size(); ++o) {
        const Shape& sh = shapes[o];
        candidates.clear();
        Eigen::Vector3d planeN, planeO;
        btDbvtVolume box;
        if (sh.plane) {
            const ColliderDef& cd = colliders[static_cast<size_t>(sh.collider)];
            planeN = cd.normal();
            planeO = cd.pose.position;
        } else {
            const btBroadphaseProxy* proxy = objects[o]->getBroadphaseHandle();
            box = btDbvtVolume::FromMM(proxy->m_aabbMin, proxy->m_aabbMax);
        }
        for (auto& pc : pieces) {
            if (!pc->tree.m_root) continue;
            if (sh.plane ? !(belowPlane(pc->around, planeN, planeO) < 0) : !Intersect(pc->around, box)) continue;
            if (!pc->refitted) refitMoved(*pc, x, v, dt);
            if (!sh.plane) {
                pc->tree.collideTVNoStackAlloc(pc->tree.m_root, box, stack, collect);
                continue;
            }
            // the leaves whose box reaches below the plane
            walk.assign(1, pc->tree.m_root);
            while (!walk.empty()) {
                const btDbvtNode* n = walk.back();
                walk.pop_back();
                if (!(belowPlane(n->volume, planeN, planeO) < 0)) continue;
                if (n->isleaf())
                    candidates.push_back(n->dataAsInt);
                else
                    walk.push_back(n->childs[0]), walk.push_back(n->childs[1]);
            }
        }
        if (candidates.empty()) continue;
        // faces of a cut this tool does not touch: dropped here, their points reached through
        // other candidate faces only
        const int ignored =
            sh.tool < 0 || ignoredCut.empty() || P.triCut.empty() ? -1 : ignoredCut[static_cast<size_t>(sh.tool)];
        if (ignored >= 0)
            candidates.erase(std::remove_if(candidates.begin(), candidates.end(),
                                            [&](int t) { return P.triCut[static_cast<size_t>(t)] == ignored; }),
                             candidates.end());
        // the candidate triangles' points, each once
        const size_t ntri = candidates.size();
        if (++query == std::numeric_limits<int>::max()) {
            std::fill(stamp.begin(), stamp.end(), -1);
            query = 0;
        }
        for (size_t c = 0; c < ntri; ++c) {
            const int t = candidates[c];
            for (int k = P.triStart[static_cast<size_t>(t)]; k < P.triStart[static_cast<size_t>(t) + 1]; ++k) {
                const int p = P.triPoints[static_cast<size_t>(k)];
                if (stamp[static_cast<size_t>(p)] == query) continue;
                stamp[static_cast<size_t>(p)] = query;
                candidates.push_back(p);
            }
        }
        candidates.erase(candidates.begin(), candidates.begin() + static_cast<std::ptrdiff_t>(ntri));
        const btTransform frame = sh.tool >= 0 ? now[o]
                                  : sh.plane   ? btTransform::getIdentity()
                                               : objects[o]->getWorldTransform();
        const btTransform back = sh.tool >= 0 ? other[o] * now[o].inverse() : btTransform::getIdentity();
        const btVector3 bc = frame.getOrigin();
        const double br = sh.radius;
        for (int p : candidates) {
            interpolate(x, p);
            const btVector3 q = bt(Eigen::Vector3d(xp.col(p)));
            double d = 0;
            Eigen::Vector3d n;  // the way out of the shape
            if (sh.plane) {
                n = planeN;
                d = planeN.dot(xp.col(p) - planeO);
                if (!(d < speculative)) continue;
            } else {
                // bounding sphere of the part about its origin: points outside it need no distance
                if (q.distance2(bc) > br * br) continue;
                if (!closedFormDistance(sh.part, frame, q, d, n)) {
                    btGjkEpaSolver2::sResults res;
                    d = btGjkEpaSolver2::SignedDistance(q, 0, btShapes[o].get(), frame, res);
                    n = eig(res.normal);
                }
            }
            ++st.tested;
            if (!(d < speculative) || !std::isfinite(d)) continue;
            if (!n.allFinite() || std::abs(n.norm() - 1) > 1e-6) continue;
            Touch tc;
            tc.point = p;
            tc.shape = static_cast<int>(o);
            tc.n_ = n;
            tc.depth = -d;
            tc.c0 = xp.col(p);
            tc.friction = sh.friction;
            // the velocity of the shape's material point at q over the step (tools only move)
            tc.vWall = sh.tool >= 0 && tq != tOther ? Eigen::Vector3d((eig(q) - eig(back * q)) / (tq - tOther))
                                                    : Eigen::Vector3d::Zero();
            tc.first = static_cast<int>(terms.size());
            tc.n = P.count[static_cast<size_t>(p)];
            for (int i = 0; i < tc.n; ++i) terms.push_back({P.nodes(i, p), P.weights(i, p)});
            touches.push_back(tc);
            if (!(d < 0)) continue;  // a speculative contact: near, not in
            if (sh.tool >= 0)
                ++st.contacts, st.maxDepth = std::max(st.maxDepth, -d);
            else
                ++st.colliderContacts, st.colliderDepth = std::max(st.colliderDepth, -d);
        }
    }
    // 4. pieces pressed into each other
    if (withPieces && pieceContact && pieces.size() > 1 && restPts.cols() == P.points()) {
        for (auto& pc : pieces)
            if (!pc->refitted && pc->tree.m_root) {
                bool near = false;
                for (auto& q : pieces)
                    near = near || (q.get() != pc.get() && q->tree.m_root && Intersect(pc->around, q->around));
                if (near) refitMoved(*pc, x, v, dt);
            }
        for (auto& pc : pieces)
            if (pc->tree.m_root) pc->around = pc->tree.m_root->volume;  // refitted: exact where they meet
        touchPieces();
    }
}

void ContactWorld::addForces(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double time, double dt,
                             Eigen::Matrix3Xd& f) {
    Impl& m = *impl_;
    const ContactPoints& P = m.pts;
    m.gather(x, v, time, time + dt, false);
    // penalty f = s_p max(0, k d - c v_n) n, spread to the nodes by the interpolation's transpose
    for (const Touch& tc : m.touches) {
        const Shape& sh = m.shapes[static_cast<size_t>(tc.shape)];
        const double k = sh.tool >= 0 ? m.tools[static_cast<size_t>(sh.tool)].stiffness
                                      : m.colliderStiffness[static_cast<size_t>(sh.collider)];
        const double c = sh.tool >= 0 ? m.tools[static_cast<size_t>(sh.tool)].damping
                                      : m.colliderDamping[static_cast<size_t>(sh.collider)];
        const int p = tc.point;
        const double vn = tc.n_.dot(m.pointVelocity(v, p) - tc.vWall);
        const double fn = P.scale(p) * std::max(0.0, k * tc.depth - c * vn);
        const Eigen::Vector3d fp = fn * tc.n_;
        for (int i = 0; i < P.count[static_cast<size_t>(p)]; ++i) f.col(P.nodes(i, p)) += P.weights(i, p) * fp;
        if (sh.tool >= 0) m.last.reaction[static_cast<size_t>(sh.tool)] -= fp;
    }
}

// Kinematic contact, as explicit codes constrain nodes to rigid walls: at the end of the step each
// point inside a shape gets the impulse that stops its approach (inelastic; Coulomb friction
// bounded by mu times that impulse), then is moved back onto the surface without a change of
// velocity (split impulse: the correction adds no kinetic energy). A contact moves its nodes by the
// least mass-weighted change, delta x_i = w_i lambda n / m_i with lambda = m_c delta_c and
// m_c = 1 / sum_i (w_i^2 / m_i); contacts sharing nodes are solved by projected Gauss-Seidel in a
// fixed order (deterministic). No stiffness, so no limit on the step (docs/method.md, Contact).
void ContactWorld::project(const Eigen::VectorXd& invMass, double time, double dt, Eigen::Matrix3Xd& x,
                           Eigen::Matrix3Xd& v) {
    Impl& m = *impl_;
    m.gather(x, v, time, time - dt, true);
    ContactStep& st = m.last;
    st.residualDepth = 0;
    if (m.touches.empty()) return;
    auto applyTo = [&](Eigen::Matrix3Xd& y, const Touch& tc, const Eigen::Vector3d& impulse) {
        for (int i = tc.first; i < tc.first + tc.n; ++i) {
            const Term& t = m.terms[static_cast<size_t>(i)];
            y.col(t.node) += (t.w * t.im) * impulse;
        }
    };
    // Node masses capped below at the mean of the contact's free nodes: with pure 1/m the light
    // control points of a small cut share (weight w, mass m) would take a correction of up to
    // depth / w, several element sizes; the cap keeps the correction geometric (as limitStretch does).
    // A contact whose free nodes carry less than kMinFreeWeight of it (a point on the fixed part)
    // is left alone: stopping it would take node moves of 1 / (their weight) times its own.
    for (Touch& tc : m.touches) {
        double mean = 0, w = 0, freeWeight = 0;
        int free = 0;
        for (int i = tc.first; i < tc.first + tc.n; ++i)
            if (const double im = invMass(m.terms[static_cast<size_t>(i)].node); im > 0)
                mean += 1 / im, ++free, freeWeight += std::abs(m.terms[static_cast<size_t>(i)].w);
        mean = free ? mean / free : 0;
        if (freeWeight < kMinFreeWeight) {
            tc.mass = 0;
            continue;
        }
        for (int i = tc.first; i < tc.first + tc.n; ++i) {
            Term& t = m.terms[static_cast<size_t>(i)];
            const double im = invMass(t.node);
            t.im = im > 0 ? 1 / std::max(1 / im, mean) : 0.0;
            w += t.w * t.w * t.im;
        }
        tc.mass = w > 0 ? 1.0 / w : 0.0;  // 0: on fixed nodes only, nothing to move
    }
    // velocities: no approach, friction within the cone
    for (int it = 0; it < kProjectionIterations; ++it)
        for (Touch& tc : m.touches) {
            if (tc.mass == 0) continue;
            // the normal speed is held against the world, not the tool: a tool moves what it presses
            // by the position correction below (quasi-static), so a tool set to a new pose in one
            // tick (a haptic device's sample) does not throw the tissue off at its jump's speed
            Eigen::Vector3d rel = m.combine(v, tc);
            const double allowed = tc.depth < 0 && dt > 0 ? tc.depth / dt : 0.0;  // a gap may close, no more
            const double lambda = std::max(0.0, tc.lambda + tc.mass * (allowed - tc.n_.dot(rel)));
            applyTo(v, tc, (lambda - tc.lambda) * tc.n_);
            tc.lambda = lambda;
            if (!(tc.friction > 0)) continue;
            rel = m.combine(v, tc) - tc.vWall;
            Eigen::Vector3d t = tc.tangent - tc.mass * (rel - tc.n_.dot(rel) * tc.n_);
            const double cap = tc.friction * tc.lambda, len = t.norm();
            if (len > cap) t *= cap / len;
            applyTo(v, tc, t - tc.tangent);
            tc.tangent = t;
        }
    // positions: back onto the surface, depths linearised about the detected points
    for (int it = 0; it < kProjectionIterations; ++it)
        for (Touch& tc : m.touches) {
            if (tc.mass == 0) continue;
            const double depth = tc.depth - tc.n_.dot(m.combine(x, tc) - tc.c0);
            const double push = std::max(0.0, tc.push + tc.mass * depth);
            applyTo(x, tc, (push - tc.push) * tc.n_);
            tc.push = push;
        }
    // the reaction on each tool: minus the momentum given to the tissue over the step
    for (const Touch& tc : m.touches) {
        if (tc.mass > 0 && tc.depth > 0)
            st.residualDepth = std::max(st.residualDepth, tc.depth - tc.n_.dot(m.combine(x, tc) - tc.c0));
        if (tc.shape < 0) continue;
        const Shape& sh = m.shapes[static_cast<size_t>(tc.shape)];
        if (sh.tool >= 0 && dt > 0) st.reaction[static_cast<size_t>(sh.tool)] -= (tc.lambda * tc.n_ + tc.tangent) / dt;
    }
}

}  // namespace cutsim
