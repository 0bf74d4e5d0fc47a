#include "mesh/generate.hpp"

#include <utility>

namespace cutsim {

TetMesh boxMesh(double lx, double ly, double lz, int nx, int ny, int nz) {
    TetMesh m;
    const int px = nx + 1, py = ny + 1, pz = nz + 1;
    m.X.resize(3, static_cast<Eigen::Index>(px) * py * pz);
    auto id = [&](int i, int j, int k) { return i + px * (j + py * k); };
    for (int k = 0; k < pz; ++k)
        for (int j = 0; j < py; ++j)
            for (int i = 0; i < px; ++i) m.X.col(id(i, j, k)) << lx * i / nx, ly * j / ny, lz * k / nz;
    // Kuhn (Freudenthal) split: one tet per permutation of the axes, walking corner 0 -> 7.
    static constexpr int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    m.tets.resize(4, 6 * static_cast<Eigen::Index>(nx) * ny * nz);
    int t = 0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                for (const auto& p : perms) {
                    int c[3] = {i, j, k}, v[4];
                    v[0] = id(i, j, k);
                    for (int s = 0; s < 3; ++s) {
                        ++c[p[s]];
                        v[s + 1] = id(c[0], c[1], c[2]);
                    }
                    m.tets.col(t) << v[0], v[1], v[2], v[3];
                    if (tetSignedVolume(m, t) < 0) std::swap(m.tets(2, t), m.tets(3, t));
                    ++t;
                }
    m.source = "box";
    return m;
}

} // namespace cutsim
