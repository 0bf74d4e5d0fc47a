// Mesh readers and writers on the third-party meshes (counts and volumes from SOURCES.md) and
// on small meshes written by hand, where every number can be checked on paper.
#include "mesh/io.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace cutsim;

namespace {

using test::writeText;

int unreferenced(const SurfaceMesh& s) {
    std::vector<char> used(static_cast<size_t>(s.vertices()), 0);
    for (long i = 0; i < s.F.size(); ++i) used[static_cast<size_t>(s.F.data()[i])] = 1;
    return static_cast<int>(std::count(used.begin(), used.end(), 0));
}

// The unit corner tet and the regular tet on its slanted face: volumes 1/6 + 1/3.
// Node ids 10, 20, 30, 40, 50 (not contiguous) in file order.
const Eigen::Matrix<double, 3, 5> kTwoTetX =
    (Eigen::Matrix<double, 3, 5>() << 0, 1, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 0, 1, 1).finished();

}  // namespace

// ---- Gmsh ----

TEST(MeshIo, SofaLiverLegacyV1) {
    ReadReport rep;
    const TetMesh m = readTetMesh(test::data("tet/sofa_liver.msh"), {}, &rep);
    EXPECT_EQ(m.nodes(), 181);
    EXPECT_EQ(m.elements(), 596);
    EXPECT_NEAR(totalVolume(m), 36.56, 0.01);
    EXPECT_EQ(boundaryFaces(m).cols(), 276);
    EXPECT_TRUE(rep.inverted.empty());
    EXPECT_EQ(rep.skippedElements, 0);
    EXPECT_EQ(rep.unreferencedNodes, 0);
    ASSERT_EQ(m.nodeIds.size(), 181u);
    EXPECT_EQ(m.nodeIds.front(), 1);
    EXPECT_EQ(m.nodeIds.back(), 181);
    EXPECT_DOUBLE_EQ(m.X(0, 0), -0.979259);  // first node line: "1 -0.979259 2.23512 2.61245"
}

TEST(MeshIo, SofaLiverGmsh22IdenticalToV1) {
    const TetMesh a = readTetMesh(test::data("tet/sofa_liver.msh"));
    const TetMesh b = readTetMesh(test::data("tet/sofa_liver.gmsh22.msh"));
    EXPECT_EQ(a.X, b.X);
    EXPECT_EQ(a.tets, b.tets);
    EXPECT_EQ(a.nodeIds, b.nodeIds);
}

TEST(MeshIo, SofaLiver2NonContiguousIdsAndMixedElements) {
    ReadReport rep;
    const TetMesh m = readTetMesh(test::data("tet/sofa_liver2.msh"), {}, &rep);
    EXPECT_EQ(m.nodes(), 507);
    EXPECT_EQ(m.elements(), 1493);
    EXPECT_EQ(rep.skippedElements, 860 + 71);  // triangles + lines
    EXPECT_EQ(rep.unreferencedNodes, 0);
    EXPECT_TRUE(rep.inverted.empty());
    ASSERT_EQ(m.nodeIds.size(), 507u);
    EXPECT_EQ(*std::min_element(m.nodeIds.begin(), m.nodeIds.end()), 2);
    EXPECT_EQ(*std::max_element(m.nodeIds.begin(), m.nodeIds.end()), 1393);
    EXPECT_EQ(boundaryFaces(m).cols(), 860);
    EXPECT_GE(m.tets.minCoeff(), 0);
    EXPECT_LT(m.tets.maxCoeff(), 507);
}

TEST(MeshIo, Gmsh41HandWrittenWithEntityBlocks) {
    const std::string dir = test::tempDir();
    // Nodes in two blocks (one parametric on a curve), a triangle block to skip, then the tets.
    const std::string path = writeText(dir + "/two.msh", R"($MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
0 0 0 1
1 0 0 0 1 1 1 0 0
$EndEntities
$Nodes
2 5 10 50
3 1 0 3
10
20
30
0 0 0
1 0 0
0 1 0
1 7 1 2
40
50
0 0 1 0.25
1 1 1 0.5
$EndNodes
$Elements
2 3 1 3
2 1 2 1
100 20 30 40
3 1 4 2
1 10 20 30 40
2 20 30 40 50
$EndElements
)");
    ReadReport rep;
    const TetMesh m = readTetMesh(path, {}, &rep);
    ASSERT_EQ(m.nodes(), 5);
    ASSERT_EQ(m.elements(), 2);
    EXPECT_EQ(m.X, kTwoTetX);
    EXPECT_EQ(m.nodeIds, (std::vector<long>{10, 20, 30, 40, 50}));
    EXPECT_EQ(m.tets.col(0), Eigen::Vector4i(0, 1, 2, 3));
    EXPECT_EQ(rep.skippedElements, 1);
    EXPECT_NEAR(totalVolume(m), 0.5, 1e-15);
    for (int e = 0; e < 2; ++e) EXPECT_GT(tetSignedVolume(m, e), 0);
}

