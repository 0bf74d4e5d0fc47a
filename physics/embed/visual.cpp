#include "embed/visual.hpp"

#include "mesh/broadphase.hpp"
#include "embed/clip.hpp"

#include <algorithm>
#include <limits>

namespace cutsim {

VisualEmbedding embedVisual(const SurfaceMesh& s, const Eigen::Matrix4Xi& tets, const Eigen::Matrix3Xd& X) {
    VisualEmbedding out;
    EmbeddedSurface& es = out.surface;
    // Only the vertices the triangles use: a stray vertex far away must not count as outside.
    std::vector<int> index(static_cast<size_t>(s.V.cols()), -1);
    std::vector<int> used;
    es.triangles.resize(3, s.F.cols());
    for (int t = 0; t < s.F.cols(); ++t)
        for (int k = 0; k < 3; ++k) {
            int& v = index[static_cast<size_t>(s.F(k, t))];
            if (v < 0) {
                v = static_cast<int>(used.size());
                used.push_back(s.F(k, t));
            }
            es.triangles(k, t) = v;
        }
    es.cutId.assign(static_cast<size_t>(s.F.cols()), -1);
    const int nv = static_cast<int>(used.size());
    es.element.assign(static_cast<size_t>(nv), -1);
    es.weights.resize(4, nv);
    if (nv == 0 || tets.cols() == 0) return out;

    ElementBroadphase bp;
    bp.refit(tets, X);
    const double diag = (X.rowwise().maxCoeff() - X.rowwise().minCoeff()).norm();
    const double tol = 1e-9;  // weights this far below 0 are round-off on a shared face [-]
    auto weightsIn = [&](int e, const Eigen::Vector3d& p) {
        return barycentric(p, X.col(tets(0, e)), X.col(tets(1, e)), X.col(tets(2, e)), X.col(tets(3, e)));
    };
    auto distanceTo = [&](int e, const Eigen::Vector3d& p) {
        double d = std::numeric_limits<double>::infinity();
        for (int a = 0; a < 4; ++a)  // the face opposite corner a
            d = std::min(d, pointTriangleDistance(p, X.col(tets((a + 1) % 4, e)), X.col(tets((a + 2) % 4, e)),
                                                  X.col(tets((a + 3) % 4, e))));
        return d;
    };
    std::vector<int> cand;
    for (int v = 0; v < nv; ++v) {
        const Eigen::Vector3d p = s.V.col(used[static_cast<size_t>(v)]);
        // Inside: of the elements holding p, the one it is deepest in.
        bp.query(p, p, cand);
        int best = -1;
        Eigen::Vector4d bestW;
        for (int e : cand) {
            const Eigen::Vector4d w = weightsIn(e, p);
            if (w.minCoeff() >= -tol && (best < 0 || w.minCoeff() > bestW.minCoeff())) best = e, bestW = w;
        }
        if (best < 0) {
            // Outside: the nearest element, found in boxes of half-size r grown until the nearest
            // distance is at most r (every element that close has a box meeting the search box).
            // Equal distances (p nearest to a shared edge or corner): the least extrapolation.
            double bestD = std::numeric_limits<double>::infinity();
            for (double r = std::max(0.01 * diag, 1e-12);; r *= 2) {
                bp.query(p - Eigen::Vector3d::Constant(r), p + Eigen::Vector3d::Constant(r), cand);
                for (int e : cand) {
                    const double d = distanceTo(e, p);
                    const Eigen::Vector4d w = weightsIn(e, p);
                    const bool tie = std::abs(d - bestD) <= 1e-12 * diag;
                    if ((!tie && d < bestD) || (tie && w.minCoeff() > bestW.minCoeff())) {
                        best = e, bestW = w;
                        bestD = std::min(d, bestD);
                    }
                }
                if (best >= 0 && bestD <= r) break;
            }
            ++out.outside;
            if (bestD > out.maxOutside) out.maxOutside = bestD, out.farthest = v;
        }
        es.element[static_cast<size_t>(v)] = best;
        es.weights.col(v) = bestW;
    }
    return out;
}

}  // namespace cutsim
