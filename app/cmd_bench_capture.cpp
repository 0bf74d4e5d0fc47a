// `cutsim bench capture`: frames per second of the capture path of a scene, split into its parts:
// the snapshot from the state (physics), drawing with the HUD, reading the frame back, and the
// hand-off to the video encoder (its writer thread encodes meanwhile), and the CPU time a frame
// costs this process and ffmpeg: on 2 cores, 60 fps needs their sum under 33 ms. The state stays at the
// scene's start, so the number is the capture path alone, not the simulation.
#include "bench.hpp"
#include "commands.hpp"

#include "sim/simulation.hpp"
#include "snapshot/scene_snapshot.hpp"
#include "util/stopwatch.hpp"

#ifdef CUTSIM_HAVE_RENDER
#include "renderer.hpp"
#include "png_writer.hpp"
#include "video.hpp"
#endif

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>

#include <sys/resource.h>

namespace cutsim::app {
namespace {

// CPU time of this process (all its threads, llvmpipe's too) or of its waited-for children [s].
double cpuSeconds(int who) {
    rusage u{};
    getrusage(who, &u);
    auto s = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
    return s(u.ru_utime) + s(u.ru_stime);
}

struct CaptureArgs {
    std::string scene = "assets/scenes/demo.json";
    int frames = 60;
    int width = 1280, height = 720;
    bool hud = true;
    bool video = true;
    int samples = 0;  // 0: the scene's capture.samples
    bool smooth = true;
    std::string save;  // PNG of the last timed frame
};

int runCapture(const CaptureArgs& a) {
#ifndef CUTSIM_HAVE_RENDER
    (void)a;
    throw std::runtime_error("this cutsim was built without the renderer (-DCUTSIM_RENDER=OFF)");
#else
    const SceneDef sc = loadScene(a.scene);
    Simulation::Options so;
    so.renderSurface = true;
    Simulation sim(sc, so);
    SceneSnapshot scene(sc, sim.model(), sim.analyzer().estimates().r1r, sim.dt(), sim.surface());
    render::RenderOptions ro;
    ro.width = a.width;
    ro.height = a.height;
    ro.hud = a.hud;
    ro.samples = a.samples > 0 ? a.samples : sc.capture.samples;
    ro.smoothEdges = a.smooth;
    ro.xray = sc.capture.xray;
    ro.floor = sc.capture.floor;
    render::Renderer renderer(ro);
    std::unique_ptr<render::VideoEncoder> video;
    const std::string mp4 = (std::filesystem::temp_directory_path() / "cutsim_bench_capture.mp4").string();
    if (a.video && !render::findOnPath("ffmpeg").empty() && a.width % 2 == 0 && a.height % 2 == 0)
        video = std::make_unique<render::VideoEncoder>(mp4, a.width, a.height, sc.capture.fps);
    const FrameInfo fi = frameInfoOf(sim, std::numeric_limits<double>::quiet_NaN());

    // Warm-up (shader compilation, ImGui's hidden first frame), then the timed frames.
    double snapT = 0, drawT = 0, readT = 0, handT = 0, cpu0 = 0;
    for (int f = -3; f < a.frames; ++f) {
        if (f == 0) cpu0 = cpuSeconds(RUSAGE_SELF);
        const Stopwatch t0;
        const RenderSnapshot& snap = scene.update(sim.model(), sim.state(), fi);
        const double t1 = t0.seconds();
        renderer.draw(snap);
        const double t2 = t0.seconds();
        render::Image img = video ? video->spareFrame() : render::Image{};
        renderer.read(img);
        const double t3 = t0.seconds();
        if (!a.save.empty() && f == a.frames - 1) render::writePng(a.save, img);
        if (video) video->addFrame(std::move(img));
        const double t4 = t0.seconds();
        if (f < 0) continue;
        snapT += t1;
        drawT += t2 - t1;
        readT += t3 - t2;
        handT += t4 - t3;
    }
    const double cpuT = cpuSeconds(RUSAGE_SELF) - cpu0;
    const Stopwatch tf;
    if (video) video->finish();
    const double finishT = tf.seconds();
    const double encoderCpu = cpuSeconds(RUSAGE_CHILDREN) / (a.frames + 3);  // ffmpeg, warm-up frames too
    std::filesystem::remove(mp4);
    const double n = a.frames, total = snapT + drawT + readT + handT;
    std::printf("scene,width,height,hud,samples,frames,snapshot_ms,draw_ms,read_ms,handoff_ms,frame_ms,fps,"
                "cpu_ms_per_frame,encoder_cpu_ms_per_frame,encoder_drain_s,renderer\n");
    std::printf("%s,%d,%d,%d,%d,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.1f,%.2f,%.2f,%.2f,%s\n", sc.name.c_str(), a.width,
                a.height, a.hud ? 1 : 0, renderer.samples(), a.frames, 1e3 * snapT / n, 1e3 * drawT / n,
                1e3 * readT / n, 1e3 * handT / n, 1e3 * total / n, n / total, 1e3 * cpuT / n, 1e3 * encoderCpu, finishT,
                renderer.glRenderer().c_str());
    return 0;
#endif
}

}  // namespace

void addCaptureBench() {
    addBenchSubcommand([](CLI::App& bench) {
        auto a = std::make_shared<CaptureArgs>();
        auto* c = bench.add_subcommand(
            "capture", "Capture frames per second of a scene's first frame: snapshot, draw (with the HUD), read-back "
                       "and hand-off to the video encoder, in ms per frame (CSV)");
        c->add_option("SCENE", a->scene, "Scene file")->capture_default_str();
        c->add_option("--frames", a->frames, "Timed frames (after 3 warm-up frames)")
            ->check(CLI::Range(1, 100000))
            ->capture_default_str();
        c->add_option("--width", a->width, "Frame width [px]")->check(CLI::Range(16, 8192))->capture_default_str();
        c->add_option("--height", a->height, "Frame height [px]")->check(CLI::Range(16, 8192))->capture_default_str();
        c->add_option("--samples", a->samples,
                      "MSAA samples (1: smoothed lines and silhouettes instead); default: the scene's capture.samples")
            ->check(CLI::Range(1, 16));
        c->add_flag("!--no-smooth-edges", a->smooth, "Without anti-aliased lines and silhouettes");
        c->add_option("--save", a->save, "Write the last timed frame to this PNG");
        c->add_flag("!--no-hud", a->hud, "Without the HUD");
        c->add_flag("!--no-video", a->video, "Without the hand-off to ffmpeg");
        c->callback([a] { setExitCode(benchGuarded([&] { return runCapture(*a); })); });
    });
}

}  // namespace cutsim::app
