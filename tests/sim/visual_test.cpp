// object.visual through the Simulation: the liver's smooth surface on its tet mesh, refused when
// scaled wrongly, split by a cut with cut faces.
#include "sim/simulation.hpp"

#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <functional>
#include <string>

namespace cutsim {
namespace {

using nlohmann::json;

// liver_cuts.json as shipped (with its object.visual); relative paths resolve against its folder.
const std::string kScene = test::source("assets/scenes/liver_cuts.json");

json liverCuts() {
    std::ifstream in(kScene);
    return json::parse(in);
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const std::exception& e) {
        return e.what();
    }
    return "";
}

Simulation liver(const json& j, bool render = true) {
    SimulationOptions o;
    o.threads = 1;
    o.renderSurface = render;
    return Simulation(parseScene(j, kScene), o);
}

TEST(Visual, LiverSurfaceIsDrawnAndReported) {
    const Simulation sim = liver(liverCuts());
    ASSERT_NE(sim.surface(), nullptr);
    EXPECT_EQ(sim.surface()->faces(), 4384);
    EXPECT_EQ(sim.surface()->vertices(), 2194);
    const json r = sim.report()["visual"];
    EXPECT_EQ(r["vertices"], 2194);
    EXPECT_GT(r["outside"].get<int>(), 0);                     // the fine surface bulges past the coarse one
    EXPECT_LT(r["max_outside_fraction"].get<double>(), 0.02);  // ... by little: same frame and scale
}

TEST(Visual, WrongScaleIsRefusedNamingTheKey) {
    json j = liverCuts();
    j["object"]["visual"] = {{"path", "../meshes/sofa_liver-smooth.obj"}, {"scale", 0.0254 * 1.5}};
    const std::string e = errorOf([&] { liver(j); });
    EXPECT_NE(e.find("liver_cuts.json: object.visual: vertex"), std::string::npos) << e;
    EXPECT_NE(e.find("outside the tet mesh"), std::string::npos) << e;
}

TEST(Visual, BadKeysAreRefusedNamingThem) {
    json j = liverCuts();
    j["object"]["visual"] = "no_such.obj";
    EXPECT_NE(errorOf([&] { parseScene(j, kScene); }).find("object.visual: file not found"), std::string::npos);
    j["object"]["visual"] = {{"path", "../meshes/sofa_liver-smooth.obj"}, {"scale", -1}};
    EXPECT_NE(errorOf([&] { parseScene(j, kScene); }).find("object.visual.scale"), std::string::npos);
    j["object"]["visual"] = {{"path", "../meshes/sofa_liver-smooth.obj"}, {"colour", 1}};
    EXPECT_NE(errorOf([&] { parseScene(j, kScene); }).find("object.visual.colour"), std::string::npos);
}

// An MI object (the coarse liver surface in a lattice) drawn with the smooth one: frames show the
// visual surface, split by cuts, while contact and the physics keep the MI surface.
TEST(Visual, DrawsAnMiObjectWhoseOwnSurfaceIsTouched) {
    json j = liverCuts();
    j["object"].erase("mesh");
    j["object"]["surface"] = {{"path", "../meshes/sofa_liver.obj"}, {"cells", 6}};
    json plain = j;
    plain["object"].erase("visual");
    Simulation a = liver(j), b = liver(plain);
    EXPECT_EQ(a.surface()->faces(), 4384);
    EXPECT_NE(b.surface()->faces(), 4384);
    ASSERT_TRUE(a.cutNextScripted());
    ASSERT_TRUE(b.cutNextScripted());
    for (int i = 0; i < 20; ++i) {
        a.step();
        b.step();
    }
    EXPECT_TRUE(a.state().x == b.state().x);  // the drawn surface changes nothing else
    int cutFaces = 0;
    for (int t = 0; t < a.surface()->faces(); ++t) cutFaces += a.surface()->cutFace(t);
    EXPECT_GT(cutFaces, 20);
    EXPECT_GT(a.surface()->faces() - cutFaces, 4384);
}

// A plane cut through the liver splits the visual surface and adds cut faces; every vertex still
// rides an element of the cut model.
TEST(Visual, PlaneCutAddsCutFacesToTheVisualSurface) {
    Simulation sim = liver(liverCuts());
    ASSERT_TRUE(sim.cutNextScripted());
    const EmbeddedSurface& s = *sim.surface();
    int cutFaces = 0;
    for (int t = 0; t < s.faces(); ++t) cutFaces += s.cutFace(t);
    EXPECT_GT(cutFaces, 20);
    EXPECT_GT(s.faces() - cutFaces, 4384);  // the surface's triangles, those the cut crosses split
    for (int e : s.element) ASSERT_TRUE(e >= 0 && e < sim.model().elements());
}

}  // namespace
}  // namespace cutsim
