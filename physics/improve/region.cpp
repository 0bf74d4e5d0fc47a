#include "improve/region.hpp"

#include <stdexcept>

namespace cutsim {

ImproveReport improveRegion(TetMesh& mesh, const std::vector<int>& freeNodes, ImproveOptions opts) {
    const int n = mesh.nodes();
    std::vector<char> isFree(static_cast<size_t>(n), 0);
    for (const int i : freeNodes)
        if (i >= 0 && i < n) isFree[static_cast<size_t>(i)] = 1;
    for (const int i : opts.fixedNodes)
        if (i >= 0 && i < n) isFree[static_cast<size_t>(i)] = 0;
    // The region: elements with a free node, and their nodes numbered locally.
    std::vector<int> region, keep, global;
    for (int e = 0; e < mesh.elements(); ++e) {
        bool in = false;
        for (int a = 0; a < 4; ++a) in |= isFree[static_cast<size_t>(mesh.tets(a, e))] != 0;
        (in ? region : keep).push_back(e);
    }
    if (region.empty()) return improveMesh(mesh, opts);  // nothing free: a report of the unchanged mesh
    TetMesh sub = subMesh(mesh, region, global);
    opts.fixedNodes.clear();
    for (size_t l = 0; l < global.size(); ++l)
        if (!isFree[static_cast<size_t>(global[l])]) opts.fixedNodes.push_back(static_cast<int>(l));
    opts.collapse = false;
    ImproveReport rep = improveMesh(sub, opts);
    if (sub.nodes() != static_cast<int>(global.size()))
        throw std::logic_error("improveRegion: the region's node count changed");
    for (size_t l = 0; l < global.size(); ++l) mesh.X.col(global[l]) = sub.X.col(static_cast<Eigen::Index>(l));
    Eigen::Matrix4Xi tets(4, static_cast<Eigen::Index>(keep.size()) + sub.elements());
    for (size_t k = 0; k < keep.size(); ++k) tets.col(static_cast<Eigen::Index>(k)) = mesh.tets.col(keep[k]);
    for (int e = 0; e < sub.elements(); ++e)
        for (int a = 0; a < 4; ++a)
            tets(a, static_cast<Eigen::Index>(keep.size()) + e) = global[static_cast<size_t>(sub.tets(a, e))];
    mesh.tets = std::move(tets);
    return rep;
}

}  // namespace cutsim
