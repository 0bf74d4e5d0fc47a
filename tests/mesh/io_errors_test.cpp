// Bad input never crashes a reader: each case is an InputError whose text names the file and line.
#include "mesh/io.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

using namespace cutsim;

namespace {

using test::writeText;

// Message of the InputError that `f` throws; a failure if it throws nothing or something else.
std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const InputError& e) {
        return e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "not an InputError: " << e.what();
        return {};
    }
    ADD_FAILURE() << "no exception";
    return {};
}

std::string tetError(const std::string& path, const ReadOptions& opts = {}) {
    return errorOf([&] { readTetMesh(path, opts); });
}

std::string surfaceError(const std::string& path) {
    return errorOf([&] { readSurfaceMesh(path); });
}

// "name:line:" as the message starts after the folder.
std::string at(const std::string& path, long line) {
    return std::filesystem::path(path).filename().string() + ":" + std::to_string(line) + ":";
}

#define EXPECT_HAS(msg, part) EXPECT_NE((msg).find(part), std::string::npos) << "message: " << (msg)

// A small valid 2.2 mesh with one line to break: node 5 at (1,1,1), element count on line 13,
// elements from line 14.
std::string msh22(const std::string& elements, int count = 2) {
    return "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n"
           "$EndNodes\n$Elements\n" +
           std::to_string(count) + "\n" + elements + "$EndElements\n";
}

}  // namespace

TEST(MeshIoErrors, InvertedTetRejectedOrReoriented) {
    const std::string path = test::data("broken/sofa_6_tetra_bad.msh");
    const std::string msg = tetError(path);
    EXPECT_HAS(msg, at(path, 31));  // the 6th element line
    EXPECT_HAS(msg, "tet 5 ");
    EXPECT_HAS(msg, "inverted");

    ReadOptions opts;
    opts.reorient = true;
    ReadReport rep;
    const TetMesh m = readTetMesh(path, opts, &rep);
    EXPECT_EQ(m.elements(), 6);
    EXPECT_EQ(rep.inverted, std::vector<int>{5});
    for (int e = 0; e < m.elements(); ++e) EXPECT_GT(tetSignedVolume(m, e), 0) << "tet " << e;
}

TEST(MeshIoErrors, TruncatedFiles) {
    const std::string dir = test::tempDir();
    for (const char* rel : {"tet/sofa_liver.msh", "tet/sofa_liver.gmsh22.msh", "tet/sofa_liver2.msh",
                            "tet/igltests_decimated-knight.mesh", "tet/igl_octopus-low.mesh",
                            "tet/sofa_Armadillo_Tetra_4406.vtu", "surface/igl_bunny.off"}) {
        SCOPED_TRACE(rel);
        const std::string full = test::readText(test::data(rel));
        const std::string half = full.substr(0, full.size() / 2);
        const std::string path = writeText(dir + "/" + std::filesystem::path(rel).filename().string(), half);
        // The error is at the last line that has text.
        const size_t last = half.find_last_not_of(" \t\r\n");
        const long line = 1 + static_cast<long>(std::count(half.begin(), half.begin() + static_cast<long>(last), '\n'));
        const std::string msg = std::string(rel).starts_with("surface") ? surfaceError(path) : tetError(path);
        EXPECT_HAS(msg, at(path, line));
    }
}

TEST(MeshIoErrors, TruncatedBinaryStl) {
    const std::string dir = test::tempDir();
    const std::string full = test::readText(test::data("surface/sofa_Bunny.stl"));
    const std::string path = writeText(dir + "/bunny.stl", full.substr(0, full.size() / 2));
    const std::string msg = surfaceError(path);
    EXPECT_HAS(msg, "bunny.stl");
    EXPECT_HAS(msg, "2728 facets");
}

