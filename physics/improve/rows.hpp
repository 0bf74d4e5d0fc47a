// The assembled stiffness rows and nodal volumes that the mesh improver (improve.cpp) keeps up to
// date under every move and flip, and the operator of its exact step built from them.
#pragma once

#include "fem/tet.hpp"
#include "timestep/timestep.hpp"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace cutsim {

struct KeptRows {
    using Tet = std::array<int, 4>;
    using Slots = std::array<int, 16>;  // an element's block (a, b) is blk[t[a]][slot[4 a + b]]

    std::vector<std::vector<int>> nbr;              // nodes coupled to node i; lists only grow
    std::vector<std::vector<Eigen::Matrix3d>> blk;  // K_ij for j = nbr[i][k] [N/m]
    std::vector<double> vs;                         // volume of the elements around node i [m^3]
    double lame = 0, mu = 0;

    void resize(int nodes);
    // Position of row j in node i's list, appended when new: an element's slots stay valid while
    // it lives, dies and revives.
    int slotOf(int i, int j);
    // Adds (V > 0) or removes (V < 0) an element's share, K_ab of fem/tet.hpp:
    // V [lambda g_a g_b^T + mu g_b g_a^T + mu (g_a.g_b) I].
    void scatter(const Tet& t, const Mat34& g, double V, const Slots& slot);
    // Replaces an element's share at (g0, v0) by its share at (g1, v1) in one pass over its blocks.
    void rescatter(const Tet& t, const Mat34& g0, double v0, const Mat34& g1, double v1, const Slots& slot);
    // M^-1/2 K M^-1/2 of the live mesh, masses rq vs: the nodes with elements (nt: a node's alive
    // elements, of T) in order, their rows restricted to the couplings of live elements.
    void scaled(const std::vector<std::vector<int>>& nt, const std::vector<Tet>& T, double rq,
                ScaledStiffness& op) const;
};

}  // namespace cutsim
