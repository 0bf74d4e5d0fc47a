#include "cut/polyhedron.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

namespace cutsim {

double Halfspace::at(const Eigen::Vector3d& xi, int corner) const {
    if (corner >= 0) return s[corner];
    return s[0] + (s[1] - s[0]) * xi[0] + (s[2] - s[0]) * xi[1] + (s[3] - s[0]) * xi[2];
}

ConvexPiece referenceTet() {
    ConvexPiece p;
    p.xi = {Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()};
    p.corner = {0, 1, 2, 3};
    // Outward orientation of the reference tet's faces; tag = the corner opposite.
    p.faces = {{{1, 2, 3}, 0}, {{0, 3, 2}, 1}, {{0, 1, 3}, 2}, {{0, 2, 1}, 3}};
    return p;
}

ConvexPiece clip(const ConvexPiece& piece, const Halfspace& h) {
    const int nv = static_cast<int>(piece.xi.size());
    std::vector<double> s(static_cast<size_t>(nv));
    std::vector<char> in(static_cast<size_t>(nv));
    int nin = 0;
    for (int i = 0; i < nv; ++i) {
        s[i] = h.at(piece.xi[i], piece.corner[i]);
        in[i] = h.positive ? (s[i] >= 0) : (s[i] < 0);
        nin += in[i];
    }
    if (nin == nv) return piece;
    if (nin == 0) return {};

    ConvexPiece out;
    std::vector<int> keep(static_cast<size_t>(nv), -1);
    for (int i = 0; i < nv; ++i)
        if (in[i]) {
            keep[i] = static_cast<int>(out.xi.size());
            out.xi.push_back(piece.xi[i]);
            out.corner.push_back(piece.corner[i]);
        }

    // Crossing point of edge (i, j), shared by the two faces of the edge. When the non-negative end
    // lies exactly on the plane the crossing is that vertex itself (keyed by it, so every edge into
    // it yields one vertex).
    std::map<std::pair<int, int>, int> crossing;
    std::vector<int> capVerts;
    auto cross = [&](int i, int j) {
        const int neg = s[i] < 0 ? i : j, pos = s[i] < 0 ? j : i;
        const bool onPlane = s[pos] == 0;
        if (onPlane && keep[pos] >= 0) {
            if (std::find(capVerts.begin(), capVerts.end(), keep[pos]) == capVerts.end()) capVerts.push_back(keep[pos]);
            return keep[pos];
        }
        const auto key = onPlane ? std::make_pair(pos, pos) : std::make_pair(std::min(i, j), std::max(i, j));
        auto it = crossing.find(key);
        if (it != crossing.end()) return it->second;
        const int id = static_cast<int>(out.xi.size());
        if (onPlane) {
            out.xi.push_back(piece.xi[pos]);
            out.corner.push_back(piece.corner[pos]);
        } else {
            const double t = s[neg] / (s[neg] - s[pos]);
            out.xi.push_back(piece.xi[neg] + t * (piece.xi[pos] - piece.xi[neg]));
            out.corner.push_back(-1);
        }
        crossing.emplace(key, id);
        capVerts.push_back(id);
        return id;
    };

    // Sutherland-Hodgman on every face.
    for (const PolyFace& f : piece.faces) {
        PolyFace g;
        g.tag = f.tag;
        const size_t m = f.v.size();
        for (size_t k = 0; k < m; ++k) {
            const int a = f.v[k], b = f.v[(k + 1) % m];
            if (in[a]) g.v.push_back(keep[a]);
            if (in[a] != in[b]) {
                const int c = cross(a, b);
                if (g.v.empty() || g.v.back() != c) g.v.push_back(c);
            }
        }
        while (g.v.size() > 1 && g.v.front() == g.v.back()) g.v.pop_back();
        if (g.v.size() >= 3) out.faces.push_back(std::move(g));
    }

    // The cap: crossing points ordered counter-clockwise about the piece's outward normal, which
    // is -grad s on the positive side and +grad s on the negative side.
    if (capVerts.size() >= 3) {
        Eigen::Vector3d n(h.s[1] - h.s[0], h.s[2] - h.s[0], h.s[3] - h.s[0]);
        if (h.positive) n = -n;
        n.normalize();
        const Eigen::Vector3d u = n.unitOrthogonal(), w = n.cross(u);
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int id : capVerts) c += out.xi[id];
        c /= static_cast<double>(capVerts.size());
        std::vector<std::pair<double, int>> order;
        for (int id : capVerts) {
            const Eigen::Vector3d d = out.xi[id] - c;
            order.emplace_back(std::atan2(d.dot(w), d.dot(u)), id);
        }
        std::sort(order.begin(), order.end());
        PolyFace cap;
        cap.tag = 4 + h.cut;
        for (const auto& o : order) cap.v.push_back(o.second);
        out.faces.push_back(std::move(cap));
    }
    if (out.faces.size() < 4) return {};
    return out;
}

