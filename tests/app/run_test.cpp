// `cutsim run`: the report.json contract, final.vtu, and refusal of bad scenes before any output.
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <unistd.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::workDir;

json barSagJson() {
    std::ifstream in(test::source("assets/scenes/bar_sag.json"));
    return json::parse(in);
}

std::string writeScene(const std::string& dir, const std::string& name, const json& j) {
    const std::string p = dir + "/" + name;
    std::ofstream(p) << j.dump(2) << "\n";
    return p;
}

json readReport(const std::string& out) {
    std::ifstream in(out + "/report.json");
    return json::parse(in);
}

// Runs assets/scenes/<name> without frames (plus `extra` flags) into a fresh work folder; its exit
// code, with the report in *report and stderr in *err.
int runShipped(const std::string& name, const std::string& extra, json* report, std::string* err) {
    const std::string out = workDir() + "/out";
    const int rc = test::runCutsim("run " + test::source("assets/scenes/" + name) + " --out " + out +
                                       " --no-render --quiet" + extra,
                                   nullptr, err);
    if (rc == 0) *report = readReport(out);
    return rc;
}

// A bad scene: exit 2, "error:" and the key path on stderr, and no --out folder.
void expectRefused(const std::string& scene, const std::string& sets, const std::string& keyPath,
                   std::string* errOut = nullptr) {
    static int counter = 0;
    const fs::path fresh = fs::temp_directory_path() /
                           ("cutsim_run_never_" + std::to_string(::getpid()) + "_" + std::to_string(++counter));
    fs::remove_all(fresh);
    const std::string out = fresh.string();
    std::string err;
    const int code = test::runCutsim("run " + scene + " --out " + out + " --no-render --quiet " + sets, nullptr, &err);
    EXPECT_EQ(code, 2) << err;
    EXPECT_NE(err.find("error:"), std::string::npos) << err;
    EXPECT_NE(err.find(keyPath), std::string::npos) << "expected '" << keyPath << "' in: " << err;
    EXPECT_FALSE(fs::exists(out)) << "the output folder must not be created for a bad scene";
    if (errOut) *errOut = err;
}

// The number that follows `after` in `text`, or NaN.
double numberAfter(const std::string& text, const std::string& after) {
    const auto p = text.find(after);
    if (p == std::string::npos) return std::nan("");
    return std::strtod(text.c_str() + p + after.size(), nullptr);
}

