// The probe scene end to end (`cutsim run`): the force on the probe grows with depth, returns to
// zero once the probe has left, and the surface is not left inside it. Scenes without tools make
// no Bullet world. Bad tool keys are refused with their key path.
#include "sim/simulation.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include <unistd.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string workDir(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("cutsim_contact_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir.string();
}

json runReport(const std::string& scene, const std::string& out, const std::string& sets = "") {
    std::string err;
    const int code = test::runCutsim("run " + scene + " --out " + out + " --no-render --quiet " + sets, nullptr, &err);
    EXPECT_EQ(code, 0) << err;
    std::ifstream in(out + "/report.json");
    return json::parse(in);
}

// Mean of a series over [t0, t1).
double meanOver(const json& s, const std::string& key, double t0, double t1) {
    double sum = 0;
    int n = 0;
    for (size_t i = 0; i < s["time"].size(); ++i) {
        const double t = s["time"][i].get<double>();
        if (t >= t0 && t < t1) {
            sum += s[key][i].get<double>();
            ++n;
        }
    }
    return n ? sum / n : std::nan("");
}

TEST(Probe, ForceGrowsWithDepthAndVanishesAfterWithdrawal) {
    const std::string out = workDir("probe") + "/out";
    const json r = runReport(test::source("assets/scenes/probe.json"), out);
    ASSERT_TRUE(r.contains("tool"));
    const json& tool = r["tool"];
    const json& s = tool["series"];
    // the probe (radius 1 cm) goes down 12 mm from t = 0.1 s to 0.5 s, stays until 0.6 s, leaves by 1 s
    ASSERT_GT(s["time"].size(), 1000u);
    // pressing: the upward reaction, averaged over 50 ms windows, grows window after window
    double prev = 0;
    for (int w = 0; w < 5; ++w) {
        const double t = 0.25 + 0.05 * w;
        const double f = meanOver(s, "fy", t, t + 0.05);
        EXPECT_GT(f, prev) << "window at " << t << " s";
        prev = f;
    }
    EXPECT_GT(prev, 0.3);  // a firm push at full depth [N]
    EXPECT_GT(tool["max_force"].get<double>(), 0.5);
    // the probe has left: no force at all in the last 0.3 s, nothing inside it at the end
    EXPECT_EQ(meanOver(s, "max", 1.0, 1.3), 0.0);
    EXPECT_EQ(tool["final_depth"].get<double>(), 0.0);
    // never deeper than 2 mm (a fifth of the radius) inside the probe
    EXPECT_LT(tool["max_depth"].get<double>(), 0.002);
    EXPECT_GT(tool["contact_steps"].get<long>(), 100);
    EXPECT_GT(r["stages"]["contact"].get<double>(), 0.0);
    EXPECT_EQ(r["status"], "ok");
}

TEST(Probe, SceneWithoutToolHasNoContactStage) {
    const std::string out = workDir("notool") + "/out";
    const json r = runReport(test::source("assets/scenes/bar_sag.json"), out, "--set duration=0.01");
    EXPECT_FALSE(r.contains("tool"));
    EXPECT_EQ(r["stages"]["contact"].get<double>(), 0.0);
}

TEST(Probe, TooStiffPenaltyIsLoweredToTheStableLimit) {
    const std::string dir = workDir("stiff");
    std::ifstream in(test::source("assets/scenes/probe.json"));
    json j = json::parse(in);
    j["object"]["mesh"] = test::source("assets/meshes/liver.msh");
    j["object"]["visual"] = test::source("assets/meshes/sofa_liver-smooth.obj");
    j["duration"] = 0.01;
    j["tools"][0]["stiffness"] = 1e9;
    j["contact"]["model"] = "penalty";  // the projection model has no stiffness
    const std::string p = dir + "/s.json";
    std::ofstream(p) << j.dump();
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + p + " --out " + dir + "/out --no-render --quiet", nullptr, &err), 0) << err;
    EXPECT_NE(err.find("above the stable limit"), std::string::npos) << err;
    std::ifstream rin(dir + "/out/report.json");
    const json r = json::parse(rin);
    const json& tool = r["tool"];
    EXPECT_EQ(tool["stiffness_clamped"], json::array({"probe"}));
    EXPECT_EQ(tool["stiffness"][0].get<double>(), tool["stiffness_limit"].get<double>());
    EXPECT_LT(tool["stiffness_limit"].get<double>(), 1e9);
    ASSERT_EQ(r["warnings"].size(), 1u);
    EXPECT_EQ(r["warnings"][0]["kind"], "tool_stiffness_clamped");
    EXPECT_EQ(r["warnings"][0]["count"], 1);
    // the library records it and prints nothing: the program says it once
    EXPECT_EQ(err.find("warning: "), err.rfind("warning: "));
    const Simulation sim(parseScene(j, p), SimulationOptions{1, false});
    const WarningStat& w = sim.record().warnings[Warning::ToolStiffnessClamped];
    EXPECT_EQ(w.count, 1);
    EXPECT_NE(w.first.find("tool probe: stiffness 1e+09 N/m is above the stable limit"), std::string::npos) << w.first;
    EXPECT_EQ(sim.record().warnings[Warning::KeepStepMass].count, 0);
}

TEST(Probe, BadToolKeysAreRefusedWithTheirPath) {
    const std::string scene = test::source("assets/scenes/probe.json");
    const std::string dir = workDir("bad");
    // edit the scene text: a missing radius, an unknown key, a reversed keyframe order
    std::ifstream in(scene);
    json base = json::parse(in);
    base["object"]["mesh"] = test::source("assets/meshes/liver.msh");
    base["object"]["visual"] = test::source("assets/meshes/sofa_liver-smooth.obj");
    auto expectRefused = [&](json j, const std::string& key) {
        const std::string p = dir + "/s.json";
        std::ofstream(p) << j.dump();
        const std::string out = dir + "/never";
        std::string err;
        const int code = test::runCutsim("run " + p + " --out " + out + " --no-render --quiet", nullptr, &err);
        EXPECT_EQ(code, 2) << err;
        EXPECT_NE(err.find(key), std::string::npos) << "expected '" << key << "' in: " << err;
        EXPECT_FALSE(fs::exists(out));
    };
    json j = base;
    j["tools"][0].erase("radius");
    expectRefused(j, "tools[0].radius");
    j = base;
    j["tools"][0]["shape"] = "round";
    expectRefused(j, "tools[0].shape");
    j = base;
    j["tools"][0]["keyframes"][1]["time"] = -1;
    expectRefused(j, "tools[0].keyframes[1].time");
    j = base;
    j["tools"][0]["kind"] = "hull";
    j["tools"][0]["obj"] = "missing.obj";
    j["tools"][0].erase("radius");
    expectRefused(j, "tools[0].obj");
}

}  // namespace
}  // namespace cutsim
