#include "mesh/generate.hpp"

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <unordered_map>
#include <vector>
#include <utility>

namespace cutsim {

TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz, BoxSplit split) {
    TetMesh m;
    const int px = nx + 1, py = ny + 1, pz = nz + 1;
    m.X.resize(3, static_cast<Eigen::Index>(px) * py * pz);
    auto id = [&](int i, int j, int k) { return i + px * (j + py * k); };
    for (int k = 0; k < pz; ++k)
        for (int j = 0; j < py; ++j)
            for (int i = 0; i < px; ++i) m.X.col(id(i, j, k)) << lx * i / nx, ly * j / ny, lz * k / nz;
    // Kuhn (Freudenthal) split: one tet per permutation of the axes, walking the cube from one
    // corner to the opposite one. Mirrored: the walk starts on the high side of every axis whose
    // cube index is odd, so two neighbours are reflections of each other across their shared
    // face, and that face is split the same way from both sides.
    static constexpr int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    m.tets.resize(4, 6 * static_cast<Eigen::Index>(nx) * ny * nz);
    int t = 0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                for (const auto& p : perms) {
                    const int lo[3] = {i, j, k};
                    int c[3], d[3], v[4];
                    for (int s = 0; s < 3; ++s) {
                        const bool flip = split == BoxSplit::Mirrored && (lo[s] & 1);
                        c[s] = lo[s] + (flip ? 1 : 0);
                        d[s] = flip ? -1 : 1;
                    }
                    v[0] = id(c[0], c[1], c[2]);
                    for (int s = 0; s < 3; ++s) {
                        c[p[s]] += d[p[s]];
                        v[s + 1] = id(c[0], c[1], c[2]);
                    }
                    m.tets.col(t) << v[0], v[1], v[2], v[3];
                    if (tetSignedVolume(m, t) < 0) std::swap(m.tets(2, t), m.tets(3, t));
                    ++t;
                }
    m.source = "box";
    return m;
}

TetMesh refineTets(const TetMesh& mesh) {
    TetMesh out;
    const int n0 = mesh.nodes(), ne = mesh.elements();
    std::unordered_map<long, int> mid;  // edge (lo * n0 + hi) -> midpoint node
    std::vector<Eigen::Vector3d> extra;
    auto midpoint = [&](int a, int b) {
        const long key = static_cast<long>(std::min(a, b)) * n0 + std::max(a, b);
        auto [it, added] = mid.try_emplace(key, n0 + static_cast<int>(extra.size()));
        if (added) extra.push_back(0.5 * (mesh.X.col(a) + mesh.X.col(b)));
        return it->second;
    };
    out.tets.resize(4, 8 * static_cast<Eigen::Index>(ne));
    for (int e = 0; e < ne; ++e) {
        const int x0 = mesh.tets(0, e), x1 = mesh.tets(1, e), x2 = mesh.tets(2, e), x3 = mesh.tets(3, e);
        const int x01 = midpoint(x0, x1), x02 = midpoint(x0, x2), x03 = midpoint(x0, x3);
        const int x12 = midpoint(x1, x2), x13 = midpoint(x1, x3), x23 = midpoint(x2, x3);
        const int kids[8][4] = {{x0, x01, x02, x03},  {x01, x1, x12, x13},  {x02, x12, x2, x23},  {x03, x13, x23, x3},
                                {x01, x02, x03, x13}, {x01, x02, x12, x13}, {x02, x03, x13, x23}, {x02, x12, x13, x23}};
        for (int k = 0; k < 8; ++k) out.tets.col(8 * e + k) << kids[k][0], kids[k][1], kids[k][2], kids[k][3];
    }
    out.X.resize(3, n0 + static_cast<Eigen::Index>(extra.size()));
    out.X.leftCols(n0) = mesh.X;
    for (size_t k = 0; k < extra.size(); ++k) out.X.col(n0 + static_cast<Eigen::Index>(k)) = extra[k];
    for (int t = 0; t < out.elements(); ++t)
        if (tetSignedVolume(out, t) < 0) std::swap(out.tets(2, t), out.tets(3, t));
    out.source = mesh.source + " (refined)";
    return out;
}

TetMesh spatialOrder(const TetMesh& mesh, std::vector<int>* nodeFrom, std::vector<int>* elementFrom) {
    const int ne = mesh.elements(), nn = mesh.nodes();
    if (nodeFrom) nodeFrom->resize(static_cast<size_t>(nn));
    if (elementFrom) elementFrom->resize(static_cast<size_t>(ne));
    if (ne == 0) {
        if (nodeFrom) std::iota(nodeFrom->begin(), nodeFrom->end(), 0);
        return mesh;
    }
    Eigen::Matrix3Xd c(3, ne);
    for (int e = 0; e < ne; ++e)
        c.col(e) = 0.25 * (mesh.X.col(mesh.tets(0, e)) + mesh.X.col(mesh.tets(1, e)) + mesh.X.col(mesh.tets(2, e)) +
                           mesh.X.col(mesh.tets(3, e)));
    const Eigen::Vector3d lo = c.rowwise().minCoeff(), span = (c.rowwise().maxCoeff() - lo).cwiseMax(1e-300);
    // 21 bits per axis, interleaved
    auto spread = [](std::uint64_t v) {
        v &= 0x1fffff;
        v = (v | v << 32) & 0x1f00000000ffffULL;
        v = (v | v << 16) & 0x1f0000ff0000ffULL;
        v = (v | v << 8) & 0x100f00f00f00f00fULL;
        v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
        v = (v | v << 2) & 0x1249249249249249ULL;
        return v;
    };
    std::vector<std::pair<std::uint64_t, int>> key(static_cast<size_t>(ne));
    for (int e = 0; e < ne; ++e) {
        std::uint64_t code = 0;
        for (int k = 0; k < 3; ++k) {
            const double u = std::clamp((c(k, e) - lo(k)) / span(k), 0.0, 1.0);
            code |= spread(static_cast<std::uint64_t>(u * 2097151.0)) << k;
        }
        key[static_cast<size_t>(e)] = {code, e};
    }
    std::sort(key.begin(), key.end());  // ties in element order: deterministic
    std::vector<int> newNode(static_cast<size_t>(nn), -1);
    int next = 0;
    TetMesh out;
    out.source = mesh.source;
    out.tets.resize(4, ne);
    for (int e = 0; e < ne; ++e)
        for (int k = 0; k < 4; ++k) {
            int& n = newNode[static_cast<size_t>(mesh.tets(k, key[static_cast<size_t>(e)].second))];
            if (n < 0) n = next++;
            out.tets(k, e) = n;
        }
    for (int& n : newNode)
        if (n < 0) n = next++;  // nodes of no element keep their relative order, last
    out.X.resize(3, nn);
    if (!mesh.nodeIds.empty()) out.nodeIds.resize(static_cast<size_t>(nn));
    if (elementFrom)
        for (int e = 0; e < ne; ++e) (*elementFrom)[static_cast<size_t>(e)] = key[static_cast<size_t>(e)].second;
    for (int i = 0; i < nn; ++i) {
        if (nodeFrom) (*nodeFrom)[static_cast<size_t>(newNode[static_cast<size_t>(i)])] = i;
        out.X.col(newNode[static_cast<size_t>(i)]) = mesh.X.col(i);
        if (!mesh.nodeIds.empty())
            out.nodeIds[static_cast<size_t>(newNode[static_cast<size_t>(i)])] = mesh.nodeIds[static_cast<size_t>(i)];
    }
    return out;
}

}  // namespace cutsim