namespace {

// Calls f(a, b, c) for the fan triangles of every face, with the first vertex as apex, so the
// signed tets (apex, a, b, c) tile the piece.
template <class F>
void forEachFanTet(const ConvexPiece& p, F&& f) {
    const Eigen::Vector3d& r = p.xi[0];
    for (const PolyFace& face : p.faces)
        for (size_t k = 1; k + 1 < face.v.size(); ++k) f(r, p.xi[face.v[0]], p.xi[face.v[k]], p.xi[face.v[k + 1]]);
}

}  // namespace

double volumeFraction(const ConvexPiece& piece) {
    if (piece.empty()) return 0;
    double v = 0;
    // 6 x the volume of each tet, relative to the reference tet's 1/6.
    forEachFanTet(piece, [&](const Eigen::Vector3d& r, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c) { v += (a - r).dot((b - r).cross(c - r)); });
    return v;
}

void weightIntegrals(const ConvexPiece& piece, Eigen::Vector4d& first, Eigen::Vector4d& second) {
    first.setZero();
    second.setZero();
    if (piece.empty()) return;
    // Exact for linear fields on a tet: int l = V mean(l_i); int l^2 = V/20 (sum l_i^2 + (sum l_i)^2).
    forEachFanTet(piece, [&](const Eigen::Vector3d& r, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                             const Eigen::Vector3d& c) {
        const double vol = (a - r).dot((b - r).cross(c - r));
        Eigen::Matrix4d L;
        L << weightsOf(r), weightsOf(a), weightsOf(b), weightsOf(c);
        const Eigen::Vector4d sum = L.rowwise().sum();
        first += vol * sum / 4.0;
        second += vol / 20.0 * (L.cwiseAbs2().rowwise().sum() + sum.cwiseAbs2());
    });
}

double faceAreaFraction(const std::vector<FaceSide>& sides) {
    // Triangle in its own barycentric coordinates (m1, m2); corners keep their ids for exact ties.
    // Each side adds at most one vertex: size the buffers once (this runs for every glued face).
    const size_t cap = 3 + sides.size();
    std::vector<Eigen::Vector2d> p, q;
    std::vector<int> corner, qc;
    std::vector<double> s(cap);
    std::vector<char> in(cap);
    p.reserve(cap), q.reserve(cap), corner.reserve(cap), qc.reserve(cap);
    p = {{0, 0}, {1, 0}, {0, 1}};
    corner = {0, 1, 2};
    for (const FaceSide& side : sides) {
        const size_t m = p.size();
        if (m < 3) return 0;
        for (size_t i = 0; i < m; ++i) {
            s[i] = corner[i] >= 0 ? side.s[corner[i]]
                                  : side.s[0] + (side.s[1] - side.s[0]) * p[i][0] + (side.s[2] - side.s[0]) * p[i][1];
            in[i] = side.positive ? (s[i] >= 0) : (s[i] < 0);
        }
        q.clear();
        qc.clear();
        for (size_t k = 0; k < m; ++k) {
            const size_t a = k, b = (k + 1) % m;
            if (in[a]) {
                q.push_back(p[a]);
                qc.push_back(corner[a]);
            }
            if (in[a] != in[b]) {
                const size_t neg = s[a] < 0 ? a : b, pos = s[a] < 0 ? b : a;
                if (s[pos] == 0) {
                    q.push_back(p[pos]);
                    qc.push_back(corner[pos]);
                } else {
                    const double t = s[neg] / (s[neg] - s[pos]);
                    q.push_back(p[neg] + t * (p[pos] - p[neg]));
                    qc.push_back(-1);
                }
            }
        }
        p.swap(q);
        corner.swap(qc);
    }
    if (p.size() < 3) return 0;
    double area2 = 0;
    for (size_t k = 0; k < p.size(); ++k) {
        const Eigen::Vector2d& a = p[k];
        const Eigen::Vector2d& b = p[(k + 1) % p.size()];
        area2 += a[0] * b[1] - a[1] * b[0];
    }
    return std::abs(area2);  // the whole triangle has 2 x area 1
}

}  // namespace cutsim