TEST(Run, BarSagReportHoldsTheContract) {
    const std::string out = workDir() + "/out";
    const std::string scene = test::source("assets/scenes/bar_sag.json");
    std::string err;
    const int code =
        test::runCutsim("run " + scene + " --out " + out + " --no-render --quiet --set duration=0.05", nullptr, &err);
    ASSERT_EQ(code, 0) << err;
    ASSERT_TRUE(fs::exists(out + "/report.json"));
    const json r = readReport(out);

    for (const char* key : {"scene",
                            "name",
                            "status",
                            "steps",
                            "sim_time",
                            "wall_time",
                            "threads",
                            "integrator",
                            "dt",
                            "dt_limit_action",
                            "dt_initial",
                            "critical_elements",
                            "mesh",
                            "cuts",
                            "pieces",
                            "mass",
                            "energy",
                            "inverted",
                            "stages",
                            "frames",
                            "video",
                            "steps_per_second",
                            "real_time_factor"})
        EXPECT_TRUE(r.contains(key)) << key;
    EXPECT_EQ(r["scene"].get<std::string>(), scene);
    EXPECT_EQ(r["name"].get<std::string>(), "bar_sag");
    EXPECT_EQ(r["status"].get<std::string>(), "ok");
    EXPECT_EQ(r["integrator"].get<std::string>(), "symplectic_euler");
    EXPECT_EQ(r["dt_limit_action"].get<std::string>(), "none");

    // Time step: 0.9 of the exact limit, certified below exact.
    const json& d0 = r["dt_initial"];
    for (const char* key : {"exact", "certified", "estimate"}) ASSERT_TRUE(d0.contains(key)) << key;
    const double exact = d0["exact"].get<double>(), certified = d0["certified"].get<double>();
    EXPECT_GT(exact, 0);
    EXPECT_GT(certified, 0);
    EXPECT_LE(certified, exact);
    EXPECT_GT(d0["estimate"].get<double>(), 0);
    const double dt = r["dt"].get<double>();
    EXPECT_EQ(dt, 0.9 * exact);

    // Steps and time: the run covers the duration with a whole number of steps of dt.
    const long steps = r["steps"].get<long>();
    const double simTime = r["sim_time"].get<double>();
    EXPECT_GE(simTime, 0.05);
    EXPECT_LT(simTime, 0.05 + dt + 1e-12);
    EXPECT_EQ(steps, static_cast<long>(std::ceil(0.05 / dt - 1e-9)));
    EXPECT_NEAR(simTime, steps * dt, 1e-9 * simTime);
    EXPECT_GT(r["wall_time"].get<double>(), 0);

    // Mesh: the 40 x 4 x 4 box, 6 tets per cube, clamped at x = 0 (5 x 5 nodes).
    EXPECT_EQ(r["mesh"]["file"].get<std::string>(), "box");
    EXPECT_EQ(r["mesh"]["nodes"].get<int>(), 41 * 5 * 5);
    EXPECT_EQ(r["mesh"]["elements"].get<int>(), 40 * 4 * 4 * 6);
    EXPECT_EQ(r["mesh"]["fixed_nodes"].get<int>(), 25);

    // Topology and mass: no cuts, one piece, mass = rho * volume = 1000 * 1 * 0.1 * 0.1 kg.
    ASSERT_TRUE(r["cuts"].is_array());
    EXPECT_TRUE(r["cuts"].empty());
    EXPECT_EQ(r["pieces"].get<int>(), 1);
    const double m0 = r["mass"]["initial"].get<double>(), m1 = r["mass"]["final"].get<double>();
    EXPECT_EQ(m0, m1);
    EXPECT_NEAR(m0, 1000 * 1.0 * 0.1 * 0.1, 1e-9 * 10.0);

    // Energy: one entry per 1/fps of simulated time from t = 0, plus the final state.
    ASSERT_TRUE(r["energy"].is_array());
    ASSERT_GE(r["energy"].size(), 2u);
    EXPECT_EQ(r["energy"][0]["time"].get<double>(), 0.0);
    EXPECT_NEAR(r["energy"].back()["time"].get<double>(), simTime, 1e-12);
    for (const auto& e : r["energy"]) {
        for (const char* key : {"time", "kinetic", "elastic", "gravity", "total"}) ASSERT_TRUE(e.contains(key)) << key;
        EXPECT_NEAR(e["total"].get<double>(),
                    e["kinetic"].get<double>() + e["elastic"].get<double>() + e["gravity"].get<double>(), 1e-9);
        EXPECT_GE(e["kinetic"].get<double>(), 0);
    }
    EXPECT_EQ(r["energy"][0]["kinetic"].get<double>(), 0.0);      // starts at rest
    EXPECT_GT(r["energy"].back()["kinetic"].get<double>(), 0.0);  // and falls under gravity

    // Stages: all nine (Stage); with --no-render and no tools nor cuts only loads, forces,
    // integrate, checks and timestep take time.
    const json& st = r["stages"];
    EXPECT_EQ(st.size(), 9u);
    for (const char* key : {"loads", "contact", "cut", "forces", "integrate", "checks", "timestep", "render", "encode"})
        ASSERT_TRUE(st.contains(key)) << key;
    for (const char* key : {"contact", "cut", "render", "encode"}) EXPECT_EQ(st[key].get<double>(), 0.0) << key;
    for (const char* key : {"forces", "integrate", "checks", "timestep"}) EXPECT_GT(st[key].get<double>(), 0.0) << key;
    EXPECT_EQ(r["exit_code"].get<int>(), 0);
    EXPECT_EQ(r["state_hash"].get<std::string>().size(), 16u);

    EXPECT_EQ(r["frames"].get<int>(), 0);
    EXPECT_EQ(r["video"].get<std::string>(), "");
    EXPECT_EQ(r["inverted"]["steps"].get<long>(), 0);
    EXPECT_GT(r["steps_per_second"].get<double>(), 0);
    EXPECT_GT(r["real_time_factor"].get<double>(), 0);

    EXPECT_TRUE(fs::exists(out + "/final.vtu"));
    EXPECT_GT(fs::file_size(out + "/final.vtu"), 0u);
    EXPECT_FALSE(fs::exists(out + "/frames"));
    EXPECT_FALSE(fs::exists(out + "/video.mp4"));
    EXPECT_FALSE(fs::exists(out + "/report.json.tmp"));
}

TEST(Run, OutputVtuFalseWritesNoVtu) {
    const std::string out = workDir() + "/out";
    std::string err;
    const int code = test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out +
                                         " --no-render --quiet --set duration=0.01 --set output.vtu=false",
                                     nullptr, &err);
    ASSERT_EQ(code, 0) << err;
    EXPECT_TRUE(fs::exists(out + "/report.json"));
    EXPECT_FALSE(fs::exists(out + "/final.vtu"));
}

