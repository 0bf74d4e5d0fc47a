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

}  // namespace

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

    ContactPoints pts;
    std::vector<int> ignoredCut;      // per tool: the cut whose faces it does not touch, or -1
    btDbvt tree;                      // triangle boxes, fattened by `fat`
    std::vector<btDbvtNode*> leaves;  // (nTris)
    double fat = 1e-3;                // [m]
    Eigen::Matrix3Xd xp;              // point positions (3 x nPoints) [m]; vertices every step, others on demand
    std::vector<int> stamp;           // last query that visited each point (nPoints)
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
            smallest = std::min(smallest, parts[i].size.minCoeff() > 0 ? parts[i].size.minCoeff() : parts[i].size.x());
        }
    }
    // leaves move only when a point leaves a box this much bigger than itself
    m.fat = std::clamp(0.25 * smallest, 1e-5, 5e-3);
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
}

void ContactWorld::addForces(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double time, double dt,
                             Eigen::Matrix3Xd& f) {
    Impl& m = *impl_;
    const ContactPoints& P = m.pts;
    const int nv = P.triangles.size() ? P.triangles.maxCoeff() + 1 : 0;
    const int nt = static_cast<int>(P.triangles.cols());
    auto interpolate = [&](int p) {
        Eigen::Vector3d xs = Eigen::Vector3d::Zero();
        for (int i = 0; i < P.count[static_cast<size_t>(p)]; ++i) xs += P.weights(i, p) * x.col(P.nodes(i, p));
        m.xp.col(p) = xs;
    };
    // 1. vertex positions by interpolation; edge and face points lie in their triangle's box
    for (int p = 0; p < nv; ++p) interpolate(p);
    // 2. refit the triangle tree: a leaf moves only when its triangle left the fattened box
    auto triBox = [&](int t) {
        const Eigen::Vector3d a = m.xp.col(P.triangles(0, t)), b = m.xp.col(P.triangles(1, t)),
                              c = m.xp.col(P.triangles(2, t));
        return btDbvtVolume::FromMM(bt(Eigen::Vector3d(a.cwiseMin(b).cwiseMin(c))),
                                    bt(Eigen::Vector3d(a.cwiseMax(b).cwiseMax(c))));
    };
    if (static_cast<int>(m.leaves.size()) != nt) {
        m.clearTree();
        m.leaves.resize(static_cast<size_t>(nt));
        for (int t = 0; t < nt; ++t) {
            btDbvtVolume vol = triBox(t);
            vol.Expand(btVector3(m.fat, m.fat, m.fat));
            m.leaves[static_cast<size_t>(t)] = m.tree.insert(vol, nullptr);
            m.leaves[static_cast<size_t>(t)]->dataAsInt = t;
        }
    } else {
        for (int t = 0; t < nt; ++t) {
            btDbvtNode* leaf = m.leaves[static_cast<size_t>(t)];
            btDbvtVolume vol = triBox(t);
            if (leaf->volume.Contain(vol)) continue;  // inside its fattened box
            m.tree.update(leaf, vol, m.fat);
        }
    }
    // 3. tool parts at t and t + dt into the collision world; its broad phase updates their boxes
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
    // 4. narrow phase per part: candidates from the tree, signed distance by GJK/EPA
    ContactStep& st = m.last;
    st.reaction.assign(m.tools.size(), Eigen::Vector3d::Zero());
    st.contacts = 0;
    st.maxDepth = 0;
    Collect collect;
    collect.out = &m.candidates;
    for (size_t o = 0; o < m.objects.size(); ++o) {
        const ToolDef& tool = m.tools[static_cast<size_t>(m.partTool[o])];
        const btBroadphaseProxy* proxy = m.objects[o]->getBroadphaseHandle();
        const btDbvtVolume box = btDbvtVolume::FromMM(proxy->m_aabbMin, proxy->m_aabbMax);
        m.candidates.clear();
        if (m.tree.m_root) m.tree.collideTVNoStackAlloc(m.tree.m_root, box, m.stack, collect);
        // the candidate triangles' points, each once; edge and face points interpolated now
        // faces of a cut this tool does not touch: dropped here, their points reached through
        // other candidate faces only
        const int ignored =
            m.ignoredCut.empty() || P.triCut.empty() ? -1 : m.ignoredCut[static_cast<size_t>(m.partTool[o])];
        if (ignored >= 0)
            m.candidates.erase(std::remove_if(m.candidates.begin(), m.candidates.end(),
                                              [&](int t) { return P.triCut[static_cast<size_t>(t)] == ignored; }),
                               m.candidates.end());
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
                if (p >= nv) interpolate(p);
                m.candidates.push_back(p);
            }
        }
        m.candidates.erase(m.candidates.begin(), m.candidates.begin() + static_cast<std::ptrdiff_t>(ntri));
        const btConvexShape* shape = m.shapes[o].get();
        const btTransform toolNext = next[o] * now[o].inverse();
        // bounding sphere of the part about its origin: points outside it need no GJK
        const btVector3 bc = now[o].getOrigin();
        const double br = m.partRadius[o];
        for (int p : m.candidates) {
            const btVector3 xp = bt(Eigen::Vector3d(m.xp.col(p)));
            if (xp.distance2(bc) > br * br) continue;
            btGjkEpaSolver2::sResults res;
            const btScalar d = btGjkEpaSolver2::SignedDistance(xp, 0, shape, now[o], res);
            if (!(d < 0) || !std::isfinite(d)) continue;
            const Eigen::Vector3d n = eig(res.normal);  // the way out of the tool
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
