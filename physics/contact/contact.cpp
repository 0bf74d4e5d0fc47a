#include "contact/contact.hpp"

#include "timestep/timestep.hpp"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkEpa2.h>
#include <btBulletCollisionCommon.h>
#include <Eigen/SparseCore>
#include <Spectra/MatOp/SparseCholesky.h>
#include <Spectra/MatOp/SparseSymMatProd.h>
#include <Spectra/SymGEigsSolver.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <utility>

namespace cutsim {

namespace {

std::atomic<int> gLiveWorlds{0};

// Steps of motion a moved leaf is grown by along its velocity (at most 4 fat).
constexpr double kLookahead = 16;

btVector3 bt(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d eig(const btVector3& v) { return {v.x(), v.y(), v.z()}; }
btTransform bt(const Pose& p) {
    const Eigen::Quaterniond& q = p.orientation;
    return btTransform(btQuaternion(q.x(), q.y(), q.z(), q.w()), bt(p.position));
}

// One point of the surface: a weighted sum of embedded vertices.
struct Acc {
    int n = 0;
    int nodes[ContactPoints::kMaxNodes] = {};
    double w[ContactPoints::kMaxNodes] = {};
    void add(int node, double weight) {
        for (int i = 0; i < n; ++i)
            if (nodes[i] == node) {
                w[i] += weight;
                return;
            }
        nodes[n] = node;
        w[n++] = weight;
    }
};

}  // namespace

double contactPointCount(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                         double spacing) {
    Eigen::Matrix3Xd rest;
    embeddedPositions(s, tets, X, rest);
    auto pieces = [&](int a, int b) {  // as in contactPoints, in doubles: a tiny spacing must not overflow
        return spacing > 0 ? std::max(1.0, std::ceil((rest.col(a) - rest.col(b)).norm() / spacing)) : 1.0;
    };
    std::set<std::pair<int, int>> edges;
    double n = s.vertices();
    for (int t = 0; t < s.faces(); ++t) {
        double longest = 1;
        for (int k = 0; k < 3; ++k) {
            const int a = s.triangles(k, t), b = s.triangles((k + 1) % 3, t);
            const double p = pieces(a, b);
            longest = std::max(longest, p);
            if (edges.insert(std::minmax(a, b)).second) n += p - 1;
        }
        n += (longest - 1) * (longest - 2) / 2;
    }
    return n;
}

ContactPoints contactPoints(const EmbeddedSurface& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X,
                            double spacing) {
    Eigen::Matrix3Xd rest;
    embeddedPositions(s, tets, X, rest);
    std::vector<Acc> acc;
    auto addVertex = [&](Acc& a, int v, double b) {
        const int e = s.element[static_cast<size_t>(v)];
        for (int k = 0; k < 4; ++k)
            if (s.weights(k, v) != 0) a.add(tets(k, e), b * s.weights(k, v));
    };
    for (int v = 0; v < s.vertices(); ++v) {
        Acc a;
        addVertex(a, v, 1.0);
        acc.push_back(a);
    }
    auto pieces = [&](int a, int b) {
        return spacing > 0 ? std::max(1, static_cast<int>(std::ceil((rest.col(a) - rest.col(b)).norm() / spacing))) : 1;
    };
    // edge points once per edge, so a shared edge is not sampled twice
    std::map<std::pair<int, int>, std::vector<int>> edgePoints;
    for (int t = 0; t < s.faces(); ++t)
        for (int k = 0; k < 3; ++k) {
            const int a = s.triangles(k, t), b = s.triangles((k + 1) % 3, t);
            edgePoints.emplace(std::minmax(a, b), std::vector<int>{});
        }
    for (auto& [e, ids] : edgePoints) {
        const int n = pieces(e.first, e.second);
        for (int i = 1; i < n; ++i) {
            Acc p;
            addVertex(p, e.first, 1.0 - double(i) / n);
            addVertex(p, e.second, double(i) / n);
            ids.push_back(static_cast<int>(acc.size()));
            acc.push_back(p);
        }
    }
    // per triangle: its vertices, its edges' points, and interior points on a barycentric grid as
    // fine as its longest edge needs
    std::vector<int> triStart{0}, triPoints;
    for (int t = 0; t < s.faces(); ++t) {
        const int a = s.triangles(0, t), b = s.triangles(1, t), c = s.triangles(2, t);
        triPoints.insert(triPoints.end(), {a, b, c});
        for (int k = 0; k < 3; ++k) {
            const auto& ids = edgePoints.at(std::minmax(s.triangles(k, t), s.triangles((k + 1) % 3, t)));
            triPoints.insert(triPoints.end(), ids.begin(), ids.end());
        }
        const int n = std::max({pieces(a, b), pieces(b, c), pieces(c, a)});
        for (int i = 1; i < n; ++i)
            for (int j = 1; i + j < n; ++j) {
                Acc p;
                addVertex(p, a, double(i) / n);
                addVertex(p, b, double(j) / n);
                addVertex(p, c, double(n - i - j) / n);
                triPoints.push_back(static_cast<int>(acc.size()));
                acc.push_back(p);
            }
        triStart.push_back(static_cast<int>(triPoints.size()));
    }
    ContactPoints out;
    out.nodes.setZero(ContactPoints::kMaxNodes, static_cast<Eigen::Index>(acc.size()));
    out.weights.setZero(ContactPoints::kMaxNodes, static_cast<Eigen::Index>(acc.size()));
    out.count.resize(acc.size());
    out.scale = Eigen::VectorXd::Ones(static_cast<Eigen::Index>(acc.size()));
    out.triangles = s.triangles;
    if (s.cutId.size() == static_cast<size_t>(s.faces())) out.triCut = s.cutId;
    out.triStart = std::move(triStart);
    out.triPoints = std::move(triPoints);
    for (size_t p = 0; p < acc.size(); ++p) {
        out.count[p] = static_cast<std::uint8_t>(acc[p].n);
        for (int i = 0; i < acc[p].n; ++i) {
            out.nodes(i, static_cast<Eigen::Index>(p)) = acc[p].nodes[i];
            out.weights(i, static_cast<Eigen::Index>(p)) = acc[p].w[i];
        }
    }
    return out;
}

namespace {
// 1 / (w_p^T M^-1 w_p) over the free nodes [kg]; infinity when the point moves no free node
double effectiveMass(const ContactPoints& pts, const Eigen::VectorXd& invMass, int p) {
    double s = 0;
    for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i)
        s += pts.weights(i, p) * pts.weights(i, p) * invMass(pts.nodes(i, p));
    return s > 0 ? 1.0 / s : std::numeric_limits<double>::infinity();
}
}  // namespace

void scaleByMass(ContactPoints& pts, const Eigen::VectorXd& invMass, double mRef) {
    pts.scale.resize(pts.points());
    for (int p = 0; p < pts.points(); ++p) pts.scale(p) = std::min(1.0, effectiveMass(pts, invMass, p) / mRef);
}

double referenceMass(const ContactPoints& pts, const Eigen::VectorXd& invMass) {
    std::vector<double> m;
    for (int p = 0; p < pts.points(); ++p)
        if (const double mp = effectiveMass(pts, invMass, p); std::isfinite(mp)) m.push_back(mp);
    if (m.empty()) return 1;
    const auto q = m.begin() + static_cast<std::ptrdiff_t>(0.9 * static_cast<double>(m.size() - 1));
    std::nth_element(m.begin(), q, m.end());
    return *q;
}

double stableStiffness(const ContactPoints& pts, const Model& model, double dt, double dtCrit) {
    if (!(dt > 0) || !(dt < dtCrit)) return 0;
    const double target = 4.0 / (dt * dt);
    int nf = 0;
    const std::vector<int> map = freeDofMap(model, &nf);
    // B = target I - M^-1/2 K M^-1/2 and C = M^-1/2 (sum_p w_p w_p^T (x) I) M^-1/2 over the free DOFs
    Eigen::SparseMatrix<double> B = -scaledFreeStiffness(model, map, nf);
    for (int d = 0; d < nf; ++d) B.coeffRef(d, d) += target;
    std::vector<Eigen::Triplet<double>> tc;
    for (int p = 0; p < pts.points(); ++p)
        for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i)
            for (int j = 0; j < pts.count[static_cast<size_t>(p)]; ++j) {
                const int ni = pts.nodes(i, p), nj = pts.nodes(j, p);
                if (map[3 * static_cast<size_t>(ni)] < 0 || map[3 * static_cast<size_t>(nj)] < 0) continue;
                const double v = pts.scale(p) * pts.weights(i, p) * pts.weights(j, p) *
                                 std::sqrt(model.invMass(ni) * model.invMass(nj));
                for (int k = 0; k < 3; ++k)
                    tc.emplace_back(map[3 * static_cast<size_t>(ni) + k], map[3 * static_cast<size_t>(nj) + k], v);
            }
    if (tc.empty()) return std::numeric_limits<double>::infinity();
    Eigen::SparseMatrix<double> C(nf, nf);
    C.setFromTriplets(tc.begin(), tc.end());
    // k_max = 1 / nu_max of C x = nu B x: B is positive definite exactly when dt < dtCrit
    using Op = Spectra::SparseSymMatProd<double>;
    using BOp = Spectra::SparseCholesky<double>;
    Op op(C);
    BOp bop(B);
    if (bop.info() != Spectra::CompInfo::Successful) return 0;  // rounding at dt ~ dtCrit: no headroom
    Spectra::SymGEigsSolver<Op, BOp, Spectra::GEigsMode::Cholesky> eigs(op, bop, 1, std::min(24, nf));
    eigs.init();
    computeEigs(eigs, "contact stiffness limit", Spectra::SortRule::LargestAlge, 2000, 1e-10);
    if (eigs.info() != Spectra::CompInfo::Successful)
        throw EigenSolveError("contact stiffness limit: Lanczos did not converge (" + std::to_string(nf) +
                              " free DOFs)");
    const double nu = eigs.eigenvalues()(0);
    return nu > 0 ? 1.0 / nu : std::numeric_limits<double>::infinity();
}