// capture.vtu: a .vtu per capture frame (every 1/fps of simulated time and the end), a .pvd
// naming them with their times; displacement a vector of 3 components per node, stress and step per
// element. capture.cut_obj: the surface at the end, cut faces in their own group.
TEST(Run, VtuSeriesAndCutSurfaceObj) {
    const std::string out = workDir() + "/out";
    std::string err;
    const int code = test::runCutsim("run " + test::source("assets/scenes/liver_cuts.json") + " --out " + out +
                                         " --no-render --quiet --set duration=0.25 --set capture.fps=10"
                                         " --set capture.vtu=true --set capture.cut_obj=true"
                                         " --set 'cutting.compare=[]'",
                                     nullptr, &err);
    ASSERT_EQ(code, 0) << err;
    const std::string pvd = test::readText(out + "/series.pvd");
    int sets = 0;
    for (size_t at = pvd.find("<DataSet"); at != std::string::npos; at = pvd.find("<DataSet", at + 1)) ++sets;
    EXPECT_EQ(sets, 4) << pvd;  // t = 0, 0.1, 0.2 and the end
    EXPECT_NE(pvd.find("timestep=\"0.1"), std::string::npos) << pvd;
    for (int f = 0; f < 4; ++f) {
        char name[40];
        std::snprintf(name, sizeof name, "/vtu/frame_%06d.vtu", f);
        const std::string v = test::readText(out + name);
        EXPECT_NE(v.find("Name=\"displacement\" NumberOfComponents=\"3\""), std::string::npos) << name;
        EXPECT_NE(v.find("Name=\"von_mises\""), std::string::npos) << name;
        EXPECT_NE(v.find("Name=\"dt_r1r\""), std::string::npos) << name;
        EXPECT_NE(v.find("Name=\"critical\""), std::string::npos) << name;
    }
    const std::string obj = test::readText(out + "/cut_surface.obj");
    const size_t cut = obj.find("g cut\n");
    ASSERT_NE(cut, std::string::npos);
    EXPECT_NE(obj.find("\nf ", cut), std::string::npos) << "the cut at t = 0.2 s made faces";
}

TEST(Run, RefusesUnknownKey) {
    json j = barSagJson();
    j["material"]["Young"] = 1e6;
    expectRefused(writeScene(workDir(), "unknown.json", j), "", "material.Young");
    // the same through --set
    expectRefused(test::source("assets/scenes/bar_sag.json"), "--set material.Young=1e6", "material.Young");
}

TEST(Run, RefusesWrongType) {
    json j = barSagJson();
    j["material"]["E"] = "soft";
    std::string err;
    expectRefused(writeScene(workDir(), "type.json", j), "", "material.E", &err);
    EXPECT_NE(err.find("number"), std::string::npos) << err;
}

TEST(Run, RefusesIncompressibleNu) {
    json j = barSagJson();
    j["material"]["nu"] = 0.5;
    expectRefused(writeScene(workDir(), "nu.json", j), "", "material.nu");
}

TEST(Run, RefusesZeroAndNegativeE) {
    json j = barSagJson();
    j["material"]["E"] = 0;
    expectRefused(writeScene(workDir(), "e0.json", j), "", "material.E");
    j["material"]["E"] = -1e6;
    expectRefused(writeScene(workDir(), "eneg.json", j), "", "material.E");
    expectRefused(test::source("assets/scenes/bar_sag.json"), "--set integrator.min_stretch=1.5",
                  "integrator.min_stretch");
}

// integrator.solver: the implicit scheme's linear solver, refused on an explicit scheme; the
// report says which solver ran and how many CG iterations its steps took.
TEST(Run, ImplicitSolverKey) {
    const std::string bar = test::source("assets/scenes/bar_sag.json");
    expectRefused(bar, "--set integrator.solver=cg", "integrator.solver");
    expectRefused(bar, "--set integrator.scheme=backward_euler --set integrator.solver=lu", "integrator.solver");
    for (const char* solver : {"direct", "cg"}) {
        json j = barSagJson();
        j["integrator"] = {
            {"scheme", "backward_euler"}, {"solver", solver}, {"dt", {{"mode", "fixed"}, {"value", 0.002}}}};
        j["duration"] = 0.02;
        const std::string out = workDir() + "/" + solver;
        std::string err;
        ASSERT_EQ(test::runCutsim("run " + writeScene(workDir(), std::string(solver) + ".json", j) + " --out " + out +
                                      " --no-render --quiet",
                                  nullptr, &err),
                  0)
            << err;
        const json r = readReport(out);
        EXPECT_EQ(r["steps"].get<long>(), 10);
        EXPECT_EQ(r["implicit"]["solver"].get<std::string>(), solver);
        if (std::string(solver) == "cg")
            EXPECT_GT(r["implicit"]["cg_iterations_max"].get<int>(), 0);
        else
            EXPECT_EQ(r["implicit"]["cg_iterations_max"].get<int>(), 0);
    }
}