TEST(MeshIoErrors, GarbageText) {
    const std::string dir = test::tempDir();
    const std::string junk = "hello world\nthis is not a mesh\n";
    for (const char* name : {"g.msh", "g.mesh", "g.vtu"}) {
        const std::string path = writeText(dir + "/" + name, junk);
        const std::string msg = tetError(path);
        EXPECT_HAS(msg, name);
        EXPECT_TRUE(msg.find(at(path, 1)) != std::string::npos || msg.find(at(path, 2)) != std::string::npos) << msg;
    }
    writeText(dir + "/g.ele", "2 4 0\n1 1 2 3 4\n");
    EXPECT_HAS(tetError(writeText(dir + "/g.node", junk)), at(dir + "/g.node", 1));
    EXPECT_HAS(surfaceError(writeText(dir + "/g.off", junk)), at(dir + "/g.off", 1));
    EXPECT_HAS(surfaceError(writeText(dir + "/g.stl", junk)), at(dir + "/g.stl", 1));
    EXPECT_HAS(surfaceError(writeText(dir + "/g.obj", "v 0 0 0\nv 1 0 zero\n")), at(dir + "/g.obj", 2));
    // Binary noise, NUL bytes included.
    std::string noise;
    for (int i = 0; i < 4000; ++i) noise += static_cast<char>((i * 7919 + 13) % 256);
    EXPECT_HAS(tetError(writeText(dir + "/noise.msh", noise)), "noise.msh");
    EXPECT_HAS(tetError(writeText(dir + "/noise.mesh", noise)), "noise.mesh");
    EXPECT_HAS(tetError(writeText(dir + "/noise.vtu", noise)), "noise.vtu");
    EXPECT_HAS(surfaceError(writeText(dir + "/noise.off", noise)), "noise.off");
    EXPECT_HAS(surfaceError(writeText(dir + "/noise.stl", noise)), "noise.stl");
    // An empty file.
    EXPECT_HAS(tetError(writeText(dir + "/empty.msh", "")), "empty.msh");
}

TEST(MeshIoErrors, MissingFileAndUnknownExtension) {
    const std::string dir = test::tempDir();
    EXPECT_HAS(tetError(dir + "/nothere.msh"), "nothere.msh");
    EXPECT_HAS(surfaceError(dir + "/nothere.obj"), "nothere.obj");
    writeText(dir + "/lonely.node", "1 3 0 0\n1 0 0 0\n");
    EXPECT_HAS(tetError(dir + "/lonely.node"), "lonely.ele");  // the partner file is named
    EXPECT_HAS(tetError(writeText(dir + "/mesh.xyz", "1 2 3\n")), "'.xyz'");
    EXPECT_HAS(tetError(test::data("surface/sofa_liver.obj")), "surface mesh");
}