// ---- ContactWorld ----

namespace {

// A Bullet convex shape of one tool part. Margins are zero for boxes and hulls so that their core
// is the shape itself; a sphere's or capsule's radius is its margin, which SignedDistance subtracts.
std::unique_ptr<btConvexShape> makeShape(const ToolPart& p, const ToolDef& tool) {
    std::unique_ptr<btConvexShape> s;
    if (p.hull) {
        auto h = std::make_unique<btConvexHullShape>();
        for (int i = 0; i < tool.hull.cols(); ++i) h->addPoint(bt(Eigen::Vector3d(tool.hull.col(i))), false);
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

struct Collect : btDbvt::ICollide {
    std::vector<int>* out = nullptr;
    void Process(const btDbvtNode* leaf) override { out->push_back(leaf->dataAsInt); }
};

// Signed distance of the world point x to a sphere, capsule or box part whose frame is `frame`,
// in closed form (the same as btGjkEpaSolver2::SignedDistance up to rounding, without its
// iterations); n is the way out of the part. False for a hull, which goes to GJK/EPA.
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

}  // namespace

double partSignedDistance(const ToolPart& part, const ToolDef& tool, const Pose& frame, const Eigen::Vector3d& x,
                          Eigen::Vector3d& n, bool closedForm) {
    const btTransform tr = bt(frame);
    double d = 0;
    if (closedForm && closedFormDistance(part, tr, bt(x), d, n)) return d;
    const std::unique_ptr<btConvexShape> shape = makeShape(part, tool);
    btGjkEpaSolver2::sResults res;
    d = btGjkEpaSolver2::SignedDistance(bt(x), 0, shape.get(), tr, res);
    n = eig(res.normal);
    return d;
}

struct ContactWorld::Impl {
    std::vector<ToolDef> tools;
    // the collision world holds the tool parts; its broad phase keeps their boxes
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btCollisionWorld world{&dispatcher, &broadphase, &config};
    std::vector<std::unique_ptr<btConvexShape>> shapes;
    std::vector<std::unique_ptr<btCollisionObject>> objects;
    std::vector<int> partTool;       // tool of each part
    std::vector<int> partIndex;      // index of the part within its tool
    std::vector<double> partRadius;  // radius of a sphere about the part origin holding the part [m]
    std::vector<ToolPart> parts;     // each part's shape (for the closed-form distances)

    ContactPoints pts;
    std::vector<int> ignoredCut;      // per tool: the cut whose faces it does not touch, or -1
    btDbvt tree;                      // triangle boxes, each holding its triangle grown by `margin` at the last refit
    std::vector<btDbvtNode*> leaves;  // (nTris)
    double fat = 1e-3;                // a leaf moved is grown by this [m]
    double margin = 5e-4;             // and kept while its triangle stays `margin` inside it (fat / 2) [m]
    std::vector<int> surfNodes;       // nodes the surface's vertices follow
    Eigen::Matrix3Xd xRef;            // their positions when their triangles were last refitted (3 x surfNodes) [m]
    std::vector<double> moved;        // how far each moved from there, per axis (surfNodes) [m]
    std::vector<int> nodeTriStart;    // CSR: triangles following surface node k (surfNodes + 1)
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
    std::vector<btTransform> now, next;  // part transforms at t and t + dt
    ContactStep last;

    void clearTree() {
        tree.clear();
        leaves.clear();
    }
};

ContactWorld::ContactWorld(std::vector<ToolDef> tools) : impl_(std::make_unique<Impl>()) {
    ++gLiveWorlds;
    Impl& m = *impl_;
    m.tools = std::move(tools);
    double smallest = 1e300;
    for (size_t t = 0; t < m.tools.size(); ++t) {
        const auto parts = toolParts(m.tools[t], 0);
        for (size_t i = 0; i < parts.size(); ++i) {
            m.shapes.push_back(makeShape(parts[i], m.tools[t]));
            auto obj = std::make_unique<btCollisionObject>();
            obj->setCollisionShape(m.shapes.back().get());
            obj->setCollisionFlags(obj->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT |
                                   btCollisionObject::CF_NO_CONTACT_RESPONSE);
            obj->setWorldTransform(bt(toolPose(m.tools[t], 0)) * bt(parts[i].local));
            m.world.addCollisionObject(obj.get());
            m.objects.push_back(std::move(obj));
            m.partTool.push_back(static_cast<int>(t));
            m.partIndex.push_back(static_cast<int>(i));
            const ToolPart& q = parts[i];
            double rad = q.shape == ToolShape::Kind::Sphere    ? q.size.x()
                         : q.shape == ToolShape::Kind::Capsule ? q.size.x() + q.size.y()
                                                               : q.size.norm();
            if (q.hull) {
                rad = 0;
                for (int k = 0; k < m.tools[t].hull.cols(); ++k) rad = std::max(rad, m.tools[t].hull.col(k).norm());
            }
            m.partRadius.push_back(rad * (1 + 1e-9));
            m.parts.push_back(parts[i]);
            smallest = std::min(smallest, parts[i].size.minCoeff() > 0 ? parts[i].size.minCoeff() : parts[i].size.x());
        }
    }
    // leaves move only when a point leaves a box this much bigger than itself
    m.fat = std::clamp(0.5 * smallest, 1e-5, 1e-2);
    m.margin = 0.5 * m.fat;
    m.last.reaction.assign(m.tools.size(), Eigen::Vector3d::Zero());
}

ContactWorld::~ContactWorld() {
    Impl& m = *impl_;
    m.clearTree();
    for (auto& o : m.objects) m.world.removeCollisionObject(o.get());
    --gLiveWorlds;
}

int ContactWorld::live() { return gLiveWorlds.load(); }
std::vector<ToolDef>& ContactWorld::tools() { return impl_->tools; }
const std::vector<ToolDef>& ContactWorld::tools() const { return impl_->tools; }
const ContactPoints& ContactWorld::points() const { return impl_->pts; }
const ContactStep& ContactWorld::last() const { return impl_->last; }

void ContactWorld::ignoreCut(int tool, int cut) {
    Impl& m = *impl_;
    m.ignoredCut.resize(m.tools.size(), -1);
    m.ignoredCut.at(static_cast<size_t>(tool)) = cut;
}

void ContactWorld::setSurface(ContactPoints pts) {
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
}

void ContactWorld::addForces(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double time, double dt,
                             Eigen::Matrix3Xd& f) {
    Impl& m = *impl_;
    const ContactPoints& P = m.pts;
    const int nt = static_cast<int>(P.triangles.cols());
    ContactStep& st = m.last;
    st.reaction.assign(m.tools.size(), Eigen::Vector3d::Zero());
    st.contacts = 0;
    st.maxDepth = 0;
    st.tested = 0;
    auto interpolate = [&](int p) {
        Eigen::Vector3d xs = Eigen::Vector3d::Zero();
        for (int i = 0; i < P.count[static_cast<size_t>(p)]; ++i) xs += P.weights(i, p) * x.col(P.nodes(i, p));
        m.xp.col(p) = xs;
    };
    auto triBox = [&](int t) {
        const Eigen::Vector3d a = m.xp.col(P.triangles(0, t)), b = m.xp.col(P.triangles(1, t)),
                              c = m.xp.col(P.triangles(2, t));
        return btDbvtVolume::FromMM(bt(Eigen::Vector3d(a.cwiseMin(b).cwiseMin(c))),
                                    bt(Eigen::Vector3d(a.cwiseMax(b).cwiseMax(c))));
    };
    // Leaves hold their triangle grown by `margin` when refitted, and a triangle is refitted as
    // soon as one of its nodes moved more than margin / (2 wSum) from where it was at its last
    // refit (then each vertex moved at most `margin` since, the reference of a node being reset
    // when all its triangles are refitted). So the tree is exact where it is used.
    const double trigger = m.margin / (2 * std::max(m.wSum, 1e-300));
    auto build = [&]() {
        const int nv = P.triangles.maxCoeff() + 1;
        for (int p = 0; p < nv; ++p) interpolate(p);
        m.clearTree();
        m.leaves.resize(static_cast<size_t>(nt));
        for (int t = 0; t < nt; ++t) {
            btDbvtVolume vol = triBox(t);
            vol.Expand(btVector3(m.fat, m.fat, m.fat));
            m.leaves[static_cast<size_t>(t)] = m.tree.insert(vol, nullptr);
            m.leaves[static_cast<size_t>(t)]->dataAsInt = t;
        }
        for (size_t k = 0; k < m.surfNodes.size(); ++k)
            m.xRef.col(static_cast<Eigen::Index>(k)) = x.col(m.surfNodes[k]);
        std::fill(m.moved.begin(), m.moved.end(), 0.0);
    };
    auto refitMoved = [&]() {
        const int stamp = ++m.refits;
        m.dirty.clear();
        for (size_t k = 0; k < m.surfNodes.size(); ++k) {
            if (!(m.moved[k] > trigger)) continue;
            for (int i = m.nodeTriStart[k]; i < m.nodeTriStart[k + 1]; ++i) {
                const int t = m.nodeTris[static_cast<size_t>(i)];
                if (m.triStamp[static_cast<size_t>(t)] == stamp) continue;
                m.triStamp[static_cast<size_t>(t)] = stamp;
                m.dirty.push_back(t);
            }
            m.xRef.col(static_cast<Eigen::Index>(k)) = x.col(m.surfNodes[k]);
            m.moved[k] = 0;
        }
        const btVector3 grow(m.margin, m.margin, m.margin);
        for (int t : m.dirty) {
            for (int c = 0; c < 3; ++c) {
                const int p = P.triangles(c, t);
                if (m.vertStamp[static_cast<size_t>(p)] == stamp) continue;
                m.vertStamp[static_cast<size_t>(p)] = stamp;
                interpolate(p);
            }
            btDbvtNode* leaf = m.leaves[static_cast<size_t>(t)];
            btDbvtVolume vol = triBox(t);
            vol.Expand(grow);
            if (leaf->volume.Contain(vol)) continue;
            vol.Expand(grow);  // margin + margin = fat
            // grown along the triangle's velocity too, so a piece in steady motion (falling,
            // dragged) leaves its boxes less often (as Bullet's broad phase predicts its proxies)
            Eigen::Vector3d vt = Eigen::Vector3d::Zero();
            for (int c = 0; c < 3; ++c) {
                const int p = P.triangles(c, t);
                for (int i = 0; i < P.count[static_cast<size_t>(p)]; ++i) vt += P.weights(i, p) * v.col(P.nodes(i, p));
            }
            Eigen::Vector3d ahead = vt * (kLookahead * dt / 3);
            if (const double len = ahead.norm(); len > 4 * m.fat) ahead *= 4 * m.fat / len;
            if (ahead.allFinite()) vol.SignedExpand(bt(ahead));
            // in place, the ancestors' boxes refitted up to the first that still holds it: the
            // surface moves continuously, so neighbours stay neighbours and the tree keeps its
            // shape without Bullet's remove and insert per moved leaf
            leaf->volume = vol;
            for (btDbvtNode* n = leaf->parent; n; n = n->parent) {
                const btDbvtVolume before = n->volume;
                Merge(n->childs[0]->volume, n->childs[1]->volume, n->volume);
                if (before.Mins() == n->volume.Mins() && before.Maxs() == n->volume.Maxs()) break;
            }
        }
    };
    if (nt == 0) return;
    // 1. how far each surface node moved since its triangles were refitted; the whole surface lies
    // in the tree's root box grown by wSum times the farthest (one pass over the surface's nodes)
    double drift = 0;
    bool fresh = false;
    if (static_cast<int>(m.leaves.size()) != nt) {
        build();
        fresh = true;
    } else {
        double far = 0;
        for (size_t k = 0; k < m.surfNodes.size(); ++k) {
            m.moved[k] = (x.col(m.surfNodes[k]) - m.xRef.col(static_cast<Eigen::Index>(k))).cwiseAbs().maxCoeff();
            far = std::max(far, m.moved[k]);
        }
        drift = m.wSum * far;
    }
    // 2. tool parts at t and t + dt into the collision world; its broad phase updates their boxes
    std::vector<btTransform>& now = m.now;
    std::vector<btTransform>& next = m.next;
    now.resize(m.objects.size());
    next.resize(m.objects.size());
    for (size_t t0 = 0, o = 0; t0 < m.tools.size(); ++t0) {
        const ToolDef& tool = m.tools[t0];
        const Pose pa = toolPose(tool, time), pb = toolPose(tool, time + dt);
        const auto partsA = toolParts(tool, time), partsB = toolParts(tool, time + dt);
        for (size_t i = 0; i < partsA.size(); ++i, ++o) {
            now[o] = bt(pa) * bt(partsA[i].local);
            next[o] = bt(pb) * bt(partsB[i].local);
            m.objects[o]->setWorldTransform(now[o]);
        }
    }
    m.world.updateAabbs();
    // 3. per part: the bound-volume test, then candidates from the tree, then signed distances
    Collect collect;
    collect.out = &m.candidates;
    for (size_t o = 0; o < m.objects.size(); ++o) {
        const ToolDef& tool = m.tools[static_cast<size_t>(m.partTool[o])];
        const btBroadphaseProxy* proxy = m.objects[o]->getBroadphaseHandle();
        const btDbvtVolume box = btDbvtVolume::FromMM(proxy->m_aabbMin, proxy->m_aabbMax);
        if (!m.tree.m_root) continue;
        btDbvtVolume around = m.tree.m_root->volume;  // a tool away from the whole surface costs no more than this
        around.Expand(btVector3(drift, drift, drift));
        if (!Intersect(around, box)) continue;
        if (!fresh) {
            refitMoved();
            fresh = true;
        }
        m.candidates.clear();
        m.tree.collideTVNoStackAlloc(m.tree.m_root, box, m.stack, collect);
        // faces of a cut this tool does not touch: dropped here, their points reached through
        // other candidate faces only
        const int ignored =
            m.ignoredCut.empty() || P.triCut.empty() ? -1 : m.ignoredCut[static_cast<size_t>(m.partTool[o])];
        if (ignored >= 0)
            m.candidates.erase(std::remove_if(m.candidates.begin(), m.candidates.end(),
                                              [&](int t) { return P.triCut[static_cast<size_t>(t)] == ignored; }),
                               m.candidates.end());
        // the candidate triangles' points, each once, interpolated now
        const size_t ntri = m.candidates.size();
        if (++m.query == std::numeric_limits<int>::max()) {
            std::fill(m.stamp.begin(), m.stamp.end(), -1);
            m.query = 0;
        }
        for (size_t c = 0; c < ntri; ++c) {
            const int t = m.candidates[c];
            for (int k = P.triStart[static_cast<size_t>(t)]; k < P.triStart[static_cast<size_t>(t) + 1]; ++k) {
                const int p = P.triPoints[static_cast<size_t>(k)];
                if (m.stamp[static_cast<size_t>(p)] == m.query) continue;
                m.stamp[static_cast<size_t>(p)] = m.query;
                m.candidates.push_back(p);
            }
        }
        m.candidates.erase(m.candidates.begin(), m.candidates.begin() + static_cast<std::ptrdiff_t>(ntri));
        const btConvexShape* shape = m.shapes[o].get();
        const ToolPart& part = m.parts[o];
        const btTransform toolNext = next[o] * now[o].inverse();
        // bounding sphere of the part about its origin: points outside it need no distance
        const btVector3 bc = now[o].getOrigin();
        const double br = m.partRadius[o];
        for (int p : m.candidates) {
            interpolate(p);
            const btVector3 xp = bt(Eigen::Vector3d(m.xp.col(p)));
            if (xp.distance2(bc) > br * br) continue;
            ++st.tested;
            double d = 0;
            Eigen::Vector3d n;  // the way out of the tool
            if (!closedFormDistance(part, now[o], xp, d, n)) {
                btGjkEpaSolver2::sResults res;
                d = btGjkEpaSolver2::SignedDistance(xp, 0, shape, now[o], res);
                n = eig(res.normal);
            }
            if (!(d < 0) || !std::isfinite(d)) continue;
            if (!n.allFinite() || std::abs(n.norm() - 1) > 1e-6) continue;
            // velocity of the point, and of the tool's material point at xp over this step
            Eigen::Vector3d vp = Eigen::Vector3d::Zero();
            for (int i = 0; i < P.count[static_cast<size_t>(p)]; ++i) vp += P.weights(i, p) * v.col(P.nodes(i, p));
            const Eigen::Vector3d vTool =
                dt > 0 ? Eigen::Vector3d((eig(toolNext * xp) - eig(xp)) / dt) : Eigen::Vector3d::Zero();
            const double vn = n.dot(vp - vTool);
            const double fn = P.scale(p) * std::max(0.0, tool.stiffness * (-d) - tool.damping * vn);
            const Eigen::Vector3d fp = fn * n;
            for (int i = 0; i < P.count[static_cast<size_t>(p)]; ++i) f.col(P.nodes(i, p)) += P.weights(i, p) * fp;
            st.reaction[static_cast<size_t>(m.partTool[o])] -= fp;
            ++st.contacts;
            st.maxDepth = std::max(st.maxDepth, double(-d));
        }
    }
}

}  // namespace cutsim
