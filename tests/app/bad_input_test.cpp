// Bad input and faults end in a clear error with a non-zero exit, never in a crash, a hang, an
// exit-0 run of nonsense or a half-written output folder. Each test is a reproducer: a shipped
// mesh scaled to extreme coordinates, a surface with repeated faces, deep JSON, a signal mid-run.
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::workDir;

// The shipped liver (Gmsh v1) with every coordinate multiplied by (fx, fy, fz).
std::string scaledLiver(const std::string& path, double fx, double fy, double fz) {
    std::istringstream in(test::readText(test::source("assets/meshes/liver.msh")));
    std::ostringstream out;
    bool nodes = false;
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("$NOD", 0) == 0) nodes = true;
        if (line.rfind("$ENDNOD", 0) == 0) nodes = false;
        std::istringstream ls(line);
        long id;
        double x, y, z;
        if (nodes && (ls >> id >> x >> y >> z)) {
            char buf[128];
            std::snprintf(buf, sizeof buf, "%ld %.17g %.17g %.17g", id, x * fx, y * fy, z * fz);
            out << buf << "\n";
        } else {
            out << line << "\n";
        }
    }
    return test::writeText(path, out.str());
}

json barSag() { return json::parse(test::readText(test::source("assets/scenes/bar_sag.json"))); }

std::string writeScene(const std::string& path, const json& j) { return test::writeText(path, j.dump(2)); }

// exit 2 with "error:" and `needle` on stderr; never an abort (134) or an exit 0
void expectBadInput(const std::string& args, const std::string& needle) {
    std::string err;
    const int code = test::runCutsim(args, nullptr, &err);
    EXPECT_EQ(code, 2) << args << "\n" << err;
    EXPECT_NE(err.find("error:"), std::string::npos) << err;
    EXPECT_NE(err.find(needle), std::string::npos) << "expected '" << needle << "' in: " << err;
}

TEST(BadInput, ExtremeCoordinatesAreRefusedWhereTheyAreRead) {
    const std::string dir = workDir();
    const std::string flat = scaledLiver(dir + "/flat.msh", 1e-200, 1, 1);
    const std::string huge = scaledLiver(dir + "/huge.msh", 1e100, 1e100, 1e100);
    const std::string tiny = scaledLiver(dir + "/tiny.msh", 1e-100, 1e-100, 1e-100);
    expectBadInput("dt " + flat, "flat.msh");
    expectBadInput("dt " + flat, "is degenerate");
    expectBadInput("dt " + huge + " --json", "coordinates must lie within");
    expectBadInput("dt " + tiny, "the mesh spans");
    expectBadInput("mesh " + huge + " --json", "huge.msh");
    expectBadInput("dt " + test::source("assets/meshes/liver.msh") + " --scale 1e100", "coordinates");
}

TEST(BadInput, MaterialOutsideItsRangeNamesTheKey) {
    const std::string dir = workDir();
    json j = barSag();
    j["material"]["E"] = 1e-300;
    expectBadInput("run " + writeScene(dir + "/e.json", j) + " --out " + dir + "/o --no-render --quiet", "material.E");
    j = barSag();
    j["material"]["rho"] = 1e300;
    expectBadInput("run " + writeScene(dir + "/rho.json", j) + " --out " + dir + "/o --no-render --quiet",
                   "material.rho");
    EXPECT_FALSE(fs::exists(dir + "/o"));
}

TEST(BadInput, CaptureRangeFloorAndPlaybackNameTheKey) {
    const std::string dir = workDir();
    for (const json& range : {json::array({1.0, 1.0}), json::array({2.0}), json("x"), json::array({0, "a"})}) {
        json j = barSag();
        j["capture"]["range"] = range;
        expectBadInput("run " + writeScene(dir + "/r.json", j) + " --out " + dir + "/o --no-render --quiet",
                       "capture.range");
    }
    json j = barSag();
    j["capture"]["floor_height"] = 1e9;
    expectBadInput("run " + writeScene(dir + "/f.json", j) + " --out " + dir + "/o --no-render --quiet",
                   "capture.floor_height");
    j = barSag();
    j["capture"]["playback_fps"] = -1;
    expectBadInput("run " + writeScene(dir + "/p.json", j) + " --out " + dir + "/o --no-render --quiet",
                   "capture.playback_fps");
    EXPECT_FALSE(fs::exists(dir + "/o"));
}

