// `cutsim bench haptic`: can a haptic loop (1 kHz) step a 20,000-tet organ with a probe pressing it?
// The SOFA liver is tetrahedralised again by TetGen to the asked number of tets (the red-refined
// liver without TetGen), held at its back and bottom as probe.json holds it, and a 1 cm sphere
// presses 12 mm into its top over the run (the tissue relaxes away from a probe that stops);
// projection contact, symplectic Euler at 0.9 of the exact step. Reported: steps per wall second, the contact stage's
// share of the loop, and the simulated seconds per wall second (a haptic loop steps at the stable step, so real time
// needs 1 / dt steps a second).
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "cut/remesh.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "sim/scene.hpp"
#include "sim/simulation.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace cutsim::bench {

namespace {

using nlohmann::json;

struct HapticArgs {
    bool json = false, tiny = false;
    int tets = 20000;
    double duration = 0.1;  // simulated [s]
    std::vector<int> threads = {1, 2};
    std::string mesh = "assets/meshes/liver.msh";  // the SOFA liver, inches
    std::string csv;                               // the runs as CSV
};

constexpr double kInch = 0.0254;
constexpr double kTouch = 0.140, kPressed = 0.128;  // probe centre heights: touching, 12 mm in [m]

// The liver in metres with about `tets` tets.
TetMesh hapticMesh(const std::string& path, int tets, std::string& how) {
    ReadOptions ro;
    ro.scale = kInch;
    TetMesh m = readTetMesh(path, ro);
    if (haveTetGen()) {
        // TetGen's quality bound adds tets beyond the volume bound's count: the bound is corrected
        // by the count it gave, twice
        RemeshOptions o;
        o.maxVolume = totalVolume(m) / std::max(tets, 1);
        TetMesh out;
        for (int pass = 0; pass < 3; ++pass) {
            out = remeshPieces(m, o).mesh;
            o.maxVolume *= static_cast<double>(out.elements()) / std::max(tets, 1);
        }
        m = std::move(out);
        how = "TetGen (" + o.switches + ", volume bound)";
    } else {
        while (m.elements() * 4 < tets) m = refineTets(m);
        how = "red refinement (no TetGen in this build)";
    }
    return m;
}

json hapticScene(const TetMesh& m, double duration) {
    json nodes = json::array(), el = json::array();
    for (int i = 0; i < m.nodes(); ++i) nodes.push_back({m.X(0, i), m.X(1, i), m.X(2, i)});
    for (int e = 0; e < m.elements(); ++e) el.push_back({m.tets(0, e), m.tets(1, e), m.tets(2, e), m.tets(3, e)});
    json probe = {{"name", "probe"},
                  {"kind", "sphere"},
                  {"radius", 0.01},
                  {"keyframes", json::array({{{"time", 0.0}, {"position", {0.0, kTouch, 0.008}}},
                                             {{"time", duration}, {"position", {0.0, kPressed, 0.008}}}})}};
    return {
        {"name", "haptic-bench"},
        {"object", {{"mesh", {{"nodes", nodes}, {"tets", el}}}}},
        {"material", {{"E", 30000}, {"nu", 0.3}, {"rho", 1000}, {"damping", 20.0}}},
        {"fixed", json::array({{{"plane", {{"point", {0, 0, -0.043}}, {"normal", {0, 0, 1}}, {"distance", 0.015}}}},
                               {{"plane", {{"point", {0, 0.0055, 0}}, {"normal", {0, 1, 0}}, {"distance", 0.012}}}}})},
        {"loads", {{"gravity", {0, 0, 0}}}},
        {"integrator",
         {{"scheme", "symplectic_euler"}, {"dt", {{"mode", "fraction"}, {"of", "exact"}, {"fraction", 0.9}}}}},
        {"tools", json::array({probe})},
        {"duration", duration},
        {"capture", {{"enabled", false}}},
        {"output", {{"vtu", false}}}};
}

struct HapticRow {
    int threads = 0, tets = 0, points = 0, contacts = 0;
    long steps = 0;
    double dt = 0, wall = 0, contact = 0, elastic = 0, force = 0, depth = 0;
    std::string status;
};

HapticRow runHapticRow(const SceneDef& def, int threads) {
    Simulation::Options so;
    so.threads = threads;
    Simulation sim(def, so);
    HapticRow r;
    r.threads = threads;
    const Stopwatch sw;
    while (sim.status() == RunStatus::Running && !sim.finished()) sim.step();
    r.wall = sw.seconds();
    sim.finish();
    const RunRecord& rec = sim.record();
    r.status = sim.report()["status"].get<std::string>();
    r.steps = sim.state().steps;
    r.tets = sim.model().elements();
    r.dt = sim.dt();
    r.contact = rec.stages[Stage::Contact];
    r.elastic = rec.stages[Stage::Forces] + rec.stages[Stage::Integrate];
    r.points = sim.contact()->points().points();
    r.contacts = sim.contact()->last().contacts;
    r.force = sim.contact()->last().reaction[0].norm();
    r.depth = rec.tool.maxDepth;
    return r;
}

int runHaptic(const HapticArgs& a) {
    const json machine = machineJson();
    const int tets = a.tiny ? 1500 : a.tets;
    const double duration = a.tiny ? 0.005 : a.duration;
    std::string how;
    const TetMesh mesh = hapticMesh(a.mesh, tets, how);
    const SceneDef def = parseScene(hapticScene(mesh, duration), "haptic-bench");
    std::vector<HapticRow> rows;
    for (int th : a.threads) rows.push_back(runHapticRow(def, th));
    json runs = json::array();
    for (const HapticRow& r : rows) {
        const double rate = static_cast<double>(r.steps) / r.wall;
        runs.push_back({{"threads", r.threads},
                        {"tets", r.tets},
                        {"contact_points", r.points},
                        {"steps", r.steps},
                        {"dt", r.dt},
                        {"wall_seconds", r.wall},
                        {"steps_per_second", rate},
                        {"contact_share", r.contact / r.wall},
                        {"contact_per_elastic", r.contact / r.elastic},
                        {"haptic_rate", rate >= 1000},
                        {"real_time_factor", rate * r.dt},
                        {"final_contacts", r.contacts},
                        {"final_force", r.force},
                        {"max_depth", r.depth},
                        {"status", r.status}});
    }
    if (!a.csv.empty())
        writeCsv(a.csv, runs,
                 {"threads", "tets", "contact_points", "steps", "dt", "wall_seconds", "steps_per_second",
                  "contact_share", "contact_per_elastic", "haptic_rate", "real_time_factor", "final_contacts",
                  "final_force", "max_depth", "status"});
    int failed = 0;
    for (const HapticRow& r : rows) failed += r.status != "ok";
    if (a.json) {
        printResult(json{{"mesh", how}, {"duration", duration}, {"runs", runs}}, machine);
        return failed ? 1 : 0;
    }
    std::printf("liver, %s: %d tets; 1 cm probe pressing 12 mm over %.3g s\n", how.c_str(), mesh.elements(), duration);
    std::printf("%7s %7s %9s %10s %7s %12s %9s %13s %9s %8s %10s\n", "threads", "steps", "dt [us]", "steps/s", "1 kHz",
                "contact [%]", "c/elastic", "sim s/wall s", "touching", "force[N]", "depth[mm]");
    for (const HapticRow& r : rows) {
        const double rate = static_cast<double>(r.steps) / r.wall;
        std::printf("%7d %7ld %9.2f %10.0f %7s %12.1f %9.3f %13.3f %9d %8.3f %10.3f\n", r.threads, r.steps, r.dt * 1e6,
                    rate, rate >= 1000 ? "yes" : "no", 100 * r.contact / r.wall, r.contact / r.elastic, rate * r.dt,
                    r.contacts, r.force, r.depth * 1e3);
        if (r.status != "ok") std::printf("  %d threads: %s\n", r.threads, r.status.c_str());
    }
    std::printf("(contact: the contact stage's share of the loop's wall time; c/elastic: contact over forces + "
                "integrate; sim s/wall s: real time needs 1, i.e. 1 / dt steps a second)\n");
    return failed ? 1 : 0;
}

void hapticOptions(CLI::App& c, HapticArgs& a) {
    jsonFlag(c, a.json, "{mesh, duration, runs: [...]}", true);
    tinyFlag(c, a.tiny, "~1,500 tets, 5 ms");
    csvOption(c, a.csv, "runs");
    c.add_option("--tets", a.tets, "Tets to mesh the liver with (about)")
        ->check(CLI::Range(100, 2000000))
        ->capture_default_str();
    c.add_option("--duration", a.duration, "Simulated time [s]")->check(CLI::PositiveNumber)->capture_default_str();
    c.add_option("--threads", a.threads, "Worker thread counts, one run each")->capture_default_str();
    c.add_option("--mesh", a.mesh, "The liver (inches)")->check(CLI::ExistingFile)->capture_default_str();
}

}  // namespace

void addHapticBench() {
    addSubcommand("haptic",
                  "Steps per second of a ~20k-tet liver with a probe pressing it (projection contact): a haptic "
                  "loop's 1 kHz?",
                  hapticOptions, runHaptic);
}

}  // namespace cutsim::bench
