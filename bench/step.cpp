// `cutsim bench step` (tet-steps per second with the share of each stage) and `cutsim bench cost`
// (what each optional part of a scene costs).
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "sim/simulation.hpp"
#include "sim/scene.hpp"
#include "bench/random_cuts.hpp"
#include "bench/step_box.hpp"
#include "fem/forces.hpp"
#include "mesh/generate.hpp"
#include "mesh/io.hpp"
#include "timestep/timestep.hpp"
#include "timestep/modes.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace cutsim::bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// ---- bench step ----

struct StepArgs {
    bool json = false, tiny = false;
    double seconds = 1.0;  // measuring time per configuration [s]
    std::string csv;       // the runs as CSV
};

int runStep(const StepArgs& a) {
    const json machine = machineJson();
    const std::vector<int> sizes = a.tiny ? std::vector<int>{3} : std::vector<int>{6, 12, 26, 55};
    const std::vector<int> threadCounts = {1, 2};
    json j;
    j["runs"] = json::array();
    if (!a.json)
        std::printf("%9s %7s %9s %8s %14s %12s %12s %12s\n", "tets", "threads", "precision", "steps", "tet-steps/s",
                    "element %", "nodes %", "integrate %");
    for (int n : sizes) {
        Model m = stepBox(n);
        for (int th : threadCounts)
            for (ForcePrecision precision : {ForcePrecision::Double, ForcePrecision::Single}) {
                setThreads(th);
                m.precision = precision;
                const char* precisionName = precision == ForcePrecision::Single ? "single" : "double";
                State s = makeState(m);
                s.x = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix() * m.X;
                Stepper st;
                const StepOptions opt{Integrator::SymplecticEuler, 1e-6};
                for (int k = 0; k < 3; ++k) st.step(m, s, opt);
                // Whole steps for at least the measuring time (at least 3).
                long steps = 0;
                double forceSec = 0;
                const auto t0 = WallClock::now();
                while (steps < 3 || secondsSince(t0) < a.seconds) {
                    st.step(m, s, opt);
                    forceSec += st.lastForceSeconds();
                    ++steps;
                }
                const double total = secondsSince(t0);
                // The force stage split into its phases, timed in passes of their own on the same threads.
                ForceStageSeconds phases;
                const int reps = static_cast<int>(std::max<long>(1, steps / 4));
                for (int r = 0; r < reps; ++r) computeForces(m, s, nullptr, 0, false, &phases);
                const double perStep = total / steps;
                const double elemShare = phases.elements / reps / perStep, nodeShare = phases.nodes / reps / perStep;
                const double integrateShare = std::max(0.0, 1.0 - forceSec / total);
                const double rate = static_cast<double>(m.elements()) * steps / total;
                j["runs"].push_back({{"tets", m.elements()},
                                     {"nodes", m.nodes()},
                                     {"threads", th},
                                     {"precision", precisionName},
                                     {"steps", steps},
                                     {"seconds", total},
                                     {"tet_steps_per_second", rate},
                                     {"stages",
                                      {{"forces", forceSec / total},
                                       {"element", elemShare},
                                       {"nodes", nodeShare},
                                       {"integrate", integrateShare}}}});
                if (!a.json)
                    std::printf("%9d %7d %9s %8ld %14.4g %12.1f %12.1f %12.1f\n", m.elements(), th, precisionName,
                                steps, rate, 100 * elemShare, 100 * nodeShare, 100 * integrateShare);
            }
    }
    setThreads(0);
    if (!a.csv.empty())
        writeCsv(a.csv, j["runs"],
                 {"tets", "nodes", "threads", "precision", "steps", "seconds", "tet_steps_per_second", "stages/forces",
                  "stages/element", "stages/nodes", "stages/integrate"});
    if (a.json) printResult(j, machine);
    return 0;
}

// ---- bench cost ----

struct CostArgs {
    std::string scene;
    std::vector<std::string> sets;
    bool json = false;
    int threads = 0;
    std::string csv;  // the variants as CSV
};

// The scene run without rendering by the library's Simulation, as `cutsim run --no-render` runs it.
json runVariant(const std::string& scene, std::vector<std::string> sets, int threads) {
    const SceneDef def = loadScene(scene, sets);
    Simulation::Options so;
    so.threads = threads;
    Simulation sim(def, so);
    const Stopwatch wall;
    while (sim.status() == RunStatus::Running && !sim.finished()) sim.step();
    sim.finish();
    json r = sim.report({{"wall_time", wall.seconds() + sim.record().wallSetup}});
    return r;
}

