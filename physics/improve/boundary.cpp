#include "improve/boundary.hpp"

#include "embed/clip.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <utility>

namespace cutsim {

namespace {
Eigen::Vector3d faceNormal(const std::array<Eigen::Vector3d, 3>& t) { return (t[1] - t[0]).cross(t[2] - t[0]); }
}  // namespace

void ReferenceBoundary::build(const TetMesh& mesh, double featureAngleDeg, bool moveBoundary) {
    const int n = mesh.nodes();
    movable.assign(static_cast<size_t>(n), 1);
    onBoundary.assign(static_cast<size_t>(n), 0);
    ring.assign(static_cast<size_t>(n), {});
    faces.clear();
    tris.clear();
    const Eigen::Matrix3Xi F = boundaryFaces(mesh);
    for (int f = 0; f < F.cols(); ++f) {
        faces.push_back({F(0, f), F(1, f), F(2, f)});
        tris.push_back({mesh.X.col(F(0, f)), mesh.X.col(F(1, f)), mesh.X.col(F(2, f))});
        for (int k = 0; k < 3; ++k) {
            onBoundary[static_cast<size_t>(F(k, f))] = 1;
            ring[static_cast<size_t>(F(k, f))].push_back(f);
        }
    }
    // Feature edges: boundary edges whose two faces turn by more than the feature angle.
    const double cosFeature = std::cos(featureAngleDeg * std::numbers::pi / 180);
    std::map<std::pair<int, int>, std::vector<int>> edgeFaces;
    for (int f = 0; f < static_cast<int>(faces.size()); ++f)
        for (int k = 0; k < 3; ++k) {
            const int u = faces[static_cast<size_t>(f)][static_cast<size_t>(k)],
                      v = faces[static_cast<size_t>(f)][static_cast<size_t>((k + 1) % 3)];
            edgeFaces[{std::min(u, v), std::max(u, v)}].push_back(f);
        }
    crease.assign(static_cast<size_t>(n), {});
    std::vector<char> nonManifold(static_cast<size_t>(n), 0);
    for (const auto& [edge, fs] : edgeFaces) {
        if (fs.size() != 2) {
            nonManifold[static_cast<size_t>(edge.first)] = nonManifold[static_cast<size_t>(edge.second)] = 1;
            continue;
        }
        if (faceNormal(tris[static_cast<size_t>(fs[0])])
                .normalized()
                .dot(faceNormal(tris[static_cast<size_t>(fs[1])]).normalized()) < cosFeature) {
            crease[static_cast<size_t>(edge.first)].push_back(edge.second);
            crease[static_cast<size_t>(edge.second)].push_back(edge.first);
        }
    }
    for (int i = 0; i < n; ++i) {
        const auto si = static_cast<size_t>(i);
        if (!onBoundary[si]) continue;
        if (!moveBoundary || nonManifold[si]) {
            movable[si] = 0;
            continue;
        }
        // A disk: every edge from i is on exactly two of its faces.
        std::map<int, int> edgeUse;
        for (int f : ring[si])
            for (int v : faces[static_cast<size_t>(f)])
                if (v != i) ++edgeUse[v];
        bool disk = true;
        for (const auto& [v, c] : edgeUse) disk = disk && c == 2;
        // Free on a smooth patch, along the crease between two feature edges, fixed at a corner.
        const size_t creases = crease[si].size();
        movable[si] = disk && (creases == 0 || creases == 2);
    }
}

double ReferenceBoundary::distance(const Eigen::Vector3d& p, const std::vector<int>& of) const {
    double best = std::numeric_limits<double>::infinity();
    for (int f : of) {
        const auto& t = tris[static_cast<size_t>(f)];
        best = std::min(best, (closestPointOnTriangle(p, t[0], t[1], t[2]) - p).squaredNorm());
    }
    return std::sqrt(best);
}

bool ReferenceBoundary::within(const Eigen::Vector3d& p, const std::vector<int>& of, double tol) const {
    for (int f : of) {
        const auto& t = tris[static_cast<size_t>(f)];
        if (std::sqrt((closestPointOnTriangle(p, t[0], t[1], t[2]) - p).squaredNorm()) <= tol) return true;
    }
    return false;
}

double ReferenceBoundary::distanceMoved(const Eigen::Vector3d& p, const std::vector<int>& of,
                                        const Eigen::Matrix3Xd& X) const {
    double best = std::numeric_limits<double>::infinity();
    for (int f : of) {
        const auto& u = faces[static_cast<size_t>(f)];
        best = std::min(best, (closestPointOnTriangle(p, X.col(u[0]), X.col(u[1]), X.col(u[2])) - p).squaredNorm());
    }
    return std::sqrt(best);
}

bool ReferenceBoundary::withinMoved(const Eigen::Vector3d& p, const std::vector<int>& of, const Eigen::Matrix3Xd& X,
                                    double tol) const {
    for (int f : of) {
        const auto& u = faces[static_cast<size_t>(f)];
        if ((closestPointOnTriangle(p, X.col(u[0]), X.col(u[1]), X.col(u[2])) - p).squaredNorm() <= tol * tol)
            return true;
    }
    return false;
}

Eigen::Vector3d ReferenceBoundary::projectToCrease(int i, const Eigen::Vector3d& p, const Eigen::Matrix3Xd& X0) const {
    Eigen::Vector3d best = p;
    double bd = std::numeric_limits<double>::infinity();
    const Eigen::Vector3d o = X0.col(i);
    for (int k : crease[static_cast<size_t>(i)]) {
        const Eigen::Vector3d q = X0.col(k), d = q - o;
        const Eigen::Vector3d c = o + d * std::clamp((p - o).dot(d) / d.squaredNorm(), 0.0, 1.0);
        if ((c - p).squaredNorm() < bd) bd = (c - p).squaredNorm(), best = c;
    }
    return best;
}

Eigen::Vector3d ReferenceBoundary::projectToRing(int i, const Eigen::Vector3d& p) const {
    Eigen::Vector3d best = p;
    double bd = std::numeric_limits<double>::infinity();
    for (int f : ring[static_cast<size_t>(i)]) {
        const auto& t = tris[static_cast<size_t>(f)];
        const Eigen::Vector3d c = closestPointOnTriangle(p, t[0], t[1], t[2]);
        const double d = (c - p).squaredNorm();
        if (d < bd) bd = d, best = c;
    }
    return best;
}

double ReferenceBoundary::movedDistance(const Eigen::Matrix3Xd& X, const Eigen::Matrix3Xd& X0, bool bothWays) const {
    double worst = 0;
    std::vector<int> patch;
    for (const auto& t : faces) {
        if (X.col(t[0]) == X0.col(t[0]) && X.col(t[1]) == X0.col(t[1]) && X.col(t[2]) == X0.col(t[2])) continue;
        patch.clear();
        for (int v : t)
            for (int g : ring[v]) patch.push_back(g);
        for (const auto& s : samples(X.col(t[0]), X.col(t[1]), X.col(t[2])))
            worst = std::max(worst, distance(s, patch));
        if (!bothWays) continue;
        const auto& o = tris[static_cast<size_t>(&t - faces.data())];
        for (const auto& s : samples(o[0], o[1], o[2])) worst = std::max(worst, distanceMoved(s, patch, X));
    }
    return worst;
}

}  // namespace cutsim
