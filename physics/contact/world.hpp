// The contact world's state, shared by its files (internal): contact.cpp queries and projects,
// surface_tree.cpp keeps the surface's triangle trees, pieces.cpp makes contacts between pieces.
#pragma once

#include "contact/contact.hpp"
#include "contact/shapes.hpp"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>
#include <btBulletCollisionCommon.h>

#include <algorithm>
#include <deque>
#include <memory>
#include <utility>
#include <vector>

namespace cutsim {

// Steps of motion a moved leaf is grown by along its velocity (at most 4 fat).
inline constexpr double kLookahead = 16;
// Depth in the rest shape, as a fraction of the leaf margin, beyond which a point behind a triangle
// of another piece is overlap the cut made (an embedded surface is not split at the cut, so
// triangles of one side reach over the other's), not contact.
inline constexpr double kMadeOverlap = 0.1;
// Depth below which two pieces touch without pressing: faces a cut made coincide to rounding [m].
inline constexpr double kSlop = 1e-7;
// Distance outside a shape, as a fraction of the leaf margin, within which a point is a
// speculative contact of the projection.
inline constexpr double kSpeculative = 0.1;
// Drift of a piece near a shape, in leaf fattenings, beyond which all its moved triangles are
// refitted at once rather than those near the shape only.
inline constexpr double kRefitAll = 2;
// Leaf fattening as a fraction of the surface's mean triangle extent.
inline constexpr double kLeafFat = 0.05;
// Band around the static colliders beyond the speculative reach, in leaf fattenings (without the
// least fattening), whose points a piece keeps between queries.
inline constexpr double kNearBand = 2;

// Steps after a surface change during which a shape near a piece scans the piece's triangles
// instead of building its trees: a blade cuts at every step of its stroke, and inserting every
// triangle into a new tree at each of them cost more than testing each triangle's box.
inline constexpr int kScanSteps = 32;

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
// Its triangles are in one tree per cut that made them (-1: none), so a blade skips the faces of
// its own cut, which lie inside it, without visiting them.
struct Piece {
    std::deque<btDbvt> trees;  // a deque: btDbvt cannot move
    std::vector<int> treeCut;  // the cut of each tree's triangles, -1 for the uncut surface
    std::vector<int> nodes;    // indices into surfNodes
    std::vector<int> tris;     // its triangles, ascending
    bool built = false;        // its trees hold its triangles; else `box` stands for them
    btDbvtVolume box;          // its triangles at reference, grown by fat (until built)
    double drift = 0;          // how far any of its points may be outside its leaf [m]
    bool refitted = false;     // this step
    btDbvtVolume around;       // its root grown by drift
    int facing = 1;            // +1: triangles counter-clockwise from outside; -1: from inside; 0: encloses nothing
    // Static colliders without a tree query per step (resting contact costs what touches): the
    // points within nearBand of each collider when `snap` (its nodes, as in `nodes`) was taken.
    // No other point can reach a collider until one of its nodes moved (nearBand - speculative) /
    // (sqrt(3) wSum) along an axis since: then the trees are queried again.
    Eigen::Matrix3Xd snap;
    std::vector<std::vector<int>> near;  // per shape (tools' stay empty), ascending
    bool nearValid = false;
    double nearMove = 0;     // this step: largest per-axis move of its nodes since snap [m]
    bool nearFresh = false;  // this step queries the trees and takes the lists and snap anew
    btDbvt& treeOf(int cut) {
        for (size_t i = 0; i < treeCut.size(); ++i)
            if (treeCut[i] == cut) return trees[i];
        treeCut.push_back(cut);
        return trees.emplace_back();
    }
    // the box of all its trees' roots; false when it has no triangle
    bool bounds(btDbvtVolume& out) const {
        if (!built) {
            out = box;
            return !tris.empty();
        }
        bool any = false;
        for (const btDbvt& t : trees)
            if (t.m_root) {
                if (any)
                    Merge(out, t.m_root->volume, out);
                else
                    out = t.m_root->volume;
                any = true;
            }
        return any;
    }
    bool empty() const {
        if (!built) return tris.empty();
        for (const btDbvt& t : trees)
            if (t.m_root) return false;
        return true;
    }
};

struct ContactWorld::Impl {
    std::vector<ToolDef> tools;
    std::vector<ColliderDef> colliders;
    // the collision world holds the tool parts and the colliders; its broad phase keeps their boxes.
    // Its narrow phase never runs (distances come from contact.cpp), so the configuration's pools
    // of manifolds and algorithms hold one each: Bullet's defaults (4096) cost page faults at a
    // scene's start.
    static btDefaultCollisionConstructionInfo poolsOfOne() {
        btDefaultCollisionConstructionInfo info;
        info.m_defaultMaxPersistentManifoldPoolSize = 1;
        info.m_defaultMaxCollisionAlgorithmPoolSize = 1;
        return info;
    }
    btDefaultCollisionConfiguration config{poolsOfOne()};
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
    std::vector<std::uint8_t> outside;      // per node: lies outside the material (setSurface), or empty
    std::vector<int> ignoredCut;            // per tool: the cut whose faces it does not touch, or -1
    std::vector<std::uint8_t> dropped;      // per point: out of contact until the next setSurface (dropPoints)
    std::vector<ContactWorld::Slot> slots;  // per tool: the slot it slides in (ContactWorld::setSlot), or empty
    std::vector<std::unique_ptr<Piece>> pieces;
    std::vector<int> triPiece;    // piece of each triangle (nTris)
    std::vector<int> pointPiece;  // piece of each point (nPoints)
    double nearBand = 2e-3;       // how far from a static collider a piece keeps its points [m]
    std::vector<int> nodePiece;   // piece of each surface node (surfNodes)
    std::vector<btDbvtNode*>
        leaves;            // (nTris): each triangle's box in its piece's tree, grown by `leafMargin` at the last refit
    double margin = 5e-4;  // contact reach: speculative contacts and piece contact (fat / 2) [m]
    double minFat = 1e-3;  // least leaf fattening: 2 margin [m]
    double fat = 1e-3;     // a leaf moved is grown by this [m]
    double leafMargin = 5e-4;       // and kept while its triangle stays `leafMargin` inside it (fat / 2) [m]
    std::vector<int> surfNodes;     // nodes the surface's vertices follow
    std::vector<int> nodeSlot;      // node -> its index in surfNodes, or -1
    Eigen::Matrix3Xd xRef;          // their reference positions (3 x surfNodes) [m]
    Eigen::Matrix3Xd vertRef;       // the surface vertices (points 0..) at xRef [m]
    std::vector<int> vertStamp;     // last batch that placed each vertex in vertRef
    std::vector<int> nodeTriStart;  // CSR: triangles following surface node k (surfNodes + 1)
    std::vector<int> nodeTris;
    std::vector<int> triNodeStart;  // CSR: surface nodes triangle t follows (nTris + 1)
    std::vector<int> triNodes;
    double wSum = 1;             // largest sum_i |w_i| of a vertex: it moves at most this x its nodes
    double trigger = 0;          // a node moved more than this gets its triangles refitted: leafMargin / (2 wSum) [m]
    std::vector<int> dirty;      // triangles to refit in one batch
    std::vector<int> visited;    // leaves within a piece's drift of a shape
    std::vector<int> resetting;  // their surface nodes to reset
    std::vector<int> triStamp;   // last batch that queued each triangle (nTris)
    int refits = 0;
    int sinceChange = 0;      // gathers since the surface last changed
    std::vector<int> placed;  // last gather that placed each point in xp (nPoints)
    int placing = 0;
    Eigen::Matrix3Xd xp;     // point positions (3 x nPoints) [m], computed for candidates only
    std::vector<int> stamp;  // last query that visited each point (nPoints)
    int query = 0;
    std::vector<int> triangles;              // a shape's candidate triangles
    std::vector<int> candidates;             // their points, and those kept (Piece::near)
    std::vector<const btDbvtNode*> walk;     // the tree traversal's stack
    std::vector<btDbvtNode*> mergeStack;     // inner nodes merged bottom up
    std::vector<std::pair<int, int>> pairs;  // triangles of two pieces whose boxes overlap
    std::vector<btTransform> now, other;     // shape transforms at the query time and at the step's other end
    std::vector<Touch> touches;
    std::vector<Term> terms;
    std::vector<int> interpolateNow;  // points to place for the piece test
    Eigen::Matrix3Xd restPts;         // point positions in the rest shape (3 x nPoints) [m]; empty: no piece contact
    const Eigen::Matrix3Xd* xNow = nullptr;  // positions of this step's query
    ContactStep last;