int runCost(const CostArgs& a) {
    const json machine = machineJson();
    // The scene as given, then without each optional part it uses: the subsystems it leaves out
    // must cost nothing, and each one it uses shows up as the difference.
    struct Variant {
        std::string name;
        std::vector<std::string> sets;
    };
    const SceneDef def = loadScene(a.scene, a.sets);
    std::vector<Variant> variants = {{"as given", {}}};
    if (!def.forces.empty()) variants.push_back({"without loads", {"loads.forces=[]"}});
    if (def.damping != 0) variants.push_back({"without damping", {"material.damping=0"}});
    if (def.writeVtu) variants.push_back({"without final.vtu", {"output.vtu=false"}});
    json j;
    j["scene"] = a.scene;
    j["variants"] = json::array();
    for (auto& v : variants) {
        std::vector<std::string> sets = a.sets;
        sets.insert(sets.end(), v.sets.begin(), v.sets.end());
        json r;
        try {
            r = runVariant(a.scene, sets, a.threads);
        } catch (const InputError& e) {
            if (v.sets.empty()) throw;
            continue;  // the scene format has no such switch for this scene: skip the variant
        }
        const double steps = std::max(1.0, r["steps"].get<double>());
        json perStep = json::object();
        for (auto& [k, val] : r["stages"].items()) perStep[k] = val.get<double>() / steps;
        j["variants"].push_back({{"name", v.name},
                                 {"status", r["status"]},
                                 {"steps", r["steps"]},
                                 {"wall_time", r["wall_time"]},
                                 {"stages", r["stages"]},
                                 {"stage_seconds_per_step", perStep}});
    }
    if (!a.csv.empty())
        writeCsv(a.csv, j["variants"],
                 {"name", "status", "steps", "wall_time", "stages/loads", "stages/contact", "stages/cut",
                  "stages/forces", "stages/integrate", "stages/checks", "stages/timestep", "stages/render",
                  "stages/encode"});
    if (a.json) {
        printResult(j, machine);
        return 0;
    }
    std::printf("scene %s (no rendering)\n%-20s %8s %10s", a.scene.c_str(), "variant", "steps", "wall [s]");
    const std::vector<std::string> stages = {"loads", "contact", "cut", "forces", "integrate", "checks", "timestep"};
    for (const auto& s : stages) std::printf(" %11s", s.c_str());
    std::printf("\n");
    for (const auto& v : j["variants"]) {
        std::printf("%-20s %8ld %10.3f", v["name"].get<std::string>().c_str(), v["steps"].get<long>(),
                    v["wall_time"].get<double>());
        for (const auto& s : stages) std::printf(" %11.4g", v["stages"][s].get<double>());
        std::printf("\n");
    }
    std::printf("(stage seconds over the run; a stage the scene does not use stays 0)\n");
    return 0;
}

// Extensions of `bench`: one line per configuration or subcommand from elsewhere, e.g.
//   addAccuracyConfig("mi-bar", miBarPoints);
void stepOptions(CLI::App& c, StepArgs& a) {
    jsonFlag(c, a.json, "{runs: [{tets, threads, precision, steps, tet_steps_per_second, stages}]}", true);
    c.add_option("--seconds", a.seconds, "Measuring time per configuration [s]")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    tinyFlag(c, a.tiny, "one small box");
    csvOption(c, a.csv, "runs");
}

void costOptions(CLI::App& c, CostArgs& a) {
    c.add_option("SCENE", a.scene, "Scene file")->required();
    c.add_option("--set", a.sets, "Override a scene value: key.path=value");
    threadsOption(c, a.threads, "Worker threads (0 = all cores)", 0);
    jsonFlag(c, a.json, "{scene, variants: [{name, steps, wall_time, stages, stage_seconds_per_step}]}", true);
    csvOption(c, a.csv, "variants");
}

}  // namespace

void addStepCostBench() {
    addSubcommand("step",
                  "Tet-steps per second on boxes of 1k to 1M tets, 1 and 2 threads, double and "
                  "single-precision forces, and the share of each stage",
                  stepOptions, runStep);
    addSubcommand("cost", "Per-stage cost of a scene (no rendering), as given and without each optional part",
                  costOptions, runCost);
}

}  // namespace cutsim::bench
