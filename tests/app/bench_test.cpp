// `cutsim bench`: each subcommand at test size, its JSON contract and a value derivable by hand.
#include "test_support.hpp"

#include "bench/machine.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string workDir(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("cutsim_bench_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir.string();
}

json runJson(const std::string& args) {
    std::string out, err;
    const int rc = test::runCutsim(args, &out, &err);
    EXPECT_EQ(rc, 0) << err;
    return json::parse(out);
}

// Hand-made points: per problem, a point is on the front when no other point is at most as
// costly and at most as wrong, and better in one of the two.
TEST(BenchAccuracy, ParetoFrontAndSummaryOfHandMadePoints) {
    const std::string dir = workDir("pareto");
    const std::string csv = test::writeText(dir + "/points.csv",
                                            "problem,config,error,wall_per_sim_second,dt,scheme\n"
                                            "p,a,0.1,1,1e-4,explicit\n"      // front: cheapest
                                            "p,b,0.05,2,1e-4,explicit\n"     // front
                                            "p,c,0.05,3,1e-4,explicit\n"     // beaten by b (same error, dearer)
                                            "p,d,0.2,2,1e-4,explicit\n"      // beaten by a and b
                                            "p,e,0.005,50,1e-2,implicit\n"   // front: most accurate
                                            "p,f,0.009,8,1e-4,explicit\n"    // front
                                            "q,g,0.5,100,1e-3,implicit\n");  // alone on its problem's front
    const json j = runJson("bench accuracy --from " + csv + " --json --csv " + dir + "/out.csv");
    ASSERT_EQ(j["points"].size(), 7u);
    EXPECT_FALSE(j.contains("machine"));  // nothing measured here
    const std::string expected = "TTFFTTT";
    for (size_t k = 0; k < 7; ++k) EXPECT_EQ(j["points"][k]["pareto"].get<bool>(), expected[k] == 'T') << "point " << k;
    EXPECT_DOUBLE_EQ(j["summary"]["p"]["best_explicit_cost_at_1pct"].get<double>(), 8.0);
    EXPECT_DOUBLE_EQ(j["summary"]["p"]["implicit_cost_at_1pct"].get<double>(), 50.0);
    EXPECT_TRUE(j["summary"]["q"]["best_explicit_cost_at_1pct"].is_null());
    EXPECT_TRUE(j["summary"]["q"]["implicit_cost_at_1pct"].is_null());
    // finest error both reach on p: explicit 0.009, implicit 0.005 -> 0.009; costs 8 and none
    EXPECT_DOUBLE_EQ(j["summary"]["p"]["common_error"].get<double>(), 0.009);
    EXPECT_DOUBLE_EQ(j["summary"]["p"]["explicit_cost_at_common_error"].get<double>(), 8.0);
    EXPECT_DOUBLE_EQ(j["summary"]["p"]["implicit_cost_at_common_error"].get<double>(), 50.0);
    EXPECT_NE(test::readText(dir + "/out.csv").find("p,f,0.009,8,0.0001,explicit,1"), std::string::npos);
}

TEST(BenchAccuracy, BadCsvNamesFileAndLine) {
    const std::string dir = workDir("badcsv");
    const std::string csv =
        test::writeText(dir + "/bad.csv", "problem,config,error,wall_per_sim_second,dt\np,a,x,1,1\n");
    std::string err;
    EXPECT_EQ(test::runCutsim("bench accuracy --from " + csv, nullptr, &err), 2);
    EXPECT_NE(err.find("bad.csv:2"), std::string::npos) << err;
}