// integrator.precision: single runs the element forces in float, refused on the implicit scheme
// and for an unknown value; the report says which ran, and the sagging bar's elastic energy after
// 0.2 s is the double run's to 1e-4 (strains ~1e-3 against float's ~6e-8 on F).
TEST(Run, ForcePrecisionKey) {
    const std::string bar = test::source("assets/scenes/bar_sag.json");
    expectRefused(bar, "--set integrator.precision=half", "integrator.precision");
    expectRefused(bar, "--set integrator.scheme=backward_euler --set integrator.precision=single",
                  "integrator.precision");
    double elastic[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
        const std::string precision = k ? "single" : "double";
        const std::string out = workDir() + "/" + precision;
        std::string err;
        ASSERT_EQ(test::runCutsim("run " + bar + " --out " + out +
                                      " --no-render --quiet --set duration=0.2 --set integrator.precision=" + precision,
                                  nullptr, &err),
                  0)
            << err;
        const json r = readReport(out);
        EXPECT_EQ(r["force_precision"].get<std::string>(), precision);
        ASSERT_FALSE(r["energy"].empty());
        elastic[k] = r["energy"].back()["elastic"].get<double>();
    }
    EXPECT_GT(elastic[0], 0);
    EXPECT_NE(elastic[1], elastic[0]);
    EXPECT_NEAR(elastic[1] / elastic[0], 1.0, 1e-4);
}

TEST(Run, RefusesMissingMeshFile) {
    json j = barSagJson();
    j["object"] = {{"mesh", "nope.msh"}};
    std::string err;
    expectRefused(writeScene(workDir(), "mesh.json", j), "", "object.mesh", &err);
    EXPECT_NE(err.find("nope.msh"), std::string::npos) << err;
}

TEST(Run, RefusesInvalidJsonNamingTheLine) {
    const std::string p = workDir() + "/broken.json";
    std::ofstream(p) << "{\n"
                        "  \"object\": { \"box\": { \"size\": [1.0, 0.1, 0.1], \"cells\": [4, 1, 1] } },\n"
                        "  \"material\": { \"E\": 1.0e6,, \"nu\": 0.3 },\n"
                        "  \"duration\": 0.01\n"
                        "}\n";
    std::string err;
    expectRefused(p, "", "broken.json:3:", &err);
    EXPECT_NE(err.find("invalid JSON"), std::string::npos) << err;
}

TEST(Run, RefusesFixedStepAboveTheExactLimit) {
    const std::string scene = test::source("assets/scenes/bar_sag.json");
    // The exact limit of this scene, from a short valid run.
    const std::string ref = workDir() + "/ref";
    std::string err;
    ASSERT_EQ(
        test::runCutsim("run " + scene + " --out " + ref + " --no-render --quiet --set duration=0.001", nullptr, &err),
        0)
        << err;
    const double exact = readReport(ref)["dt_initial"]["exact"].get<double>();

    json j = barSagJson();
    j["integrator"]["dt"] = {{"mode", "fixed"}, {"value", 1.0}};
    expectRefused(writeScene(workDir(), "fixed.json", j), "", "integrator.dt", &err);
    EXPECT_NE(err.find("on_limit"), std::string::npos) << err;
    // the message states the exact limit (to the precision it prints)
    const double said = numberAfter(err, "exact stable limit ");
    EXPECT_NEAR(said, exact, 0.01 * exact) << err;

    // the same through --set
    expectRefused(scene, "--set 'integrator.dt={\"mode\":\"fixed\",\"value\":1.0}'", "integrator.dt");
}

TEST(Run, RefusalStatesASmallExactLimitPrecisely) {
    // A stiff material puts the exact limit near 1e-7 s; the message must still state it.
    const std::string scene = test::source("assets/scenes/bar_sag.json");
    const std::string stiff = "--set material.E=1e12 --set duration=1e-6";
    const std::string ref = workDir() + "/ref";
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + scene + " --out " + ref + " --no-render --quiet " + stiff, nullptr, &err), 0)
        << err;
    const double exact = readReport(ref)["dt_initial"]["exact"].get<double>();
    ASSERT_LT(exact, 1e-6);

    expectRefused(scene, stiff + " --set 'integrator.dt={\"mode\":\"fixed\",\"value\":1e-3}'", "integrator.dt", &err);
    const double said = numberAfter(err, "exact stable limit ");
    EXPECT_NEAR(said, exact, 0.01 * exact) << err;
}

TEST(Run, ClampsAFixedStepWhenAsked) {
    const std::string out = workDir() + "/out";
    std::string err;
    const int code = test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out +
                                         " --no-render --quiet --set duration=0.01"
                                         " --set 'integrator.dt={\"mode\":\"fixed\",\"value\":1.0}'"
                                         " --set integrator.dt.on_limit=\"clamp\"",
                                     nullptr, &err);
    ASSERT_EQ(code, 0) << err;
    const json r = readReport(out);
    EXPECT_EQ(r["status"].get<std::string>(), "ok");
    EXPECT_EQ(r["dt_limit_action"].get<std::string>(), "clamped");
    const double dt = r["dt"].get<double>(), exact = r["dt_initial"]["exact"].get<double>();
    EXPECT_LT(dt, exact);
    EXPECT_GT(dt, 0.9 * exact);  // clamped just below the limit, not to something tiny
    EXPECT_GE(r["sim_time"].get<double>(), 0.01);
}

