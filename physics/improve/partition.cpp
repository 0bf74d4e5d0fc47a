#include "improve/partition.hpp"

#include <algorithm>
#include <limits>
#include <numeric>

namespace cutsim {

void partitionNodes(const std::vector<int>& nodes, const Eigen::Matrix3Xd& X, const std::vector<std::array<int, 4>>& T,
                    const std::vector<std::vector<int>>& nt, std::vector<std::vector<int>>& parts,
                    std::vector<int>& later) {
    const int k = static_cast<int>(parts.size()), n = static_cast<int>(nodes.size());
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (int i : nodes) {
        lo = lo.cwiseMin(X.col(i));
        hi = hi.cwiseMax(X.col(i));
    }
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    auto key = [&](int q) { return X(axis, nodes[q]); };
    std::sort(order.begin(), order.end(), [&](int a, int b) { return key(a) < key(b) || (key(a) == key(b) && a < b); });
    // Each slab claims from its middle outwards, the slabs taking turns, so that nodes contested
    // at a cut are shared out evenly.
    double total = 0;
    for (int i : nodes) total += static_cast<double>(nt[i].size());
    std::vector<std::vector<int>> slab(k);
    double sum = 0;
    for (int q : order) {
        slab[std::min(k - 1, static_cast<int>(k * sum / total))].push_back(q);
        sum += static_cast<double>(nt[nodes[q]].size());
    }
    for (auto& sl : slab) {
        const int size = static_cast<int>(sl.size()), mid = size / 2;
        std::vector<int> out;
        for (int d = 0; static_cast<int>(out.size()) < size; ++d) {
            if (mid + d < size) out.push_back(sl[mid + d]);
            if (d > 0 && mid - d >= 0) out.push_back(sl[mid - d]);
        }
        sl = std::move(out);
    }
    std::vector<int> owner(T.size(), -1), part(n, -1), ring, elems;
    std::vector<char> seen(T.size(), 0);
    size_t longest = 0;
    for (const auto& sl : slab) longest = std::max(longest, sl.size());
    for (size_t r = 0; r < longest; ++r)
        for (int p = 0; p < k; ++p) {
            if (r >= slab[p].size()) continue;
            const int q = slab[p][r], i = nodes[q];
            ring.clear();
            for (int e : nt[i])
                for (int b : T[e]) ring.push_back(b);
            elems.clear();
            for (int a : ring)
                for (int f : nt[a])
                    if (!seen[f]) {
                        seen[f] = 1;
                        elems.push_back(f);
                    }
            bool free = true;
            for (int e : elems) {
                seen[e] = 0;
                free = free && (owner[e] < 0 || owner[e] == p);
            }
            if (!free) continue;
            for (int e : elems) owner[e] = p;
            part[q] = p;
        }
    for (int q = 0; q < n; ++q) (part[q] >= 0 ? parts[part[q]] : later).push_back(nodes[q]);
}

}  // namespace cutsim
