// `cutsim bench mi-bar` (Table 6.1): JSON contract, the uncut bar's step from an independent dense
// solve, MI's step near the uncut one in every row, and the conforming baselines below it after
// the 25% cut.
#include "cut/remesh.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <map>
#include <string>

namespace cutsim {
namespace {

using nlohmann::json;

TEST(BenchMiBar, TableContractAndStepOrdering) {
    // 1 x 1 x 10 cubes: fast; the 75% and 25% cuts fall inside cells, the 50% cut on a lattice plane.
    const int cells = 1;
    if (!haveTetGen()) GTEST_SKIP() << "built without TetGen (the remesh rows)";
    std::string out, err;
    ASSERT_EQ(test::runCutsim("bench mi-bar --cells " + std::to_string(cells) + " --json", &out, &err), 0) << err;
    const json j = json::parse(out);
    ASSERT_TRUE(j.is_array());
    ASSERT_EQ(j.size(), 12u);  // 4 kept shares x 3 methods

    // The uncut bar: same mesh for every method, step checked against a dense eigen-solve.
    const Material mat;  // the command's default material
    const Model bar = buildModel(test::boxMesh(0.01, 0.01, 0.1, cells, cells, 10 * cells), mat);
    const double dtUncut = 2 / std::sqrt(test::denseLambdaMax(bar));

    std::map<std::pair<double, std::string>, json> byKey;
    for (const json& r : j) {
        ASSERT_TRUE(r.is_object());
        for (const char* k : {"kept", "method", "nodes", "elements", "dt_exact"}) ASSERT_TRUE(r.contains(k)) << k << " in " << r;
        ASSERT_EQ(r.size(), 5u) << r;
        const double kept = r["kept"].get<double>();
        const std::string method = r["method"].get<std::string>();
        EXPECT_TRUE(method == "mi" || method == "subdivision" || method == "remesh") << method;
        EXPECT_TRUE(kept == 1 || kept == 0.75 || kept == 0.5 || kept == 0.25) << kept;
        EXPECT_GT(r["nodes"].get<int>(), 0);
        EXPECT_GT(r["elements"].get<int>(), 0);
        EXPECT_TRUE(byKey.emplace(std::make_pair(kept, method), r).second) << "duplicate row " << r;
    }
    ASSERT_EQ(byKey.size(), 12u);

    for (const char* m : {"mi", "subdivision", "remesh"}) {
        const json& u = byKey.at({1.0, m});
        SCOPED_TRACE(m);
        EXPECT_EQ(u["nodes"].get<int>(), (cells + 1) * (cells + 1) * (10 * cells + 1));
        EXPECT_EQ(u["elements"].get<int>(), 6 * cells * cells * 10 * cells);
        EXPECT_NEAR(u["dt_exact"].get<double>(), dtUncut, 1e-7 * dtUncut);
    }
    // MI keeps the lattice's step up to the free-end effect of a shorter bar: a cut on a lattice
    // plane leaves a plain shorter bar (below 1 x uncut by 4.7e-4 here), and virtual elements add
    // little to it (measured lowest 0.9991 here, 0.9967 at 3 cells), so MI does not reach "at least
    // the uncut step" exactly; within 1% it must, where the conforming cuts lose 45% and more.
    for (double k : {1.0, 0.75, 0.5, 0.25}) {
        SCOPED_TRACE(k);
        const json& r = byKey.at({k, "mi"});
        EXPECT_GE(r["dt_exact"].get<double>(), 0.99 * dtUncut);
        EXPECT_LE(r["nodes"].get<int>(), (cells + 1) * (cells + 1) * (10 * cells + 1));  // MI never adds nodes
    }
    // The 50% cut lies on a lattice plane: MI and subdivision keep the same shorter bar.
    const json& mi50 = byKey.at({0.5, "mi"});
    const json& sub50 = byKey.at({0.5, "subdivision"});
    EXPECT_EQ(mi50["nodes"], sub50["nodes"]);
    EXPECT_EQ(mi50["elements"], sub50["elements"]);
    EXPECT_EQ(mi50["elements"].get<int>(), 6 * cells * cells * 5 * cells);
    EXPECT_NEAR(mi50["dt_exact"].get<double>(), sub50["dt_exact"].get<double>(), 1e-9 * dtUncut);
    // Thesis Table 6.1: both conforming baselines lose step at 25% kept, far below MI.
    for (const char* m : {"subdivision", "remesh"}) {
        SCOPED_TRACE(m);
        const double dt = byKey.at({0.25, m})["dt_exact"].get<double>();
        EXPECT_LT(dt, dtUncut);
        EXPECT_LT(dt, byKey.at({0.25, "mi"})["dt_exact"].get<double>());
    }
}

TEST(BenchMiBar, SweepMovesTheCutThroughOneCell) {
    // 2 x 2 x 20 cubes (h = 5 mm): the 75% plane z = 25 mm lies in cell 5, swept at z = 25, 26.25,
    // 27.5, 28.75 mm. Each position gives one MI and one subdivision row.
    std::string out, err;
    ASSERT_EQ(test::runCutsim("bench mi-bar --cells 2 --sweep 4 --json", &out, &err), 0) << err;
    const json j = json::parse(out);
    ASSERT_EQ(j.size(), 8u);
    const Model bar = buildModel(test::boxMesh(0.01, 0.01, 0.1, 2, 2, 20), Material{});
    const double dtUncut = 2 / std::sqrt(test::denseLambdaMax(bar));
    std::map<double, std::map<std::string, double>> dt;
    for (const json& r : j) dt[r["kept"].get<double>()][r["method"].get<std::string>()] = r["dt_exact"].get<double>();
    ASSERT_EQ(dt.size(), 4u);
    const double expectKept[4] = {1 - 28.75 / 100, 1 - 27.5 / 100, 1 - 26.25 / 100, 0.75};  // ascending
    int i = 0;
    double subLow = 1;
    for (const auto& [kept, m] : dt) {
        EXPECT_NEAR(kept, expectKept[i++], 1e-12);
        ASSERT_EQ(m.size(), 2u);
        // MI stays within 1% of the lattice's step wherever the cut falls (measured 0.9908 at
        // worst at 3 cells); a cut on the lattice plane gives the same shorter bar both ways.
        EXPECT_GE(m.at("mi"), 0.99 * dtUncut) << kept;
        EXPECT_LE(m.at("mi"), 1.001 * dtUncut) << kept;
        subLow = std::min(subLow, m.at("subdivision") / dtUncut);
    }
    EXPECT_NEAR(dt.at(0.75).at("mi"), dt.at(0.75).at("subdivision"), 1e-9 * dtUncut);
    EXPECT_LT(subLow, 0.7);  // subdivision's slivers cost far more somewhere in the cell
}

TEST(BenchMiBar, BadMaterialIsAnInputError) {
    std::string err;
    EXPECT_EQ(test::runCutsim("bench mi-bar --nu 0.5 --json", nullptr, &err), 2);
    EXPECT_NE(err.find("material"), std::string::npos) << err;
}

} // namespace
} // namespace cutsim
