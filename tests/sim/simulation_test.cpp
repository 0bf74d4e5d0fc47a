// The simulation loop (sim/simulation.hpp): it adds nothing to the physics, times its stages,
// applies one step rule after every cut, and refuses or fails runs that cannot be trusted; a take
// of it (sim/take.hpp) replays bitwise.
#include "sim/simulation.hpp"
#include "snapshot/scene_snapshot.hpp"
#include "sim/take.hpp"

#include "fem/forces.hpp"
#include "mesh/generate.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <functional>
#include <string>

namespace cutsim {
namespace {

using nlohmann::json;

// A 10 cm x 2 cm x 2 cm cantilever of 120 tets clamped at x = 0, sagging under gravity.
json barScene() {
    return json::parse(R"({
      "object": { "box": { "size": [0.1, 0.02, 0.02], "cells": [10, 2, 2] } },
      "fixed": [ { "plane": { "point": [0, 0, 0], "normal": [1, 0, 0], "distance": 1e-6 } } ],
      "duration": 0.02,
      "capture": { "enabled": false }
    })");
}

Simulation makeSim(const json& j) {
    SimulationOptions o;
    o.threads = 1;
    return Simulation(parseScene(j, "bar.json"), o);
}

// The loop's positions are bitwise those of a hand-written loop over the same Model and Stepper.
TEST(Simulation, StepsAsTheStepperAlone) {
    Simulation sim = makeSim(barScene());
    Model m = buildModel(boxMesh(0.1, 0.02, 0.02, 10, 2, 2), Material{});
    m.gravity = Eigen::Vector3d(0, 0, -9.81);
    for (int i = 0; i < m.nodes(); ++i) m.fixed[static_cast<size_t>(i)] = m.X(0, i) <= 1e-6;
    updateMasses(m);
    State s = makeState(m);
    Stepper stepper;
    const StepOptions so{Integrator::SymplecticEuler, sim.dt()};
    EXPECT_DOUBLE_EQ(sim.dt(), 0.9 * sim.initialLimits().exact);  // the default policy
    while (sim.step() == RunStatus::Running) stepper.step(m, s, so);
    stepper.step(m, s, so);  // the step that finished the run
    EXPECT_EQ(sim.status(), RunStatus::Finished);
    EXPECT_EQ(sim.state().steps, s.steps);
    EXPECT_EQ((sim.state().x - s.x).cwiseAbs().maxCoeff(), 0.0);
    // Stages: forces and integration ran, no tool, no cut.
    const StageTimes& st = sim.record().stages;
    EXPECT_GT(st[Stage::Forces], 0.0);
    EXPECT_EQ(st[Stage::Contact], 0.0);
    EXPECT_EQ(st[Stage::Cuts], 0.0);
    EXPECT_EQ(sim.report()["status"], "ok");
}

// After a cut the policy is chosen again at the new limits: 0.9 of the new exact step.
TEST(Simulation, ACutRechoosesTheStepByThePolicy) {
    Simulation sim = makeSim(barScene());
    sim.advance(0.005);
    CutSurface plane;
    plane.point = Eigen::Vector3d(0.0525, 0, 0);
    plane.normal = Eigen::Vector3d(1, 0.2, 0).normalized();
    const int version = sim.topologyVersion();
    const CutResult r = sim.cut(plane, "test");
    ASSERT_TRUE(r.changed());
    EXPECT_EQ(sim.topologyVersion(), version + 1);
    const json& c = sim.record().cuts.back();
    EXPECT_EQ(c["key"], "test");
    EXPECT_DOUBLE_EQ(c["dt_used"].get<double>(), 0.9 * c["dt_after"]["exact"].get<double>());
    EXPECT_DOUBLE_EQ(sim.dt(), 0.9 * sim.limits().exact);
    EXPECT_EQ(sim.advance(1.0), RunStatus::Finished);
    EXPECT_EQ(sim.report()["pieces"], 2);
}

// A fixed step above the limit with on_limit refuse is bad input before the first step; after a
// cut lowers the limit below a fixed step, the run stops as refused (exit 4).
TEST(Simulation, RefusedStepBeforeAndAfterACut) {
    json j = barScene();
    j["integrator"] = {{"dt", {{"mode", "fixed"}, {"value", 1.0}}}};
    EXPECT_THROW(makeSim(j), InputError);
    Simulation probe = makeSim(barScene());
    j["integrator"]["dt"]["value"] = 0.999 * probe.initialLimits().exact;
    Simulation sim = makeSim(j);
    sim.step();
    CutSurface sliver;  // a cut just inside the free end's last layer lowers the exact step a little
    sliver.point = Eigen::Vector3d(0.0955, 0, 0);
    sliver.normal = Eigen::Vector3d(1, 0.3, 0.1).normalized();
    sim.cut(sliver, "sliver");
    ASSERT_LT(sim.limits().exact, j["integrator"]["dt"]["value"].get<double>());
    EXPECT_EQ(sim.status(), RunStatus::Refused);
    EXPECT_NE(sim.message().find("after the cut"), std::string::npos) << sim.message();
    const long steps = sim.state().steps;
    EXPECT_EQ(sim.step(), RunStatus::Refused);  // no more steps
    EXPECT_EQ(sim.state().steps, steps);
}

// A blow-up is caught by the speed bound while every value is still finite.
TEST(Simulation, ABlowUpIsCaughtBeforeItIsNonFinite) {
    json j = barScene();
    j["integrator"] = {{"dt", {{"mode", "fraction"}, {"fraction", 1.5}, {"on_limit", "damp"}}}};
    j["duration"] = 1.0;
    Simulation sim = makeSim(j);
    EXPECT_EQ(sim.limitAction(), LimitAction::Damped);
    EXPECT_EQ(sim.advance(1.0), RunStatus::Diverged);
    EXPECT_TRUE(sim.state().x.allFinite());
    EXPECT_EQ(sim.message().rfind("diverged:", 0), 0u) << sim.message();
}

// The thread count changes only speed: one thread, two, and the measured choice (which switches
// between them as the run goes) give bitwise the same state on a mesh above the parallel threshold.
TEST(Simulation, ThreadCountDoesNotChangeTheState) {
    json j = barScene();
    j["object"]["box"] = {{"size", {0.1, 0.02, 0.02}}, {"cells", {36, 8, 6}}};  // 10,368 tets
    j["duration"] = 0.1;  // ~400 steps: the measured choice switches between 1 and 2 threads
    std::vector<std::uint64_t> hashes;
    for (int threads : {1, 2, 0}) {
        SimulationOptions o;
        o.threads = threads;
        Simulation sim(parseScene(j, "bar.json"), o);
        EXPECT_EQ(sim.advance(1.0), RunStatus::Finished);
        EXPECT_GT(sim.state().steps, 300);
        hashes.push_back(sim.stateHash());
    }
    EXPECT_EQ(hashes[0], hashes[1]);
    EXPECT_EQ(hashes[0], hashes[2]);
}

// A take (sim/take.hpp): the bar with a probe coming down on its free end and a scripted cut at
// x = 5 cm due long after the end; held tools and a cut made due by hand, written back as a
// scene, replay to bitwise the same state.
json probedBar() {
    json j = barScene();
    j["tools"] = json::parse(R"([ { "name": "probe", "kind": "sphere", "radius": 0.005, "keyframes": [
        { "time": 0, "position": [0.08, 0.01, 0.03] },
        { "time": 0.02, "position": [0.08, 0.01, 0.018], "rotation_deg": [0, 20, 0] } ] } ])");
    j["cutting"] = json::parse(R"({ "cuts": [ { "time": 5, "point": [0.05, 0.01, 0.01], "normal": [1, 0, 0] } ] })");
    return j;
}

