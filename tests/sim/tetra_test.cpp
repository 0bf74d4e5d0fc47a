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
#include <vector>

namespace cutsim {
namespace {

namespace fs = std::filesystem;

// A latitude-longitude ellipsoid of semi-axes a, b, c: its polar fans are needles (longitude steps
// of 360/n degrees, height pi/m of a meridian), the slivers that make TetGen's boundary tets flat.
SurfaceMesh uvEllipsoid(double a, double b, double c, int n, int m) {
    SurfaceMesh s;
    s.source = "ellipsoid";
    s.V.resize(3, 2 + n * (m - 1));
    s.V.col(0) = Eigen::Vector3d(0, 0, c);
    s.V.col(1) = Eigen::Vector3d(0, 0, -c);
    for (int i = 1; i < m; ++i)
        for (int j = 0; j < n; ++j) {
            const double th = M_PI * i / m, ph = 2 * M_PI * j / n;
            s.V.col(2 + (i - 1) * n + j) =
                Eigen::Vector3d(a * std::sin(th) * std::cos(ph), b * std::sin(th) * std::sin(ph), c * std::cos(th));
        }
    auto at = [n](int i, int j) { return 2 + (i - 1) * n + (j % n); };
    std::vector<Eigen::Vector3i> f;
    for (int j = 0; j < n; ++j) {
        f.emplace_back(0, at(1, j), at(1, j + 1));
        f.emplace_back(1, at(m - 1, j + 1), at(m - 1, j));
        for (int i = 1; i + 1 < m; ++i) {
            f.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
            f.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        }
    }
    s.F.resize(3, static_cast<Eigen::Index>(f.size()));
    for (size_t k = 0; k < f.size(); ++k) s.F.col(static_cast<Eigen::Index>(k)) = f[k];
    return s;
}

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
// Gmsh's remesh at edges of 3 cm, a tenth of the liver's length, cuts its rims by several percent:
// the default mesher falls back to TetGen and says why.
TEST(Tetra, TheLiverSurfaceGivesAMeshOfItsVolume) {
    TetraOptions o;
    o.size = 0.03;
    o.material = Material{30000, 0.3, 1000};
    const TetraResult r = tetraFromSurface(readSurfaceMesh(test::data("surface/sofa_liver.obj"), 0.0254), o);
    const TetraReport& t = r.report;
    EXPECT_EQ(t.mesher, "tetgen");
    if (!gmshTetraProgram().empty()) {
        EXPECT_NE(t.mesherNote.find("Gmsh's mesh left the bounds"), std::string::npos) << t.mesherNote;
    }
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

// A made mesh of tets in (low, high), nothing inverted, its volume and boundary within 1% of the
// surface's volume and diagonal (the bounds cutsim tetra promises).
void expectMeshWithinBounds(const TetraReport& t, int low, int high) {
    EXPECT_GT(t.tets, low);
    EXPECT_LT(t.tets, high);
    EXPECT_EQ(t.inverted, 0);
    EXPECT_LT(std::abs(t.volumeMesh - t.volumeSurface), 0.01 * t.volumeSurface);
    EXPECT_LE(t.boundaryDistance, 0.01 * t.diagonal);
}

// Gmsh remeshes the ellipsoid's surface at the size, so its polar needles do not reach the tets:
// the volume and boundary of the surface within 1% (the boundary measured both ways), nothing
// inverted, and a step quality TetGen's mesh of the same surface does not reach. The surface is a
// polyhedron: its own volume (the report's) is the reference, the ellipsoid's 4/3 pi abc a check
// of the polyhedron.
TEST(Tetra, GmshRemeshesAnEllipsoidWithPolarSlivers) {
    if (gmshTetraProgram().empty()) GTEST_SKIP() << "cutsim-gmsh-tetra not built (libgmsh-dev)";
    const SurfaceMesh s = uvEllipsoid(0.04, 0.03, 0.025, 48, 24);
    TetraOptions o;
    o.size = 0.004;
    o.material = Material{30000, 0.3, 1000};
    o.mesher = Mesher::Gmsh;
    const TetraResult g = tetraFromSurface(s, o);
    const TetraReport& t = g.report;
    EXPECT_EQ(t.mesher, "gmsh");
    // the polyhedron's, 0.71% under the ellipsoid's
    EXPECT_NEAR(t.volumeSurface, (1 - 0.0071) * 4 / 3.0 * M_PI * 0.04 * 0.03 * 0.025, 1e-4 * t.volumeSurface);
    // about the volume over the regular tet of edge 0.004 (1.25e-4 / 7.5e-6 = 16.6k)
    expectMeshWithinBounds(t, 5000, 20000);
    EXPECT_GT(t.dtAfter / t.dtScale, 0.3);
    // TetGen keeps the needles: several times the tets and a step quality under a third of Gmsh's
    o.mesher = Mesher::TetGen;
    const TetraReport tg = tetraFromSurface(s, o).report;
    EXPECT_EQ(tg.mesher, "tetgen");
    EXPECT_GT(tg.tets, 2 * t.tets);
    EXPECT_LT(tg.dtAfter / tg.dtScale, t.dtAfter / t.dtScale / 3);
}

// igl_bunny's ears are 2.7-4 mm thick under 5.6 mm edges. At the first crease angle Gmsh can
// split it by, a tip becomes a sliver patch meshed with sub-millimetre triangles (a step quality
// near 0.1); past it, the ears' rims are cut off, 1.2% of the diagonal from the surface, and auto
// fell back to TetGen (about 200k tets, quality 0.03). Passing over the sliver split and refining
// where the boundary leaves the bound gives a Gmsh mesh within both bounds and a step quality
// over 0.2 (the mesh varies with Gmsh's memory layout, so the bounds are the check).
TEST(Tetra, GmshRefinesWhereThinEarsLeaveTheBound) {
    if (gmshTetraProgram().empty()) GTEST_SKIP() << "cutsim-gmsh-tetra not built (libgmsh-dev)";
    TetraOptions o;
    o.size = 0.0056;
    o.material = Material{30000, 0.3, 1000};
    const TetraReport t = tetraFromSurface(readSurfaceMesh(test::data("surface/igl_bunny.off")), o).report;
    EXPECT_EQ(t.mesher, "gmsh") << t.mesherNote;
    EXPECT_GE(t.creaseAngle, 70);
    EXPECT_GE(t.gmshRefinements, 1);
    EXPECT_LE(t.meshedDistance, 0.0075 * t.diagonal);
    expectMeshWithinBounds(t, 20000, 50000);
    EXPECT_GE(t.dtAfter / t.dtScale, 0.2);
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
