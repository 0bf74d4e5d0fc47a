// The mesh improver's elements as a mesh (topology.hpp).
#include "improve/topology.hpp"

#include <algorithm>
#include <map>

namespace cutsim {

TetMesh liveMesh(const Eigen::Matrix3Xd& X, const std::vector<std::array<int, 4>>& T, const std::vector<char>& alive) {
    std::vector<int> map(X.cols(), -1);
    int nNodes = 0, nTets = 0;
    for (size_t e = 0; e < T.size(); ++e)
        if (alive[e]) {
            ++nTets;
            for (int a : T[e])
                if (map[a] < 0) map[a] = nNodes++;
        }
    // Keep the input's node order.
    nNodes = 0;
    for (auto& m : map)
        if (m >= 0) m = nNodes++;
    TetMesh out;
    out.X.resize(3, nNodes);
    for (int i = 0; i < X.cols(); ++i)
        if (map[i] >= 0) out.X.col(map[i]) = X.col(i);
    out.tets.resize(4, nTets);
    int k = 0;
    for (size_t e = 0; e < T.size(); ++e)
        if (alive[e]) {
            for (int a = 0; a < 4; ++a) out.tets(a, k) = map[T[e][a]];
            ++k;
        }
    return out;
}

bool manifoldAfter(int q, const std::vector<int>& olds, const std::vector<std::array<int, 4>>& news,
                   const std::vector<std::vector<int>>& nt, const std::vector<std::array<int, 4>>& T) {
    std::map<std::array<int, 3>, int> faceUse;
    std::vector<std::array<int, 4>> sets;
    auto add = [&](std::array<int, 4> t) {
        std::sort(t.begin(), t.end());
        sets.push_back(t);
        for (int o = 0; o < 4; ++o) {
            std::array<int, 3> f;
            int k = 0;
            for (int a = 0; a < 4; ++a)
                if (a != o) f[k++] = t[a];
            ++faceUse[f];
        }
    };
    for (int f : nt[q])
        if (std::find(olds.begin(), olds.end(), f) == olds.end()) add(T[f]);
    for (const auto& t : news) add(t);
    for (const auto& [f, c] : faceUse)
        if (c > 2) return false;
    std::sort(sets.begin(), sets.end());
    return std::adjacent_find(sets.begin(), sets.end()) == sets.end();
}

}  // namespace cutsim
