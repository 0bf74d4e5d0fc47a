// `cutsim mesh`: exit codes, the error line on stderr, the --json keys and --out conversion.
#include "mesh/io.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

using namespace cutsim;

TEST(CutsimMesh, BrokenFileExitsWithCode2AndMessage) {
    std::string out, err;
    const int code = test::runCutsim("mesh " + test::data("broken/sofa_6_tetra_bad.msh"), &out, &err);
    EXPECT_EQ(code, 2);
    EXPECT_EQ(err.rfind("error: ", 0), 0u) << err;
    EXPECT_NE(err.find("sofa_6_tetra_bad.msh:31:"), std::string::npos) << err;
    EXPECT_NE(err.find("inverted"), std::string::npos) << err;
    EXPECT_TRUE(out.empty()) << out;
}

TEST(CutsimMesh, MissingFileExitsWithCode2) {
    std::string err;
    EXPECT_EQ(test::runCutsim("mesh " + test::tempDir() + "/nothere.vtu", nullptr, &err), 2);
    EXPECT_NE(err.find("nothere.vtu"), std::string::npos) << err;
}

TEST(CutsimMesh, JsonOnGoodTetMesh) {
    std::string out, err;
    ASSERT_EQ(test::runCutsim("mesh " + test::data("tet/sofa_liver2.msh") + " --json", &out, &err), 0) << err;
    const auto j = nlohmann::json::parse(out);
    EXPECT_EQ(j["kind"], "tet");
    EXPECT_EQ(j["nodes"], 507);
    EXPECT_EQ(j["elements"], 1493);
    EXPECT_EQ(j["skipped_elements"], 931);
    EXPECT_EQ(j["unreferenced_nodes"], 0);
    EXPECT_TRUE(j["inverted"].empty());
    EXPECT_EQ(j["boundary_faces"], 860);
    EXPECT_GT(j["volume"].get<double>(), 1.0);
    ASSERT_EQ(j["bbox_min"].size(), 3u);
    ASSERT_EQ(j["bbox_max"].size(), 3u);
    EXPECT_LT(j["bbox_min"][0].get<double>(), j["bbox_max"][0].get<double>());
}

// --spatial-order writes the same mesh renumbered: counts, volume and boundary as the input's.
TEST(CutsimMesh, SpatialOrderWritesTheSameMesh) {
    const std::string out = test::tempDir() + "/liver2_ordered.msh";
    std::string text, err;
    ASSERT_EQ(test::runCutsim("mesh " + test::data("tet/sofa_liver2.msh") + " --spatial-order --out " + out + " --json",
                              &text, &err),
              0)
        << err;
    const TetMesh in = readTetMesh(test::data("tet/sofa_liver2.msh")), m = readTetMesh(out);
    EXPECT_EQ(m.nodes(), in.nodes());
    EXPECT_EQ(m.elements(), in.elements());
    EXPECT_NEAR(totalVolume(m), totalVolume(in), 1e-9 * totalVolume(in));
    EXPECT_EQ(boundaryFaces(m).cols(), boundaryFaces(in).cols());
    EXPECT_FALSE(m.tets == in.tets);  // renumbered
}

TEST(CutsimMesh, JsonOnSurfaceWithScale) {
    std::string out, err;
    ASSERT_EQ(test::runCutsim("mesh " + test::data("surface/sofa_liver.obj") + " --scale 0.01 --json", &out, &err), 0)
        << err;
    const auto j = nlohmann::json::parse(out);
    EXPECT_EQ(j["kind"], "surface");
    EXPECT_EQ(j["nodes"], 181);
    EXPECT_EQ(j["elements"], 274);
    EXPECT_EQ(j["unreferenced_nodes"], 42);
    EXPECT_EQ(j["open_edges"], 0);
    EXPECT_NEAR(j["volume"].get<double>(), 36.57e-6, 1e-8);
}

TEST(CutsimMesh, ReorientAndConvert) {
    const std::string dir = test::tempDir();
    std::string out, err;
    ASSERT_EQ(test::runCutsim("mesh " + test::data("broken/sofa_6_tetra_bad.msh") + " --reorient --json --out " + dir +
                                  "/fixed.vtu",
                              &out, &err),
              0)
        << err;
    const auto j = nlohmann::json::parse(out);
    EXPECT_EQ(j["inverted"], nlohmann::json::array({5}));
    const TetMesh m = readTetMesh(dir + "/fixed.vtu");  // no longer inverted
    EXPECT_EQ(m.elements(), 6);

    ASSERT_EQ(test::runCutsim("mesh " + test::data("tet/sofa_liver.msh") + " --out " + dir + "/liver.msh", &out, &err),
              0)
        << err;
    EXPECT_NE(out.find("nodes:"), std::string::npos) << out;
    EXPECT_NE(out.find("bounding box:"), std::string::npos) << out;
    EXPECT_EQ(readTetMesh(dir + "/liver.msh").X, readTetMesh(test::data("tet/sofa_liver.msh")).X);

    EXPECT_EQ(test::runCutsim("mesh " + test::data("tet/sofa_liver.msh") + " --out " + dir + "/liver.stl", &out, &err),
              2);
    EXPECT_NE(err.find("liver.stl"), std::string::npos) << err;
}