// ---- TetGen ----

TEST(MeshIo, TetGenZeroBasedWithAttributesAndMarkers) {
    const std::string dir = test::tempDir();
    writeText(dir + "/two.node", "# five points\n5 3 1 1\n0 0 0 0 7.5 1\n1 1 0 0 7.5 1\n2 0 1 0 7.5 1\n"
                                 "3 0 0 1 7.5 0\n4 1 1 1 7.5 1 # last\n");
    writeText(dir + "/two.ele", "2 4 1\n0 0 1 2 3 1\n1 1 2 3 4 2\n");
    for (const char* name : {"/two.node", "/two.ele"}) {
        ReadReport rep;
        const TetMesh m = readTetMesh(dir + name, {}, &rep);
        ASSERT_EQ(m.nodes(), 5);
        ASSERT_EQ(m.elements(), 2);
        EXPECT_EQ(m.X, kTwoTetX);
        EXPECT_EQ(m.nodeIds, (std::vector<long>{0, 1, 2, 3, 4}));
        EXPECT_EQ(m.tets.col(1), Eigen::Vector4i(1, 2, 3, 4));
        EXPECT_NEAR(totalVolume(m), 0.5, 1e-15);
        EXPECT_TRUE(rep.inverted.empty());
    }
}

TEST(MeshIo, TetGenOneBasedMinimalHeader) {
    const std::string dir = test::tempDir();
    writeText(dir + "/one.node", "5 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n");
    writeText(dir + "/one.ele", "2 4 0\n1 1 2 3 4\n2 2 3 4 5\n");
    ReadReport rep;
    const TetMesh m = readTetMesh(dir + "/one.ele", {}, &rep);
    EXPECT_EQ(m.X, kTwoTetX);
    EXPECT_EQ(m.tets.col(0), Eigen::Vector4i(0, 1, 2, 3));
    EXPECT_EQ(m.tets.col(1), Eigen::Vector4i(1, 2, 3, 4));
    EXPECT_EQ(rep.unreferencedNodes, 0);
}

// ---- MEDIT and VTU ----

TEST(MeshIo, KnightMedit) {
    ReadReport rep;
    const TetMesh m = readTetMesh(test::data("tet/igltests_decimated-knight.mesh"), {}, &rep);
    EXPECT_EQ(m.nodes(), 1822);
    EXPECT_EQ(m.elements(), 5452);
    EXPECT_EQ(boundaryFaces(m).cols(), 3544);
    EXPECT_TRUE(m.nodeIds.empty());  // implicit numbering
    EXPECT_TRUE(rep.inverted.empty());
    // The surface version of the same shape encloses the same volume.
    const SurfaceMesh s = readSurfaceMesh(test::data("surface/igl_decimated-knight.off"));
    EXPECT_NEAR(totalVolume(m), 0.02449, 1e-5);
    EXPECT_NEAR(enclosedVolume(s), totalVolume(m), 1e-6);
}

TEST(MeshIo, OctopusMedit) {
    const TetMesh m = readTetMesh(test::data("tet/igl_octopus-low.mesh"));
    EXPECT_EQ(m.nodes(), 452);
    EXPECT_EQ(m.elements(), 1140);
    EXPECT_EQ(boundaryFaces(m).cols(), 898);
}

TEST(MeshIo, MeditKeywordsAnyCaseAndOtherSections) {
    const std::string dir = test::tempDir();
    const std::string path = writeText(dir + "/two.mesh", "MeshVersionFormatted 2\n# comment\ndimension\n3\n"
                                                          "VERTICES\n5\n0 0 0 1\n1 0 0 1\n0 1 0 1\n0 0 1 1\n1 1 1 1\n"
                                                          "Corners\n1\n1\nEdges\n1\n1 2 0\n"
                                                          "tetrahedra\n2\n1 2 3 4 0\n2 3 4 5 0\nEnd\n");
    ReadReport rep;
    const TetMesh m = readTetMesh(path, {}, &rep);
    EXPECT_EQ(m.X, kTwoTetX);
    EXPECT_EQ(m.tets.col(1), Eigen::Vector4i(1, 2, 3, 4));
    EXPECT_EQ(rep.skippedElements, 1);  // the edge; corners are not elements
}