TEST(Run, RefusesAFixedRegionThatSelectsNoNode) {
    json j = barSagJson();
    j["fixed"] = json::parse(R"([{"box": {"min": [5, 5, 5], "max": [6, 6, 6]}}])");
    std::string err;
    expectRefused(writeScene(workDir(), "nofix.json", j), "", "fixed[0]", &err);
    EXPECT_NE(err.find("selects no node"), std::string::npos) << err;
}

// A fixed step of 1/60 s on the bar, 41x its exact limit, with on_limit "damp": the per-element
// damping cannot hold it and the state blows up. The run must say so (exit 3, ExitCode::Diverged)
// long before a value is non-finite, name the damp policy, and write no final.vtu.
TEST(Run, DampedStepThatBlowsUpIsDiverged) {
    const std::string out = workDir() + "/out";
    std::string err;
    const int code = test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out +
                                         " --no-render --quiet"
                                         " --set 'integrator.dt={\"mode\":\"fixed\",\"value\":0.016666666666666666,"
                                         "\"on_limit\":\"damp\"}'",
                                     nullptr, &err);
    EXPECT_EQ(code, 3) << err;
    const json r = readReport(out);
    const std::string status = r["status"];
    EXPECT_EQ(status.rfind("diverged:", 0), 0u) << status;
    EXPECT_NE(status.find("on_limit \"damp\" could not hold"), std::string::npos) << status;
    EXPECT_EQ(r["exit_code"].get<int>(), 3);
    EXPECT_EQ(r["dt_limit_action"].get<std::string>(), "damped");
    EXPECT_LT(r["steps"].get<long>(), 90);  // 1.5 s would be 90 steps: stopped early
    EXPECT_FALSE(fs::exists(out + "/final.vtu"));
    // Still finite and far from the 1e181 m the unchecked run reached.
    for (const auto& e : r["energy"]) EXPECT_TRUE(e["total"].is_number()) << e;
    EXPECT_LT(r["checks"]["displacement_seen"].get<double>(), 1e3);
}

// Each bound is a failure of its own: a speed bound below what the sagging bar reaches trips the
// speed check, with the key named.
TEST(Run, SpeedAboveTheCheckIsDiverged) {
    const std::string out = workDir() + "/out";
    std::string err;
    const int code = test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out +
                                         " --no-render --quiet --set checks.max_speed=0.05",
                                     nullptr, &err);
    EXPECT_EQ(code, 3) << err;
    const std::string status = readReport(out)["status"];
    EXPECT_NE(status.find("above the bound 0.05 m/s"), std::string::npos) << status;
}

// The derived bounds for the bar: c_p = sqrt(E (1 - nu) / ((1 + nu)(1 - 2 nu) rho)) = 36.69 m/s
// (E = 1 MPa, nu = 0.3, rho = 1000), size sqrt(1 + 0.01 + 0.01) = 1.00995 m, T = 1.5 s, g = 9.81:
// speed 10 c_p + g T = 381.61 m/s, displacement 10 L + g T^2 / 2 = 21.136 m.
TEST(Run, DivergenceBoundsFollowTheScene) {
    json r;
    std::string err;
    ASSERT_EQ(runShipped("bar_sag.json", "", &r, &err), 0) << err;
    EXPECT_NEAR(r["checks"]["wave_speed"].get<double>(), 36.6900, 1e-3);
    EXPECT_NEAR(r["checks"]["size"].get<double>(), 1.009950, 1e-5);
    EXPECT_NEAR(r["checks"]["max_speed"].get<double>(), 10 * 36.68997 + 9.81 * 1.5, 1e-2);
    EXPECT_NEAR(r["checks"]["max_displacement"].get<double>(), 10 * 1.0099505 + 0.5 * 9.81 * 2.25, 1e-4);
    EXPECT_LT(r["checks"]["speed_seen"].get<double>(), 0.1 * r["checks"]["max_speed"].get<double>());
    EXPECT_EQ(r["status"].get<std::string>(), "ok");
    EXPECT_EQ(r["exit_code"].get<int>(), 0);
}

// A scene in which nothing can move is refused (exit 2) before anything is written, naming the key.
TEST(Run, RefusesAFixedRegionThatSelectsEveryNode) {
    json j = barSagJson();
    j["fixed"] = json::parse(R"([{"box": {"min": [-1, -1, -1], "max": [2, 2, 2]}}])");
    std::string err;
    expectRefused(writeScene(workDir(), "allfixed.json", j), "", "fixed[0]", &err);
    EXPECT_NE(err.find("every node of the object (1025) is fixed"), std::string::npos) << err;
}

