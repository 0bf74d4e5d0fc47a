// object.reorder: a mesh file runs in spatial order, and what names nodes keeps the file's numbering.
#include "sim/simulation.hpp"

#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <numeric>
#include <random>

namespace cutsim {
namespace {

using nlohmann::json;

// A 10 cm bar of 4 x 2 x 2 cubes (96 tets) with its nodes and elements shuffled, as a mesher's
// arbitrary order, written to a file.
std::string shuffledBar() {
    const TetMesh box = boxMesh(0.1, 0.02, 0.02, 4, 2, 2);
    std::mt19937 rng(7);
    std::vector<int> perm(static_cast<size_t>(box.nodes())), order(static_cast<size_t>(box.elements()));
    std::iota(perm.begin(), perm.end(), 0);
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::shuffle(order.begin(), order.end(), rng);
    TetMesh m;
    m.X.resize(3, box.nodes());
    m.tets.resize(4, box.elements());
    for (int i = 0; i < box.nodes(); ++i) m.X.col(perm[static_cast<size_t>(i)]) = box.X.col(i);
    for (int e = 0; e < box.elements(); ++e)
        for (int k = 0; k < 4; ++k)
            m.tets(k, e) = perm[static_cast<size_t>(box.tets(k, order[static_cast<size_t>(e)]))];
    const std::string path = test::workDir() + "/bar.msh";
    writeMsh22(path, m);
    return path;
}

// The scene clamps the file's nodes at x = 0 by their indices and pulls the tip by a plane region.
json barScene(const std::string& mesh) {
    const TetMesh m = readTetMesh(mesh);
    std::vector<int> clamp;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) < 1e-9) clamp.push_back(i);
    return {{"object", {{"mesh", mesh}}},
            {"fixed", {{{"nodes", clamp}}}},
            {"loads",
             {{"forces",
               {{{"plane", {{"point", {0.1, 0, 0}}, {"normal", {1, 0, 0}}, {"distance", 1e-6}}},
                 {"force", {0, 0, -0.5}}}}}}},
            {"duration", 0.01},
            {"capture", {{"enabled", false}}}};
}

TEST(Reorder, AMeshFileRunsInSpatialOrderUnderTheFilesNumbering) {
    const std::string mesh = shuffledBar();
    const json j = barScene(mesh);
    json kept = j;
    kept["object"]["reorder"] = false;
    Simulation a(parseScene(j, "bar.json"), {1, false}), b(parseScene(kept, "bar.json"), {1, false});
    ASSERT_TRUE(a.reordered());
    ASSERT_FALSE(b.reordered());
    ASSERT_EQ(a.model().nodes(), b.model().nodes());
    ASSERT_EQ(a.model().elements(), b.model().elements());
    // node n of the run is node inputNode(n) of the file; the clamp by index holds the same 9 nodes
    int fixed = 0;
    for (int n = 0; n < a.model().nodes(); ++n) {
        const int f = a.inputNode(n);
        EXPECT_EQ(a.model().X.col(n), b.model().X.col(f)) << n;
        EXPECT_EQ(a.model().fixed[static_cast<size_t>(n)], b.model().fixed[static_cast<size_t>(f)]) << n;
        fixed += a.model().fixed[static_cast<size_t>(n)];
        EXPECT_EQ(b.inputNode(f), f);
    }
    EXPECT_EQ(fixed, 9);
    for (int e = 0; e < a.model().elements(); ++e)
        for (int k = 0; k < 4; ++k)
            EXPECT_EQ(a.inputNode(a.model().tets(k, e)), b.model().tets(k, a.inputElement(e))) << e;
    // the same motion: the sums run in another order, so equal to rounding
    a.advance(1);
    b.advance(1);
    ASSERT_EQ(a.state().steps, b.state().steps);
    double worst = 0, tip = 0;
    for (int n = 0; n < a.model().nodes(); ++n) {
        worst = std::max(worst, (a.state().x.col(n) - b.state().x.col(a.inputNode(n))).norm());
        tip = std::max(tip, (a.state().x.col(n) - a.model().X.col(n)).norm());
    }
    EXPECT_GT(tip, 1e-5);
    EXPECT_LT(worst, 1e-9 * (1 + tip));
    EXPECT_EQ(a.report()["mesh"]["reordered"], true);
}

TEST(Reorder, OnlyAMeshFileIsReordered) {
    json j = {{"object", {{"box", {{"size", {0.1, 0.02, 0.02}}, {"cells", {4, 1, 1}}}}, {"reorder", true}}},
              {"capture", {{"enabled", false}}}};
    try {
        parseScene(j, "box.json");
        FAIL() << "object.reorder on a box was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("box.json: object.reorder"), std::string::npos) << e.what();
    }
    j["object"].erase("reorder");
    Simulation s(parseScene(j, "box.json"), {1, false});
    EXPECT_FALSE(s.reordered());
    EXPECT_EQ(s.inputNode(5), 5);
}

}  // namespace
}  // namespace cutsim
