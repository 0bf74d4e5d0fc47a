// Scene reading: --set into array elements and an object given inline as nodes and tets.
#include "sim/simulation.hpp"

#include "mesh/generate.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <functional>

namespace cutsim {
namespace {

using nlohmann::json;

json barScene() {
    return json::parse(R"({
      "object": { "box": { "size": [0.1, 0.02, 0.02], "cells": [10, 2, 2] } },
      "fixed": [ { "plane": { "point": [0, 0, 0], "normal": [1, 0, 0], "distance": 1e-6 } } ],
      "tools": [ { "kind": "sphere", "radius": 0.01, "keyframes": [ { "time": 0, "position": [0.05, 0.01, 0.05] } ] } ],
      "duration": 0.01,
      "capture": { "enabled": false }
    })");
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(Scene, SetReachesArrayElementsByIndex) {
    const json j = applySets(barScene(), {"tools.0.radius=0.02", "tools.0.keyframes.0.position.2=0.07"});
    const SceneDef s = parseScene(j, "bar.json");
    EXPECT_EQ(s.tools.at(0).radius, 0.02);
    EXPECT_EQ(s.tools.at(0).keys.at(0).pose.position.z(), 0.07);
    EXPECT_NE(errorOf([] { applySets(barScene(), {"tools.1.radius=0.02"}); }).find("not an index of an array of 1"),
              std::string::npos);
    EXPECT_NE(errorOf([] { applySets(barScene(), {"tools.x.radius=0.02"}); }).find("'x' is not an index"),
              std::string::npos);
    EXPECT_NE(errorOf([] { applySets(barScene(), {"duration.x=1"}); }).find("inside a non-object"), std::string::npos);
}

// The same box given inline runs bitwise as the generated one.
TEST(Scene, InlineMeshRunsAsTheBox) {
    const TetMesh box = boxMesh(0.1, 0.02, 0.02, 10, 2, 2);
    json j = barScene();
    json nodes = json::array(), tets = json::array();
    for (int i = 0; i < box.nodes(); ++i) nodes.push_back({box.X(0, i), box.X(1, i), box.X(2, i)});
    for (int e = 0; e < box.elements(); ++e)
        tets.push_back({box.tets(0, e), box.tets(1, e), box.tets(2, e), box.tets(3, e)});
    j["object"] = {{"mesh", {{"nodes", nodes}, {"tets", tets}}}};
    Simulation a(parseScene(j, "inline.json"), {1, false}), b(parseScene(barScene(), "bar.json"), {1, false});
    a.advance(1);
    b.advance(1);
    EXPECT_EQ(a.state().steps, b.state().steps);
    EXPECT_EQ(a.stateHash(), b.stateHash());

    j["object"]["mesh"]["tets"][3][1] = box.nodes();
    EXPECT_NE(errorOf([&] { parseScene(j, "inline.json"); }).find("inline.json: object.mesh.tets: tet 3"),
              std::string::npos);
    j["object"]["mesh"].erase("nodes");
    EXPECT_NE(errorOf([&] { parseScene(j, "inline.json"); }).find("object.mesh.nodes: is required"), std::string::npos);
}

}  // namespace
}  // namespace cutsim