// Without gnuplot, --plot fails up front with a message, not a crash or a half-written file.
TEST(BenchAccuracy, PlotWithoutGnuplotFailsClearly) {
    const std::string dir = workDir("nognuplot");
    const std::string csv =
        test::writeText(dir + "/points.csv", "problem,config,error,wall_per_sim_second,dt\np,a,0.1,1,1\n");
    const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
    ::setenv("PATH", dir.c_str(), 1);
    std::string err;
    const int rc = test::runCutsim("bench accuracy --from " + csv + " --plot " + dir + "/plot.png", nullptr, &err);
    ::setenv("PATH", path.c_str(), 1);
    EXPECT_EQ(rc, 2);
    EXPECT_NE(err.find("gnuplot"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(dir + "/plot.png"));
}

const json* findPoint(const json& j, const std::string& problem, const std::string& config) {
    for (const auto& p : j["points"])
        if (p["problem"] == problem && p["config"] == config) return &p;
    return nullptr;
}

// The configurations beyond the conforming cantilever, at test size: MI lattices, the notched
// cantilever per lumping option, the liver sag (checked on TinyRunContract's run: one run of the
// command serves both).
void checkMiLumpingAndLiver(const json& j) {
    // An MI lattice aligned with the bar is the conforming 10x1x1 mesh of the Kuhn split (the
    // lattice's): same step, same answer.
    const json* conf = findPoint(j, "cantilever_static", "explicit kuhn 10x1x1 f=0.9");
    const json* aligned = findPoint(j, "cantilever_static", "mi aligned h=L/10 f=0.9");
    const json* shifted = findPoint(j, "cantilever_static", "mi shifted 0.3 h=L/10 f=0.9");
    ASSERT_TRUE(conf && aligned && shifted);
    EXPECT_NEAR((*aligned)["dt"].get<double>(), (*conf)["dt"].get<double>(), 1e-12 * (*conf)["dt"].get<double>());
    EXPECT_NEAR((*aligned)["error"].get<double>(), (*conf)["error"].get<double>(), 1e-6);
    const auto& lat = j["references"]["mi_lattices"];
    ASSERT_EQ(lat.size(), 2u);
    EXPECT_EQ(lat[0]["interface_tets"].get<int>(), 0);
    EXPECT_EQ(lat[0]["tets"].get<int>(), 60);
    // shifted by 0.3 cells: 2 x 2 cells across, 10 along; every Kuhn tet holds its cube's lowest
    // corner and its highest, and in each cube one of the two is outside the bar: no tet is inside
    EXPECT_GT(lat[1]["tets"].get<int>(), 60);
    EXPECT_LE(lat[1]["tets"].get<int>(), 6 * 10 * 2 * 2);
    EXPECT_EQ(lat[1]["interface_tets"].get<int>(), lat[1]["tets"].get<int>());
    EXPECT_TRUE(std::isfinite((*shifted)["error"].get<double>()));

    // The notch (half the depth, at x = 0.3125 m) makes the bar softer: more sag, lower frequency.
    const auto& ns = j["references"]["cantilever_notch_static"];
    const auto& nf = j["references"]["cantilever_notch_frequency"];
    EXPECT_GT(std::abs(ns["reference"].get<double>()), std::abs(ns["uncut_reference"].get<double>()));
    EXPECT_LT(nf["reference"].get<double>(), nf["uncut_reference"].get<double>());
    // XFEM cuts the same 12 tets whatever the lumping (on 20x2x2 the plane crosses one column of
    // cubes; the notch takes its upper layer: 2 cubes of 6 tets) and every lumping gives a finite
    // error. K does not depend on the lumping, so the linear static tips differ only by how the
    // weight of the cut tets is spread over their corners.
    // Then enrichment with the step floor and with the hybrid: the notch does not lower the step,
    // so the floor adds no mass and changes nothing; the hybrid matches elements and gains step.
    ASSERT_EQ(ns["xfem"].size(), 5u);
    for (int k = 0; k < 3; ++k) {
        const json& x = ns["xfem"][k];
        EXPECT_EQ(x["crossed"].get<int>(), 12) << x.dump();
        EXPECT_NEAR(x["linear_static_tip"].get<double>(), ns["xfem"][2]["linear_static_tip"].get<double>(),
                    1e-3 * 0.01);
    }
    const json& fl = ns["xfem"][3];
    const json& hy = ns["xfem"][4];
    EXPECT_EQ(fl["added_mass"].get<double>(), 0.0);
    EXPECT_EQ(fl["linear_static_tip"].get<double>(), ns["xfem"][2]["linear_static_tip"].get<double>());
    EXPECT_EQ(fl["dt_exact"].get<double>(), ns["xfem"][2]["dt_exact"].get<double>());
    EXPECT_GT(hy["matched"].get<int>(), 0);
    EXPECT_GT(hy["dt_exact"].get<double>(), ns["xfem"][2]["dt_exact"].get<double>());
    for (const char* route : {"xfem enrichment+floor 20x2x2 f=0.9", "xfem enrichment+hybrid 20x2x2 f=0.9"})
        for (const char* prob : {"cantilever_notch_static", "cantilever_notch_frequency"}) {
            const json* p = findPoint(j, prob, route);
            ASSERT_TRUE(p) << prob << " " << route;
            EXPECT_TRUE((*p)["error"].is_number()) << p->dump();
        }
    for (const char* l : {"row_sum", "weighted_diagonal", "enrichment"}) {
        for (const char* prob : {"cantilever_notch_static", "cantilever_notch_frequency"}) {
            const json* p = findPoint(j, prob, std::string("xfem ") + l + " 20x2x2 f=0.9");
            ASSERT_TRUE(p) << prob << " " << l;
            ASSERT_TRUE((*p)["error"].is_number()) << p->dump();
            EXPECT_LT((*p)["error"].get<double>(), 1.0) << p->dump();
        }
    }
    // The conforming pipeline on the same bar: the plane x = 0.3125 (a quarter cell past the
    // lattice) splits the 4 cubes it crosses (24 tets) and snaps nothing; cube edges, face and body
    // diagonals cut it in a 5 x 5 grid, whose 2 rows above z = 0.05 open. The slivers cut the
    // step; the improvement raises it, the hybrid keeps 0.95 of the uncut step.
    const auto& sub = ns["subdivision"];
    ASSERT_EQ(sub.size(), 4u);
    for (const json& x : sub) {
        EXPECT_EQ(x["split"].get<int>(), 24) << x.dump();
        EXPECT_EQ(x["snapped"].get<int>(), 0) << x.dump();
        EXPECT_EQ(x["duplicated"].get<int>(), 10) << x.dump();
        const json* p = findPoint(j, "cantilever_notch_static", x["config"].get<std::string>());
        ASSERT_TRUE(p) << x.dump();
        EXPECT_TRUE((*p)["error"].is_number()) << p->dump();
    }
    EXPECT_LT(sub[0]["dt_ratio"].get<double>(), 0.5);
    EXPECT_GT(sub[1]["dt_ratio"].get<double>(), sub[0]["dt_ratio"].get<double>());
    EXPECT_GT(sub[3]["matched"].get<int>(), 0);
    EXPECT_GE(sub[3]["dt_ratio"].get<double>(), 0.95 * (1 - 1e-9));

    // Enrichment lumping keeps the uncut step (isolated virtual elements keep their parent's
    // eigenvalues); row sum gives far corners of small pieces small masses and a shorter step.
    const double dtEnr =
        findPoint(j, "cantilever_notch_static", "xfem enrichment 20x2x2 f=0.9")->at("dt").get<double>();
    const double dtRow = findPoint(j, "cantilever_notch_static", "xfem row_sum 20x2x2 f=0.9")->at("dt").get<double>();
    EXPECT_LT(dtRow, dtEnr);

    // The liver: the refined meshes keep the coarse nodes, the reference sags by centimetres, and
    // the coarse liver (linear tets) is stiffer than the refined one.
    const auto& lv = j["references"]["liver_sag"];
    ASSERT_EQ(lv["levels"].size(), 2u);
    EXPECT_EQ(lv["levels"][0]["tets"].get<int>(), 596);
    EXPECT_EQ(lv["levels"][1]["tets"].get<int>(), 8 * 596);
    EXPECT_GT(lv["max_sag_m"].get<double>(), 0.005);
    EXPECT_LT(lv["max_sag_m"].get<double>(), 0.2);
    const double eqErr = lv["levels"][0]["equilibrium_error"].get<double>();
    EXPECT_GT(eqErr, 0.0);
    EXPECT_LT(eqErr, 1.0);
    int liverPts = 0;
    double plain = NAN, damped = NAN;
    for (const auto& p : j["points"])
        if (p["problem"] == "liver_sag") {
            ++liverPts;
            ASSERT_TRUE(p["error"].is_number()) << p.dump();
            const std::string config = p["config"].get<std::string>();
            if (config.rfind("explicit liver", 0) == 0) plain = p["error"].get<double>();
            if (config.rfind("explicit alpha_e_0.95 liver", 0) == 0) damped = p["error"].get<double>();
        }
    // explicit, per-element damping at 1.5 x the limit and backward Euler on the coarse liver,
    // explicit on the MI liver
    EXPECT_EQ(liverPts, 4);
    // Damping the few elements faster than 1.5 x the limit changes the sag little: their stiffness
    // is scaled, but the equilibrium is set by the whole liver (a change of a few percent at most).
    EXPECT_NEAR(damped, plain, 0.05 * plain);
    // The MI liver (6 cells across): its lattice step is several times the conforming liver's
    // (0.45 ms, Table 4.3), and its sag is the same physics: within the coarse mesh's own error
    // scale of the reference, not off by the whole sag.
    ASSERT_EQ(lv["mi"].size(), 1u);
    EXPECT_GT(lv["mi"][0]["dt_exact"].get<double>(), 2 * 0.451e-3);
    EXPECT_LT(lv["mi"][0]["equilibrium_error"].get<double>(), 1.0);
    for (const char* prob : {"cantilever_notch_static", "cantilever_notch_frequency", "liver_sag"})
        EXPECT_TRUE(j["summary"].contains(prob)) << prob;
}

// The tiny run: references, explicit and implicit points on both problems, Pareto marks
// consistent with the points, and the beam-theory values of the bar by hand.
TEST(BenchAccuracy, TinyRunContract) {
    const std::string dir = workDir("tiny");
    const json j = runJson("bench accuracy --tiny --json --csv " + dir + "/p.csv");
    ASSERT_TRUE(j.contains("points") && j.contains("summary"));
    EXPECT_TRUE(j["machine"].contains("load_average_end"));  // measured here, so the machine is named
    int explicitPts = 0, implicitPts = 0;
    for (const auto& p : j["points"]) {
        for (const char* k : {"problem", "config", "error", "wall_per_sim_second", "dt", "pareto"})
            ASSERT_TRUE(p.contains(k)) << k;
        // a diverged run has no error (null); the plain explicit and implicit runs here are stable
        const bool damped = p["config"].get<std::string>().find("alpha_e") != std::string::npos;
        if (!damped) {
            ASSERT_TRUE(p["error"].is_number()) << p.dump();
        }
        if (!p["error"].is_number()) continue;
        EXPECT_GT(p["wall_per_sim_second"].get<double>(), 0);
        EXPECT_GT(p["dt"].get<double>(), 0);
        (p["scheme"] == "explicit" ? explicitPts : implicitPts)++;
    }
    EXPECT_GE(explicitPts, 2);
    EXPECT_GE(implicitPts, 2);
    for (const auto& p : j["points"]) {
        if (!p["error"].is_number()) {
            EXPECT_FALSE(p["pareto"].get<bool>());
            continue;
        }
        bool beaten = false;
        for (const auto& q : j["points"])
            if (q["problem"] == p["problem"] && q["error"].is_number() && q["error"] <= p["error"] &&
                q["wall_per_sim_second"] <= p["wall_per_sim_second"] &&
                (q["error"] < p["error"] || q["wall_per_sim_second"] < p["wall_per_sim_second"]))
                beaten = true;
        EXPECT_EQ(p["pareto"].get<bool>(), !beaten) << p.dump();
    }
    for (const char* prob : {"cantilever_static", "cantilever_frequency"}) {
        ASSERT_TRUE(j["summary"].contains(prob));
        EXPECT_TRUE(j["summary"][prob].contains("best_explicit_cost_at_1pct"));
        EXPECT_TRUE(j["summary"][prob].contains("implicit_cost_at_1pct"));
    }
    // q = rho g h^2, I = h^4 / 12, E = 1e8, G = E / 2.6, L = 1, h = 0.1
    const double E = 1e8, h = 0.1, I = h * h * h * h / 12, q = 1000 * 9.81 * h * h;
    const double tip = q / (8 * E * I) + q / (2 * (5.0 / 6.0) * (E / 2.6) * h * h);
    EXPECT_NEAR(j["references"]["cantilever_static"]["beam_theory"].get<double>(), -tip, 1e-9);
    const double f1 = 1.8751 * 1.8751 / (2 * M_PI) * std::sqrt(E * I / (1000 * h * h));
    EXPECT_NEAR(j["references"]["cantilever_frequency"]["beam_theory"].get<double>(), f1, 1e-9);
    // Coarse linear tets are stiff: deflection below and frequency above the 3D answer.
    const auto& st = j["references"]["cantilever_static"]["values"];
    EXPECT_LT(std::abs(st[0].get<double>()), std::abs(st[1].get<double>()));
    const auto& fr = j["references"]["cantilever_frequency"]["values"];
    EXPECT_GT(fr[0].get<double>(), fr[1].get<double>());
    EXPECT_TRUE(fs::exists(dir + "/p.csv"));
    checkMiLumpingAndLiver(j);
}

// The frequency problem's error is the first mode's complex frequency, measured from the tip:
// on the mirrored 20x2x2 bar it is what the integrator's mode formula gives from the mesh's own
// Lanczos frequency, for symplectic Euler (no decay) and backward Euler (decay and a longer
// period) alike. The Kuhn split's skew bending axes make the tip beat: a spurious decay.
TEST(BenchAccuracy, FrequencyErrorIsTheIntegratorsModeError) {
    const json j = runJson("bench accuracy --res 2 --implicit-max-res 2 --ref-levels 2,4 --only cantilever --json");
    int checked = 0;
    for (const auto& p : j["points"]) {
        if (p["problem"] != "cantilever_frequency" || !p["error"].is_number()) continue;
        const std::string config = p["config"].get<std::string>();
        const double e = p["error"].get<double>();
        // the two parts make the whole
        EXPECT_NEAR(std::hypot(p["frequency_error"].get<double>(), p["damping_ratio"].get<double>()), e, 1e-9 * e)
            << config;
        if (config.find("kuhn") != std::string::npos) {
            EXPECT_GT(std::abs(p["damping_ratio"].get<double>()), 5e-3) << config;
            continue;
        }
        if (!p.contains("predicted_error")) continue;
        EXPECT_NEAR(e, p["predicted_error"].get<double>(), 2e-3 * e) << config;
        if (p["scheme"] == "explicit") {
            EXPECT_LT(std::abs(p["damping_ratio"].get<double>()), 1e-4) << config;
        } else {
            // backward Euler at dt = 0.01 / 0.003: its decay is ln(1 + w^2 dt^2) / (2 dt)
            const double w = 2 * M_PI * j["implicit_projection"][0]["mesh_frequency"].get<double>(),
                         dt = p["dt"].get<double>();
            EXPECT_NEAR(p["damping_ratio"].get<double>() * 2 * M_PI *
                            j["references"]["cantilever_frequency"]["reference"].get<double>(),
                        std::log1p(w * w * dt * dt) / (2 * dt), 2e-3 * w)
                << config;
        }
        ++checked;
    }
    // explicit at 0.9, 0.98 and 0.999 of the limit and in single precision at 0.999, backward Euler
    // at dt = 0.01 and 0.003 (0.1 and 0.03 overdamp the mode), and its CG solve at 0.003, which
    // must give the direct solve's error
    EXPECT_EQ(checked, 7);
    double direct = NAN, cg = NAN, dbl = NAN, sgl = NAN;
    for (const auto& p : j["points"])
        if (p["problem"] == "cantilever_frequency") {
            if (p["config"] == "backward_euler 20x2x2 dt=0.003") direct = p["error"].get<double>();
            if (p["config"] == "backward_euler cg 20x2x2 dt=0.003") cg = p["error"].get<double>();
            if (p["config"] == "explicit 20x2x2 f=0.999") dbl = p["error"].get<double>();
            if (p["config"] == "explicit single 20x2x2 f=0.999") sgl = p["error"].get<double>();
        }
    EXPECT_NEAR(cg, direct, 1e-8 * direct);
    // The CG run on the finest mesh took turns with the explicit runs at 0.999 (runPaired): the same
    // steps in slices, so the same errors, bitwise; the ratios are of the costs, and a ratio of sums
    // lies between the smallest and largest ratio of its parts (the slices, the halves).
    ASSERT_EQ(j["paired"].size(), 1u);
    const auto& pc = j["paired"][0];
    EXPECT_EQ(pc["implicit"], "backward_euler cg 20x2x2 dt=0.003");
    EXPECT_EQ(pc["implicit_error"].get<double>(), cg);
    EXPECT_EQ(pc["slices"].get<int>(), 20);
    ASSERT_EQ(pc["explicit"].size(), 2u);
    for (const auto& e : pc["explicit"]) {
        const double err = e["error"].get<double>();
        EXPECT_EQ(err, e["config"] == "explicit 20x2x2 f=0.999" ? dbl : sgl) << e.dump();
        const double ratio = e["ratio"].get<double>(), h1 = e["ratio_first_half"].get<double>(),
                     h2 = e["ratio_second_half"].get<double>();
        EXPECT_NEAR(ratio, pc["implicit_cost"].get<double>() / e["cost"].get<double>(), 1e-12 * ratio);
        EXPECT_GT(ratio, 0);
        EXPECT_LE(std::min(h1, h2), ratio * (1 + 1e-12));
        EXPECT_GE(std::max(h1, h2), ratio * (1 - 1e-12));
        EXPECT_LE(e["slice_ratio_min"].get<double>(), std::min(h1, h2) * (1 + 1e-12));
        EXPECT_GE(e["slice_ratio_max"].get<double>(), std::max(h1, h2) * (1 - 1e-12));
    }
    // 26% off: no pairing at 1%
    EXPECT_TRUE(j["summary"]["cantilever_frequency"]["speedup_at_1pct_paired"].is_null());
    // float forces move the measured mode by far less than the mesh's 26%, but do move it
    EXPECT_NEAR(sgl, dbl, 1e-4 * dbl);
    EXPECT_NE(sgl, dbl);
    // The mesh is 26% off: no dt brings backward Euler to 1%, and nothing is projected.
    ASSERT_EQ(j["implicit_projection"].size(), 1u);
    const auto& pr = j["implicit_projection"][0];
    EXPECT_EQ(pr["tets"].get<int>(), 480);
    EXPECT_GT(pr["mesh_error"].get<double>(), 0.2);
    EXPECT_TRUE(pr["dt_at_1pct"].is_null());
    EXPECT_GT(pr["step_seconds_direct"].get<double>(), 0);
    EXPECT_GT(pr["step_seconds_cg"].get<double>(), 0);
    EXPECT_GT(pr["cg_iterations"].get<int>(), 0);
    EXPECT_EQ(pr["step_seconds"].get<double>(),
              std::min(pr["step_seconds_direct"].get<double>(), pr["step_seconds_cg"].get<double>()));
    EXPECT_TRUE(j["summary"]["cantilever_frequency"]["implicit_cost_at_1pct_projected"].is_null());
}

// A single tet: plain explicit schemes are stable up to the exact limit and not past it
// (the top mode grows as soon as omega dt > 2); per-element damping goes further.
TEST(BenchStability, SingleTetLimitIsTheExactOne) {
    const json j = runJson("bench stability --tiny --json --cut-runs 0");  // the random cuts have their own test
    ASSERT_EQ(j["sweeps"].size(), 5u);
    for (const auto& s : j["sweeps"]) {
        const double f = s["largest_stable_fraction"].get<double>();
        if (s["scheme"] == "plain") {
            EXPECT_GE(f, 0.99) << s["integrator"];
            EXPECT_LE(f, 1.0) << s["integrator"];
            for (const auto& r : s["runs"]) {
                if (r["fraction"].get<double>() >= 1.005) {
                    EXPECT_FALSE(r["stable"].get<bool>()) << r.dump();
                }
            }
        } else if (s["scheme"] == "alpha_e_0.95") {
            // one element: alpha = (0.95 dt_e / dt)^2 makes omega dt = 2 * 0.95 at any dt
            EXPECT_GE(f, 3.0);
        }
    }
    // symplectic: the energy oscillates but does not drift
    EXPECT_LT(std::abs(j["energy_drift"]["drift"].get<double>()), 0.02);
}

// After the notch cut: every lumping option is stable to just below the cut model's exact limit
// and not past it; enrichment keeps the uncut step, row sum and weighted diagonal lose some.
// Random cut sequences: each run of c cuts takes (c + 1) x cut-steps steps.
TEST(BenchStability, AfterCutsAndRandomCuts) {
    const json j = runJson("bench stability --tiny --json --cut-runs 2 --cut-steps 40");
    ASSERT_EQ(j["after_cuts"].size(), 3u);
    for (const auto& s : j["after_cuts"]) {
        const double f = s["largest_stable_fraction"].get<double>();
        EXPECT_GE(f, 0.99) << s["lumping"];
        EXPECT_LE(f, 1.0) << s["lumping"];
        for (const auto& r : s["runs"])
            if (r["fraction"].get<double>() >= 1.02) {
                EXPECT_FALSE(r["stable"].get<bool>()) << s["lumping"] << r.dump();
            }
        EXPECT_GT(s["crossed"].get<int>(), 0);
        if (s["lumping"] == "enrichment") {
            EXPECT_NEAR(s["dt_ratio"].get<double>(), 1.0, 1e-6);
        } else {
            EXPECT_LT(s["dt_ratio"].get<double>(), 1.0);
        }
    }
    ASSERT_GE(j["random_cuts"].size(), 1u);
    for (const auto& r : j["random_cuts"]) {
        EXPECT_EQ(r["runs"].get<int>(), 2);
        EXPECT_EQ(r["failures"].get<int>(), 0) << r.dump();
        EXPECT_GE(r["cuts"].get<int>(), 2);
        EXPECT_LE(r["cuts"].get<int>(), 8);
        EXPECT_EQ(r["steps"].get<long>(), 40L * (r["cuts"].get<long>() + r["runs"].get<long>()));
        EXPECT_LT(r["max_volume_error"].get<double>(), 1e-9);
        EXPECT_LE(r["min_dt_ratio"].get<double>(), 1.0);
        EXPECT_GT(r["min_dt_ratio"].get<double>(), 0.0);
    }
}

// `bench contact --tiny`: the probe away from the slab touches nothing; pressed 2 mm it touches
// points, sinks less than its radius and is pushed back up; a stiffer penalty lets it sink less.
TEST(BenchContact, TinyRunContract) {
    const json j = runJson("bench contact --tiny --json");
    ASSERT_EQ(j["runs"].size(), 6u);  // away and pressing, then four stiffness fractions
    for (const auto& r : j["runs"]) {
        EXPECT_EQ(r["status"], "ok");
        EXPECT_GT(r["points"].get<int>(), 1000);
        EXPECT_GT(r["steps"].get<long>(), 10);
        EXPECT_GE(r["contact_seconds_per_step"].get<double>(), 0);
        if (r["tool"] == "away") {
            EXPECT_EQ(r["max_depth"].get<double>(), 0);
            EXPECT_EQ(r["final_contacts"].get<int>(), 0);
        } else {
            EXPECT_GT(r["final_contacts"].get<int>(), 0);
            EXPECT_GT(r["max_depth"].get<double>(), 0);
            EXPECT_LT(r["max_depth"].get<double>(), 0.01);
            EXPECT_GT(r["final_force"].get<double>(), 0);
        }
    }
    EXPECT_GT(j["runs"][2]["max_depth"].get<double>(), j["runs"][5]["max_depth"].get<double>());  // k 0.1 vs 1.0
}

// `bench contact --plot` draws one PNG, and leaves no temporary file beside it; without gnuplot
// it fails up front and writes nothing.
TEST(BenchContact, PlotWritesOnePng) {
    const std::string dir = workDir("contact_plot");
    const std::string png = dir + "/contact.png";
    std::string err;
    if (std::system("command -v gnuplot > /dev/null 2>&1") == 0) {
        ASSERT_EQ(test::runCutsim("bench contact --tiny --plot " + png, nullptr, &err), 0) << err;
        std::ifstream f(png, std::ios::binary);
        char magic[4] = {};
        f.read(magic, 4);
        EXPECT_EQ(std::string(magic + 1, 3), "PNG");
        EXPECT_FALSE(fs::exists(png + ".tmp.png"));
        fs::remove(png);
    }
    const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
    ::setenv("PATH", dir.c_str(), 1);
    const int rc = test::runCutsim("bench contact --tiny --plot " + png, nullptr, &err);
    ::setenv("PATH", path.c_str(), 1);
    EXPECT_EQ(rc, 2);
    EXPECT_NE(err.find("gnuplot"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(png));
}

// `bench haptic --tiny`: a small remeshed liver pressed by the probe, one run per thread count,
// each touching it with a positive rate and a contact share within the loop.
TEST(BenchHaptic, TinyRunContract) {
    const json j = runJson("bench haptic --tiny --json --mesh " + test::source("assets/meshes/liver.msh"));
    ASSERT_EQ(j["runs"].size(), 2u);  // 1 and 2 threads
    for (const auto& r : j["runs"]) {
        EXPECT_EQ(r["status"], "ok");
        EXPECT_GT(r["tets"].get<int>(), 500);
        EXPECT_GT(r["steps"].get<long>(), 10);
        EXPECT_GT(r["steps_per_second"].get<double>(), 0);
        EXPECT_GE(r["contact_share"].get<double>(), 0);
        EXPECT_LT(r["contact_share"].get<double>(), 1);
        EXPECT_GT(r["final_contacts"].get<int>(), 0);
        EXPECT_GT(r["final_force"].get<double>(), 0);
    }
    EXPECT_EQ(j["runs"][0]["steps"], j["runs"][1]["steps"]);
}

// `bench capture --json`: a run per scene and round, each with the parts its report.json gives and
// the ratios made of them; --csv holds the same runs; the result names the machine.
TEST(BenchCapture, JsonRunsCsvAndMachine) {
    const std::string dir = workDir("capture");
    const json j = runJson("bench capture " + test::source("assets/scenes/bar_sag.json") +
                           " --set duration=0.1 --width 64 --height 48 --no-video --runs 2 --json --csv " + dir +
                           "/runs.csv --keep " + dir + "/last");
    EXPECT_EQ(j["width"], 64);
    EXPECT_EQ(j["height"], 48);
    EXPECT_EQ(j["video"], false);
    EXPECT_EQ(j["mode"], "pipelined");
    ASSERT_EQ(j["runs"].size(), 2u);
    std::ifstream in(dir + "/last/report.json");
    const json rep = json::parse(in);
    for (size_t k = 0; k < 2; ++k) {
        const json& r = j["runs"][k];
        EXPECT_EQ(r["status"], "ok");
        EXPECT_EQ(r["run"].get<int>(), static_cast<int>(k));
        EXPECT_EQ(r["frames"], rep["frames"]);  // the same scene: the kept run's frames
        const double wall = r["wall_s"].get<double>(), physics = r["physics_s"].get<double>();
        const double capture = r["render_s"].get<double>() + r["encode_s"].get<double>();
        EXPECT_GT(physics, 0);
        EXPECT_GT(capture, 0);
        EXPECT_NEAR(r["capture_ms_per_frame"].get<double>(), 1e3 * capture / r["frames"].get<double>(), 1e-9);
        EXPECT_NEAR(r["wall_over_max"].get<double>(), wall / std::max(physics, capture), 1e-9);
        EXPECT_NEAR(r["wall_over_sum"].get<double>(), wall / (physics + capture), 1e-9);
        EXPECT_GE(r["cpu_ms_per_frame"].get<double>(), 0);
    }
    EXPECT_NEAR(j["runs"][1]["wall_s"].get<double>(), rep["wall_time"].get<double>(), 1e-9);
    EXPECT_TRUE(j["machine"].contains("load_average_end"));
    std::ifstream f(dir + "/runs.csv");
    std::vector<std::string> lines;
    for (std::string l; std::getline(f, l);) lines.push_back(l);
    ASSERT_EQ(lines.size(), 3u);
    EXPECT_EQ(lines[0].substr(0, 39), "scene,run,mode,width,height,frames,wall");
    EXPECT_EQ(lines[2].substr(0, 24), "bar_sag,1,pipelined,64,4");
}

TEST(BenchCapture, BadOptionsExitTwo) {
    const std::string scene = test::source("assets/scenes/bar_sag.json");
    for (const std::string& args :
         std::vector<std::string>{"bench capture " + scene + " --runs 0", "bench capture " + scene + " --width 8",
                                  "bench capture " + scene + " --threads -1", "bench capture no_such_scene.json",
                                  "bench capture " + scene + " --set capture.enabled=false --json"}) {
        std::string err;
        EXPECT_EQ(test::runCutsim(args, nullptr, &err), 2) << args << "\n" << err;
    }
}

// `bench threads`: per round, each count once idle and once with another core busy, the order
// reversed every other round; counts 1 and 2 are what the run ends on, the measured one is one of
// them; every count ends in the same state; the runs' step and set-up times make up their wall.
TEST(BenchThreads, RoundsTakeTurnsAndEndInOneState) {
    const std::string dir = workDir("threads");
    const json j = runJson("bench threads " + test::source("assets/scenes/bar_sag.json") +
                           " --set duration=0.02 --rounds 2 --busy --json --csv " + dir + "/runs.csv");
    const auto& runs = j["runs"];
    ASSERT_EQ(runs.size(), 12u);  // 2 rounds x (idle, busy) x (1, 2, 0)
    const int asked[] = {1, 2, 0, 1, 2, 0, 0, 2, 1, 0, 2, 1};
    for (size_t k = 0; k < runs.size(); ++k) {
        const json& r = runs[k];
        EXPECT_EQ(r["threads"].get<int>(), asked[k]) << k;
        EXPECT_EQ(r["round"].get<int>(), static_cast<int>(k / 6)) << k;
        EXPECT_EQ(r["load"], (k / 3) % 2 ? "busy" : "idle") << k;
        const int chosen = r["threads_chosen"].get<int>();
        if (asked[k] > 0) {
            EXPECT_EQ(chosen, asked[k]) << k;
        }
        EXPECT_TRUE(chosen == 1 || chosen == 2) << k;
        EXPECT_EQ(r["status"], "ok");
        EXPECT_EQ(r["state_hash"], runs[0]["state_hash"]) << k;
        EXPECT_EQ(r["steps"], runs[0]["steps"]);
        EXPECT_GT(r["step_seconds"].get<double>(), 0);
        EXPECT_GT(r["setup_seconds"].get<double>(), 0);
        EXPECT_NEAR(r["step_seconds"].get<double>() + r["setup_seconds"].get<double>(), r["wall_seconds"].get<double>(),
                    1e-9);
    }
    EXPECT_EQ(j["sets"], json::array({"duration=0.02"}));
    EXPECT_TRUE(j["machine"].contains("load_average_end"));
    EXPECT_EQ(test::readText(dir + "/runs.csv").substr(0, 22), "scene,name,round,load,");
}

TEST(BenchThreads, BadOptionsExitTwo) {
    const std::string scene = test::source("assets/scenes/bar_sag.json");
    for (const std::string& args : std::vector<std::string>{
             "bench threads " + scene + " --rounds 0", "bench threads " + scene + " --threads -1", "bench threads",
             "bench threads no_such_scene.json", "bench threads " + scene + " --set no_such_key=1"}) {
        std::string err;
        EXPECT_EQ(test::runCutsim(args, nullptr, &err), 2) << args << "\n" << err;
    }
}

// The busy process spins (its CPU time grows) and is gone once the object is.
TEST(BenchMachine, BusyCoreSpinsUntilDestroyed) {
    auto cpuTicks = [](int pid) {
        std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
        std::string stat;
        std::getline(f, stat);
        // fields after the command's closing parenthesis: state is field 3, utime 14, stime 15
        std::istringstream rest(stat.substr(stat.rfind(')') + 2));
        std::vector<std::string> v;
        for (std::string x; rest >> x;) v.push_back(x);
        return v.size() > 12 ? std::stol(v[11]) + std::stol(v[12]) : -1L;
    };
    int pid = 0;
    {
        const BusyCore busy;
        pid = busy.pid();
        ASSERT_GT(pid, 0);
        long ticks = 0;
        for (int k = 0; k < 100 && ticks <= 0; ++k) {
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
            ticks = cpuTicks(pid);
        }
        EXPECT_GT(ticks, 0);
    }
    EXPECT_EQ(::kill(pid, 0), -1);  // reaped: no such process
    EXPECT_EQ(errno, ESRCH);
}

// `bench improve --speed`: each mesh and count once a round, idle rounds first; the improver's
// result at a count is the one `cutsim improve --threads K` gives.
TEST(BenchImprove, SpeedRunsTakeTurns) {
    const json j =
        runJson("bench improve --speed --speed-meshes liver --threads 1,2 --rounds 1 --busy-rounds 1 --json");
    const auto& runs = j["runs"];
    ASSERT_EQ(runs.size(), 4u);
    const int threads[] = {1, 2, 2, 1};
    for (size_t k = 0; k < 4; ++k) {
        EXPECT_EQ(runs[k]["mesh"], "liver");
        EXPECT_EQ(runs[k]["tets"].get<int>(), 596);
        EXPECT_EQ(runs[k]["threads"].get<int>(), threads[k]);
        EXPECT_EQ(runs[k]["load"], k < 2 ? "idle" : "busy");
        EXPECT_GT(runs[k]["seconds"].get<double>(), 0);
    }
    const json one = runJson("improve " + test::data("tet/sofa_liver.msh") + " --scale 0.0254 --threads 1 --json");
    EXPECT_DOUBLE_EQ(runs[0]["gain"].get<double>(), one["gain"].get<double>());
    EXPECT_DOUBLE_EQ(runs[3]["gain"].get<double>(), one["gain"].get<double>());
    std::string err;
    EXPECT_EQ(test::runCutsim("bench improve --speed --speed-meshes spleen", nullptr, &err), 2);
    EXPECT_NE(err.find("known: liver"), std::string::npos) << err;
}

TEST(BenchStep, TinyRunContract) {
    const json j = runJson("bench step --tiny --json --seconds 0.02");
    ASSERT_EQ(j["runs"].size(), 4u);  // 1 and 2 threads, each in double and single precision
    for (const auto& r : j["runs"]) {
        EXPECT_EQ(r["tets"].get<int>(), 6 * 27);
        EXPECT_GT(r["tet_steps_per_second"].get<double>(), 0);
        EXPECT_NEAR(r["tet_steps_per_second"].get<double>(),
                    162.0 * r["steps"].get<double>() / r["seconds"].get<double>(),
                    1e-6 * r["tet_steps_per_second"].get<double>());
        // shares of the step, each timed in its own pass: on a loaded machine they need not sum
        // to 1 (BENCHMARKS.md), so only their sign and finiteness are a contract
        for (const char* k : {"element", "nodes", "integrate"}) {
            EXPECT_GE(r["stages"][k].get<double>(), 0);
            EXPECT_TRUE(std::isfinite(r["stages"][k].get<double>()));
        }
    }
    const char* precisions[] = {"double", "single"};
    for (int k = 0; k < 4; ++k) {
        EXPECT_EQ(j["runs"][k]["threads"], 1 + k / 2);
        EXPECT_EQ(j["runs"][k]["precision"], precisions[k % 2]);
    }
}

// --csv writes the JSON's runs, one line each in the header's columns (nested keys by their last
// name), and the result names the machine it ran on.
TEST(BenchStep, CsvIsTheJsonsRunsAndTheMachineIsNamed) {
    const std::string dir = workDir("stepcsv");
    const json j = runJson("bench step --tiny --json --seconds 0.02 --csv " + dir + "/runs.csv");
    std::ifstream f(dir + "/runs.csv");
    std::vector<std::string> lines;
    for (std::string l; std::getline(f, l);) lines.push_back(l);
    ASSERT_EQ(lines.size(), 1 + j["runs"].size());
    EXPECT_EQ(lines[0],
              "tets,nodes,threads,precision,steps,seconds,tet_steps_per_second,forces,element,nodes,integrate");
    for (size_t k = 0; k < j["runs"].size(); ++k) {
        const json& r = j["runs"][k];
        std::vector<std::string> cells = {r["tets"].dump(),
                                          r["nodes"].dump(),
                                          r["threads"].dump(),
                                          r["precision"].get<std::string>(),
                                          r["steps"].dump(),
                                          r["seconds"].dump(),
                                          r["tet_steps_per_second"].dump()};
        for (const char* s : {"forces", "element", "nodes", "integrate"}) cells.push_back(r["stages"][s].dump());
        std::string want;
        for (const std::string& c : cells) {
            if (!want.empty()) want += ',';
            want += c;
        }
        EXPECT_EQ(lines[k + 1], want);
    }
    const json& m = j["machine"];
    EXPECT_GE(m["cores"].get<int>(), 1);
    EXPECT_TRUE(m["cpu"].is_string());
    for (const char* k : {"load_average", "load_average_end"}) {
        EXPECT_TRUE(m[k].size() == 3 || m[k].empty()) << k;  // 1, 5, 15 min, where the system gives them
        for (const auto& v : m[k]) EXPECT_GE(v.get<double>(), 0);
    }
}

// Tables 5.5 and 5.6 on the bar: four cuts per method; the floor holds 0.95 of the uncut step
// after every cut; subdivision adds elements with every cut; every step a real one.
TEST(BenchCutStep, TinyRunContract) {
    const json j = runJson("bench cutstep --tiny --json");
    ASSERT_EQ(j["objects"].size(), 1u);
    const json& o = j["objects"][0];
    EXPECT_EQ(o["name"], "bar");
    const double dt0 = o["dt_uncut"].get<double>();
    ASSERT_TRUE(std::isfinite(dt0));
    ASSERT_GT(dt0, 0);
    std::vector<std::string> names;
    for (const auto& m : o["methods"]) {
        const std::string name = m["name"].get<std::string>();
        names.push_back(name);
        ASSERT_EQ(m["cuts"].size(), 4u) << name;
        int elements = o["tets"].get<int>();
        for (const auto& c : m["cuts"]) {
            ASSERT_TRUE(c["dt_exact"].is_number()) << name;
            const double dt = c["dt_exact"].get<double>();
            EXPECT_TRUE(std::isfinite(dt) && dt > 0) << name;
            EXPECT_NEAR(c["dt_ratio"].get<double>(), dt / dt0, 1e-9) << name;
            EXPECT_LE(c["critical"].get<int>(), c["elements"].get<int>()) << name;
            // the floor and the hybrid (whose dt_sim is 0.95 of the uncut step) both hold 0.95
            if (name == "xfem+floor" || name == "xfem+hybrid") {
                EXPECT_GE(c["dt_ratio"].get<double>(), 0.95 * (1 - 1e-6)) << name << " cut " << c["cut"];
            }
            if (name == "subdivision") {
                EXPECT_GT(c["elements"].get<int>(), elements) << "cut " << c["cut"];
            }
            elements = c["elements"].get<int>();
        }
        const double cost = m["cost"]["wall_per_simulated_second"].get<double>();
        EXPECT_TRUE(std::isfinite(cost) && cost > 0) << name;
    }
    EXPECT_EQ(names, (std::vector<std::string>{"subdivision", "subdivision+improve", "subdivision+improve-full", "xfem",
                                               "xfem+floor", "xfem+hybrid"}));
}

// What a scene does not use costs nothing: no tools, no cuts, no rendering -> those stages are 0.
TEST(BenchCost, UnusedSubsystemsCostNothing) {
    const json j = runJson("bench cost " + test::source("assets/scenes/bar_sag.json") +
                           " --json --set duration=0.02 --set object.box.cells=[10,1,1]");
    ASSERT_GE(j["variants"].size(), 2u);
    EXPECT_EQ(j["variants"][0]["name"], "as given");
    bool sawNoDamping = false;
    for (const auto& v : j["variants"]) {
        EXPECT_EQ(v["status"], "ok");
        for (const char* k : {"contact", "cut", "render", "encode"}) EXPECT_EQ(v["stages"][k].get<double>(), 0.0) << k;
        EXPECT_GT(v["stages"]["forces"].get<double>(), 0.0);
        sawNoDamping |= v["name"] == "without damping";
    }
    EXPECT_TRUE(sawNoDamping);  // bar_sag is damped
}

}  // namespace
}  // namespace cutsim
