// `cutsim bench capture`: what capture costs in real runs. Each scene runs to its end as `cutsim
// run` runs it (its deformation, cuts and frames, PNGs and video as its capture settings ask) at
// the size asked, and its report.json gives the per-frame cost of each part of the capture (the
// snapshot of the frame's state, drawing with the HUD, reading the frame back, the hand-off to the
// PNG and video writers, their drain at the end), the physics stages, and how much of the two the
// pipeline hid: wall time against their sum and against the larger of them.
#include "bench/bench.hpp"
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
    int runs = 1;
    int threads = 0;
    std::string keep;  // keep the last run's output folder here
};

// CPU time of this process's threads or of its waited-for children (ffmpeg) [s].
double cpuSeconds(int who) {
    rusage u{};
    getrusage(who, &u);
    auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
    return s(u.ru_utime) + s(u.ru_stime);
}

double loadAverage() {
    double l[1] = {0};
    return getloadavg(l, 1) == 1 ? l[0] : -1;
}

int runCapture(const CaptureArgs& a) {
    namespace fs = std::filesystem;
    const fs::path tmp = fs::temp_directory_path() / ("cutsim_bench_capture_" + std::to_string(::getpid()));
    std::printf("scene,run,mode,width,height,frames,wall_s,setup_s,physics_s,render_s,encode_s,snapshot_ms,draw_ms,"
                "read_ms,handoff_ms,finish_ms,capture_ms_per_frame,waited_s,wall_over_max,wall_over_sum,"
                "cpu_ms_per_frame,ffmpeg_cpu_ms_per_frame,load\n");
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
            app::RunOptions ro;
            ro.out = (tmp / "out").string();
            ro.quiet = true;
            ro.threads = a.threads;
            ro.pipelined = !a.serial;
            const double load = loadAverage();
            const double cpu0 = cpuSeconds(RUSAGE_SELF), child0 = cpuSeconds(RUSAGE_CHILDREN);
            const int code = app::runScene(sc, ro);
            const double cpu = cpuSeconds(RUSAGE_SELF) - cpu0, child = cpuSeconds(RUSAGE_CHILDREN) - child0;
            std::ifstream in(fs::path(ro.out) / "report.json");
            const json rep = json::parse(in);
            if (code != 0 || !rep.contains("capture")) {
                std::fprintf(stderr, "%s: %s (exit %d)\n", file.c_str(), rep.value("status", "?").c_str(), code);
                status = code ? code : 1;
                continue;
            }
            const json& st = rep["stages"];
            const json& c = rep["capture"];
            double physics = 0;
            for (const char* k : {"loads", "contact", "cut", "forces", "integrate", "checks", "timestep"})
                physics += st.value(k, 0.0);
            const double render = st.value("render", 0.0), encode = st.value("encode", 0.0);
            const double wall = rep.value("wall_time", 0.0), setup = c.value("setup_seconds", 0.0);
            const int n = std::max(1, c.value("frames", 0));
            auto ms = [&](const char* k) { return 1e3 * c.value(k, 0.0) / n; };
            std::printf("%s,%d,%s,%d,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.3f,%.3f,%.3f,%.1f,"
                        "%.1f,%.2f\n",
                        sc.name.c_str(), r, a.serial ? "serial" : "pipelined", a.width, a.height, n, wall, setup,
                        physics, render, encode, ms("snapshot_seconds"), ms("draw_seconds"), ms("read_seconds"),
                        ms("handoff_seconds"), ms("finish_seconds"), 1e3 * (render + encode) / n,
                        c.value("waited_seconds", 0.0), wall / std::max(physics, render + encode),
                        wall / (physics + render + encode), 1e3 * cpu / n, 1e3 * child / n, load);
            std::fflush(stdout);
            if (!a.keep.empty() && r + 1 == a.runs) {
                fs::remove_all(a.keep);
                fs::create_directories(fs::path(a.keep).parent_path().empty() ? fs::path(".")
                                                                              : fs::path(a.keep).parent_path());
                fs::rename(ro.out, a.keep);
            }
        }
    }
    fs::remove_all(tmp);
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
}

}  // namespace

void addCaptureBench() {
    addSubcommand("capture",
                  "Capture in real runs: each scene run to its end with its frames, deformation and cuts; per "
                  "frame the snapshot, draw (with the HUD), read-back and hand-off to the PNG and video "
                  "writers, the physics stages, and how much the pipeline overlapped them (CSV)",
                  captureOptions, runCapture);
}

}  // namespace cutsim::bench