TEST(BadInput, NonUtf8NamesGiveValidJson) {
    const std::string dir = workDir();
    const std::string mesh = dir + "/liver\xff.msh";
    test::writeText(mesh, test::readText(test::source("assets/meshes/liver.msh")));
    std::string out, err;
    ASSERT_EQ(test::runCutsim("mesh '" + mesh + "' --json", &out, &err), 0) << err;
    EXPECT_EQ(json::parse(out)["elements"], 596);
    // a run named by --set with a byte that is not UTF-8: the report is written and valid
    const std::string o = dir + "/out";
    ASSERT_EQ(test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + o +
                                  " --no-render --quiet --set duration=0.01 --set 'name=bar\xff'",
                              nullptr, &err),
              0)
        << err;
    const json r = json::parse(test::readText(o + "/report.json"));
    EXPECT_EQ(r["status"], "ok");
    for (const auto& e : fs::recursive_directory_iterator(o))
        EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
}

TEST(BadInput, DeeplyNestedJsonIsRefusedNotRecursedInto) {
    const std::string dir = workDir();
    const int depth = 200000;
    const std::string scene = test::writeText(
        dir + "/deep.json", R"({"name": "deep", "description": )" + std::string(depth, '[') + std::string(depth, ']') +
                                R"(, "object": {"box": {"size": [1, 0.1, 0.1], "cells": [4, 1, 1]}}})");
    expectBadInput("run " + scene + " --out " + dir + "/o --no-render --quiet", "nested deeper than 64");
    expectBadInput("run " + test::source("assets/scenes/bar_sag.json") + " --out " + dir +
                       "/o --no-render --quiet --set 'description=" + std::string(100, '[') + std::string(100, ']') +
                       "'",
                   "--set description");
}

TEST(BadInput, NumberBeyondDoubleRangeNamesTheLine) {
    const std::string dir = workDir();
    const std::string scene =
        test::writeText(dir + "/big.json", "{\n  \"name\": \"big\",\n  \"object\": {\"box\": {\"size\": [1, 0.1, 0.1], "
                                           "\"cells\": [4, 1, 1]}},\n  \"duration\": 1e400\n}\n");
    expectBadInput("run " + scene + " --out " + dir + "/o --no-render --quiet", "big.json:4:");
    expectBadInput("run " + scene + " --out " + dir + "/o --no-render --quiet", "beyond the range of a double");
}

TEST(BadInput, IntegersAbove63BitsAreNotReadAsMinusOne) {
    const std::string dir = workDir();
    expectBadInput("run " + test::source("assets/scenes/bar_sag.json") + " --out " + dir +
                       "/o --quiet --set capture.width=18446744073709551615",
                   "got 18446744073709551615");
}

TEST(BadInput, FoldersAndPipesAreNotFiles) {
    const std::string dir = workDir();
    expectBadInput("run " + dir + " --out " + dir + "/o --no-render --quiet", "is a folder, not a file");
    const std::string fifo = dir + "/mesh.msh";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    expectBadInput("mesh " + fifo, "is not a regular file");  // a read would block forever
    expectBadInput("dt " + fifo, "is not a regular file");
}

// Found by fuzzing the Release build: a path with a component longer than the system allows made
// std::filesystem throw from the scene loader instead of an error naming the key.
TEST(BadInput, FileNamesTooLongNameTheKey) {
    const std::string dir = workDir();
    const std::string longName = std::string(300, 'e') + ".msh";
    json j = barSag();
    j["object"] = {{"mesh", longName}};
    expectBadInput("run " + writeScene(dir + "/long.json", j) + " --out " + dir + "/o --no-render --quiet",
                   "object.mesh: cannot read");
    expectBadInput("mesh " + dir + "/" + longName, "cannot read");
}

TEST(BadInput, UsageErrorsExitTwo) {
    std::string err;
    EXPECT_EQ(test::runCutsim("dt --no-such-flag x.msh", nullptr, &err), 2) << err;
    EXPECT_EQ(test::runCutsim("run", nullptr, &err), 2) << err;
    EXPECT_EQ(test::runCutsim("no-such-command", nullptr, &err), 2) << err;
    EXPECT_EQ(test::runCutsim("--help"), 0);
}

