// `cutsim tetra` and object.tetra (sim/tetra.hpp): a closed surface to a mesh that runs, broken
// surfaces refused with their defect named, the cache.
#include "sim/tetra.hpp"

#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "sim/simulation.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>

namespace cutsim {
namespace {

namespace fs = std::filesystem;

std::string refusal(const std::string& file) {
    try {
        tetraFromSurface(readSurfaceMesh(test::data(file)), TetraOptions{0.05, true, {}, 1, {}});
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

// The SOFA liver at its coarsest (about 8k tets: TetGen keeps its 274 triangles): the volume and boundary of the
// surface, nothing inverted, a larger step than TetGen's, and the elements in spatial order already.
TEST(Tetra, TheLiverSurfaceGivesAMeshOfItsVolume) {
    TetraOptions o;
    o.size = 0.03;
    o.material = Material{30000, 0.3, 1000};
    const TetraResult r = tetraFromSurface(readSurfaceMesh(test::data("surface/sofa_liver.obj"), 0.0254), o);
    const TetraReport& t = r.report;
    EXPECT_EQ(t.surfaceTriangles, 274);
    EXPECT_GT(t.tets, 3000);
    EXPECT_LT(t.tets, 15000);
    EXPECT_EQ(t.tets, r.mesh.elements());
    EXPECT_EQ(t.inverted, 0);
    // 36.57 cubic inches (the data's SOURCES.md)
    EXPECT_NEAR(t.volumeSurface, 36.57 * std::pow(0.0254, 3), 0.01 * t.volumeSurface);
    EXPECT_LT(std::abs(t.volumeMesh - t.volumeSurface), 0.01 * t.volumeSurface);
    EXPECT_LE(t.boundaryDistance, 0.01 * t.diagonal);
    EXPECT_GT(t.dtAfter, t.dtBefore);
    const TetMesh again = spatialOrder(r.mesh);
    EXPECT_TRUE(again.tets == r.mesh.tets && again.X == r.mesh.X);
}

TEST(Tetra, BrokenSurfacesAreRefusedWithTheirDefect) {
    EXPECT_NE(refusal("broken/igl_camelhead.off").find("the surface is open: 56 edges"), std::string::npos)
        << refusal("broken/igl_camelhead.off");
    EXPECT_NE(refusal("broken/sofa_suzanne.stl").find("the surface is open"), std::string::npos);
    EXPECT_NE(refusal("broken/sofa_dragon.obj").find("38 duplicated triangles"), std::string::npos)
        << refusal("broken/sofa_dragon.obj");
}

// The command exits 2 naming the file and the defect, and writes nothing.
TEST(Tetra, TheCommandRefusesABrokenSurface) {
    const std::string out = test::workDir() + "/camel.msh";
    std::string err;
    EXPECT_EQ(
        test::runCutsim("tetra " + test::data("broken/igl_camelhead.off") + " --size 0.05 --out " + out, nullptr, &err),
        2);
    EXPECT_NE(err.find("igl_camelhead.off: the surface is open"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(out));
}

// object.tetra builds once, then reads the cache; a second scene with the same surface and size
// gets the same mesh.
TEST(Tetra, TheSceneFormCachesByContent) {
    const std::string cache = test::workDir() + "/cache";
    ::setenv("CUTSIM_CACHE", cache.c_str(), 1);
    const nlohmann::json j = {
        {"object", {{"tetra", {{"surface", test::data("surface/sofa_liver.obj")}, {"size", 0.03}}}, {"scale", 0.0254}}},
        {"material", {{"E", 30000}, {"nu", 0.3}, {"rho", 1000}}},
        {"fixed", {{{"plane", {{"point", {0, 0, -0.043}}, {"normal", {0, 0, 1}}, {"distance", 0.015}}}}}},
        {"duration", 0.002},
        {"capture", {{"enabled", false}}}};
    Simulation a(parseScene(j, "liver.json"), {1, false});
    Simulation b(parseScene(j, "liver.json"), {1, false});
    ::unsetenv("CUTSIM_CACHE");
    const auto ra = a.report(), rb = b.report();
    EXPECT_EQ(ra["tetra"]["cached"], false);
    EXPECT_EQ(rb["tetra"]["cached"], true);
    EXPECT_TRUE(a.model().tets == b.model().tets && a.model().X == b.model().X);
    int files = 0;
    for (const auto& f : fs::directory_iterator(cache)) {
        ++files;
        EXPECT_EQ(f.path().extension(), ".msh");
        EXPECT_EQ(f.path().string(), rb["tetra"]["cache_file"].get<std::string>());
    }
    EXPECT_EQ(files, 1);

    nlohmann::json bad = j;
    bad["object"]["tetra"].erase("size");
    try {
        parseScene(bad, "liver.json");
        ADD_FAILURE() << "object.tetra without size was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("object.tetra.size"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace cutsim
