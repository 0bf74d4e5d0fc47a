// Surface vertices that ride the same nodes at the same weights are at the same place in every
// configuration, so a cut surface makes them one vertex: neighbouring elements share their edges
// and shade smoothly across.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <utility>

namespace cutsim {

using VertexKey = std::array<std::pair<int, long long>, 4>;

// The (node, weight) pairs of a vertex at weights w in element e, weights rounded to 1e-7 (the
// crossings of a cut, computed per element, agree to round-off); sorted, zero weights dropped.
inline VertexKey vertexKey(const Eigen::Matrix4Xi& tets, int e, const Eigen::Vector4d& w) {
    VertexKey k{};
    for (int a = 0; a < 4; ++a) {
        const long long q = std::llround(w[a] * 1e7);
        k[static_cast<size_t>(a)] = q == 0 ? std::pair{-1, 0LL} : std::pair{tets(a, e), q};
    }
    std::sort(k.begin(), k.end());
    return k;
}

// Hash of a VertexKey, for welding in a hash map (the vertices' numbering follows the order they
// are first met, not the map's).
struct VertexKeyHash {
    size_t operator()(const VertexKey& k) const {
        std::uint64_t h = 1469598103934665603ULL;  // FNV-1a over the pairs' words
        for (const auto& [node, q] : k) {
            h = (h ^ static_cast<std::uint64_t>(static_cast<std::uint32_t>(node))) * 1099511628211ULL;
            h = (h ^ static_cast<std::uint64_t>(q)) * 1099511628211ULL;
        }
        return static_cast<size_t>(h ^ (h >> 29));
    }
};

}  // namespace cutsim