// Limits that depend on the mesh are checked where the scene's key is applied and name the scene
// file and that key, not only the mesh or surface the key was applied to.
TEST(BadInput, ScaleAndLatticeLimitsNameTheSceneKey) {
    const std::string dir = workDir(), probe = test::source("assets/scenes/probe.json");
    const std::string run = " --out " + dir + "/o --no-render --quiet";
    // the liver is 0.3 m across: x 1e9 leaves the coordinate range, x 1e-9 falls below the smallest object
    expectBadInput("run " + probe + run + " --set object.scale=1e9", "probe.json: object.scale: 1e+09 applied to");
    expectBadInput("run " + probe + run + " --set object.scale=1e9", "coordinates must lie within");
    expectBadInput("run " + probe + run + " --set object.scale=1e-9", "probe.json: object.scale");
    // an empty path is the key's error, not a file's
    expectBadInput("run " + probe + run + " --set object.mesh=", "probe.json: object.mesh: is empty");
    // lattices: 1000 cells across the liver is above the tet limit; h = 1e-7 m is 1e6 cells along
    // an axis; h = 10 m is a cell so much larger than the object that no element keeps a share of it
    const std::string mi = test::source("assets/scenes/demo_mi.json");
    expectBadInput("run " + mi + run + " --set object.surface.cells=1000", "demo_mi.json: object.surface.cells");
    json j = json::parse(test::readText(mi));
    j["object"]["surface"] = {{"path", test::source("assets/meshes/sofa_liver.obj")}, {"h", 1e-7}};
    expectBadInput("run " + writeScene(dir + "/fine.json", j) + run, "fine.json: object.surface.h: lattice too fine");
    j["object"]["surface"]["h"] = 10.0;
    expectBadInput("run " + writeScene(dir + "/coarse.json", j) + run,
                   "coarse.json: object.surface.h: no lattice element lies inside the surface: the cell edge");
    // h = 0.5 m keeps elements, but none of their nodes lies in demo_mi's 3 cm thick fixed slab:
    // the region's error names the lattice's spacing and its key (it said only "selects no node")
    j["object"]["surface"]["h"] = 0.5;
    expectBadInput("run " + writeScene(dir + "/coarse.json", j) + run,
                   "coarse.json: fixed[0]: selects no node of the lattice, whose nodes lie 0.5 m apart "
                   "(object.surface.h)");
    EXPECT_FALSE(fs::exists(dir + "/o"));
}

// A box's or an inline mesh's coordinates are known where object.scale is read: their range after
// scaling is checked there (with any_size a box 1e9 m long ran "ok", and at 1e-9 was blamed on
// fixed[0]).
TEST(BadInput, BoxAndInlineMeshScaleIsCheckedWhereItIsRead) {
    const std::string dir = workDir(), run = " --out " + dir + "/o --no-render --quiet --set object.any_size=true";
    const std::string bar = test::source("assets/scenes/bar_sag.json");
    expectBadInput("run " + bar + run + " --set object.scale=1e9", "bar_sag.json: object.scale: 1e+09 makes the box");
    expectBadInput("run " + bar + run + " --set object.scale=1e-9", "bar_sag.json: object.scale: 1e-09 makes the box");
    json j = barSag();
    j["object"] = json::parse(R"({"mesh": {"nodes": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                                           "tets": [[0, 1, 2, 3]]}, "scale": 1e9})");
    j["fixed"] = json::array();
    expectBadInput("run " + writeScene(dir + "/inline.json", j) + run,
                   "inline.json: object.scale: 1e+09 applied to " + dir + "/inline.json: object.mesh: coordinates");
    EXPECT_FALSE(fs::exists(dir + "/o"));
}

// object.tetra: the scale and the target edge length name their keys, not object.tetra or --size.
TEST(BadInput, TetraLimitsNameTheSceneKey) {
    const std::string dir = workDir(), run = " --out " + dir + "/o --no-render --quiet";
    json j = barSag();
    j["object"] = {{"tetra", {{"surface", test::source("assets/meshes/sofa_liver.obj")}, {"size", 0.01}}},
                   {"scale", 1e9}};
    expectBadInput("run " + writeScene(dir + "/big.json", j) + run, "big.json: object.scale: 1e+09 applied to");
    j["object"]["scale"] = 0.0254;
    j["object"]["tetra"]["size"] = 1e-5;
    expectBadInput("run " + writeScene(dir + "/fine.json", j) + run,
                   "fine.json: object.tetra.size: 1e-05 m makes about");
    EXPECT_FALSE(fs::exists(dir + "/o"));
}

// A fixed node the mesh does not have is the scene's error: file, key and the node.
TEST(BadInput, FixedNodeIdsNameTheSceneFile) {
    const std::string dir = workDir();
    json j = barSag();
    j["fixed"] = json::parse(R"([{"nodes": [0, 5000]}])");
    expectBadInput("run " + writeScene(dir + "/nodes.json", j) + " --out " + dir + "/o --no-render --quiet",
                   "nodes.json: fixed[0].nodes: node 5000 does not exist (mesh has 1025)");
    EXPECT_FALSE(fs::exists(dir + "/o"));
}

