#include "embed/surface_distance.hpp"

#include "embed/clip.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace cutsim {

namespace {

// The triangles of a surface binned in a uniform grid of cubes, for nearest-triangle queries by
// growing shells of cells.
class TriangleGrid {
public:
    TriangleGrid(const SurfaceMesh& s, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) : s_(s), lo_(lo) {
        // about one triangle per cell along the surface: the mean edge as the cell
        double edges = 0;
        for (int f = 0; f < s.faces(); ++f)
            for (int k = 0; k < 3; ++k) edges += (s.V.col(s.F(k, f)) - s.V.col(s.F((k + 1) % 3, f))).norm();
        const Eigen::Vector3d ext = hi - lo;
        cell_ = std::max(edges / (3.0 * std::max(1, s.faces())), ext.maxCoeff() / 256);
        for (int k = 0; k < 3; ++k) n_[k] = std::max(1, static_cast<int>(std::ceil(ext[k] / cell_)));
        start_.assign(static_cast<size_t>(n_[0]) * n_[1] * n_[2] + 1, 0);
        // two passes: count, then fill (compressed rows)
        for (int pass = 0; pass < 2; ++pass) {
            for (int f = 0; f < s.faces(); ++f) {
                Eigen::Vector3d a = s.V.col(s.F(0, f)), b = a;
                for (int k = 1; k < 3; ++k) {
                    a = a.cwiseMin(s.V.col(s.F(k, f)));
                    b = b.cwiseMax(s.V.col(s.F(k, f)));
                }
                const Eigen::Vector3i i0 = index(a), i1 = index(b);
                for (int z = i0[2]; z <= i1[2]; ++z)
                    for (int y = i0[1]; y <= i1[1]; ++y)
                        for (int x = i0[0]; x <= i1[0]; ++x) {
                            const size_t c = flat(x, y, z);
                            if (pass == 0)
                                ++start_[c + 1];
                            else
                                tris_[fill_[c]++] = f;
                        }
            }
            if (pass == 0) {
                for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
                tris_.resize(static_cast<size_t>(start_.back()));
                fill_.assign(start_.begin(), start_.end() - 1);
            }
        }
        stamp_.assign(static_cast<size_t>(s.faces()), 0);
    }

    // Distance from p (inside the grid's box) to the nearest triangle, which goes to `which`.
    double nearest(const Eigen::Vector3d& p, int& which) {
        ++query_;
        const Eigen::Vector3i c = index(p);
        double best = std::numeric_limits<double>::infinity();
        const int rings = std::max({n_[0], n_[1], n_[2]});
        for (int r = 0; r <= rings; ++r) {
            // the cells of Chebyshev ring r around c
            for (int z = c[2] - r; z <= c[2] + r; ++z) {
                if (z < 0 || z >= n_[2]) continue;
                for (int y = c[1] - r; y <= c[1] + r; ++y) {
                    if (y < 0 || y >= n_[1]) continue;
                    const bool side = std::abs(z - c[2]) == r || std::abs(y - c[1]) == r;
                    for (int x = c[0] - r; x <= c[0] + r; x += (side ? 1 : std::max(1, 2 * r))) {
                        if (x < 0 || x >= n_[0]) continue;
                        const size_t cell = flat(x, y, z);
                        for (int t = start_[cell]; t < start_[cell + 1]; ++t) {
                            const int f = tris_[static_cast<size_t>(t)];
                            if (stamp_[static_cast<size_t>(f)] == query_) continue;
                            stamp_[static_cast<size_t>(f)] = query_;
                            const double d = distance(p, f);
                            if (d < best) best = d, which = f;
                        }
                    }
                }
            }
            // a triangle met only in rings beyond r lies at least r cells away
            if (best <= r * cell_) break;
        }
        return best;
    }

    double distance(const Eigen::Vector3d& p, int f) const {
        return pointTriangleDistance(p, s_.V.col(s_.F(0, f)), s_.V.col(s_.F(1, f)), s_.V.col(s_.F(2, f)));
    }

private:
    Eigen::Vector3i index(const Eigen::Vector3d& p) const {
        Eigen::Vector3i i;
        for (int k = 0; k < 3; ++k)
            i[k] = std::clamp(static_cast<int>(std::floor((p[k] - lo_[k]) / cell_)), 0, n_[k] - 1);
        return i;
    }
    size_t flat(int x, int y, int z) const {
        return (static_cast<size_t>(z) * static_cast<size_t>(n_[1]) + static_cast<size_t>(y)) *
                   static_cast<size_t>(n_[0]) +
               static_cast<size_t>(x);
    }

    const SurfaceMesh& s_;
    Eigen::Vector3d lo_;
    double cell_ = 1;
    int n_[3] = {1, 1, 1};
    std::vector<int> start_, fill_, tris_;
    std::vector<std::uint32_t> stamp_;
    std::uint32_t query_ = 0;
};

}  // namespace

