#include "embed/winding.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <unordered_map>

namespace cutsim {

namespace {

int buildNode(WindingTree& t, const Eigen::Matrix3Xd& centroid, int first, int count) {
    const SurfaceMesh& s = *t.surface;
    const int id = static_cast<int>(t.nodes.size());
    t.nodes.emplace_back();
    WindingTree::Node n;
    n.lo = Eigen::Vector3d::Constant(1e300);
    n.hi = Eigen::Vector3d::Constant(-1e300);
    Eigen::Vector3d cLo = n.lo, cHi = n.hi, wsum = Eigen::Vector3d::Zero();
    n.areaNormal.setZero();
    double asum = 0;
    for (int k = first; k < first + count; ++k) {
        const int f = t.order[k];
        const Eigen::Vector3d a = s.V.col(s.F(0, f)), b = s.V.col(s.F(1, f)), c = s.V.col(s.F(2, f));
        for (const auto* p : {&a, &b, &c}) {
            n.lo = n.lo.cwiseMin(*p);
            n.hi = n.hi.cwiseMax(*p);
        }
        cLo = cLo.cwiseMin(centroid.col(f));
        cHi = cHi.cwiseMax(centroid.col(f));
        const Eigen::Vector3d an = 0.5 * (b - a).cross(c - a);
        n.areaNormal += an;
        const double area = an.norm();
        wsum += area * centroid.col(f);
        asum += area;
    }
    n.center = asum > 0 ? Eigen::Vector3d(wsum / asum) : Eigen::Vector3d(0.5 * (n.lo + n.hi));
    for (int k = first; k < first + count; ++k)
        for (int v = 0; v < 3; ++v) n.radius = std::max(n.radius, (s.V.col(s.F(v, t.order[k])) - n.center).norm());
    if (count <= 8) {
        n.first = first;
        n.count = count;
        t.nodes[id] = n;
        return id;
    }
    Eigen::Index axis = 0;
    (cHi - cLo).maxCoeff(&axis);
    const int mid = first + count / 2;
    std::nth_element(t.order.begin() + first, t.order.begin() + mid, t.order.begin() + first + count,
                     [&](int x, int y) { return centroid(axis, x) < centroid(axis, y); });
    t.nodes[id] = n;
    const int l = buildNode(t, centroid, first, mid - first);
    const int r = buildNode(t, centroid, mid, first + count - mid);
    t.nodes[id].left = l;
    t.nodes[id].right = r;
    return id;
}

}  // namespace

WindingTree buildWindingTree(const SurfaceMesh& s) {
    WindingTree t;
    t.surface = &s;
    const int nf = s.faces();
    t.order.resize(nf);
    for (int f = 0; f < nf; ++f) t.order[f] = f;
    if (nf == 0) return t;
    Eigen::Matrix3Xd centroid(3, nf);
    for (int f = 0; f < nf; ++f) centroid.col(f) = (s.V.col(s.F(0, f)) + s.V.col(s.F(1, f)) + s.V.col(s.F(2, f))) / 3.0;
    t.nodes.reserve(static_cast<size_t>(nf / 4 + 16));
    buildNode(t, centroid, 0, nf);
    return t;
}

double solidAngle(const Eigen::Vector3d& q, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  const Eigen::Vector3d& c) {
    // van Oosterom & Strackee: tan(Omega / 2) = det / (|A||B||C| + (A.B)|C| + (B.C)|A| + (C.A)|B|)
    const Eigen::Vector3d A = a - q, B = b - q, C = c - q;
    const double la = A.norm(), lb = B.norm(), lc = C.norm();
    const double det = A.dot(B.cross(C));
    const double den = la * lb * lc + A.dot(B) * lc + B.dot(C) * la + C.dot(A) * lb;
    return 2.0 * std::atan2(det, den);
}

double windingNumberExact(const SurfaceMesh& s, const Eigen::Vector3d& q) {
    double w = 0;
    for (int f = 0; f < s.faces(); ++f) w += solidAngle(q, s.V.col(s.F(0, f)), s.V.col(s.F(1, f)), s.V.col(s.F(2, f)));
    return w / (4 * std::numbers::pi);
}

double windingNumber(const WindingTree& t, const Eigen::Vector3d& q) {
    if (t.nodes.empty()) return 0;
    const SurfaceMesh& s = *t.surface;
    double w = 0;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const WindingTree::Node& n = t.nodes[stack[--top]];
        const Eigen::Vector3d d = n.center - q;
        const double r = d.norm();
        if (r > t.beta * n.radius) {
            // Dipole term: sum of a_t n_t . (p_t - q) / |p_t - q|^3 with every p_t at the centre.
            w += n.areaNormal.dot(d) / (r * r * r);
        } else if (n.count > 0) {
            for (int k = n.first; k < n.first + n.count; ++k) {
                const int f = t.order[k];
                w += solidAngle(q, s.V.col(s.F(0, f)), s.V.col(s.F(1, f)), s.V.col(s.F(2, f)));
            }
        } else {
            stack[top++] = n.left;
            stack[top++] = n.right;
        }
    }
    return w / (4 * std::numbers::pi);
}