// The hook before a topology change runs before every cut (a scripted one in a step, one ahead of
// its time, a driver's), with the arrays still of their size before it, and never in plain steps.
TEST(Simulation, HookBeforeEveryTopologyChange) {
    json j = barScene();
    j["cutting"] = json::parse(R"({ "cuts": [ { "time": 0.004, "point": [0.03, 0.01, 0.01], "normal": [1, 0, 0] },
                                              { "time": 0.015, "point": [0.07, 0.01, 0.01], "normal": [1, 0, 0] } ] })");
    Simulation sim = makeSim(j);
    std::vector<long> seen;  // node count at each call
    sim.setBeforeTopologyChange([&] { seen.push_back(static_cast<long>(sim.state().x.cols())); });
    const long n0 = sim.model().nodes();
    sim.advance(0.003);
    EXPECT_TRUE(seen.empty());
    sim.advance(0.006);  // the scripted cut at 0.004 s, in a step's cut stage
    ASSERT_EQ(seen.size(), 1u);
    EXPECT_EQ(seen[0], n0);
    const long n1 = sim.model().nodes();
    EXPECT_GT(n1, n0);
    EXPECT_TRUE(sim.cutNextScripted());  // the one at 0.015 s, now
    ASSERT_EQ(seen.size(), 2u);
    EXPECT_EQ(seen[1], n1);
    CutDef cd;
    cd.point = Eigen::Vector3d(0.05, 0.01, 0.01);
    cd.normal = Eigen::Vector3d::UnitX();
    sim.cut(cutSurfaceOf(cd), "driver");
    EXPECT_EQ(seen.size(), 3u);
    sim.advance(0.02);
    EXPECT_EQ(seen.size(), 3u);
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

