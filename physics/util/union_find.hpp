// Disjoint sets with path halving, and the connected pieces of a tet mesh built on them.
#pragma once

#include <Eigen/Core>

#include <numeric>
#include <vector>

namespace cutsim {

struct UnionFind {
    std::vector<int> p;  // parent of each item; a root is its own parent
    UnionFind() = default;
    explicit UnionFind(size_t n) { reset(n); }
    void reset(size_t n) {
        p.resize(n);
        std::iota(p.begin(), p.end(), 0);
    }
    int find(int i) {
        while (p[static_cast<size_t>(i)] != i)
            i = p[static_cast<size_t>(i)] = p[static_cast<size_t>(p[static_cast<size_t>(i)])];
        return i;
    }
    // Joins the sets of a and b; the smaller root index becomes the root (labels independent of order).
    void join(int a, int b) {
        const int ra = find(a), rb = find(b);
        if (ra != rb) p[static_cast<size_t>(std::max(ra, rb))] = std::min(ra, rb);
    }
};

// Nodes joined through shared elements (tets: 4 x nElems node indices into nNodes nodes).
inline UnionFind elementPieces(const Eigen::Matrix4Xi& tets, int nNodes) {
    UnionFind uf(static_cast<size_t>(nNodes));
    for (Eigen::Index e = 0; e < tets.cols(); ++e)
        for (int a = 1; a < 4; ++a) uf.join(tets(0, e), tets(a, e));
    return uf;
}

}  // namespace cutsim
