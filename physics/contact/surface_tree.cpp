// The surface's triangle trees (per piece, one btDbvt per cut that made its triangles) and how they
// follow the surface's motion.
#include "contact/world.hpp"
#include "mesh/dbvt.hpp"

#include <algorithm>

namespace cutsim {

// Invariant: each leaf holds its triangle grown by `leafMargin`, the triangle's vertices taken at the
// reference positions of their nodes (xRef), and a node's reference changes only together with a
// refit of every triangle following it. A triangle is then inside its leaf grown by wSum times its
// nodes' largest move since their reference (minus leafMargin), whichever leaves were refitted: so the
// tree needs refitting only where a shape may reach, and a node is reset there once it moved more
// than `trigger`, keeping every leaf there leafMargin / 2 (>= margin) around its triangle.
void ContactWorld::Impl::build(const Eigen::Matrix3Xd& x) {
    const int nt = static_cast<int>(pts.triangles.cols());
    const int nv = pts.triangles.maxCoeff() + 1;
    for (int p = 0; p < nv; ++p) interpolate(x, p);
    clearTree();
    // leaves fattened by a quarter of the mean triangle extent (a thin blade's margin would have
    // them refitted at every tremor; the triangles' own boxes sort out the excess candidates)
    double extent = 0;
    for (int t = 0; t < nt; ++t) {
        const btDbvtVolume b = triangleBox(xp, pts.triangles, t);
        extent += eig(b.Lengths()).maxCoeff();
    }
    fat = std::max(minFat, kLeafFat * extent / std::max(nt, 1));
    leafMargin = 0.5 * fat;
    // not fat: a collider-only world's minFat is a centimetre, and every point within the band is
    // tested at every step
    nearBand = kSpeculative * margin + kNearBand * kLeafFat * extent / std::max(nt, 1);
    trigger = leafMargin / (2 * std::max(wSum, 1e-300));
    leaves.assign(static_cast<size_t>(nt), nullptr);
    for (size_t k = 0; k < surfNodes.size(); ++k) xRef.col(static_cast<Eigen::Index>(k)) = x.col(surfNodes[k]);
    vertRef = xp.leftCols(nv);  // the vertices at x = xRef
    vertStamp.assign(static_cast<size_t>(nv), -1);
    ++placing;  // xp was overwritten for the vertices
    // which way each piece's triangles face: out when its enclosed (signed) volume is positive;
    // a surface that encloses nothing (open, or flat) takes no part in piece contact. And the box
    // of each piece's leaves, which stands for its trees until a shape comes near.
    std::vector<double> volume(pieces.size(), 0.0), scale(pieces.size(), 0.0);
    for (auto& pc : pieces) pc->built = false;
    for (int t = 0; t < nt; ++t) {
        const Eigen::Vector3d a = xp.col(pts.triangles(0, t)), b = xp.col(pts.triangles(1, t)),
                              c = xp.col(pts.triangles(2, t));
        const auto k = static_cast<size_t>(triPiece[static_cast<size_t>(t)]);
        volume[k] += a.dot(b.cross(c)) / 6;
        scale[k] += (b - a).cross(c - a).norm() * (a.norm() + b.norm() + c.norm()) / 18;
        btDbvtVolume vol = triangleBox(xp, pts.triangles, t);
        vol.Expand(btVector3(fat, fat, fat));
        Piece& pc = *pieces[k];
        if (pc.tris.front() == t)
            pc.box = vol;
        else
            Merge(pc.box, vol, pc.box);
    }
    for (size_t k = 0; k < pieces.size(); ++k)
        pieces[k]->facing = std::abs(volume[k]) > 1e-3 * scale[k] ? (volume[k] > 0 ? 1 : -1) : 0;
}

// The piece's trees, made when a shape or another piece first comes near it after the surface
// changed (a cut that leaves the tools away then costs no tree): its triangles at their reference
// positions grown by fat, as if refitted.
void ContactWorld::Impl::buildTrees(Piece& pc) {
    if (pc.built) return;
    pc.built = true;
    for (const int t : pc.tris) {
        const Eigen::Vector3d a = vertRef.col(pts.triangles(0, t)), b = vertRef.col(pts.triangles(1, t)),
                              c = vertRef.col(pts.triangles(2, t));
        btDbvtVolume vol = btDbvtVolume::FromMM(bt(Eigen::Vector3d(a.cwiseMin(b).cwiseMin(c))),
                                                bt(Eigen::Vector3d(a.cwiseMax(b).cwiseMax(c))));
        vol.Expand(btVector3(fat, fat, fat));
        const int cut = pts.triCut.empty() ? -1 : pts.triCut[static_cast<size_t>(t)];
        btDbvtNode* leaf = pc.treeOf(cut).insert(vol, nullptr);
        leaf->dataAsInt = t;
        leaves[static_cast<size_t>(t)] = leaf;
    }
}

Eigen::Vector3d ContactWorld::Impl::atReference(int p) const {
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for (int i = 0; i < pts.count[static_cast<size_t>(p)]; ++i)
        s += pts.weights(i, p) * xRef.col(nodeSlot[static_cast<size_t>(pts.nodes(i, p))]);
    return s;
}

void ContactWorld::Impl::refitLeaf(int t, const Eigen::Matrix3Xd& v, double dt, bool up) {
    const btVector3 grow(leafMargin, leafMargin, leafMargin);
    const Eigen::Vector3d a = vertRef.col(pts.triangles(0, t)), b = vertRef.col(pts.triangles(1, t)),
                          c = vertRef.col(pts.triangles(2, t));
    btDbvtNode* leaf = leaves[static_cast<size_t>(t)];
    btDbvtVolume vol = btDbvtVolume::FromMM(bt(Eigen::Vector3d(a.cwiseMin(b).cwiseMin(c))),
                                            bt(Eigen::Vector3d(a.cwiseMax(b).cwiseMax(c))));
    vol.Expand(grow);
    if (leaf->volume.Contain(vol)) return;
    vol.Expand(grow);  // leafMargin + leafMargin = fat
    // grown along the triangle's velocity too, so a piece in steady motion (falling, dragged)
    // leaves its boxes less often (as Bullet's broad phase predicts its proxies)
    Eigen::Vector3d vt = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) vt += pointVelocity(v, pts.triangles(k, t));
    Eigen::Vector3d ahead = vt * (kLookahead * dt / 3);
    if (const double len = ahead.norm(); len > 4 * fat) ahead *= 4 * fat / len;
    if (ahead.allFinite()) vol.SignedExpand(bt(ahead));
    // in place, the ancestors' boxes refitted up to the first that still holds it: the surface
    // moves continuously, so neighbours stay neighbours and the tree keeps its shape without
    // Bullet's remove and insert per moved leaf
    leaf->volume = vol;
    if (!up) return;
    for (btDbvtNode* n = leaf->parent; n; n = n->parent) {
        const btDbvtVolume before = n->volume;
        Merge(n->childs[0]->volume, n->childs[1]->volume, n->volume);
        if (before.Mins() == n->volume.Mins() && before.Maxs() == n->volume.Maxs()) break;
    }
}

