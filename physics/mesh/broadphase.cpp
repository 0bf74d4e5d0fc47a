#include "mesh/broadphase.hpp"

#include "mesh/dbvt.hpp"

#include <algorithm>

namespace cutsim {

namespace {

// Leaves are set again once a node may have drifted this many margins from where it was then.
constexpr double kDriftMargins = 3;

btDbvtVolume elementBox(const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& x, int e) {
    Eigen::Vector3d lo = x.col(tets(0, e)), hi = lo;
    for (int a = 1; a < 4; ++a) {
        lo = lo.cwiseMin(x.col(tets(a, e)));
        hi = hi.cwiseMax(x.col(tets(a, e)));
    }
    return btDbvtVolume::FromMM(btVector3(lo.x(), lo.y(), lo.z()), btVector3(hi.x(), hi.y(), hi.z()));
}

struct Collect : btDbvt::ICollide {
    std::vector<int>* out = nullptr;
    void Process(const btDbvtNode* leaf) override { out->push_back(leaf->dataAsInt); }
};

}  // namespace

struct ElementBroadphase::Impl {
    double margin = 0;
    btDbvt tree;
    std::vector<btDbvtNode*> leaves;
    mutable btNodeStack stack;
    Eigen::Matrix3Xd xRef;  // node positions when the leaves were last set
    double carry = 0;       // how far an appended node's original had moved from there [m]
    double drift = 0;       // bound on how far any element's box has moved out of its leaf's [m]
    std::vector<btDbvtNode*> mergeStack;
};

ElementBroadphase::ElementBroadphase(double margin) : impl_(std::make_unique<Impl>()) { impl_->margin = margin; }
ElementBroadphase::~ElementBroadphase() { impl_->tree.clear(); }
int ElementBroadphase::elements() const { return static_cast<int>(impl_->leaves.size()); }

void ElementBroadphase::refit(const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& x) {
    Impl& m = *impl_;
    const int ne = static_cast<int>(tets.cols());
    const int had = static_cast<int>(m.leaves.size());
    auto insert = [&](int e) {
        btDbvtVolume v = elementBox(tets, x, e);
        v.Expand(btVector3(m.margin, m.margin, m.margin));
        m.leaves[static_cast<size_t>(e)] = m.tree.insert(v, nullptr);
        m.leaves[static_cast<size_t>(e)]->dataAsInt = e;
    };
    if (ne < had || had == 0) {  // renumbered (or first): a new, balanced tree
        m.tree.clear();
        m.leaves.resize(static_cast<size_t>(ne));
        for (int e = 0; e < ne; ++e) insert(e);
        m.tree.optimizeTopDown();
        m.xRef = x;
        m.carry = m.drift = 0;
        return;
    }
    // A cut appends elements and keeps the old indices: only the new leaves go in (rebuilding the
    // tree after every blade step cost more than the step).
    m.leaves.resize(static_cast<size_t>(ne));
    for (int e = had; e < ne; ++e) insert(e);
    // The other leaves stay as they were set while no node has left its position then by more than
    // a few margins: a query widens by that drift past the margin instead. A node a cut appended
    // copies one that may have drifted that far already: it carries that drift.
    const Eigen::Index old = std::min(m.xRef.cols(), x.cols());
    double far = old > 0 ? (x.leftCols(old) - m.xRef.leftCols(old)).cwiseAbs().maxCoeff() : 0.0;
    if (x.cols() > old) {
        m.carry = std::max(m.carry, far);
        m.xRef.conservativeResize(3, x.cols());
        m.xRef.rightCols(x.cols() - old) = x.rightCols(x.cols() - old);
    }
    m.drift = far + m.carry;
    if (m.margin > 0 && m.drift < kDriftMargins * m.margin) return;
    if (m.margin > 0) {
        // every leaf set in place and the inner boxes merged again once: the tree keeps its shape
        // (Bullet's update removes and inserts each leaf, at many times the cost)
        for (int e = 0; e < had; ++e) {
            btDbvtVolume v = elementBox(tets, x, e);
            v.Expand(btVector3(m.margin, m.margin, m.margin));
            m.leaves[static_cast<size_t>(e)]->volume = v;
        }
        mergeInnerBoxes(m.tree, m.mergeStack);
    } else {
        for (int e = 0; e < had; ++e) {
            btDbvtVolume v = elementBox(tets, x, e);
            btDbvtNode* leaf = m.leaves[static_cast<size_t>(e)];
            if (!(leaf->volume.Mins() == v.Mins() && leaf->volume.Maxs() == v.Maxs())) m.tree.update(leaf, v);
        }
    }
    m.xRef = x;
    m.carry = m.drift = 0;
}

void ElementBroadphase::query(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::vector<int>& out) const {
    out.clear();
    if (!impl_->tree.m_root) return;
    Collect c;
    c.out = &out;
    const double w = std::max(0.0, impl_->drift - impl_->margin);  // leaves set before the nodes drifted
    const btDbvtVolume box = btDbvtVolume::FromMM(btVector3(lo.x() - w, lo.y() - w, lo.z() - w),
                                                  btVector3(hi.x() + w, hi.y() + w, hi.z() + w));
    impl_->tree.collideTVNoStackAlloc(impl_->tree.m_root, box, impl_->stack, c);
    std::sort(out.begin(), out.end());
}

}  // namespace cutsim
