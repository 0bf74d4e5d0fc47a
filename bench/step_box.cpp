#include "bench/step_box.hpp"
#include "mesh/generate.hpp"

#include <vector>

namespace cutsim {

Model stepBox(int n) {
    Model m = buildModel(boxMesh(0.01 * n, 0.01 * n, 0.01 * n, n, n, n), Material{});
    std::vector<int> fixedNodes;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) < 1e-9) fixedNodes.push_back(i);
    fixNodes(m, fixedNodes);
    m.gravity << 0, 0, -9.81;
    return m;
}

}  // namespace cutsim
