// A take (sim/take.hpp): a run with held tools and a cut made due by hand, written back as a scene,
// replays to bitwise the same state; camera keys hold a still camera until it moves.
#include "sim/take.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace cutsim {
namespace {

using nlohmann::json;

// The 120-tet cantilever of simulation_test.cpp with a probe coming down on its free end and a
// scripted cut, at x = 5 cm, due long after the end.
json probedBar() {
    return json::parse(R"({
      "object": { "box": { "size": [0.1, 0.02, 0.02], "cells": [10, 2, 2] } },
      "fixed": [ { "plane": { "point": [0, 0, 0], "normal": [1, 0, 0], "distance": 1e-6 } } ],
      "tools": [ { "name": "probe", "kind": "sphere", "radius": 0.005, "keyframes": [
        { "time": 0, "position": [0.08, 0.01, 0.03] },
        { "time": 0.02, "position": [0.08, 0.01, 0.018], "rotation_deg": [0, 20, 0] } ] } ],
      "cutting": { "cuts": [ { "time": 5, "point": [0.05, 0.01, 0.01], "normal": [1, 0, 0] } ] },
      "duration": 0.02,
      "capture": { "enabled": false }
    })");
}

TEST(Take, HeldToolsAndADueCutReplayBitwise) {
    SimulationOptions o;
    o.threads = 1;
    Simulation live(parseScene(probedBar(), "bar.json"), o);
    live.advance(0.005);  // the probe still above the bar, in the middle of its keyframed path
    live.holdTool(0, Eigen::Vector3d(0.08, 0.01, 0.0235));  // pressing 1.5 mm in
    live.holdTool(0, Eigen::Vector3d(0.08, 0.01, 0.0238));  // twice at the same time: the last holds
    live.advance(0.011);
    EXPECT_EQ(live.dueNextScripted(), 0);
    live.advance(0.014);
    live.holdTool(0, Eigen::Vector3d(0.07, 0.01, 0.023));
    live.advance(1.0);
    ASSERT_EQ(live.status(), RunStatus::Finished);
    ASSERT_EQ(live.record().cuts.size(), 1u);
    EXPECT_GT(live.record().tool.maxForce, 0.0);

    const json take = takeScene(live, "take.json");
    // the first key, then the pose at each hold and the held pose (the second hold at 0.005 s replaced the first)
    EXPECT_EQ(take["tools"][0]["keyframes"].size(), 5u) << take["tools"][0].dump();
    EXPECT_EQ(take["cutting"]["cuts"][0]["time"].get<double>(), live.record().cuts[0]["time"].get<double>());
    Simulation replay(parseScene(json::parse(take.dump()), "take.json"), o);  // through the text, as written
    replay.advance(1.0);
    EXPECT_EQ(replay.state().steps, live.state().steps);
    EXPECT_EQ(replay.stateHash(), live.stateHash());
    EXPECT_EQ(replay.report()["pieces"], live.report()["pieces"]);
    ASSERT_EQ(replay.record().cuts.size(), 1u);
    EXPECT_EQ(replay.record().cuts[0]["split"], live.record().cuts[0]["split"]);
}

// A take that ends early is as long as it went.
TEST(Take, EndsWhereTheTakeEnded) {
    SimulationOptions o;
    o.threads = 1;
    Simulation live(parseScene(probedBar(), "bar.json"), o);
    live.advance(0.01);
    EXPECT_EQ(takeScene(live, "take.json")["duration"].get<double>(), live.state().time);
}

TEST(Take, CameraKeysHoldAStillCameraUntilItMoves) {
    std::vector<CameraKey> keys;
    CameraKey a;
    a.eye = Eigen::Vector3d(1, 0, 0);
    CameraKey prev = a;
    for (double t : {0.1, 0.2, 0.3}) {  // still
        CameraKey now = a;
        now.time = t;
        addCameraKey(keys, prev, now);
        prev = now;
    }
    ASSERT_EQ(keys.size(), 1u);
    CameraKey moved = a;
    moved.time = 0.4;
    moved.eye.y() = 1;
    addCameraKey(keys, prev, moved);
    ASSERT_EQ(keys.size(), 3u);  // first, held until 0.3, moved at 0.4
    EXPECT_EQ(keys[1].time, 0.3);
    EXPECT_EQ(keys[1].eye, a.eye);
    EXPECT_EQ(keys[2].eye, moved.eye);
}

}  // namespace
}  // namespace cutsim