    void clearTree() {
        for (auto& p : pieces) {
            for (btDbvt& t : p->trees) t.clear();
            p->trees.clear();
            p->treeCut.clear();
            p->built = false;
        }
        leaves.clear();
    }
    // how far surface node k moved from its reference, per axis [m]
    double moved(const Eigen::Matrix3Xd& x, size_t k) const {
        return (x.col(surfNodes[k]) - xRef.col(static_cast<Eigen::Index>(k))).cwiseAbs().maxCoeff();
    }
    void interpolate(const Eigen::Matrix3Xd& x, int p) {
        Eigen::Vector3d s = Eigen::Vector3d::Zero();
        for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i) s += pts.weights(i, p) * x.col(pts.nodes(i, p));
        xp.col(p) = s;
    }
    // xp of point p at x, once per gather
    void place(const Eigen::Matrix3Xd& x, int p) {
        if (placed[static_cast<size_t>(p)] == placing) return;
        placed[static_cast<size_t>(p)] = placing;
        interpolate(x, p);
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
    // whole: the piece all of whose moved nodes are reset; its trees' inner boxes are then merged
    // once, bottom up, instead of from each refitted leaf up
    void resetNodes(const int* first, const int* end, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt,
                    Piece* whole = nullptr);
    void refitLeaf(int t, const Eigen::Matrix3Xd& v, double dt, bool up);
    Eigen::Vector3d atReference(int p) const;
    void build(const Eigen::Matrix3Xd& x);
    void buildTrees(Piece& pc);
    void touchPieces();
    void pointsInTriangle(int source, int target);
    void gather(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double tq, double tOther, bool withPieces);
    // gather's phases (contact.cpp)
    struct ShapeQuery;
    void resetStep();
    void measureDrift(const Eigen::Matrix3Xd& x);
    void poseTools(double tq, double tOther);
    ShapeQuery shapeQuery(size_t o) const;
    void queryPieces(const ShapeQuery& sq, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt, bool scan);
    void walkTrees(Piece& pc, const ShapeQuery& sq, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt);
    void candidatePoints(const ShapeQuery& sq, const Eigen::Matrix3Xd& x, double speculative);
    void testPoints(const ShapeQuery& sq, const Eigen::Matrix3Xd& x, double tq, double tOther, double speculative);
    void addTouch(const ShapeQuery& sq, int p, const btVector3& q, double d, const Eigen::Vector3d& n, double tq,
                  double tOther);
    void keepNear(const Eigen::Matrix3Xd& x);
    void pressPieces(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt);
    // ContactWorld::project's parts (contact.cpp)
    void apply(Eigen::Matrix3Xd& y, const Touch& tc, const Eigen::Vector3d& impulse);
    double inverseMass(const Touch& tc) const;
    void remeasure(Touch& tc, double sum, const Eigen::Matrix3Xd& x);
    bool setUpTouch(Touch& tc, const Eigen::VectorXd& invMass, const Eigen::Matrix3Xd& x);
    bool measureInside(Touch& tc, const Eigen::Matrix3Xd& x);
    bool dropLightNodes(Touch& tc, const Eigen::Matrix3Xd& x);
    void recountDepths();
    void sweepVelocities(Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& v, double dt);
    void sweepPositions(Eigen::Matrix3Xd& x);
    void reportProjection(const Eigen::Matrix3Xd& x, double dt, std::vector<int>* moved);
};

// Bounds of the triangle of points a, b, c (3 x nPoints columns of xp).
inline btDbvtVolume triangleBox(const Eigen::Matrix3Xd& xp, const Eigen::Matrix3Xi& tris, int t) {
    const Eigen::Vector3d a = xp.col(tris(0, t)), b = xp.col(tris(1, t)), c = xp.col(tris(2, t));
    return btDbvtVolume::FromMM(bt(Eigen::Vector3d(a.cwiseMin(b).cwiseMin(c))),
                                bt(Eigen::Vector3d(a.cwiseMax(b).cwiseMax(c))));
}
// Squared distance from the point c to the box.
inline double boxDistance2(const btDbvtVolume& box, const btVector3& c) {
    double s = 0;
    for (int i = 0; i < 3; ++i) {
        const double d = std::max({box.Mins()[i] - c[i], c[i] - box.Maxs()[i], 0.0});
        s += d * d;
    }
    return s;
}
// Smallest n . (x - o) over a box: how far the box reaches below the plane through o.
inline double belowPlane(const btDbvtVolume& box, const Eigen::Vector3d& n, const Eigen::Vector3d& o) {
    const Eigen::Vector3d c = eig(box.Center()), h = eig(box.Extents());
    return n.dot(c - o) - n.cwiseAbs().dot(h);
}

}  // namespace cutsim
