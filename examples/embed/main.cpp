// cutsim inside another program: load a scene file, step it, cut it with a plane, and print the
// stable step before and after the cut. Built against an installed cutsim (find_package(cutsim)).
//   cutsim_embed SCENE.json [STEPS]
#include "cut/xfem.hpp"
#include "mesh/mesh.hpp"
#include "sim/scene.hpp"
#include "sim/simulation.hpp"
#include "util/memory.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

namespace {

void printStep(const char* when, const cutsim::Simulation& sim) {
    std::printf("%s: stable step exact %.6e s, certified %.6e s, step used %.6e s\n", when, sim.limits().exact,
                sim.limits().certified, sim.dt());
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argc > 3) {
        std::fprintf(stderr, "usage: %s SCENE.json [STEPS]\n", argv[0]);
        return 2;
    }
    const int steps = argc == 3 ? std::atoi(argv[2]) : 100;
    if (steps < 1) {
        std::fprintf(stderr, "error: STEPS must be a positive integer, not '%s'\n", argv[2]);
        return 2;
    }
    cutsim::mapLargeArrays();  // the arrays a cut grows are remapped, not copied
    try {
        const cutsim::SceneDef scene = cutsim::loadScene(argv[1]);
        cutsim::Simulation sim(scene, {.threads = 1});
        std::printf("%s: %d nodes, %d elements\n", argv[1], static_cast<int>(sim.model().X.cols()),
                    static_cast<int>(sim.model().elements()));
        printStep("before the cut", sim);
        const auto run = [&] {
            for (int i = 0; i < steps && sim.status() == cutsim::RunStatus::Running; ++i) sim.step();
        };
        run();

        // A plane across the object's longest side, just off its middle (off the lattice's node planes).
        const Eigen::Vector3d lo = sim.model().X.rowwise().minCoeff(), hi = sim.model().X.rowwise().maxCoeff();
        const Eigen::Vector3d size = hi - lo;
        Eigen::Index axis = 0;
        size.maxCoeff(&axis);
        cutsim::CutSurface plane;
        plane.normal = Eigen::Vector3d::Unit(axis);
        plane.point = lo + 0.5 * size + 0.01 * size(axis) * plane.normal;
        const cutsim::CutResult r = sim.cut(plane, "example");
        std::printf("cut: %d elements crossed, %d split, %d new nodes\n", r.crossed, r.split,
                    static_cast<int>(r.newNodes.size()));
        printStep("after the cut", sim);
        run();
        std::printf("t = %.6f s after %d steps: %s\n", sim.state().time, 2 * steps,
                    cutsim::runStatusName(sim.status()));
        return sim.status() == cutsim::RunStatus::Running || sim.status() == cutsim::RunStatus::Finished ? 0 : 3;
    } catch (const cutsim::InputError& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}
