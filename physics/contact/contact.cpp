#include "contact/world.hpp"

#include "util/union_find.hpp"

#include <BulletCollision/NarrowPhaseCollision/btGjkEpa2.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace cutsim {
namespace {

std::atomic<int> gLiveWorlds{0};

// Least sum of |w_i| over the free nodes of a contact the projection moves.
constexpr double kMinFreeWeight = 0.1;
// Most a node may move, as a multiple of its contact point's correction: equal masses give at most
// about 1.4 (a point at a corner: 1), so only light nodes carrying a small share reach it.
constexpr double kMaxLever = 2.0;

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
    m.minFat = std::clamp(0.5 * smallest, 1e-5, 1e-2);
    m.margin = 0.5 * m.minFat;
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

void ContactWorld::dropPoints(const std::vector<int>& nodes) {
    Impl& m = *impl_;
    if (nodes.empty() || m.pts.points() == 0) return;
    if (m.dropped.empty()) m.dropped.assign(static_cast<size_t>(m.pts.points()), 0);
    std::vector<std::uint8_t> hit(static_cast<size_t>(m.pts.nodes.maxCoeff() + 1), 0);
    for (int i : nodes)
        if (i >= 0 && static_cast<size_t>(i) < hit.size()) hit[static_cast<size_t>(i)] = 1;
    for (int p = 0; p < m.pts.points(); ++p)
        for (int i = 0; i < m.pts.count[static_cast<size_t>(p)]; ++i)
            if (hit[static_cast<size_t>(m.pts.nodes(i, p))]) {
                m.dropped[static_cast<size_t>(p)] = 1;
                break;
            }
}

void ContactWorld::ignoreCut(int tool, int cut) {
    Impl& m = *impl_;
    m.ignoredCut.resize(m.tools.size(), -1);
    m.ignoredCut.at(static_cast<size_t>(tool)) = cut;
}

bool ContactWorld::Slot::contains(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d d = x - origin;
    if (polygons.empty() || !(std::abs(u.cross(v).dot(d)) <= halfWidth)) return false;
    const Eigen::Vector2d q(d.dot(u), d.dot(v));
    for (const auto& poly : polygons) {
        // inside a convex polygon of either orientation: the same side of every edge
        int pos = 0, neg = 0;
        for (size_t i = 0, n = poly.size(); i < n; ++i) {
            const Eigen::Vector2d e = poly[(i + 1) % n] - poly[i], r = q - poly[i];
            const double c = e.x() * r.y() - e.y() * r.x();
            pos += c > 0, neg += c < 0;
        }
        if (poly.size() >= 3 && (pos == 0 || neg == 0)) return true;
    }
    return false;
}

void ContactWorld::setSlot(int tool, Slot slot) {
    Impl& m = *impl_;
    m.slots.resize(m.tools.size());
    m.slots.at(static_cast<size_t>(tool)) = std::move(slot);
}

void ContactWorld::setSurface(ContactPoints pts, const Eigen::Matrix3Xd* rest, std::vector<std::uint8_t> outside) {
    Impl& m = *impl_;
    m.clearTree();
    m.outside = std::move(outside);
    m.pts = std::move(pts);
    m.xp.resize(3, m.pts.points());
    m.stamp.assign(static_cast<size_t>(m.pts.points()), -1);
    m.dropped.clear();
    m.query = 0;
    // the nodes each triangle's box depends on: those of its three vertices (edge and face
    // points are combinations of the vertices, inside the triangle); linear in the surface, as
    // this runs after every cut
    const auto nt = static_cast<size_t>(m.pts.triangles.cols());
    std::vector<int> slot;  // node -> index in surfNodes, or -1
    m.surfNodes.clear();
    m.wSum = 0;
    for (size_t t = 0; t < nt; ++t)
        for (int c = 0; c < 3; ++c) {
            const int p = m.pts.triangles(c, static_cast<Eigen::Index>(t));
            double w = 0;
            for (int i = 0; i < m.pts.count[static_cast<size_t>(p)]; ++i) {
                const auto node = static_cast<size_t>(m.pts.nodes(i, p));
                w += std::abs(m.pts.weights(i, p));
                if (node >= slot.size()) slot.resize(node + 1, -1);
                slot[node] = 0;
            }
            m.wSum = std::max(m.wSum, w);
        }
    // surface nodes in index order, so the per-step drift pass reads the positions in order
    for (size_t n = 0; n < slot.size(); ++n)
        if (slot[n] == 0) slot[n] = static_cast<int>(m.surfNodes.size()), m.surfNodes.push_back(static_cast<int>(n));
    // each triangle's surface nodes, ascending, and each node's triangles, ascending
    m.triNodeStart.assign(nt + 1, 0);
    m.triNodes.clear();
    m.nodeTriStart.assign(m.surfNodes.size() + 1, 0);
    for (size_t t = 0; t < nt; ++t) {
        const size_t first = m.triNodes.size();
        for (int c = 0; c < 3; ++c) {
            const int p = m.pts.triangles(c, static_cast<Eigen::Index>(t));
            for (int i = 0; i < m.pts.count[static_cast<size_t>(p)]; ++i) {
                const int k = slot[static_cast<size_t>(m.pts.nodes(i, p))];
                if (std::find(m.triNodes.begin() + static_cast<std::ptrdiff_t>(first), m.triNodes.end(), k) ==
                    m.triNodes.end())
                    m.triNodes.push_back(k), ++m.nodeTriStart[static_cast<size_t>(k) + 1];
            }
        }
        std::sort(m.triNodes.begin() + static_cast<std::ptrdiff_t>(first), m.triNodes.end());
        m.triNodeStart[t + 1] = static_cast<int>(m.triNodes.size());
    }
    for (size_t k = 0; k < m.surfNodes.size(); ++k) m.nodeTriStart[k + 1] += m.nodeTriStart[k];
    m.nodeTris.resize(m.triNodes.size());
    {
        std::vector<int> fill(m.nodeTriStart.begin(), m.nodeTriStart.end() - 1);
        for (size_t t = 0; t < nt; ++t)
            for (int i = m.triNodeStart[t]; i < m.triNodeStart[t + 1]; ++i)
                m.nodeTris[static_cast<size_t>(fill[static_cast<size_t>(m.triNodes[static_cast<size_t>(i)])]++)] =
                    static_cast<int>(t);
    }
    m.nodeSlot = slot;
    m.xRef.resize(3, static_cast<Eigen::Index>(m.surfNodes.size()));
    m.triStamp.assign(nt, -1);
    m.placed.assign(static_cast<size_t>(m.pts.points()), -1);
    m.placing = 0;
    m.refits = 0;
    m.sinceChange = 0;
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
        m.pieces[static_cast<size_t>(l)]->tris.push_back(static_cast<int>(t));
    }
    m.pointPiece.assign(static_cast<size_t>(m.pts.points()), -1);
    for (size_t t = 0; t < nt; ++t)
        for (int k = m.pts.triStart[t]; k < m.pts.triStart[t + 1]; ++k)
            m.pointPiece[static_cast<size_t>(m.pts.triPoints[static_cast<size_t>(k)])] = m.triPiece[t];
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

// What one shape's query needs: its bounds, the cut it does not touch, its slot, its band.
struct ContactWorld::Impl::ShapeQuery {
    size_t o = 0;                    // the shape
    Eigen::Vector3d planeN, planeO;  // a plane's normal and origin
    btDbvtVolume box;                // the shape's own box (not for a plane)
    int ignored = -1;                // the cut whose faces it does not touch, or -1
    const ContactWorld::Slot* slot = nullptr;
    bool fixedShape = false;  // a static collider
    double band = 0;          // a static collider's band (nearBand), else 0
    btDbvtVolume banded;      // box grown by band
    btTransform frame, back;  // the shape's frame at tq; a point's map from tq to tOther
};

// The surface points inside any shape at time tq (tools posed at tq), into `touches`; a tool's
// material velocity is taken over [tOther, tq] (either order). With withPieces, also the points of
// one piece inside another.
void ContactWorld::Impl::gather(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double tq, double tOther,
                                bool withPieces) {
    resetStep();
    if (pts.triangles.cols() == 0) return;
    xNow = &x;
    const double dt = std::abs(tq - tOther);
    if (++placing == std::numeric_limits<int>::max()) {
        std::fill(placed.begin(), placed.end(), -1);
        placing = 0;
    }
    // 1. how far each surface node moved from its reference; each piece lies in its
    // tree's root box grown by wSum times its farthest (one pass over the surface's nodes)
    const bool scan = sinceChange < kScanSteps;
    if (sinceChange < kScanSteps) ++sinceChange;
    measureDrift(x);
    // 2. tool parts at tq and tOther into the collision world; its broad phase updates their boxes
    poseTools(tq, tOther);
    // 3. per shape: the bound-volume test per piece, then candidates from its tree, then signed
    // distances. The projection also takes points just outside (speculative contacts, as Box2D
    // keeps resting contact): they may close the gap in this step but not pass it, so a point
    // resting on a surface keeps its contact, and its friction, from step to step.
    const double speculative = withPieces ? kSpeculative * margin : 0.0;
    for (size_t o = 0; o < shapes.size(); ++o) {
        const ShapeQuery sq = shapeQuery(o);
        candidates.clear();
        queryPieces(sq, x, v, dt, scan);
        if (candidates.empty() && triangles.empty()) continue;
        candidatePoints(sq, x, speculative);
        testPoints(sq, x, tq, tOther, speculative);
    }
    keepNear(x);
    // 4. pieces pressed into each other
    if (withPieces && pieceContact && pieces.size() > 1 && restPts.cols() == pts.points()) pressPieces(x, v, dt);
}

// The step's counts and touches back to none.
void ContactWorld::Impl::resetStep() {
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
}

// Each piece's drift (the trees built anew when the surface changed), which pieces query the static
// colliders afresh, and each piece's bound grown by its drift.
void ContactWorld::Impl::measureDrift(const Eigen::Matrix3Xd& x) {
    const int nt = static_cast<int>(pts.triangles.cols());
    if (static_cast<int>(leaves.size()) != nt) {
        build(x);
        for (auto& pc : pieces) pc->drift = 0, pc->refitted = true;
    } else {
        for (auto& pc : pieces) {
            double dr = 0, mv = 0;  // in registers: the pass is most of what a tool away costs
            const auto n = static_cast<Eigen::Index>(pc->nodes.size());
            for (Eigen::Index i = 0; i < n; ++i) {
                const auto k = static_cast<Eigen::Index>(pc->nodes[static_cast<size_t>(i)]);
                const auto xk = x.col(surfNodes[static_cast<size_t>(k)]);
                dr = std::max(dr, (xk - xRef.col(k)).cwiseAbs().maxCoeff());
                if (pc->nearValid) mv = std::max(mv, (xk - pc->snap.col(i)).cwiseAbs().maxCoeff());
            }
            pc->drift = dr;
            pc->nearMove = mv;
            pc->refitted = false;
        }
    }
    // which pieces keep their static colliders' points from an earlier query
    if (!colliders.empty())
        for (auto& pc : pieces) {
            pc->nearFresh =
                !(pc->nearValid && std::sqrt(3.0) * wSum * pc->nearMove <= nearBand - kSpeculative * margin);
            if (!pc->nearFresh) continue;
            pc->near.assign(shapes.size(), {});
            pc->nearValid = false;
        }
    for (auto& pc : pieces) {
        pc->drift *= wSum;
        if (!pc->bounds(pc->around)) continue;  // a shape away from the whole piece costs no more than this
        pc->around.Expand(btVector3(pc->drift, pc->drift, pc->drift));
    }
}

// The tools' parts posed at tq (in the collision world) and at tOther.
void ContactWorld::Impl::poseTools(double tq, double tOther) {
    now.resize(shapes.size());
    other.resize(shapes.size());
    for (size_t t0 = 0, o = 0; t0 < tools.size(); ++t0) {
        const ToolDef& tool = tools[t0];
        const Pose pa = toolPose(tool, tq), pb = toolPose(tool, tOther);
        const auto partsA = toolParts(tool, tq), partsB = toolParts(tool, tOther);
        for (size_t i = 0; i < partsA.size(); ++i, ++o) {
            now[o] = bt(pa) * bt(partsA[i].local);
            other[o] = bt(pb) * bt(partsB[i].local);
            // a tool at rest keeps its box in the broad phase
            if (objects[o]->getWorldTransform() == now[o]) continue;
            objects[o]->setWorldTransform(now[o]);
            world.updateSingleAabb(objects[o].get());
        }
    }
}

// Shape o's bounds, ignored cut, slot and band for this step's query.
ContactWorld::Impl::ShapeQuery ContactWorld::Impl::shapeQuery(size_t o) const {
    const Shape& sh = shapes[o];
    ShapeQuery sq;
    sq.o = o;
    if (sh.plane) {
        const ColliderDef& cd = colliders[static_cast<size_t>(sh.collider)];
        sq.planeN = cd.normal();
        sq.planeO = cd.pose.position;
    } else {
        // the shape's own box: the broad phase grows the boxes it updates by Bullet's contact
        // breaking threshold (2 cm, for metre-sized rigid bodies), which made a 1 mm blade 1.5 cm
        // under a resting piece reach it
        btVector3 lo, hi;
        objects[o]->getCollisionShape()->getAabb(objects[o]->getWorldTransform(), lo, hi);
        sq.box = btDbvtVolume::FromMM(lo, hi);
    }
    sq.ignored =
        sh.tool < 0 || ignoredCut.empty() || pts.triCut.empty() ? -1 : ignoredCut[static_cast<size_t>(sh.tool)];
    sq.slot = sh.tool >= 0 && static_cast<size_t>(sh.tool) < slots.size() &&
                      !slots[static_cast<size_t>(sh.tool)].polygons.empty()
                  ? &slots[static_cast<size_t>(sh.tool)]
                  : nullptr;
    // a static collider's band: points within it are kept by pieces that query the trees now
    sq.fixedShape = sh.tool < 0;
    sq.band = sq.fixedShape ? nearBand : 0.0;
    sq.banded = sq.box;
    sq.banded.Expand(btVector3(sq.band, sq.band, sq.band));
    sq.frame = sh.tool >= 0 ? now[o] : sh.plane ? btTransform::getIdentity() : objects[o]->getWorldTransform();
    sq.back = sh.tool >= 0 ? other[o] * now[o].inverse() : btTransform::getIdentity();
    return sq;
}

// One shape's candidates from each piece, into `candidates` (points kept) and `triangles`.
// A piece away from the shape costs one box test; near it, the leaves within the piece's drift of
// the shape's box are visited, their moved nodes reset (surface_tree.cpp), and those that reach the
// box are the candidates.
void ContactWorld::Impl::queryPieces(const ShapeQuery& sq, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v,
                                     double dt, bool scan) {
    const Shape& sh = shapes[sq.o];
    for (auto& pc : pieces) {
        if (pc->empty()) continue;
        if (sq.fixedShape && !pc->nearFresh) {
            const auto& kept = pc->near[sq.o];
            candidates.insert(candidates.end(), kept.begin(), kept.end());
            continue;
        }
        if (sh.plane ? !(belowPlane(pc->around, sq.planeN, sq.planeO) < sq.band) : !Intersect(pc->around, sq.banded))
            continue;
        if (scan && !pc->built) {  // each triangle's own box is tested below
            for (const int t : pc->tris)
                if (sq.ignored < 0 || pts.triCut[static_cast<size_t>(t)] != sq.ignored) triangles.push_back(t);
            continue;
        }
        walkTrees(*pc, sq, x, v, dt);
    }
}

// The triangles of a piece's trees that reach the shape, into `triangles`; the moved nodes of the
// leaves visited are reset first.
void ContactWorld::Impl::walkTrees(Piece& pc, const ShapeQuery& sq, const Eigen::Matrix3Xd& x,
                                   const Eigen::Matrix3Xd& v, double dt) {
    const Shape& sh = shapes[sq.o];
    buildTrees(pc);
    // a piece that moved far as a whole (sagging, falling) is refitted in one pass, which
    // brings its drift back down; else only where the shape may reach
    if (!pc.refitted && pc.drift > kRefitAll * fat) refitMoved(pc, x, v, dt);
    const double reach = pc.refitted ? 0.0 : pc.drift;
    btDbvtVolume region = sq.banded;
    region.Expand(btVector3(reach, reach, reach));
    auto reaches = [&](const btDbvtVolume& vol, double by, const btDbvtVolume& b) {
        return sh.plane ? belowPlane(vol, sq.planeN, sq.planeO) < by + sq.band : Intersect(vol, b);
    };
    visited.clear();
    resetting.clear();
    // faces of a cut this tool does not touch are not visited: their points are reached
    // through other candidate faces only
    walk.clear();
    for (size_t i = 0; i < pc.trees.size(); ++i)
        if (pc.trees[i].m_root && (sq.ignored < 0 || pc.treeCut[i] != sq.ignored)) walk.push_back(pc.trees[i].m_root);
    while (!walk.empty()) {
        const btDbvtNode* n = walk.back();
        walk.pop_back();
        if (!reaches(n->volume, reach, region)) continue;
        if (!n->isleaf()) {
            walk.push_back(n->childs[0]), walk.push_back(n->childs[1]);
            continue;
        }
        const auto t = static_cast<size_t>(n->dataAsInt);
        visited.push_back(n->dataAsInt);
        if (!pc.refitted)
            for (int i = triNodeStart[t]; i < triNodeStart[t + 1]; ++i)
                if (moved(x, static_cast<size_t>(triNodes[static_cast<size_t>(i)])) > trigger)
                    resetting.push_back(triNodes[static_cast<size_t>(i)]);
    }
    resetNodes(resetting.data(), resetting.data() + resetting.size(), x, v, dt);
    for (const int t : visited)
        if (reaches(leaves[static_cast<size_t>(t)]->volume, 0, sq.banded)) triangles.push_back(t);
}

// The candidate triangles' points, each once, after the points kept; `triangles` emptied.
void ContactWorld::Impl::candidatePoints(const ShapeQuery& sq, const Eigen::Matrix3Xd& x, double speculative) {
    const Shape& sh = shapes[sq.o];
    const ContactPoints& P = pts;
    if (++query == std::numeric_limits<int>::max()) {
        std::fill(stamp.begin(), stamp.end(), -1);
        query = 0;
    }
    const btVector3 bc = sq.frame.getOrigin();
    const double within = std::max(speculative, sq.band);  // what a point must reach to be tested
    const double brw = sh.radius + sq.band;
    btDbvtVolume near = sq.box;
    near.Expand(btVector3(within, within, within));
    for (const int t : triangles) {
        // the triangle's points lie in the box of its vertices: a box away from the shape's
        // box, or from its bounding sphere, leaves them all out (as the test per point would)
        for (int k = 0; k < 3; ++k) place(x, P.triangles(k, t));
        const btDbvtVolume tb = triangleBox(xp, P.triangles, t);
        if (sh.plane ? !(belowPlane(tb, sq.planeN, sq.planeO) < within)
                     : !Intersect(tb, near) || boxDistance2(tb, bc) > brw * brw * (1 + 1e-9))
            continue;
        for (int k = P.triStart[static_cast<size_t>(t)]; k < P.triStart[static_cast<size_t>(t) + 1]; ++k) {
            const int p = P.triPoints[static_cast<size_t>(k)];
            if (stamp[static_cast<size_t>(p)] == query) continue;
            stamp[static_cast<size_t>(p)] = query;
            candidates.push_back(p);
        }
    }
    triangles.clear();
    // in point order: the contacts, and the projection's sweeps over them, do not depend on
    // the trees' state (nor on whether a piece kept its points)
    std::sort(candidates.begin(), candidates.end());
}

// The candidates' signed distances to the shape: those within a static collider's band are kept
// by their pieces, those within the speculative reach become touches.
void ContactWorld::Impl::testPoints(const ShapeQuery& sq, const Eigen::Matrix3Xd& x, double tq, double tOther,
                                    double speculative) {
    const Shape& sh = shapes[sq.o];
    const btVector3 bc = sq.frame.getOrigin();
    const double brw = sh.radius + sq.band;
    for (int p : candidates) {
        if (!dropped.empty() && dropped[static_cast<size_t>(p)]) continue;
        place(x, p);
        const btVector3 q = bt(Eigen::Vector3d(xp.col(p)));
        double d = 0;
        Eigen::Vector3d n;  // the way out of the shape
        if (sh.plane) {
            n = sq.planeN;
            d = sq.planeN.dot(xp.col(p) - sq.planeO);
        } else {
            // bounding sphere of the part about its origin: points outside it need no distance
            if (q.distance2(bc) > brw * brw) continue;
            if (!closedFormDistance(sh.part, sq.frame, q, d, n)) {
                btGjkEpaSolver2::sResults res;
                d = btGjkEpaSolver2::SignedDistance(q, 0, btShapes[sq.o].get(), sq.frame, res);
                n = eig(res.normal);
            }
        }
        if (sq.fixedShape && d < sq.band) {
            Piece& pc = *pieces[static_cast<size_t>(pointPiece[static_cast<size_t>(p)])];
            if (pc.nearFresh) pc.near[sq.o].push_back(p);
        }
        if (sh.plane && !(d < speculative)) continue;
        ++last.tested;
        if (!(d < speculative) || !std::isfinite(d)) continue;
        if (!n.allFinite() || std::abs(n.norm() - 1) > 1e-6) continue;
        if (sq.slot && sq.slot->contains(xp.col(p))) continue;
        addTouch(sq, p, q, d, n, tq, tOther);
    }
}

// The touch of point p (at q, d from the shape along n), its depth counted when it is inside.
void ContactWorld::Impl::addTouch(const ShapeQuery& sq, int p, const btVector3& q, double d, const Eigen::Vector3d& n,
                                  double tq, double tOther) {
    const Shape& sh = shapes[sq.o];
    ContactStep& st = last;
    Touch tc;
    tc.point = p;
    tc.shape = static_cast<int>(sq.o);
    tc.n_ = n;
    tc.depth = -d;
    tc.c0 = xp.col(p);
    tc.friction = sh.friction;
    // the velocity of the shape's material point at q over the step (tools only move)
    tc.vWall = sh.tool >= 0 && tq != tOther ? Eigen::Vector3d((eig(q) - eig(sq.back * q)) / (tq - tOther))
                                            : Eigen::Vector3d::Zero();
    tc.first = static_cast<int>(terms.size());
    tc.n = pts.count[static_cast<size_t>(p)];
    for (int i = 0; i < tc.n; ++i) terms.push_back({pts.nodes(i, p), pts.weights(i, p)});
    touches.push_back(tc);
    if (!(d < 0)) return;  // a speculative contact: near, not in
    if (sh.tool >= 0)
        ++st.contacts, st.maxDepth = std::max(st.maxDepth, -d);
    else
        ++st.colliderContacts, st.colliderDepth = std::max(st.colliderDepth, -d);
}

// The pieces that queried the trees keep their points until they move.
void ContactWorld::Impl::keepNear(const Eigen::Matrix3Xd& x) {
    if (colliders.empty()) return;
    for (auto& pc : pieces)
        if (pc->nearFresh) {
            pc->snap.resize(3, static_cast<Eigen::Index>(pc->nodes.size()));
            for (size_t i = 0; i < pc->nodes.size(); ++i)
                pc->snap.col(static_cast<Eigen::Index>(i)) = x.col(surfNodes[static_cast<size_t>(pc->nodes[i])]);
            pc->nearValid = true;
            pc->nearFresh = false;
        }
}

// The pieces near another refitted, then the points of one piece inside another as touches.
void ContactWorld::Impl::pressPieces(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt) {
    for (auto& pc : pieces)
        if (!pc->refitted && !pc->empty()) {
            bool near = false;
            for (auto& q : pieces)
                near = near || (q.get() != pc.get() && !q->empty() && Intersect(pc->around, q->around));
            if (near) buildTrees(*pc), refitMoved(*pc, x, v, dt);
        }
    for (auto& pc : pieces) pc->bounds(pc->around);  // refitted: exact where they meet
    touchPieces();
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
                           Eigen::Matrix3Xd& v, std::vector<int>* moved) {
    Impl& m = *impl_;
    m.gather(x, v, time, time - dt, true);
    m.last.residualDepth = 0;
    if (moved) moved->clear();
    if (m.touches.empty()) return;
    bool renormalised = false;
    for (Touch& tc : m.touches) renormalised = m.setUpTouch(tc, invMass, x) || renormalised;
    if (renormalised) m.recountDepths();  // the depths reported are the ones held
    m.sweepVelocities(x, v, dt);
    m.sweepPositions(x);
    m.reportProjection(x, dt, moved);
}

// Adds the impulse to y at the touch's nodes, each by its share over its mass.
void ContactWorld::Impl::apply(Eigen::Matrix3Xd& y, const Touch& tc, const Eigen::Vector3d& impulse) {
    for (int i = tc.first; i < tc.first + tc.n; ++i) {
        const Term& t = terms[static_cast<size_t>(i)];
        y.col(t.node) += (t.w * t.im) * impulse;
    }
}

// sum_i w_i^2 / m_i over the touch's terms: the inverse of its effective mass.
double ContactWorld::Impl::inverseMass(const Touch& tc) const {
    double w = 0;
    for (int i = tc.first; i < tc.first + tc.n; ++i) {
        const Term& t = terms[static_cast<size_t>(i)];
        w += t.w * t.w * t.im;
    }
    return w;
}

// The point measured on its terms with nonzero weight again: depth moved to the new point.
void ContactWorld::Impl::remeasure(Touch& tc, double sum, const Eigen::Matrix3Xd& x) {
    for (int i = tc.first; i < tc.first + tc.n; ++i) terms[static_cast<size_t>(i)].w /= sum;
    const Eigen::Vector3d c = combine(x, tc);
    tc.depth -= tc.n_.dot(c - tc.c0);
    tc.c0 = c;
}

// A touch's nodes the projection moves, and its effective mass (0: left alone); true when the point
// was measured again on fewer nodes.
// Each point is corrected through its free nodes with their true masses, so that the velocity
// and position projections are orthogonal in the mass norm: they only take energy out. (A
// correction with masses capped at the contact's mean moved light nodes as if heavy; on an MI
// object landing on a floor that fed ~10 J into a body holding 0.5 J; docs/method.md, Contact.)
// A light node that carries a small share of the point would take most of a true-mass
// correction, up to depth / w: a node that would move more than kMaxLever times the point is
// left out of both the point's measure and its correction (weights renormalised), so the
// projection stays consistent on the nodes that remain.
// Nodes outside the material (setSurface's `outside`) take no correction when the point's other
// free nodes carry kMinFreeWeight of it: they belong to partial elements only, whose lumping
// keeps a parent's eigenvalues on light nodes (xfem.hpp), so their modes sit near the step's
// limit, and stopping them on contact every step fed a vibration that mass damping could not
// remove (a severed lobe on a floor kept ~3 mJ; docs/method.md, Contact).
// A contact whose free nodes carry less than kMinFreeWeight of it (a point on the fixed part)
// is left alone: stopping it would take node moves of 1 / (their weight) times its own.
bool ContactWorld::Impl::setUpTouch(Touch& tc, const Eigen::VectorXd& invMass, const Eigen::Matrix3Xd& x) {
    const bool anyOutside = !outside.empty();
    bool renormalised = false;
    double inside = 0, all = 0;
    for (int i = tc.first; i < tc.first + tc.n; ++i) {
        const Term& t = terms[static_cast<size_t>(i)];
        if (!(invMass(t.node) > 0)) continue;
        all += std::abs(t.w);
        if (anyOutside && !outside[static_cast<size_t>(t.node)]) inside += std::abs(t.w);
    }
    if (all < kMinFreeWeight) {
        tc.mass = 0;
        return false;
    }
    const bool skipOutside = anyOutside && inside >= kMinFreeWeight;
    if (skipOutside && tc.shape >= 0) {
        if (!measureInside(tc, x)) return false;
        renormalised = true;
    }
    for (int i = tc.first; i < tc.first + tc.n; ++i) {
        Term& t = terms[static_cast<size_t>(i)];
        const bool moves = t.w != 0 && !(skipOutside && outside[static_cast<size_t>(t.node)]);
        t.im = moves ? invMass(t.node) : 0.0;
    }
    if (dropLightNodes(tc, x)) renormalised = true;
    const double w = inverseMass(tc);
    tc.mass = w > 0 ? 1.0 / w : 0.0;  // 0: on fixed nodes only, nothing to move
    return renormalised;
}

// The point measured on its nodes inside the material; false when they carry too little of it (the
// touch is then left alone, its depth not reported as held).
// The point is then measured on the nodes inside the material too: its position and
// velocity from them alone (weights renormalised), its depth moved to that point. A
// point read through its outside nodes saw their ringing as an approach, and stopping
// it took 1 / (inside weight) times that speed from the inside nodes (a landed lobe was
// thrown off the floor).
// A point its inside nodes carry less than kMinFreeWeight of (their weights sum to
// that or below: it lies beyond them, some weights negative) is left alone: pushing
// it out would push them in (a node fought its own floor contact, ringing up to
// 150 m/s).
bool ContactWorld::Impl::measureInside(Touch& tc, const Eigen::Matrix3Xd& x) {
    double sum = 0;
    for (int i = tc.first; i < tc.first + tc.n; ++i) {
        Term& t = terms[static_cast<size_t>(i)];
        if (outside[static_cast<size_t>(t.node)])
            t.w = 0;
        else
            sum += t.w;
    }
    if (!(sum >= kMinFreeWeight)) {
        tc.mass = 0;
        tc.depth = 0;  // nor reported as held
        return false;
    }
    remeasure(tc, sum, x);
    return true;
}

// Light nodes of a small share out (a point on another piece's triangle keeps its terms:
// its weights sum to zero over the two pieces, there is no share to renormalise); true when one was.
bool ContactWorld::Impl::dropLightNodes(Touch& tc, const Eigen::Matrix3Xd& x) {
    bool renormalised = false;
    for (int round = 0; round < tc.n && tc.shape >= 0; ++round) {
        const double w2 = inverseMass(tc);
        int worst = -1;
        double lever = kMaxLever * w2;
        for (int i = tc.first; i < tc.first + tc.n; ++i)
            if (const Term& t = terms[static_cast<size_t>(i)]; std::abs(t.w) * t.im > lever)
                lever = std::abs(t.w) * t.im, worst = i;
        if (worst < 0) break;
        Term& out = terms[static_cast<size_t>(worst)];
        double rest = -out.w;
        for (int i = tc.first; i < tc.first + tc.n; ++i) rest += terms[static_cast<size_t>(i)].w;
        if (!(rest >= kMinFreeWeight)) break;  // nothing left to carry the point: keep it whole
        out.w = 0;
        out.im = 0;
        remeasure(tc, rest, x);
        renormalised = true;
    }
    return renormalised;
}

// The step's contact counts and depths from the touches' depths.
void ContactWorld::Impl::recountDepths() {
    ContactStep& st = last;
    st.contacts = st.colliderContacts = 0;
    st.maxDepth = st.colliderDepth = 0;
    for (const Touch& tc : touches) {
        if (tc.shape < 0 || !(tc.depth > 0)) continue;
        if (shapes[static_cast<size_t>(tc.shape)].tool >= 0)
            ++st.contacts, st.maxDepth = std::max(st.maxDepth, tc.depth);
        else
            ++st.colliderContacts, st.colliderDepth = std::max(st.colliderDepth, tc.depth);
    }
}

// Velocities: no approach, friction within the cone.
// Sweeps stop early once one changes no contact's velocity by more than kSettledSpeed (or its
// position by kSettledMove): a resting contact, or contacts sharing no node, need one or two.
void ContactWorld::Impl::sweepVelocities(Eigen::Matrix3Xd& x, Eigen::Matrix3Xd& v, double dt) {
    for (int it = 0, settled = 0; it < kProjectionIterations && !settled; ++it) {
        double change = 0;
        for (Touch& tc : touches) {
            if (tc.mass == 0) continue;
            // the normal speed is held against the world, not the tool: a tool moves what it presses
            // by the position correction below (quasi-static), so a tool set to a new pose in one
            // tick (a haptic device's sample) does not throw the tissue off at its jump's speed
            Eigen::Vector3d rel = combine(v, tc);
            const double allowed = tc.depth < 0 && dt > 0 ? tc.depth / dt : 0.0;  // a gap may close, no more
            const double lambda = std::max(0.0, tc.lambda + tc.mass * (allowed - tc.n_.dot(rel)));
            apply(v, tc, (lambda - tc.lambda) * tc.n_);
            change = std::max(change, std::abs(lambda - tc.lambda) / tc.mass);
            tc.lambda = lambda;
            if (!(tc.friction > 0)) continue;
            rel = combine(v, tc) - tc.vWall;
            Eigen::Vector3d t = tc.tangent - tc.mass * (rel - tc.n_.dot(rel) * tc.n_);
            const double cap = tc.friction * tc.lambda, len = t.norm();
            if (len > cap) t *= cap / len;
            apply(v, tc, t - tc.tangent);
            // and on the step's slide: x moved with the velocity before friction, so the step's
            // tangential motion is what friction undoes (else a sticking contact creeps by
            // dt^2 times the driving acceleration each step)
            if (dt > 0) apply(x, tc, dt * (t - tc.tangent));
            change = std::max(change, (t - tc.tangent).norm() / tc.mass);
            tc.tangent = t;
        }
        settled = change <= kSettledSpeed;
    }
}

// Positions: back onto the surface, depths linearised about the detected points.
void ContactWorld::Impl::sweepPositions(Eigen::Matrix3Xd& x) {
    for (int it = 0, settled = 0; it < kProjectionIterations && !settled; ++it) {
        double change = 0;
        for (Touch& tc : touches) {
            if (tc.mass == 0) continue;
            const double depth = tc.depth - tc.n_.dot(combine(x, tc) - tc.c0);
            const double push = std::max(0.0, tc.push + tc.mass * depth);
            apply(x, tc, (push - tc.push) * tc.n_);
            change = std::max(change, std::abs(push - tc.push) / tc.mass);
            tc.push = push;
        }
        settled = change <= kSettledMove;
    }
}

// The depth left, the nodes moved (ascending, each once) and the reaction on each tool: minus the
// momentum given to the tissue over the step.
void ContactWorld::Impl::reportProjection(const Eigen::Matrix3Xd& x, double dt, std::vector<int>* moved) {
    ContactStep& st = last;
    for (const Touch& tc : touches) {
        if (moved && tc.mass > 0)
            for (int i = tc.first; i < tc.first + tc.n; ++i)
                if (terms[static_cast<size_t>(i)].w != 0 && terms[static_cast<size_t>(i)].im > 0)
                    moved->push_back(terms[static_cast<size_t>(i)].node);
        if (tc.mass > 0 && tc.depth > 0)
            st.residualDepth = std::max(st.residualDepth, tc.depth - tc.n_.dot(combine(x, tc) - tc.c0));
        if (tc.shape < 0) continue;
        const Shape& sh = shapes[static_cast<size_t>(tc.shape)];
        if (sh.tool >= 0 && dt > 0) st.reaction[static_cast<size_t>(sh.tool)] -= (tc.lambda * tc.n_ + tc.tangent) / dt;
    }
    if (moved) {
        std::sort(moved->begin(), moved->end());
        moved->erase(std::unique(moved->begin(), moved->end()), moved->end());
    }
}

}  // namespace cutsim
