// The smoothing pass's cut of its nodes into parts that threads may smooth at once (improve.cpp).
#pragma once

#include <Eigen/Core>

#include <array>
#include <vector>

namespace cutsim {

// Cuts `nodes` into parts.size() slabs along the longest axis of their box, of about equal work
// (a node's element count), each kept in the nodes' order. A node whose re-solved elements (the
// alive elements touching its one ring; nt: a node's alive elements) are another part's goes to
// `later`: then no two parts' nodes read or write the same rows.
void partitionNodes(const std::vector<int>& nodes, const Eigen::Matrix3Xd& X, const std::vector<std::array<int, 4>>& T,
                    const std::vector<std::vector<int>>& nt, std::vector<std::vector<int>>& parts,
                    std::vector<int>& later);

}  // namespace cutsim