TEST(MeshIo, ArmadilloVtuIdenticalToGmsh22) {
    ReadReport rep;
    const TetMesh v = readTetMesh(test::data("tet/sofa_Armadillo_Tetra_4406.vtu"), {}, &rep);
    const TetMesh g = readTetMesh(test::data("tet/sofa_Armadillo_Tetra_4406.gmsh22.msh"));
    EXPECT_EQ(v.nodes(), 1446);
    EXPECT_EQ(v.elements(), 4406);
    EXPECT_EQ(v.X, g.X);
    EXPECT_EQ(v.tets, g.tets);
    EXPECT_EQ(boundaryFaces(v).cols(), 2532);
    EXPECT_EQ(rep.skippedElements, 0);
}

TEST(MeshIo, ScaleMultipliesCoordinates) {
    ReadOptions opts;
    opts.scale = 0.01;  // cm -> m
    const TetMesh a = readTetMesh(test::data("tet/sofa_liver.msh"));
    const TetMesh b = readTetMesh(test::data("tet/sofa_liver.msh"), opts);
    ASSERT_EQ(b.nodes(), a.nodes());
    for (long i = 0; i < a.X.size(); ++i) ASSERT_DOUBLE_EQ(b.X.data()[i], a.X.data()[i] * 0.01);
    EXPECT_NEAR(totalVolume(b), totalVolume(a) * 1e-6, 1e-12);
    const SurfaceMesh s = readSurfaceMesh(test::data("surface/sofa_liver.obj"), 0.01);
    EXPECT_NEAR(enclosedVolume(s), 36.57e-6, 1e-8);
}

// ---- writers ----

TEST(MeshIo, WriteMsh22RoundTrip) {
    const std::string dir = test::tempDir();
    const TetMesh a = readTetMesh(test::data("tet/sofa_liver2.msh"));
    writeMsh22(dir + "/out.msh", a);
    EXPECT_FALSE(std::filesystem::exists(dir + "/out.msh.tmp"));
    ReadReport rep;
    const TetMesh b = readTetMesh(dir + "/out.msh", {}, &rep);
    EXPECT_EQ(a.X, b.X);  // shortest round-trip number text: exact
    EXPECT_EQ(a.tets, b.tets);
    EXPECT_EQ(b.nodeIds.front(), 1);  // renumbered 1..n
    EXPECT_EQ(b.nodeIds.back(), 507);
    EXPECT_EQ(rep.skippedElements, 0);
}

TEST(MeshIo, WriteVtuRoundTripWithFields) {
    const std::string dir = test::tempDir();
    const TetMesh a = readTetMesh(test::data("tet/igl_octopus-low.mesh"));
    std::vector<double> vol(static_cast<size_t>(a.elements())), height(static_cast<size_t>(a.nodes()));
    for (int e = 0; e < a.elements(); ++e) vol[static_cast<size_t>(e)] = tetSignedVolume(a, e);
    for (int i = 0; i < a.nodes(); ++i) height[static_cast<size_t>(i)] = a.X(2, i);
    writeVtu(dir + "/out.vtu", a, {{"volume", vol}}, {{"height", height}});
    EXPECT_FALSE(std::filesystem::exists(dir + "/out.vtu.tmp"));
    const TetMesh b = readTetMesh(dir + "/out.vtu");
    EXPECT_EQ(a.X, b.X);
    EXPECT_EQ(a.tets, b.tets);
    const std::string text = test::readText(dir + "/out.vtu");
    EXPECT_NE(text.find("<CellData>"), std::string::npos);
    EXPECT_NE(text.find("<PointData>"), std::string::npos);
    EXPECT_NE(text.find("type=\"Float64\" Name=\"volume\""), std::string::npos);
    EXPECT_NE(text.find("type=\"Float64\" Name=\"height\""), std::string::npos);
}

TEST(MeshIo, WriteRejectsBadFieldsAndUnwritableFolders) {
    const std::string dir = test::tempDir();
    const TetMesh m = test::boxMesh(1, 1, 1, 1, 1, 1);
    EXPECT_THROW(writeVtu(dir + "/a.vtu", m, {{"v", std::vector<double>(5)}}), InputError);
    EXPECT_THROW(writeVtu(dir + "/a.vtu", m, {}, {{"p", std::vector<double>(3)}}), InputError);
    EXPECT_FALSE(std::filesystem::exists(dir + "/a.vtu"));
    EXPECT_THROW(writeVtu(dir + "/no/such/folder/a.vtu", m), InputError);
    EXPECT_THROW(writeMsh22(dir + "/no/such/folder/a.msh", m), InputError);
    try {
        writeMsh22(dir + "/missing/a.msh", m);
        FAIL() << "no exception";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("missing/a.msh"), std::string::npos) << e.what();
    }
}