TEST(MeshIoErrors, NodeIndexOutOfRange) {
    const std::string dir = test::tempDir();
    const std::string m = writeText(dir + "/range.msh", msh22("1 4 2 0 1 1 2 3 4\n2 4 2 0 1 2 3 4 9\n"));
    std::string msg = tetError(m);
    EXPECT_HAS(msg, at(m, 15));
    EXPECT_HAS(msg, "node id 9");

    const std::string v1 = writeText(dir + "/range_v1.msh", "$NOD\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$ENDNOD\n"
                                                            "$ELM\n1\n1 4 1 1 4 1 2 3 0\n$ENDELM\n");
    EXPECT_HAS(tetError(v1), at(v1, 10));

    const std::string me = writeText(dir + "/range.mesh", "MeshVersionFormatted 1\nDimension 3\nVertices\n4\n0 0 0 0\n"
                                                          "1 0 0 0\n0 1 0 0\n0 0 1 0\nTetrahedra\n1\n1 2 3 5 0\nEnd\n");
    msg = tetError(me);
    EXPECT_HAS(msg, at(me, 11));
    EXPECT_HAS(msg, "vertex number 5");

    writeText(dir + "/range.node", "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n");
    const std::string ele = writeText(dir + "/range.ele", "1 4 0\n1 1 2 3 0\n");
    EXPECT_HAS(tetError(ele), at(ele, 2));

    std::string vtu = test::readText(test::data("tet/sofa_Armadillo_Tetra_4406.vtu"));
    const size_t conn = vtu.find('\n', vtu.find("Name=\"connectivity\""));
    vtu.insert(conn + 1, "1446 ");  // first connectivity entry becomes the nonexistent node 1446
    const std::string vpath = writeText(dir + "/range.vtu", vtu);
    const long vline = 1 + static_cast<long>(std::count(vtu.begin(), vtu.begin() + static_cast<long>(conn) + 1, '\n'));
    msg = tetError(vpath);
    EXPECT_HAS(msg, at(vpath, vline));
    EXPECT_HAS(msg, "1446");

    const std::string obj = writeText(dir + "/range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n");
    EXPECT_HAS(surfaceError(obj), at(obj, 5));
    const std::string off = writeText(dir + "/range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
    EXPECT_HAS(surfaceError(off), at(off, 6));
}

TEST(MeshIoErrors, ZeroVolumeTet) {
    const std::string dir = test::tempDir();
    // Element 1 (0-based) has all four nodes in the plane z = 0: nodes 1, 2, 3 and a repeat of 1.
    const std::string path = writeText(dir + "/flat.msh", msh22("1 4 2 0 1 1 2 3 4\n7 4 2 0 1 1 2 3 1\n"));
    const std::string msg = tetError(path);
    EXPECT_HAS(msg, at(path, 15));
    EXPECT_HAS(msg, "tet 1 ");
    EXPECT_HAS(msg, "element id 7");
    EXPECT_HAS(msg, "zero volume");

    // A sliver far below the mean is caught by the minVolume rule only when asked.
    const std::string sliver =
        writeText(dir + "/sliver.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n"
                                       "4 0 0 1\n5 0.5 0.5 1e-6\n$EndNodes\n$Elements\n2\n1 4 2 0 1 1 2 3 4\n"
                                       "2 4 2 0 1 1 2 3 5\n$EndElements\n");
    EXPECT_NO_THROW(readTetMesh(sliver));
    ReadOptions opts;
    opts.minVolume = 1e-3;
    EXPECT_HAS(tetError(sliver, opts), at(sliver, 15));
}

TEST(MeshIoErrors, WrongCountsAndHugeCounts) {
    const std::string dir = test::tempDir();
    const std::string few = writeText(dir + "/few.msh", msh22("1 4 2 0 1 1 2 3 4\n", 2));
    std::string msg = tetError(few);
    EXPECT_HAS(msg, at(few, 15));
    EXPECT_HAS(msg, "only 1 of the declared 2");

    const std::string many = writeText(dir + "/many.msh", msh22("1 4 2 0 1 1 2 3 4\n2 4 2 0 1 2 3 4 5\n", 1));
    EXPECT_HAS(tetError(many), at(many, 15));

    const std::string huge = writeText(dir + "/huge.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n"
                                                          "9000000000000\n1 0 0 0\n$EndNodes\n");
    msg = tetError(huge);
    EXPECT_HAS(msg, at(huge, 5));
    EXPECT_HAS(msg, "more than the rest of the file can hold");

    const std::string hugeOff = writeText(dir + "/huge.off", "OFF\n3 2000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    EXPECT_HAS(surfaceError(hugeOff), at(hugeOff, 2));

    const std::string bigStl = dir + "/big.stl";
    std::string header(80, ' ');
    header += std::string("\xff\xff\xff\x0f", 4);  // 268 million facets declared, none present
    writeText(bigStl, header);
    EXPECT_HAS(surfaceError(bigStl), "big.stl");
}

TEST(MeshIoErrors, BadValues) {
    const std::string dir = test::tempDir();
    const std::string nan = writeText(dir + "/nan.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n2\n1 0 0 0\n"
                                                        "2 0 nan 0\n$EndNodes\n");
    std::string msg = tetError(nan);
    EXPECT_HAS(msg, at(nan, 7));
    EXPECT_HAS(msg, "non-finite");

    const std::string dup = writeText(dir + "/dup.msh", "$NOD\n2\n1 0 0 0\n1 1 0 0\n$ENDNOD\n");
    EXPECT_HAS(tetError(dup), at(dup, 4));

    const std::string bin = writeText(dir + "/bin.msh", "$MeshFormat\n2.2 1 8\n$EndMeshFormat\n");
    EXPECT_HAS(tetError(bin), at(bin, 2));

    const std::string v40 = writeText(dir + "/v40.msh", "$MeshFormat\n4 0 8\n$EndMeshFormat\n");
    EXPECT_HAS(tetError(v40), at(v40, 2));

    const std::string shortLine = writeText(dir + "/short.msh", msh22("1 4 2 0 1 1 2 3\n2 4 2 0 1 2 3 4 5\n"));
    msg = tetError(shortLine);
    EXPECT_HAS(msg, at(shortLine, 14));
    EXPECT_HAS(msg, "line ends early");

    const std::string noTets = writeText(dir + "/notets.msh", msh22("1 2 2 0 1 1 2 3\n2 1 2 0 1 2 3\n"));
    EXPECT_HAS(tetError(noTets), "no tetrahedra");

    const std::string dim2 = writeText(dir + "/flat.mesh", "MeshVersionFormatted 1\nDimension 2\n");
    EXPECT_HAS(tetError(dim2), at(dim2, 2));

    const std::string face2 = writeText(dir + "/face.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
    EXPECT_HAS(surfaceError(face2), at(face2, 3));

    ReadOptions neg;
    neg.scale = -1;
    EXPECT_HAS(tetError(test::data("tet/sofa_liver.msh"), neg), "scale");
}
