#include "contact/broadphase.hpp"

#include <BulletCollision/BroadphaseCollision/btDbvt.h>

#include <algorithm>

namespace cutsim {

namespace {

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
        return;
    }
    // A cut appends elements and keeps the old indices: only the new leaves go in (rebuilding the
    // tree after every blade step cost more than the step), the others are updated below.
    m.leaves.resize(static_cast<size_t>(ne));
    for (int e = had; e < ne; ++e) insert(e);
    for (int e = 0; e < had; ++e) {
        btDbvtVolume v = elementBox(tets, x, e);
        btDbvtNode* leaf = m.leaves[static_cast<size_t>(e)];
        if (m.margin > 0) {
            m.tree.update(leaf, v, m.margin);  // no-op while the box stays inside the fattened one
        } else if (!(leaf->volume.Mins() == v.Mins() && leaf->volume.Maxs() == v.Maxs())) {
            m.tree.update(leaf, v);
        }
    }
}

void ElementBroadphase::query(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::vector<int>& out) const {
    out.clear();
    if (!impl_->tree.m_root) return;
    Collect c;
    c.out = &out;
    const btDbvtVolume box = btDbvtVolume::FromMM(btVector3(lo.x(), lo.y(), lo.z()), btVector3(hi.x(), hi.y(), hi.z()));
    impl_->tree.collideTVNoStackAlloc(impl_->tree.m_root, box, impl_->stack, c);
    std::sort(out.begin(), out.end());
}

}  // namespace cutsim
