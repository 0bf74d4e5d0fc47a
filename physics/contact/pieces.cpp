// Contact between separated pieces of the object (contact.pieces): points of one piece just
// behind the faces of another.
#include "contact/world.hpp"

#include <algorithm>
#include <limits>

namespace cutsim {

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
        if (!dropped.empty() && dropped[static_cast<size_t>(p)]) continue;
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
            if (pa.empty() || pb.empty() || !Intersect(pa.around, pb.around)) continue;
            buildTrees(pa);
            buildTrees(pb);
            pairs.clear();
            CollidePairs collide;
            collide.out = &pairs;
            for (btDbvt& ta : pa.trees)
                for (btDbvt& tb : pb.trees)
                    if (ta.m_root && tb.m_root) ta.collideTT(ta.m_root, tb.m_root, collide);
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

}  // namespace cutsim