TEST(Run, RefusesAZeroDuration) {
    expectRefused(test::source("assets/scenes/bar_sag.json"), "--set duration=0", "duration");
}

// An object under a millimetre or over ten metres is most likely in the wrong units.
TEST(Run, RefusesAnObjectOfImplausibleSize) {
    std::string err;
    expectRefused(test::source("assets/scenes/bar_sag.json"), "--set object.scale=1e-4", "object.scale", &err);
    EXPECT_NE(err.find("object.any_size"), std::string::npos) << err;
    expectRefused(test::source("assets/scenes/bar_sag.json"), "--set object.scale=20", "object.scale");
    // unless the scene says so
    const std::string out = workDir() + "/out";
    EXPECT_EQ(
        test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out +
                        " --no-render --quiet --set object.scale=20 --set object.any_size=true --set duration=0.01"),
        0);
}

// A step count beyond integrator.max_steps is refused up front, with the count.
TEST(Run, RefusesARunOfTooManySteps) {
    std::string err;
    expectRefused(test::source("assets/scenes/bar_sag.json"), "--set integrator.dt.fraction=1e-9",
                  "integrator.max_steps", &err);
    EXPECT_NE(err.find("3.29e+12 steps"), std::string::npos) << err;
}

TEST(Run, RefusesAnUnwritableOutputBeforeSimulating) {
    const std::string dir = workDir();
    const std::string file = dir + "/a_file";
    std::ofstream(file) << "not a folder\n";
    // A duration that would take minutes to simulate: the refusal must come before the loop.
    const auto t0 = std::chrono::steady_clock::now();
    std::string err;
    const int code = test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + file +
                                         "/out --no-render --quiet --set duration=100",
                                     nullptr, &err);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(code, 2) << err;
    EXPECT_NE(err.find("error:"), std::string::npos) << err;
    EXPECT_NE(err.find(file + "/out"), std::string::npos) << err;
    EXPECT_LT(seconds, 20.0);
    EXPECT_TRUE(fs::is_regular_file(file));
}

TEST(Run, DemoPressesAndCuts) {
    std::string err;
    json r;
    ASSERT_EQ(runShipped("demo.json", "", &r, &err), 0) << err;
    EXPECT_EQ(r["status"].get<std::string>(), "ok");
    EXPECT_TRUE(r["embedding"].is_object());               // the liver given by its surface (MI)
    EXPECT_GT(r["tool"]["max_force"].get<double>(), 0.1);  // the probe presses the sagging liver
    EXPECT_GT(r["tool"]["contact_steps"].get<int>(), 100);
    EXPECT_EQ(r["tool"]["final_force"][1].get<double>(), 0.0);  // and leaves it
    ASSERT_EQ(r["cuts"].size(), 2u);
    EXPECT_GE(r["pieces"].get<int>(), 2);
    EXPECT_GT(r["stages"]["contact"].get<double>(), 0.0);
    EXPECT_GT(r["stages"]["cut"].get<double>(), 0.0);
}

TEST(Run, DemoMiPressesTheEmbeddedSurface) {
    // the embedded liver at half its exact step: the probe is held by the mass-scaled penalty at
    // its exact limit (contact/contact.hpp), not by the lightest embedded node (0.05 N, 9 mm before)
    std::string err;
    json r;
    ASSERT_EQ(runShipped("demo_mi.json", "", &r, &err), 0) << err;
    EXPECT_EQ(r["status"].get<std::string>(), "ok");
    EXPECT_TRUE(r["embedding"].is_object());
    EXPECT_GT(r["dt"].get<double>(), 2 * 0.451e-3);  // twice the conforming liver's exact step
    EXPECT_GT(r["tool"]["max_force"].get<double>(), 1.0);
    EXPECT_LT(r["tool"]["max_depth"].get<double>(), 0.006);
    EXPECT_EQ(r["tool"]["final_force"][1].get<double>(), 0.0);
}