// ---- surfaces ----

TEST(SurfaceIo, SofaLiverObj) {
    const SurfaceMesh s = readSurfaceMesh(test::data("surface/sofa_liver.obj"));
    EXPECT_EQ(s.vertices(), 181);
    EXPECT_EQ(s.faces(), 274);
    EXPECT_EQ(unreferenced(s), 42);
    EXPECT_NEAR(enclosedVolume(s), 36.57, 0.01);
}

TEST(SurfaceIo, ObjWithNormalsGroupsAndMaterials) {
    const SurfaceMesh s = readSurfaceMesh(test::data("surface/sofa_Armadillo_verysimplified.obj"));
    EXPECT_EQ(s.vertices(), 531);
    EXPECT_EQ(s.faces(), 1058);
}

TEST(SurfaceIo, ObjIndexFormsNegativeIndicesAndPolygons) {
    const std::string dir = test::tempDir();
    // Unit cube: 8 vertices, 6 quads -> 12 triangles, volume 1, written with every index form.
    const std::string path = writeText(dir + "/cube.obj", R"(# cube
mtllib cube.mtl
o cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vn 0 0 1
usemtl skin
s off
f 1 4 3 2
f 5/1 6/1 7/1 8/1
f 1/1/1 2/1/1 6/1/1 5/1/1
f 2//1 3//1 7//1 6//1
f -5 -1 -2 -6
f -8 -4 -1 -5
)");
    const SurfaceMesh s = readSurfaceMesh(path);
    EXPECT_EQ(s.vertices(), 8);
    EXPECT_EQ(s.faces(), 12);
    EXPECT_NEAR(enclosedVolume(s), 1.0, 1e-15);
}

TEST(SurfaceIo, BunnyOff) {
    const SurfaceMesh s = readSurfaceMesh(test::data("surface/igl_bunny.off"));
    EXPECT_EQ(s.vertices(), 3485);
    EXPECT_EQ(s.faces(), 6966);
    EXPECT_NEAR(enclosedVolume(s), 7.5e-4, 0.1e-4);
}

TEST(SurfaceIo, OffWithoutEdgeCountAndWithPolygons) {
    const std::string dir = test::tempDir();
    // Square pyramid: base quad fanned into 2, 4 sides: 6 triangles, volume 1/3.
    const std::string path = writeText(dir + "/pyr.off", "OFF # header comment\n5 5\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
                                                         "0 0 1\n4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4\n");
    const SurfaceMesh s = readSurfaceMesh(path);
    EXPECT_EQ(s.vertices(), 5);
    EXPECT_EQ(s.faces(), 6);
    EXPECT_NEAR(enclosedVolume(s), 1.0 / 3.0, 1e-15);
}

TEST(SurfaceIo, SofaBunnyBinaryStlWelded) {
    const SurfaceMesh s = readSurfaceMesh(test::data("surface/sofa_Bunny.stl"));
    EXPECT_EQ(s.vertices(), 1366);
    EXPECT_EQ(s.faces(), 2728);
    EXPECT_EQ(unreferenced(s), 0);
}

TEST(SurfaceIo, AsciiStlWelded) {
    const std::string dir = test::tempDir();
    // The unit corner tet: 4 facets, 12 vertex records, 4 distinct points, volume 1/6.
    const std::string path = writeText(dir + "/tet.stl", R"(solid corner
  facet normal 0 0 -1
    outer loop
      vertex 0 0 0
      vertex 0 1 0
      vertex 1 0 0
    endloop
  endfacet
  facet normal 0 -1 0
    outer loop
      vertex 0 0 0
      vertex 1 0 0
      vertex 0 0 1
    endloop
  endfacet
  facet normal -1 0 0
    outer loop
      vertex 0 0 0
      vertex 0 0 1
      vertex 0 1 0
    endloop
  endfacet
  facet normal 0.577 0.577 0.577
    outer loop
      vertex 1 0 0
      vertex 0 1 0
      vertex 0 0 1e0
    endloop
  endfacet
endsolid corner
)");
    const SurfaceMesh s = readSurfaceMesh(path);
    EXPECT_EQ(s.vertices(), 4);
    EXPECT_EQ(s.faces(), 4);
    EXPECT_NEAR(enclosedVolume(s), 1.0 / 6.0, 1e-15);
}