bool firstCrossing(const WindingTree& t, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double& at) {
    if (t.nodes.empty()) return false;
    const SurfaceMesh& s = *t.surface;
    const Eigen::Vector3d d = b - a;
    const Eigen::Vector3d lo = a.cwiseMin(b), hi = a.cwiseMax(b);
    double best = 2;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const WindingTree::Node& n = t.nodes[stack[--top]];
        if ((n.lo.array() > hi.array()).any() || (n.hi.array() < lo.array()).any()) continue;
        if (n.count == 0) {
            stack[top++] = n.left;
            stack[top++] = n.right;
            continue;
        }
        for (int k = n.first; k < n.first + n.count; ++k) {
            const int f = t.order[k];
            const Eigen::Vector3d p0 = s.V.col(s.F(0, f)), e1 = s.V.col(s.F(1, f)) - p0, e2 = s.V.col(s.F(2, f)) - p0;
            const Eigen::Vector3d h = d.cross(e2);
            const double det = e1.dot(h);
            if (std::abs(det) < 1e-300) continue;  // the segment lies in the triangle's plane
            const Eigen::Vector3d r = a - p0;
            const double u = r.dot(h) / det;
            if (u < 0 || u > 1) continue;
            const Eigen::Vector3d q = r.cross(e1);
            const double v = d.dot(q) / det;
            if (v < 0 || u + v > 1) continue;
            const double s0 = e2.dot(q) / det;
            if (s0 >= 0 && s0 <= 1) best = std::min(best, s0);
        }
    }
    if (best > 1) return false;
    at = best;
    return true;
}

SurfaceCheck checkSurface(const SurfaceMesh& s) {
    SurfaceCheck c;
    // Directed edge counts keyed by (min, max) vertex; +1 for min -> max, +2^20 for max -> min.
    std::unordered_map<long long, long long> edges;
    edges.reserve(static_cast<size_t>(3 * s.faces()));
    for (int f = 0; f < s.faces(); ++f) {
        const int v[3] = {s.F(0, f), s.F(1, f), s.F(2, f)};
        if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0]) {
            ++c.degenerateFaces;
            continue;
        }
        for (int k = 0; k < 3; ++k) {
            const int a = v[k], b = v[(k + 1) % 3];
            const long long key = static_cast<long long>(std::min(a, b)) * (1LL << 31) + std::max(a, b);
            edges[key] += a < b ? 1 : (1LL << 20);
        }
    }
    for (const auto& [key, cnt] : edges) {
        const long long fwd = cnt & ((1LL << 20) - 1), bwd = cnt >> 20;
        const long long total = fwd + bwd;
        if (total == 1)
            ++c.openEdges;
        else if (total > 2)
            ++c.nonManifoldEdges;
        else if (fwd != 1)
            ++c.misorientedEdges;
    }
    return c;
}

}  // namespace cutsim