// The surface nodes [first, end) that moved more than `trigger` take x as their reference, and the
// triangles following them are refitted, each once.
void ContactWorld::Impl::resetNodes(const int* first, const int* end, const Eigen::Matrix3Xd& x,
                                    const Eigen::Matrix3Xd& v, double dt, Piece* whole) {
    const int stampNow = ++refits;
    dirty.clear();
    for (const int* it = first; it != end; ++it) {
        const auto k = static_cast<size_t>(*it);
        if (!(moved(x, k) > trigger)) continue;
        for (int i = nodeTriStart[k]; i < nodeTriStart[k + 1]; ++i) {
            const int t = nodeTris[static_cast<size_t>(i)];
            if (triStamp[static_cast<size_t>(t)] == stampNow) continue;
            triStamp[static_cast<size_t>(t)] = stampNow;
            dirty.push_back(t);
        }
        xRef.col(static_cast<Eigen::Index>(k)) = x.col(surfNodes[k]);
    }
    // the dirty triangles' vertices at the new references, each once
    for (const int t : dirty)
        for (int c = 0; c < 3; ++c) {
            const int p = pts.triangles(c, t);
            if (vertStamp[static_cast<size_t>(p)] == stampNow) continue;
            vertStamp[static_cast<size_t>(p)] = stampNow;
            vertRef.col(p) = atReference(p);
        }
    // many leaves of a piece moved: merging all its inner boxes once is cheaper than from each leaf up
    const bool bulk = whole && 8 * dirty.size() >= whole->nodes.size();
    for (const int t : dirty) refitLeaf(t, v, dt, !bulk);
    if (bulk)
        for (btDbvt& tree : whole->trees) mergeInnerBoxes(tree, mergeStack);
}

void ContactWorld::Impl::refitMoved(Piece& piece, const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& v, double dt) {
    piece.refitted = true;
    resetNodes(piece.nodes.data(), piece.nodes.data() + piece.nodes.size(), x, v, dt, &piece);
}

}  // namespace cutsim