// What a driver does is logged, not written into the scene: the scene stays as read, and the take
// is the scene with the log applied.
TEST(Take, DriverActionsLeaveTheSceneAsRead) {
    SimulationOptions o;
    o.threads = 1;
    const SceneDef sc = parseScene(probedBar(), "bar.json");
    Simulation live(sc, o);
    live.advance(0.005);
    live.holdTool(0, Eigen::Vector3d(0.08, 0.01, 0.0235));
    EXPECT_EQ(live.dueNextScripted(), 0);
    StepPolicy p = sc.dt;
    p.fraction *= 0.5;
    EXPECT_EQ(live.setPolicy(sc.integrator, p), "");
    live.advance(0.01);
    ASSERT_EQ(live.record().cuts.size(), 1u);
    EXPECT_EQ(live.scene().cutting.cuts[0].time, sc.cutting.cuts[0].time);
    EXPECT_EQ(live.scene().tools[0].keys.size(), sc.tools[0].keys.size());
    EXPECT_EQ(live.scene().dt.fraction, sc.dt.fraction);
    EXPECT_EQ(live.report()["dt_policy"]["fraction"].get<double>(), p.fraction);
    ASSERT_EQ(live.takeLog().holds.size(), 1u);
    EXPECT_EQ(live.takeLog().cutTime(live.scene(), 0), live.record().cuts[0]["time"].get<double>());
    const json take = takeScene(live, "take.json");
    EXPECT_EQ(take["cutting"]["cuts"][0]["time"].get<double>(), live.record().cuts[0]["time"].get<double>());
    EXPECT_EQ(take["tools"][0]["keyframes"].size(),
              sc.tools[0].keys.size() + 1);  // the first key, the pose at the hold, the held pose
}

// A probe lowered by holds (a haptic device's samples) and then held still keeps pressing: its
// force 100 ms after the last hold is the force at it, not decayed towards 0.
TEST(Take, HeldProbeKeepsItsForce) {
    const json j = json::parse(R"({ "name": "held",
        "object": { "box": { "size": [0.1, 0.1, 0.02], "cells": [10, 10, 2] } },
        "material": { "E": 30000, "nu": 0.3, "rho": 1000, "damping": 20.0 },
        "fixed": [ { "plane": { "point": [0, 0, 0], "normal": [0, 0, 1], "distance": 1e-4 } } ],
        "loads": { "gravity": [0, 0, 0] },
        "integrator": { "scheme": "symplectic_euler", "dt": { "mode": "fraction", "of": "exact", "fraction": 0.8 } },
        "tools": [ { "name": "probe", "kind": "sphere", "radius": 0.01,
                     "keyframes": [ { "time": 0, "position": [0.05, 0.05, 0.03] } ] } ],
        "contact": { "spacing": 0.004 },
        "duration": 1, "capture": { "enabled": false }, "output": { "vtu": false } })");
    SimulationOptions o;
    o.threads = 1;
    Simulation sim(parseScene(j, "held.json"), o);
    sim.advance(0.005);
    const double t0 = sim.state().time;
    for (int k = 1; k <= 40; ++k) {  // 2 mm in over 40 ms, a sample a millisecond
        sim.holdTool(0, Eigen::Vector3d(0.05, 0.05, 0.03 - 0.002 * k / 40.0));
        sim.advance(t0 + 0.001 * k);
    }
    sim.advance(sim.state().time + 0.02);  // settled
    const double held = sim.contact()->last().reaction[0].norm();
    EXPECT_GT(held, 0.1);
    sim.advance(sim.state().time + 0.1);
    EXPECT_GT(sim.contact()->last().contacts, 0);
    EXPECT_NEAR(sim.contact()->last().reaction[0].norm(), held, 0.05 * held);
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