TEST(Run, LiverCutsReportEachCut) {
    std::string err;
    json r;
    ASSERT_EQ(runShipped("liver_cuts.json", " --set duration=0.9", &r, &err), 0) << err;
    EXPECT_EQ(r["status"].get<std::string>(), "ok");
    const json& cuts = r["cuts"];
    ASSERT_EQ(cuts.size(), 4u);
    const double exact0 = r["dt_initial"]["exact"].get<double>();
    int prevNodes = r["mesh"]["nodes"].get<int>();
    for (size_t i = 0; i < cuts.size(); ++i) {
        const json& c = cuts[i];
        EXPECT_EQ(c["key"].get<std::string>(), "cutting.cuts[" + std::to_string(i) + "]");
        EXPECT_GT(c["crossed"].get<int>(), 0);
        EXPECT_EQ(c["elements_cut"].get<int>(), c["split"].get<int>());
        EXPECT_NEAR(c["latency"].get<double>(), c["seconds"].get<double>() + c["update_seconds"].get<double>(), 1e-12);
        EXPECT_GT(c["new_nodes"].get<int>(), 0);
        EXPECT_EQ(c["nodes"].get<int>(), prevNodes + c["new_nodes"].get<int>());
        prevNodes = c["nodes"].get<int>();
        // virtual elements keep volume and mass exactly (the pieces partition their parent)
        EXPECT_LT(std::abs(c["volume_change"].get<double>()), 1e-12);
        EXPECT_LT(std::abs(c["mass_change"].get<double>()), 1e-12);
        // the limit after the cut: certified <= exact, ratio as reported, and the step below it
        const double ex = c["dt_after"]["exact"].get<double>();
        EXPECT_LE(c["dt_after"]["certified"].get<double>(), ex);
        EXPECT_NEAR(c["dt_ratio"].get<double>(), ex / exact0, 1e-12);
        EXPECT_GT(c["dt_ratio"].get<double>(), 0.5);
        EXPECT_LT(c["dt_used"].get<double>(), ex);
    }
    EXPECT_EQ(r["mesh"]["nodes_final"].get<int>(), prevNodes);
    EXPECT_GE(cuts.back()["pieces"].get<int>(), 3);
    EXPECT_EQ(cuts.back()["merged_pieces"].get<int>(), 2);  // two slivers of the fourth plane fused back
    EXPECT_EQ(r["pieces"].get<int>(), cuts.back()["pieces"].get<int>());
    EXPECT_EQ(r["piece_volumes"].size(), r["pieces"].get<size_t>());
    EXPECT_NEAR(r["mass"]["final"].get<double>(), r["mass"]["initial"].get<double>(),
                1e-12 * r["mass"]["initial"].get<double>());

    // The same planes by each method, in one setting (thesis sec. 5.2): XFEM keeps the step that
    // conforming subdivision and remeshing lose.
    const json& cmp = r["compare"];
    for (const char* m : {"xfem", "subdivision", "subdivision_improve", "remesh"}) {
        ASSERT_TRUE(cmp.contains(m)) << m;
        ASSERT_EQ(cmp[m]["dt_ratio"].size(), 4u) << m;
        for (const auto& q : cmp[m]["dt_ratio"]) EXPECT_LE(q.get<double>(), 1.0 + 1e-9) << m;
    }
    EXPECT_NEAR(cmp["xfem"]["dt_ratio"][0].get<double>(), 1.0, 1e-6);  // cut 1 crosses no sliver in this mesh
    EXPECT_GT(cmp["xfem"]["dt_ratio"][3].get<double>(), 2 * cmp["subdivision"]["dt_ratio"][3].get<double>());
    EXPECT_GT(cmp["xfem"]["dt_ratio"][3].get<double>(), 2 * cmp["remesh"]["dt_ratio"][3].get<double>());
    // the local improvement after each conforming cut wins back part of what it lost
    for (int k = 0; k < 3; ++k)
        EXPECT_GT(cmp["subdivision_improve"]["dt_ratio"][k].get<double>(),
                  1.3 * cmp["subdivision"]["dt_ratio"][k].get<double>())
            << "cut " << k + 1;
}

// The scene's cutting options reach the engine: without fusing, the fourth plane's two slivers
// stay loose pieces; out-of-range values are refused with their key.
TEST(Run, CuttingOptionsReachTheEngine) {
    std::string err;
    json r;
    ASSERT_EQ(runShipped("liver_cuts.json", " --set duration=0.81 --set cutting.merge_debris=false", &r, &err), 0)
        << err;
    ASSERT_EQ(r["cuts"].size(), 4u);
    for (const json& c : r["cuts"]) EXPECT_EQ(c["merged_pieces"].get<int>(), 0);
    EXPECT_EQ(r["pieces"].get<int>(), 6);
    std::ifstream in(test::source("assets/scenes/liver_cuts.json"));
    const json j0 = json::parse(in);
    for (const auto& [key, bad] : std::vector<std::pair<std::string, json>>{
             {"light_share", 0.6}, {"relax_iterations", -1}, {"merge_debris", "yes"}}) {
        json j = j0;
        j["object"]["mesh"] = test::source("assets/meshes/liver.msh");
        j["object"]["visual"] = test::source("assets/meshes/sofa_liver-smooth.obj");
        j["cutting"][key] = bad;
        expectRefused(writeScene(workDir(), "opt_" + key + ".json", j), "", "cutting." + key);
    }
}