double farthestDistance(const SurfaceMesh& from, const SurfaceMesh& to, double spacing) {
    if (from.faces() == 0 || to.faces() == 0) return std::numeric_limits<double>::infinity();
    const Eigen::Vector3d lo = from.V.rowwise().minCoeff().cwiseMin(to.V.rowwise().minCoeff());
    const Eigen::Vector3d hi = from.V.rowwise().maxCoeff().cwiseMax(to.V.rowwise().maxCoeff());
    TriangleGrid grid(to, lo, hi);
    // Branch and bound over the triangles of `from`, split in four while their bound can beat the
    // largest distance met (a lower bound). Two bounds of the distance d(p) to `to` over a triangle:
    // d is 1-Lipschitz and a point lies within the longest edge L / sqrt(3) of a corner, so the
    // largest corner distance + L / sqrt(3); and the distance to one triangle t of `to` is convex,
    // so d(p) <= d(p, t) <= the largest corner distance to t, t the nearest of any corner.
    const double rs3 = 1 / std::sqrt(3.0);
    struct Tri {
        Eigen::Vector3d x[3];
        double d[3];
        int near[3];
    };
    std::vector<double> dv(static_cast<size_t>(from.vertices()), -1);
    std::vector<int> nv(static_cast<size_t>(from.vertices()), 0);
    double low = 0;
    for (int f = 0; f < from.faces(); ++f)
        for (int k = 0; k < 3; ++k) {
            const auto v = static_cast<size_t>(from.F(k, f));
            if (dv[v] < 0) low = std::max(low, dv[v] = grid.nearest(from.V.col(from.F(k, f)), nv[v]));
        }
    double up = low;
    std::vector<Tri> stack;
    for (int f = 0; f < from.faces(); ++f) {
        Tri t;
        for (int k = 0; k < 3; ++k) {
            const auto v = static_cast<size_t>(from.F(k, f));
            t.x[k] = from.V.col(from.F(k, f)), t.d[k] = dv[v], t.near[k] = nv[v];
        }
        stack.assign(1, t);
        while (!stack.empty()) {
            const Tri c = stack.back();
            stack.pop_back();
            const double edge =
                std::max({(c.x[1] - c.x[0]).norm(), (c.x[2] - c.x[1]).norm(), (c.x[0] - c.x[2]).norm()});
            double bound = std::max({c.d[0], c.d[1], c.d[2]}) + edge * rs3;
            for (int j = 0; j < 3 && bound > low; ++j)
                bound = std::min(bound, std::max({grid.distance(c.x[0], c.near[j]), grid.distance(c.x[1], c.near[j]),
                                                  grid.distance(c.x[2], c.near[j])}));
            if (bound <= low) continue;
            if (edge <= spacing) {
                up = std::max(up, bound);
                continue;
            }
            Eigen::Vector3d m[3];
            double dm[3];
            int nm[3];
            for (int k = 0; k < 3; ++k) {
                m[k] = 0.5 * (c.x[k] + c.x[(k + 1) % 3]);  // midpoint of edge k, k+1
                low = std::max(low, dm[k] = grid.nearest(m[k], nm[k]));
            }
            stack.push_back({{c.x[0], m[0], m[2]}, {c.d[0], dm[0], dm[2]}, {c.near[0], nm[0], nm[2]}});
            stack.push_back({{m[0], c.x[1], m[1]}, {dm[0], c.d[1], dm[1]}, {nm[0], c.near[1], nm[1]}});
            stack.push_back({{m[2], m[1], c.x[2]}, {dm[2], dm[1], c.d[2]}, {nm[2], nm[1], c.near[2]}});
            stack.push_back({{m[0], m[1], m[2]}, {dm[0], dm[1], dm[2]}, {nm[0], nm[1], nm[2]}});
        }
    }
    return std::max(low, up);
}

std::vector<double> pointDistances(const Eigen::Matrix3Xd& points, const SurfaceMesh& to) {
    std::vector<double> d(static_cast<size_t>(points.cols()), std::numeric_limits<double>::infinity());
    if (to.faces() == 0 || points.cols() == 0) return d;
    const Eigen::Vector3d lo = points.rowwise().minCoeff().cwiseMin(to.V.rowwise().minCoeff());
    const Eigen::Vector3d hi = points.rowwise().maxCoeff().cwiseMax(to.V.rowwise().maxCoeff());
    TriangleGrid grid(to, lo, hi);
    int which = 0;
    for (Eigen::Index i = 0; i < points.cols(); ++i) d[static_cast<size_t>(i)] = grid.nearest(points.col(i), which);
    return d;
}

double hausdorffDistance(const SurfaceMesh& a, const SurfaceMesh& b, double spacing) {
    return std::max(farthestDistance(a, b, spacing), farthestDistance(b, a, spacing));
}

}  // namespace cutsim