std::string inputErrorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

// --set reaches array elements by index (tools.0.radius), never past an array's end.
json barWithTool() {
    json j = barScene();
    j["tools"] =
        json::parse(R"([{"kind": "sphere", "radius": 0.01, "keyframes": [{"position": [0.05, 0.01, 0.05]}]}])");
    return j;
}

TEST(Scene, SetReachesArrayElementsByIndex) {
    const json j = applySets(barWithTool(), {"tools.0.radius=0.02", "tools.0.keyframes.0.position.2=0.07"});
    const SceneDef s = parseScene(j, "bar.json");
    EXPECT_EQ(s.tools.at(0).radius, 0.02);
    EXPECT_EQ(s.tools.at(0).keys.at(0).pose.position.z(), 0.07);
    EXPECT_NE(
        inputErrorOf([] { applySets(barWithTool(), {"tools.1.radius=0.02"}); }).find("not an index of an array of 1"),
        std::string::npos);
    EXPECT_NE(inputErrorOf([] { applySets(barWithTool(), {"tools.x.radius=0.02"}); }).find("'x' is not an index"),
              std::string::npos);
    EXPECT_NE(inputErrorOf([] { applySets(barScene(), {"duration.x=1"}); }).find("inside a non-object"),
              std::string::npos);
}

// object.mesh given inline (as the Python bindings pass numpy arrays) runs bitwise as the generated box.
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
    EXPECT_NE(inputErrorOf([&] { parseScene(j, "inline.json"); }).find("inline.json: object.mesh.tets: tet 3"),
              std::string::npos);
    j["object"]["mesh"].erase("nodes");
    EXPECT_NE(inputErrorOf([&] { parseScene(j, "inline.json"); }).find("object.mesh.nodes: is required"),
              std::string::npos);
}

// The step through cuts (cutting.step_floor, object.element "hybrid"): the bar with a wedge cut
// 1.5 mm from its free end, which leaves nearly free elements (the exact step falls to ~0.86 of
// the uncut one without a floor).
json wedgeScene() {
    json j = barScene();
    j["duration"] = 0.01;
    j["cutting"] = {{"cuts", {{{"time", 0.002}, {"point", {0.0985, 0.015, 0.015}}, {"normal", {1, 0.5, 0}}}}}};
    return j;
}

json run(const json& scene) {
    SimulationOptions o;
    o.threads = 1;
    Simulation sim(parseScene(scene, "bar.json"), o);
    sim.advance(1.0);
    return sim.report();
}

TEST(CutStep, FloorHoldsWhereTheCutLostTheStep) {
    json off = wedgeScene();
    off["cutting"]["step_floor"] = 0;
    const json a = run(off);
    ASSERT_EQ(a["cuts"].size(), 1u);
    EXPECT_LT(a["cuts"][0]["dt_ratio"].get<double>(), 0.9);
    EXPECT_TRUE(a["cuts"][0]["step_floor"].is_null());
    EXPECT_EQ(a["mass"]["step_floor_added"].get<double>(), 0.0);

    const json b = run(wedgeScene());  // default 0.95
    ASSERT_EQ(b["cuts"].size(), 1u);
    const json& c = b["cuts"][0];
    EXPECT_GE(c["dt_ratio"].get<double>(), 0.95 * (1 - 1e-6));
    EXPECT_GT(c["step_floor"]["added_mass"].get<double>(), 0.0);
    EXPECT_DOUBLE_EQ(b["mass"]["step_floor_added"].get<double>(), c["step_floor"]["added_mass"].get<double>());
    // the mass the floor added is in the model: final = initial + added (the cut itself keeps mass)
    EXPECT_NEAR(b["mass"]["final"].get<double>(),
                b["mass"]["initial"].get<double>() + b["mass"]["step_floor_added"].get<double>(), 1e-12);
    EXPECT_LT(b["mass"]["step_floor_added"].get<double>() / b["mass"]["initial"].get<double>(), 5e-3);
    EXPECT_EQ(b["status"], "ok");
}

