// `cutsim mi` and the scene object `surface`: the JSON contract, volumes, refusals of bad input.
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <unistd.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string ownDir(const std::string& tag) {
    const fs::path dir = fs::temp_directory_path() / ("cutsim_mi_" + tag + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir.string();
}

TEST(CmdMi, JsonHoldsTheContractAndTheLiverVolume) {
    std::string out, err;
    const std::string liver = test::data("surface/sofa_liver.obj");
    ASSERT_EQ(test::runCutsim("mi " + liver + " --cells 8 --refine 2 --json", &out, &err), 0) << err;
    const json j = json::parse(out);
    for (const char* k : {"nodes", "dofs", "elements", "volume_embedded", "volume_surface", "dt_exact", "dt_certified",
                          "dt_background_exact", "seconds"})
        EXPECT_TRUE(j.contains(k)) << k;
    for (const char* k : {"inside", "interface", "outside"}) EXPECT_TRUE(j["elements"].contains(k)) << k;
    EXPECT_EQ(j["dofs"].get<int>(), 3 * j["nodes"].get<int>());
    const double vs = j["volume_surface"], ve = j["volume_embedded"];
    EXPECT_NEAR(vs, 36.57, 0.01);  // data/SOURCES.md
    EXPECT_NEAR(ve / vs, 1.0, 1e-6);
    EXPECT_LE(j["dt_certified"].get<double>(), j["dt_exact"].get<double>());
    EXPECT_EQ(j["volume_refined"].size(), 3u);
    EXPECT_GT(j["seconds"]["volumes"].get<double>(), 0);
}

TEST(CmdMi, RefusesAMissingAndABrokenFile) {
    std::string err;
    EXPECT_EQ(test::runCutsim("mi /nonexistent/x.obj", nullptr, &err), 2);
    EXPECT_NE(err.find("error:"), std::string::npos) << err;
    const std::string dir = ownDir("bad");
    const std::string bad = test::writeText(dir + "/bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 7\n");
    EXPECT_EQ(test::runCutsim("mi " + bad, nullptr, &err), 2);
    EXPECT_NE(err.find("bad.obj"), std::string::npos) << err;
}

TEST(CmdMi, SceneSurfaceObjectRunsAndReportsItsEmbedding) {
    const std::string dir = ownDir("scene");
    // A 1 x 0.2 x 0.2 m bar as OBJ, cantilevered under gravity.
    const std::string obj = test::writeText(dir + "/bar.obj",
        "v 0 0 0\nv 1 0 0\nv 0 0.2 0\nv 1 0.2 0\nv 0 0 0.2\nv 1 0 0.2\nv 0 0.2 0.2\nv 1 0.2 0.2\n"
        "f 1 3 4\nf 1 4 2\nf 5 6 8\nf 5 8 7\nf 1 2 6\nf 1 6 5\nf 3 8 4\nf 3 7 8\nf 1 5 7\nf 1 7 3\nf 2 4 8\nf 2 8 6\n");
    json scene = {{"object", {{"surface", {{"path", "bar.obj"}, {"h", 0.07}}}}},
                  {"material", {{"E", 1e6}}},
                  {"fixed", {{{"box", {{"min", {-1, -1, -1}}, {"max", {0.03, 1, 1}}}}}}},
                  {"duration", 0.01}};
    std::ofstream(dir + "/s.json") << scene.dump(2);
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + dir + "/s.json --out " + dir + "/out --no-render --quiet", nullptr, &err), 0) << err;
    std::ifstream in(dir + "/out/report.json");
    const json r = json::parse(in);
    EXPECT_EQ(r["status"], "ok");
    EXPECT_NEAR(r["embedding"]["volume_surface"].get<double>(), 0.04, 1e-12);
    EXPECT_NEAR(r["embedding"]["volume_embedded"].get<double>(), 0.04, 1e-8);
    EXPECT_GT(r["embedding"]["interface_elements"].get<int>(), 0);

    // cells and h together are refused, naming the key
    scene["object"]["surface"]["cells"] = 8;
    std::ofstream(dir + "/both.json") << scene.dump(2);
    EXPECT_EQ(test::runCutsim("run " + dir + "/both.json --out " + dir + "/never --no-render --quiet", nullptr, &err), 2);
    EXPECT_NE(err.find("object.surface.cells"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(dir + "/never"));
}

} // namespace
} // namespace cutsim
