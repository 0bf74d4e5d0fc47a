// `cutsim bench capture`: what capture costs in real runs. Each scene runs to its end as `cutsim
// run` runs it (its deformation, cuts and frames, PNGs and video as its capture settings ask) at
// the size asked, and its report.json gives the per-frame cost of each part of the capture (the
// snapshot of the frame's state, drawing with the HUD, reading the frame back, the hand-off to the
// PNG and video writers, their drain at the end), the physics stages, and how much of the two the
// pipeline hid: wall time against their sum and against the larger of them.
#include "bench/bench.hpp"
#include "bench/machine.hpp"
#include "bench/options.hpp"
#include "app/commands.hpp"
#include "app/run.hpp"

#include "sim/scene.hpp"
#include "util/stopwatch.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <sys/resource.h>
#include <unistd.h>

namespace cutsim::bench {
namespace {

using nlohmann::json;

struct CaptureArgs {
    std::vector<std::string> scenes{"assets/scenes/demo.json"};
    std::vector<std::string> sets;
    int width = 1280, height = 720;
    bool hud = true;
    bool video = true;
    bool serial = false;
    bool json = false;
    int runs = 1;
    int threads = 0;
    std::string keep;  // keep the last run's output folder here
    std::string csv;   // the runs as CSV
};

// A run's columns, in the CSV's order: times in s, per-frame times in ms, load = the 1-minute load
// average as the run started.
const std::vector<std::string> kColumns = {"scene",
                                           "run",
                                           "mode",
                                           "width",
                                           "height",
                                           "frames",
                                           "wall_s",
                                           "setup_s",
                                           "physics_s",
                                           "render_s",
                                           "encode_s",
                                           "snapshot_ms",
                                           "draw_ms",
                                           "read_ms",
                                           "handoff_ms",
                                           "finish_ms",
                                           "capture_ms_per_frame",
                                           "waited_s",
                                           "wall_over_max",
                                           "wall_over_sum",
                                           "cpu_ms_per_frame",
                                           "ffmpeg_cpu_ms_per_frame",
                                           "load",
                                           "status"};

// CPU time of this process's threads or of its waited-for children (ffmpeg) [s].
double cpuSeconds(int who) {
    rusage u{};
    getrusage(who, &u);
    auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
    return s(u.ru_utime) + s(u.ru_stime);
}

// One run of a scene: the capture's parts per frame and the physics from its report.json, the CPU
// time of this process and of ffmpeg over the run; status is the run's ("ok" or why it stopped).
json captureRun(const SceneDef& sc, const CaptureArgs& a, int r, const std::string& out, int& code) {
    app::RunOptions ro;
    ro.out = out;
    ro.quiet = true;
    ro.threads = a.threads;
    ro.pipelined = !a.serial;
    const json load = loadAverage();
    const double cpu0 = cpuSeconds(RUSAGE_SELF), child0 = cpuSeconds(RUSAGE_CHILDREN);
    code = app::runScene(sc, ro);
    const double cpu = cpuSeconds(RUSAGE_SELF) - cpu0, child = cpuSeconds(RUSAGE_CHILDREN) - child0;
    std::ifstream in(std::filesystem::path(out) / "report.json");
    const json rep = json::parse(in);
    json row = {{"scene", sc.name}, {"run", r},           {"mode", a.serial ? "serial" : "pipelined"},
                {"width", a.width}, {"height", a.height}, {"status", rep.value("status", "?")}};
    if (!load.empty()) row["load"] = load[0];
    if (code != 0 || !rep.contains("capture")) return row;
    const json& st = rep["stages"];
    const json& c = rep["capture"];
    double physics = 0;
    for (const char* k : {"loads", "contact", "cut", "forces", "integrate", "checks", "timestep"})
        physics += st.value(k, 0.0);
    const double render = st.value("render", 0.0), encode = st.value("encode", 0.0);
    const double wall = rep.value("wall_time", 0.0);
    const int n = std::max(1, c.value("frames", 0));
    auto ms = [&](const char* k) { return 1e3 * c.value(k, 0.0) / n; };
    row.update({{"frames", n},
                {"wall_s", wall},
                {"setup_s", c.value("setup_seconds", 0.0)},
                {"physics_s", physics},
                {"render_s", render},
                {"encode_s", encode},
                {"snapshot_ms", ms("snapshot_seconds")},
                {"draw_ms", ms("draw_seconds")},
                {"read_ms", ms("read_seconds")},
                {"handoff_ms", ms("handoff_seconds")},
                {"finish_ms", ms("finish_seconds")},
                {"capture_ms_per_frame", 1e3 * (render + encode) / n},
                {"waited_s", c.value("waited_seconds", 0.0)},
                {"wall_over_max", wall / std::max(physics, render + encode)},
                {"wall_over_sum", wall / (physics + render + encode)},
                {"cpu_ms_per_frame", 1e3 * cpu / n},
                {"ffmpeg_cpu_ms_per_frame", 1e3 * child / n}});
    return row;
}

int runCapture(const CaptureArgs& a) {
    namespace fs = std::filesystem;
    const json machine = machineJson();
    const fs::path tmp = fs::temp_directory_path() / ("cutsim_bench_capture_" + std::to_string(::getpid()));
    // without --json the runs go to stdout as CSV lines, each as its run ends
    if (!a.json) std::printf("%s", csvText(json::array(), kColumns).c_str());
    json runs = json::array();
    int status = 0;
    for (const std::string& file : a.scenes) {
        std::vector<std::string> sets = a.sets;
        sets.insert(sets.end(),
                    {"capture.width=" + std::to_string(a.width), "capture.height=" + std::to_string(a.height),
                     std::string("capture.hud=") + (a.hud ? "true" : "false"),
                     std::string("capture.video=") + (a.video ? "true" : "false")});
        const SceneDef sc = loadScene(file, sets);
        if (!sc.capture.enabled) throw InputError(file + ": capture is off; nothing to measure");
        for (int r = 0; r < a.runs; ++r) {
            const std::string out = (tmp / "out").string();
            int code = 0;
            const json row = captureRun(sc, a, r, out, code);
            runs.push_back(row);
            if (row["status"] != "ok" || !row.contains("frames")) {
                std::fprintf(stderr, "%s: %s (exit %d)\n", file.c_str(), row["status"].get<std::string>().c_str(),
                             code);
                status = code ? code : 1;
            }
            if (!a.json) {
                std::printf("%s", csvText(json::array({row}), kColumns, false).c_str());
                std::fflush(stdout);
            }
            if (!a.keep.empty() && r + 1 == a.runs) {
                fs::remove_all(a.keep);
                fs::create_directories(fs::path(a.keep).parent_path().empty() ? fs::path(".")
                                                                              : fs::path(a.keep).parent_path());
                fs::rename(out, a.keep);
            }
        }
    }
    fs::remove_all(tmp);
    if (!a.csv.empty()) writeCsv(a.csv, runs, kColumns);
    if (a.json)
        printResult(json{{"width", a.width},
                         {"height", a.height},
                         {"hud", a.hud},
                         {"video", a.video},
                         {"mode", a.serial ? "serial" : "pipelined"},
                         {"sets", a.sets},
                         {"runs", runs}},
                    machine);
    return status;
}

void captureOptions(CLI::App& c, CaptureArgs& a) {
    c.add_option("SCENES", a.scenes, "Scene files")->capture_default_str();
    c.add_option("--set", a.sets, "Override a scene value: key.path=value (JSON value)");
    c.add_option("--width", a.width, "Frame width [px]")->check(CLI::Range(16, 8192))->capture_default_str();
    c.add_option("--height", a.height, "Frame height [px]")->check(CLI::Range(16, 8192))->capture_default_str();
    c.add_flag("!--no-hud", a.hud, "Without the HUD");
    c.add_flag("!--no-video", a.video, "Without the video");
    c.add_flag("--serial", a.serial, "Draw each frame before stepping on (no pipeline), to compare");
    c.add_option("--runs", a.runs, "Runs of each scene")->check(CLI::Range(1, 1000))->capture_default_str();
    threadsOption(c, a.threads, "Physics threads (0: chosen by measuring)", 0);
    c.add_option("--keep", a.keep, "Keep the last run's output folder (frames, video, report.json) here");
    jsonFlag(c, a.json, "{width, height, hud, video, mode, sets, runs: [...]} instead of the CSV", true);
    csvOption(c, a.csv, "runs");
}

}  // namespace

void addCaptureBench() {
    addSubcommand("capture",
                  "Capture in real runs: each scene run to its end with its frames, deformation and cuts; per "
                  "frame the snapshot, draw (with the HUD), read-back and hand-off to the PNG and video "
                  "writers, the physics stages, and how much the pipeline overlapped them (CSV, or --json)",
                  captureOptions, runCapture);
}

}  // namespace cutsim::bench