// cutting.floor_method "hybrid": the wedge cut's elements under the floor are matched by shape
// first; the floor still holds (certified by the exact step), with less mass than mass alone.
TEST(CutStep, HybridFloorMatchesFirstAndAddsLessMass) {
    const json mass = run(wedgeScene());
    json j = wedgeScene();
    j["cutting"]["floor_method"] = "hybrid";
    const json r = run(j);
    EXPECT_EQ(r["status"], "ok");
    ASSERT_EQ(r["cuts"].size(), 1u);
    const json& c = r["cuts"][0];
    EXPECT_GT(c["step_floor"]["matched"].get<int>(), 0);
    EXPECT_GE(c["dt_ratio"].get<double>(), 0.95 * (1 - 1e-6));
    EXPECT_LT(r["mass"]["step_floor_added"].get<double>(), mass["mass"]["step_floor_added"].get<double>());
    EXPECT_EQ(mass["cuts"][0]["step_floor"]["matched"].get<int>(), 0);
    json bad = wedgeScene();
    bad["cutting"]["floor_method"] = "wax";
    EXPECT_NE(inputErrorOf([&] { parseScene(bad, "bar.json"); }).find("cutting.floor_method"), std::string::npos);
}

// The elements the wedge cut made critical (R1R step under 1.1 dt) are answered by the floor: listed
// with the cut's time, no longer critical, and passed to frames for capture.answered_seconds only.
TEST(CutStep, AnsweredElementsAreShownForAWhile) {
    json j = wedgeScene();
    j["capture"]["answered_seconds"] = 0.003;
    SimulationOptions o;
    o.threads = 1;
    Simulation sim(parseScene(j, "bar.json"), o);
    sim.advance(0.003);
    ASSERT_EQ(sim.record().cutsMade, 1);
    ASSERT_FALSE(sim.answered().empty());
    const Eigen::VectorXd& r1r = sim.analyzer().estimates().r1r;
    for (const Simulation::Answered& a : sim.answered()) {
        EXPECT_NEAR(a.time, 0.002, sim.dt());
        EXPECT_GE(r1r(a.element), 1.1 * sim.dt()) << a.element;  // answered: not critical now
    }
    EXPECT_EQ(sim.criticalElements(), 0);
    EXPECT_EQ(frameInfoOf(sim, 0).answered.size(), sim.answered().size());
    sim.advance(0.0065);
    EXPECT_TRUE(frameInfoOf(sim, 0).answered.empty());
    // Without the floor the step policy answers by a smaller step: the cut still made them critical.
    json off = wedgeScene();
    off["cutting"]["step_floor"] = 0;
    Simulation bare(parseScene(off, "bar.json"), o);
    bare.advance(0.003);
    EXPECT_FALSE(bare.answered().empty());
    EXPECT_LT(bare.dt(), sim.dt());
}

TEST(CutStep, HybridMatchesOnLoadAndAfterTheCut) {
    json j = wedgeScene();
    j["object"]["element"] = "hybrid";
    const json r = run(j);
    EXPECT_EQ(r["status"], "ok");
    const json& h = r["hybrid"];
    EXPECT_DOUBLE_EQ(h["dt_sim"].get<double>(), 0.95 * h["dt_fem_only"].get<double>());
    EXPECT_GE(r["dt_initial"]["exact"].get<double>(), h["dt_fem_only"].get<double>());
    ASSERT_EQ(r["cuts"].size(), 1u);
    const json& c = r["cuts"][0];
    EXPECT_GT(c["hybrid"]["added"].get<int>(), 0);
    EXPECT_GE(c["dt_after"]["exact"].get<double>(), h["dt_sim"].get<double>());
    EXPECT_TRUE(c["step_floor"].is_null());
    EXPECT_EQ(r["mass"]["final"].get<double>(), r["mass"]["initial"].get<double>());  // no mass added
    EXPECT_EQ(h["matched_final"].get<int>(), h["matched"].get<int>() + c["hybrid"]["added"].get<int>());
}

TEST(CutStep, BadKeysAreNamed) {
    json a = wedgeScene();
    a["cutting"]["step_floor"] = 1.5;
    json b = wedgeScene();
    b["object"]["element"] = "hybird";
    json c = wedgeScene();
    c["object"]["match_stiffness"] = 0;
    for (const auto& [scene, key] :
         {std::pair{a, "step_floor"}, std::pair{b, "element"}, std::pair{c, "match_stiffness"}}) {
        try {
            parseScene(scene, "bar.json");
            ADD_FAILURE() << key << " accepted";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
        }
    }
}

}  // namespace
}  // namespace cutsim
