// `cutsim bench threads`: the thread count a run picks. Each scene runs to its end as `cutsim run
// --no-render --threads K` runs it, for each K asked (by default 1, 2 and 0, the count chosen by
// measuring, sim/thread_tuner.hpp), the counts taking turns in rounds (their order reversed every
// other round, so that a slow spell of the machine falls on each), and with --busy each round again
// with a process spinning on another core. Reported per run: the wall time of the whole run and of
// its steps, the count the run ended on, and its state hash (the same for every count).
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "app/run.hpp"

#include "sim/scene.hpp"
#include "util/input_error.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

namespace cutsim::bench {
namespace {

using nlohmann::json;

struct ThreadsArgs {
    std::vector<std::string> scenes;
    std::vector<std::string> sets;
    std::vector<int> threads{1, 2, 0};
    int rounds = 2;
    bool busy = false;  // each round also with another core busy
    bool json = false;
    std::string csv;
};

// One run of a scene without frames, as `cutsim run --no-render` makes it; its report.json.
json runOnce(const SceneDef& sc, int threads, const std::string& out) {
    app::RunOptions ro;
    ro.out = out;
    ro.render = false;
    ro.quiet = true;
    ro.threads = threads;
    const int code = app::runScene(sc, ro);
    std::ifstream in(std::filesystem::path(out) / "report.json");
    json rep = json::parse(in);
    rep["exit_code"] = code;
    return rep;
}

int runThreads(const ThreadsArgs& a) {
    namespace fs = std::filesystem;
    if (a.threads.empty()) throw InputError("--threads: no thread count");
    const json machine = machineJson();
    const fs::path tmp = fs::temp_directory_path() / ("cutsim_bench_threads_" + std::to_string(::getpid()));
    std::vector<SceneDef> scenes;
    for (const std::string& file : a.scenes) scenes.push_back(loadScene(file, a.sets));
    if (!a.json)
        std::printf("%-12s %5s %5s %8s %8s %8s %10s %10s %6s  %s\n", "scene", "round", "load", "threads", "chosen",
                    "wall [s]", "steps [s]", "setup [s]", "load1", "state hash");
    json runs = json::array();
    int status = 0;
    for (size_t si = 0; si < scenes.size(); ++si) {
        const SceneDef& sc = scenes[si];
        std::string hash;
        for (int r = 0; r < a.rounds; ++r) {
            std::vector<int> order = a.threads;
            if (r % 2) std::reverse(order.begin(), order.end());
            for (const bool busy : {false, true}) {
                if (busy && !a.busy) continue;
                std::optional<BusyCore> spin;
                if (busy) spin.emplace();
                for (const int th : order) {
                    const json load = loadAverage();
                    const json rep = runOnce(sc, th, (tmp / "out").string());
                    const long steps = rep.value("steps", 0L);
                    const double rate = rep.value("steps_per_second", 0.0);
                    const double wall = rep.value("wall_time", 0.0);
                    const double stepSeconds = rate > 0 ? static_cast<double>(steps) / rate : 0.0;
                    json row = {{"scene", a.scenes[si]},
                                {"name", sc.name},
                                {"round", r},
                                {"load", busy ? "busy" : "idle"},
                                {"threads", th},
                                {"threads_chosen", rep.value("threads", 0)},
                                {"wall_seconds", wall},
                                {"step_seconds", stepSeconds},
                                {"setup_seconds", wall - stepSeconds},
                                {"steps", steps},
                                {"elements", rep["mesh"].value("elements", 0)},
                                {"load_average", load.empty() ? json(nullptr) : load[0]},
                                {"status", rep.value("status", "?")},
                                {"state_hash", rep.value("state_hash", "")}};
                    if (rep["exit_code"].get<int>() != 0) status = 1;
                    // the count does not change the answer (the force stage is the same on any count)
                    if (hash.empty()) hash = row["state_hash"].get<std::string>();
                    if (row["state_hash"] != hash) {
                        std::fprintf(stderr, "%s: %d threads ended in state %s, not %s\n", a.scenes[si].c_str(), th,
                                     row["state_hash"].get<std::string>().c_str(), hash.c_str());
                        status = 1;
                    }
                    if (!a.json) {
                        std::printf("%-12s %5d %5s %8d %8d %8.3f %10.3f %10.3f %6.2f  %s\n", sc.name.c_str(), r,
                                    busy ? "busy" : "idle", th, row["threads_chosen"].get<int>(), wall, stepSeconds,
                                    wall - stepSeconds, load.empty() ? -1.0 : load[0].get<double>(),
                                    row["state_hash"].get<std::string>().c_str());
                        std::fflush(stdout);
                    }
                    runs.push_back(row);
                }
            }
        }
    }
    fs::remove_all(tmp);
    if (!a.csv.empty())
        writeCsv(a.csv, runs,
                 {"scene", "name", "round", "load", "threads", "threads_chosen", "wall_seconds", "step_seconds",
                  "setup_seconds", "steps", "elements", "load_average", "status", "state_hash"});
    if (a.json) printResult(json{{"sets", a.sets}, {"rounds", a.rounds}, {"runs", runs}}, machine);
    return status;
}

void threadsOptions(CLI::App& c, ThreadsArgs& a) {
    c.add_option("SCENES", a.scenes, "Scene files")->required();
    c.add_option("--set", a.sets, "Override a scene value: key.path=value (JSON value), in every scene");
    c.add_option("--threads", a.threads, "Thread counts, one run each a round (0: chosen by measuring)")
        ->delimiter(',')
        ->check(CLI::Range(0, 1024))
        ->capture_default_str();
    c.add_option("--rounds", a.rounds, "Rounds of runs, the counts taking turns")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    c.add_flag("--busy", a.busy, "Each round again with a process spinning on another core (started and ended here)");
    jsonFlag(c, a.json,
             "{sets, rounds, runs: [{scene, round, load, threads, threads_chosen, wall_seconds, step_seconds, "
             "setup_seconds, steps, state_hash, ...}]}",
             true);
    csvOption(c, a.csv, "runs");
}

}  // namespace

void addThreadsBench() {
    addSubcommand("threads",
                  "The thread count a run picks: scenes run as `cutsim run --no-render` on 1, 2 and a measured "
                  "number of threads, taking turns, idle and with another core busy (wall time, the count chosen)",
                  threadsOptions, runThreads);
}

}  // namespace cutsim::bench