// A run that would take no step is refused (exit 2): "ok" always means something was simulated.
// A duration shorter than one step is refused too: its one step would end past the duration (it
// ended "ok" with sim_time 4.1e-4 s for a duration of 1e-4 s).
TEST(BadInput, ARunThatSimulatesNothingIsRefused) {
    const std::string dir = workDir(), run = "run " + test::source("assets/scenes/bar_sag.json") + " --out " + dir +
                                             "/o --no-render --quiet --set duration=";
    expectBadInput(run + "1e-15", "bar_sag.json: duration: 1e-15 s is shorter than one step of 0.0004102 s");
    expectBadInput(run + "1e-4", "bar_sag.json: duration: 0.0001 s is shorter than one step");
    EXPECT_FALSE(fs::exists(dir + "/o"));
    // one step is enough
    std::string err;
    EXPECT_EQ(test::runCutsim(run + "0.00042", nullptr, &err), 0) << err;
}

TEST(BadInput, ContactPointsAreBoundedUpFront) {
    const std::string dir = workDir();
    const std::string probe = test::source("assets/scenes/probe.json");
    expectBadInput("run " + probe + " --out " + dir + "/o --no-render --quiet --set contact.spacing=1e-6",
                   "contact.spacing");
    // a tool radius of 1e-9 m sets the automatic spacing to half of it
    json j = json::parse(test::readText(probe));
    j["tools"][0]["radius"] = 1e-9;
    j["object"]["mesh"] = test::source("assets/meshes/liver.msh");
    j["object"]["visual"] = test::source("assets/meshes/sofa_liver-smooth.obj");
    expectBadInput("run " + writeScene(dir + "/tiny_tool.json", j) + " --out " + dir + "/o --no-render --quiet",
                   "the smallest size");
    EXPECT_FALSE(fs::exists(dir + "/o"));
}

TEST(BadInput, TinyNormalsAreNormalisedAndHugeOnesRefused) {
    const std::string dir = workDir();
    // (1e-200, 0, 0) has a norm that underflows: it must still be the x axis
    json j = barSag();
    j["duration"] = 0.01;
    j["fixed"][0]["plane"]["normal"] = {1e-200, 0, 0};
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + writeScene(dir + "/tiny.json", j) + " --out " + dir + "/a --no-render --quiet",
                              nullptr, &err),
              0)
        << err;
    j["fixed"][0]["plane"]["normal"] = {1, 0, 0};
    ASSERT_EQ(test::runCutsim("run " + writeScene(dir + "/unit.json", j) + " --out " + dir + "/b --no-render --quiet",
                              nullptr, &err),
              0)
        << err;
    const json a = json::parse(test::readText(dir + "/a/report.json"));
    const json b = json::parse(test::readText(dir + "/b/report.json"));
    EXPECT_EQ(a["mesh"]["fixed_nodes"], b["mesh"]["fixed_nodes"]);
    EXPECT_GT(b["mesh"]["fixed_nodes"].get<int>(), 0);
    j["fixed"][0]["plane"]["normal"] = {1e308, 1e308, 0};
    expectBadInput("run " + writeScene(dir + "/huge.json", j) + " --out " + dir + "/c --no-render --quiet",
                   "fixed[0].plane.normal");
}

TEST(BadInput, MeshIntersectionDropsRepeatedAndDegenerateTriangles) {
    const std::string dir = workDir();
    std::string obj = test::readText(test::source("assets/meshes/sofa_liver.obj"));
    std::string face;
    {
        std::istringstream in(obj);
        for (std::string line; std::getline(in, line);)
            if (line.rfind("f ", 0) == 0) {
                face = line;
                break;
            }
    }
    std::string extra;
    for (int i = 0; i < 4000; ++i) extra += face + "\n";
    const std::string rep = test::writeText(dir + "/rep.obj", obj + "\n" + extra);
    std::string out, err;
    ASSERT_EQ(test::runCutsim("mi " + rep + " --cells 8 --json", &out, &err), 0) << err;
    const json r = json::parse(out);
    EXPECT_EQ(r["surface"]["dropped_duplicate_triangles"], 4000);
    EXPECT_EQ(r["volume_method"], "exact");  // the cleaned surface is closed again
}

}  // namespace
}  // namespace cutsim