TEST(Run, RefusesCompareWithABoundedCut) {
    std::ifstream in(test::source("assets/scenes/liver_cuts.json"));
    json j = json::parse(in);
    j["object"]["mesh"] = test::source("assets/meshes/liver.msh");
    j["object"]["visual"] = test::source("assets/meshes/sofa_liver-smooth.obj");
    j["cutting"]["cuts"][0]["polygon"] = json::parse("[[-0.085, 0, 0], [-0.085, 1, 0], [-0.235, 0, 1]]");
    std::string err;
    expectRefused(writeScene(workDir(), "bounded.json", j), "", "cutting.compare", &err);
}

TEST(Run, RefusesACutWithAZeroNormal) {
    std::ifstream in(test::source("assets/scenes/liver_cuts.json"));
    json j = json::parse(in);
    j["cutting"]["cuts"][1]["normal"] = {0, 0, 0};
    j["object"]["mesh"] = test::source("assets/meshes/liver.msh");
    j["object"]["visual"] = test::source("assets/meshes/sofa_liver-smooth.obj");
    std::string err;
    expectRefused(writeScene(workDir(), "zero.json", j), "", "cutting.cuts[1].normal", &err);
}

TEST(Run, BladeSeparatesTheLiverIntoTwoPieces) {
    std::string err;
    // the stroke is through the sagging liver by t = 0.37 s; the rest of the scene only lets the piece fall
    json r;
    ASSERT_EQ(runShipped("blade.json", " --set duration=0.4", &r, &err), 0) << err;
    EXPECT_EQ(r["status"].get<std::string>(), "ok");
    EXPECT_EQ(r["pieces"].get<int>(), 2);
    const json& cuts = r["cuts"];
    ASSERT_FALSE(cuts.empty());
    const double exact0 = r["dt_initial"]["exact"].get<double>();
    double prevTime = -1;
    int prevNodes = r["mesh"]["nodes"].get<int>();
    for (const json& c : cuts) {
        EXPECT_EQ(c["key"].get<std::string>(), "tools[0]");
        EXPECT_GT(c["time"].get<double>(), prevTime);  // one entry per step that split elements
        prevTime = c["time"].get<double>();
        EXPECT_GT(c["crossed"].get<int>(), 0);
        EXPECT_EQ(c["nodes"].get<int>(), prevNodes + c["new_nodes"].get<int>());
        prevNodes = c["nodes"].get<int>();
        EXPECT_LT(std::abs(c["volume_change"].get<double>()), 1e-9);
        EXPECT_LT(std::abs(c["mass_change"].get<double>()), 1e-9);
        // a blade step defers the exact step to the stroke's end: the certified bound backs it
        EXPECT_TRUE(c["exact_deferred"].get<bool>());
        EXPECT_TRUE(c["dt_after"]["exact"].is_null());
        EXPECT_LE(c["dt_used"].get<double>(), 0.9 * c["dt_after"]["certified"].get<double>() * (1 + 1e-12));
    }
    // the stroke, ended by the run's end, solved its exact step once
    ASSERT_EQ(r["strokes"].size(), 1u);
    const json& stroke = r["strokes"][0];
    EXPECT_EQ(stroke["blade_steps"].get<size_t>(), cuts.size());
    EXPECT_GT(stroke["exact_after"].get<double>(), 0.5 * exact0);
    EXPECT_NEAR(stroke["dt_after"].get<double>(), 0.9 * stroke["exact_after"].get<double>(), 1e-12 * exact0);
    // the stroke splits the liver in two (a blade step's entry leaves the count to its stroke's)
    for (const json& c : cuts) EXPECT_TRUE(c["pieces"].is_null());
    EXPECT_EQ(r["strokes"][0]["pieces"].get<int>(), 2);
    // all of one stroke: one cut id
    for (const json& c : cuts) EXPECT_EQ(c["cut_id"].get<int>(), cuts.front()["cut_id"].get<int>());
    EXPECT_EQ(r["blade"]["cut_steps"].get<size_t>(), cuts.size());
    // the blade slides in its own cut: no penalty spikes from pressing its cut faces apart (they
    // reached 344 N on this 0.6 kg liver; now about 10 N, as the edge enters the tissue)
    EXPECT_LT(r["tool"]["max_force"].get<double>(), 30.0);
    EXPECT_GT(r["stages"]["cut"].get<double>(), 0.0);
    EXPECT_NEAR(r["mass"]["final"].get<double>(), r["mass"]["initial"].get<double>(),
                1e-9 * r["mass"]["initial"].get<double>());
}

TEST(Run, ProbeToolBuildsNoCutter) {
    std::string err;
    json r;
    ASSERT_EQ(runShipped("probe.json", " --set duration=0.02", &r, &err), 0) << err;
    EXPECT_TRUE(r["cuts"].empty());
    EXPECT_EQ(r["stages"]["cut"].get<double>(), 0.0);
    EXPECT_FALSE(r.contains("blade"));
    EXPECT_EQ(r["pieces"].get<int>(), 1);
}

}  // namespace
}  // namespace cutsim
