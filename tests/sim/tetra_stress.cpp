// Large meshes (the stress label): the high-resolution liver of assets/scenes/liver_hires.json as
// object.tetra builds it, and a shuffled copy of it run in spatial order against its own order.
#include "sim/tetra.hpp"

#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "sim/simulation.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace cutsim {
namespace {

TetraResult hiresLiver() {
    TetraOptions o;
    o.size = 0.0038;  // liver_hires.json's
    o.material = Material{30000, 0.3, 1000};
    return tetraFromSurface(readSurfaceMesh(test::source("assets/meshes/sofa_liver.obj"), 0.0254), o);
}

// Over 40k tets, the surface's volume and boundary, nothing inverted, a larger step than the mesher's.
TEST(TetraStress, TheHighResolutionLiver) {
    const TetraResult r = hiresLiver();
    const TetraReport& t = r.report;
    EXPECT_GE(t.tets, 40000);
    EXPECT_EQ(t.inverted, 0);
    EXPECT_LT(std::abs(t.volumeMesh - t.volumeSurface), 0.01 * t.volumeSurface);
    EXPECT_LE(t.boundaryDistance, 0.01 * t.diagonal);
    EXPECT_GT(t.dtAfter, 2 * t.dtBefore);
}

// The liver shuffled and written, run with and without object.reorder: the same motion under a
// gravity sag, the file's numbering kept by inputNode.
TEST(TetraStress, AShuffledLargeMeshRunsAsItsOwnOrder) {
    const TetMesh m = hiresLiver().mesh;
    std::mt19937 rng(48);
    std::vector<int> perm(static_cast<size_t>(m.nodes())), order(static_cast<size_t>(m.elements()));
    std::iota(perm.begin(), perm.end(), 0);
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::shuffle(order.begin(), order.end(), rng);
    TetMesh s;
    s.X.resize(3, m.nodes());
    s.tets.resize(4, m.elements());
    for (int i = 0; i < m.nodes(); ++i) s.X.col(perm[static_cast<size_t>(i)]) = m.X.col(i);
    for (int e = 0; e < m.elements(); ++e)
        for (int k = 0; k < 4; ++k) s.tets(k, e) = perm[static_cast<size_t>(m.tets(k, order[static_cast<size_t>(e)]))];
    const std::string path = test::workDir() + "/shuffled.msh";
    writeMsh22(path, s);
    nlohmann::json j = {
        {"object", {{"mesh", path}}},
        {"material", {{"E", 30000}, {"nu", 0.3}, {"rho", 1000}}},
        {"fixed", {{{"plane", {{"point", {0, 0, -0.043}}, {"normal", {0, 0, 1}}, {"distance", 0.015}}}}}},
        {"loads", {{"gravity", {0, -9.81, 0}}}},
        {"duration", 0.002},
        {"capture", {{"enabled", false}}}};
    nlohmann::json kept = j;
    kept["object"]["reorder"] = false;
    Simulation a(parseScene(j, "liver.json"), {2, false}), b(parseScene(kept, "liver.json"), {2, false});
    a.advance(1);
    b.advance(1);
    ASSERT_EQ(a.state().steps, b.state().steps);
    double worst = 0, sag = 0;
    for (int n = 0; n < a.model().nodes(); ++n) {
        worst = std::max(worst, (a.state().x.col(n) - b.state().x.col(a.inputNode(n))).norm());
        sag = std::max(sag, (a.state().x.col(n) - a.model().X.col(n)).norm());
    }
    EXPECT_GT(sag, 1e-7);
    EXPECT_LT(worst, 1e-9 * (1 + sag));
}

}  // namespace
}  // namespace cutsim
