// `cutsim view`: a headless run under a virtual X server draws the scene and saves a screenshot;
// without a display it stops with a clear message.
#include "image_diff.hpp"
#include "png_writer.hpp"
#include "renderer.hpp"
#include "test_support.hpp"
#include "video.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sys/wait.h>

namespace cutsim {
namespace {

// A window under a virtual X server. Under AddressSanitizer the X11/GLX driver, which Mesa loads
// and unloads at run time, leaves 112 bytes that LeakSanitizer reports against an unloaded module
// at exit; leak checking is off for these child processes only (every other test keeps it).
const std::string kXvfb = "env ASAN_OPTIONS=detect_leaks=0 xvfb-run -a -s '-screen 0 1280x1024x24' ";

// Runs a shell command; returns its exit code, stderr in err.
int shell(const std::string& cmd, const std::string& dir, std::string* err) {
    const std::string e = dir + "/stderr.txt";
    const int status = std::system((cmd + " >" + dir + "/stdout.txt 2>" + e).c_str());
    *err = test::readText(e);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(View, HeadlessFramesWriteAScreenshotOfTheScene) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    const std::string png = dir + "/out.png";
    std::string err;
    const int code = shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/bar_sag.json") +
                               " --frames 5 --width 960 --height 540 --screenshot " + png,
                           dir, &err);
    ASSERT_EQ(code, 0) << err;
    ASSERT_TRUE(std::filesystem::exists(png)) << err;
    const render::Image img = render::readPng(png);
    ASSERT_EQ(img.width, 960);
    ASSERT_EQ(img.height, 540);

    // The bar is at the centre of the scene's camera: there most pixels are neither the
    // background nor the floor grid (background + 31 per channel), but colour-mapped surface.
    const auto bg = render::RenderOptions{}.background;
    int object = 0, total = 0;
    for (int y = img.height / 2 - 40; y < img.height / 2 + 40; ++y)
        for (int x = img.width / 2 - 80; x < img.width / 2 + 80; ++x) {
            const auto p = img.pixel(x, y);
            int d = 0;
            for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(int(p[c]) - int(bg[c])));
            object += d > 45;
            ++total;
        }
    EXPECT_GT(object, total / 3) << object << " of " << total << " centre pixels differ from the background";
    // Corners: background or grid, not surface.
    const auto corner = img.pixel(img.width - 2, 2);
    for (int c = 0; c < 3; ++c) EXPECT_LE(std::abs(int(corner[c]) - int(bg[c])), 45);
}

// Scripted cuts happen in the live view too: after the liver's four cuts (t = 0.2 to 0.8 s) the
// cut faces show in their own colour (red; the time-step colour map has no red), before them none.
TEST(View, ScriptedCutsShowTheirFaces) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    auto redPixels = [&](int frames) {
        const std::string png = dir + "/cut_" + std::to_string(frames) + ".png";
        std::string err;
        const int code =
            shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/liver_cuts.json") +
                      " --frames " + std::to_string(frames) + " --width 960 --height 540 --screenshot " + png,
                  dir, &err);
        EXPECT_EQ(code, 0) << err;
        const render::Image img = render::readPng(png);
        int red = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                const auto p = img.pixel(x, y);
                red += p[0] > 80 && p[0] > 1.6 * p[1] && p[0] > 1.4 * p[2];
            }
        return red;
    };
    EXPECT_EQ(redPixels(3), 0);     // t = 0.1 s: no cut yet
    EXPECT_GT(redPixels(26), 100);  // t = 0.87 s: four cuts made (measured 165: the last cut's two
                                    // free pieces below one element are fused back, not falling)
}

// A blade cuts in the live view as in `cutsim run`: blade.json's stroke has not reached the liver at
// t = 0.17 s and has severed its front lobe by t = 0.47 s (0.374 s in `cutsim run`), one stroke,
// whose faces show red.
TEST(View, BladeCutsAsItMoves) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    auto run = [&](int frames, int* red) {
        const std::string png = dir + "/blade_" + std::to_string(frames) + ".png";
        std::string err;
        const int code =
            shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/blade.json") +
                      " --frames " + std::to_string(frames) + " --width 960 --height 540 --screenshot " + png,
                  dir, &err);
        EXPECT_EQ(code, 0) << err;
        const render::Image img = render::readPng(png);
        *red = 0;
        for (int y = 0; y < img.height; ++y)
            for (int x = 0; x < img.width; ++x) {
                const auto p = img.pixel(x, y);
                *red += p[0] > 80 && p[0] > 1.6 * p[1] && p[0] > 1.4 * p[2];
            }
        return test::readText(dir + "/stdout.txt");
    };
    int red = 0;
    EXPECT_NE(run(5, &red).find(", 0 cuts,"), std::string::npos);
    EXPECT_LT(red, 20) << "before the cut";  // a few edge pixels of the shading (measured 2)
    EXPECT_NE(run(14, &red).find(", 1 cuts,"), std::string::npos);
    EXPECT_GT(red, 1000) << "after the cut";
    std::printf("red pixels after the stroke: %d\n", red);
}

// Tools act in the live view through Bullet as in `cutsim run`. A tool the mouse has moved holds
// its pose (--tool-at places it as a drag would): held far above, the probe scene's probe never
// touches; held 4 mm into the liver's top, it pushes within 0.1 s, when the keyframed probe has not
// reached the surface yet.
TEST(View, ToolPressesAndHoldsWhereTheMouseLeavesIt) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    auto maxForce = [&](int frames, const std::string& extra) {
        std::string err;
        const int code = shell(kXvfb + std::string(CUTSIM_BINARY) + " view " +
                                   test::source("assets/scenes/probe.json") + " --frames " + std::to_string(frames) +
                                   " --width 320 --height 180 --screenshot " + dir + "/t.png " + extra,
                               dir, &err);
        EXPECT_EQ(code, 0) << err;
        const std::string out = test::readText(dir + "/stdout.txt");
        const auto at = out.find("(max ");
        EXPECT_NE(at, std::string::npos) << out;
        return at == std::string::npos ? -1.0 : std::strtod(out.c_str() + at + 5, nullptr);
    };
    EXPECT_EQ(maxForce(20, "--tool-at 0 0.5 0"), 0.0);  // held above: no contact at all
    EXPECT_EQ(maxForce(3, ""), 0.0);                    // t = 0.1 s: keyframed probe still above
    EXPECT_GT(maxForce(3, "--tool-at 0 0.125 0.008"), 0.1);
}

// Box around the pixels that differ between two frames of the same size; empty: no pixel differs.
struct PixelBox {
    int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
    long area() const { return x1 < x0 ? 0 : long(x1 - x0 + 1) * long(y1 - y0 + 1); }
};
PixelBox differingBox(const render::Image& a, const render::Image& b) {
    PixelBox box;
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            const auto p = a.pixel(x, y), q = b.pixel(x, y);
            if (p[0] == q[0] && p[1] == q[1] && p[2] == q[2]) continue;
            box = {std::min(box.x0, x), std::min(box.y0, y), std::max(box.x1, x), std::max(box.y1, y)};
        }
    return box;
}

// h hides the panel: the same frames with and without it differ only where the panel was, and the
// panel keeps to a corner of a 960x540 window (under a sixth of it).
TEST(View, PanelHidesWithHAndKeepsToACorner) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    std::string err;
    for (const std::string& run : {std::string("shown"), std::string("hidden")}) {
        const int code =
            shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/bar_sag.json") +
                      " --threads 1 --frames 3 --width 960 --height 540 --screenshot " + dir + "/" + run + ".png" +
                      (run == "hidden" ? " --press 0,h" : ""),
                  dir, &err);
        ASSERT_EQ(code, 0) << err;
    }
    const render::Image shown = render::readPng(dir + "/shown.png"), hidden = render::readPng(dir + "/hidden.png");
    const PixelBox panel = differingBox(shown, hidden);
    std::printf("panel: %d x %d px of 960 x 540\n", panel.x1 - panel.x0 + 1, panel.y1 - panel.y0 + 1);
    EXPECT_GT(panel.area(), 0) << "the panel must show without h";
    EXPECT_LT(panel.area(), 960L * 540L / 6)
        << "panel " << panel.x0 << "," << panel.y0 << " to " << panel.x1 << "," << panel.y1;
    EXPECT_LT(panel.x1, 960 / 2);
}

// --scene-camera: the view follows the scene's camera keyframes as `cutsim run` frames them; with
// the panel hidden its frame is the run's frame of the same time, at the golden tolerance.
TEST(View, SceneCameraFollowsTheKeyframesAsRunDoes) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    const int frames = 6;  // 0.2 s at 30 fps, half way along the camera's move
    const std::string sets =
        " --threads 1 --set 'camera.keyframes=[{\"time\":0,\"eye\":[0.5,-1.6,0.25],\"target\":[0.5,0.05,-0.05]},"
        "{\"time\":0.4,\"eye\":[1.8,-0.4,0.6],\"target\":[0.5,0,-0.05]}]' --set capture.width=320 "
        "--set capture.height=180 ";
    std::string err;
    int code =
        shell(std::string(CUTSIM_BINARY) + " run " + test::source("assets/scenes/bar_sag.json") + " --quiet --out " +
                  dir + "/run" + sets + "--set capture.hud=false --set capture.video=false --set duration=" +
                  std::to_string((frames + 1) / 30.0),
              dir, &err);
    ASSERT_EQ(code, 0) << err;
    code = shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/bar_sag.json") +
                     " --scene-camera --press 0,h --frames " + std::to_string(frames) + " --screenshot " + dir +
                     "/view.png" + sets,
                 dir, &err);
    ASSERT_EQ(code, 0) << err;
    char name[32];
    std::snprintf(name, sizeof name, "/run/frames/frame_%06d.png", frames);
    const render::Image run = render::readPng(dir + name), view = render::readPng(dir + "/view.png");
    ASSERT_EQ(view.width, run.width);
    const render::ImageDiff d = render::diffImages(run, view, 5);
    EXPECT_LE(d.fraction, 0.001) << "max difference " << d.maxChannel;
    // Without the option the view keeps the first keyframe's camera: a different picture.
    code = shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/bar_sag.json") +
                     " --press 0,h --frames " + std::to_string(frames) + " --screenshot " + dir + "/still.png" + sets,
                 dir, &err);
    ASSERT_EQ(code, 0) << err;
    EXPECT_GT(render::diffImages(run, render::readPng(dir + "/still.png"), 5).fraction, 0.05);
}

// `cutsim run` and `cutsim view` drive the same Simulation: a scene with scripted cuts and a
// blade, run offscreen for N frames' time and viewed for N frames, ends with the same steps, the
// same step after every cut and bitwise the same positions and velocities (report state_hash).
TEST(View, RunAndViewTakeTheSameSteps) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    const int frames = 21;  // 0.7 s at 30 fps: the blade's stroke and both scripted cuts
    const std::string sets =
        " --threads 1 --set 'cutting.cuts=[{\"time\":0.25,\"point\":[-0.085,0.06,0.0],\"normal\":[1,0,0.15]},"
        "{\"time\":0.6,\"point\":[-0.045,0.06,0.0],\"normal\":[1,0.1,0]}]' ";
    std::string err;
    int code = shell(std::string(CUTSIM_BINARY) + " run " + test::source("assets/scenes/blade.json") +
                         " --no-render --quiet --out " + dir + "/run" + sets +
                         "--set duration=" + std::to_string(frames / 30.0),
                     dir, &err);
    ASSERT_EQ(code, 0) << err;
    code =
        shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/blade.json") + " --frames " +
                  std::to_string(frames) + " --width 320 --height 180 --report " + dir + "/view.json" + sets,
              dir, &err);
    ASSERT_EQ(code, 0) << err;
    const auto run = nlohmann::json::parse(test::readText(dir + "/run/report.json"));
    const auto view = nlohmann::json::parse(test::readText(dir + "/view.json"));
    EXPECT_EQ(run["steps"], view["steps"]);
    EXPECT_EQ(run["state_hash"], view["state_hash"]);
    ASSERT_EQ(run["cuts"].size(), view["cuts"].size());
    int scripted = 0, blade = 0;
    for (size_t i = 0; i < run["cuts"].size(); ++i) {
        EXPECT_EQ(run["cuts"][i]["key"], view["cuts"][i]["key"]);
        EXPECT_EQ(run["cuts"][i]["dt_used"].get<double>(), view["cuts"][i]["dt_used"].get<double>()) << i;
        EXPECT_EQ(run["cuts"][i]["split"], view["cuts"][i]["split"]) << i;
        const std::string key = run["cuts"][i]["key"];
        scripted += key.rfind("cutting.cuts", 0) == 0;
        blade += key.rfind("tools", 0) == 0;
    }
    EXPECT_EQ(scripted, 2);
    EXPECT_GT(blade, 5);
    EXPECT_EQ(run["pieces"], view["pieces"]);
}

// A take recorded in the live view replays offscreen: a scripted shift-drag moves the blade
// down through the liver in four jumps (holding it between them), x brings a scripted cut
// forward; `cutsim run` of the recorded scene makes the same cuts (keys, elements split), the
// same pieces, the same steps and bitwise the same final state.
TEST(View, RecordedTakeReplaysWithTheSameCutsAndPieces) {
    if (render::findOnPath("xvfb-run").empty()) GTEST_SKIP() << "xvfb-run not installed";
    const std::string dir = test::tempDir();
    const std::string cut = " --set 'cutting.cuts=[{\"time\":0.8,\"point\":[-0.085,0.06,0.0],\"normal\":[1,0,0.15]}]' ";
    std::string err;
    int code = shell(kXvfb + std::string(CUTSIM_BINARY) + " view " + test::source("assets/scenes/blade.json") +
                         " --frames 12 --width 320 --height 180 --threads 1" + cut +
                         "--drag 2,0,30 --drag 4,0,30 --drag 6,0,30 --drag 8,0,30 --press 5,x "
                         "--orbit 10,60,0 --record-camera --record " +
                         dir + "/take.json --report " + dir + "/view.json",
                     dir, &err);
    ASSERT_EQ(code, 0) << err;
    const auto take = nlohmann::json::parse(test::readText(dir + "/take.json"));
    EXPECT_GE(take["tools"][0]["keyframes"].size(), 8u) << take["tools"][0].dump();
    EXPECT_LT(take["cutting"]["cuts"][0]["time"].get<double>(), 0.2);  // made at frame 5 with x
    const auto& cam = take["camera"]["keyframes"];                     // still, turned at frame 10, still again
    ASSERT_GE(cam.size(), 2u) << cam.dump();
    EXPECT_NE(cam.front()["eye"], cam.back()["eye"]) << cam.dump();
    code = shell(std::string(CUTSIM_BINARY) + " run " + dir + "/take.json --no-render --quiet --threads 1 --out " +
                     dir + "/replay",
                 dir, &err);
    ASSERT_EQ(code, 0) << err;
    const auto view = nlohmann::json::parse(test::readText(dir + "/view.json"));
    const auto run = nlohmann::json::parse(test::readText(dir + "/replay/report.json"));
    ASSERT_EQ(run["cuts"].size(), view["cuts"].size());
    int blade = 0;
    for (size_t i = 0; i < run["cuts"].size(); ++i) {
        EXPECT_EQ(run["cuts"][i]["key"], view["cuts"][i]["key"]) << i;
        EXPECT_EQ(run["cuts"][i]["time"], view["cuts"][i]["time"]) << i;
        EXPECT_EQ(run["cuts"][i]["split"], view["cuts"][i]["split"]) << i;
        EXPECT_EQ(run["cuts"][i]["elements"], view["cuts"][i]["elements"]) << i;
        blade += run["cuts"][i]["key"].get<std::string>().rfind("tools", 0) == 0;
    }
    EXPECT_GT(blade, 0) << "the dragged blade cut nothing";
    EXPECT_EQ(run["pieces"], view["pieces"]);
    EXPECT_EQ(run["piece_volumes"], view["piece_volumes"]);
    EXPECT_EQ(run["steps"], view["steps"]);
    EXPECT_EQ(run["state_hash"], view["state_hash"]);
    std::printf("take: %zu cuts (%d by the blade), %d pieces\n", run["cuts"].size(), blade, run["pieces"].get<int>());
}

TEST(View, WithoutADisplayExitsWithAClearMessage) {
    const std::string dir = test::tempDir();
    std::string err;
    const int code =
        shell("env -u DISPLAY -u WAYLAND_DISPLAY " + std::string(CUTSIM_BINARY) + " view " +
                  test::source("assets/scenes/bar_sag.json") + " --frames 1 --screenshot " + dir + "/x.png",
              dir, &err);
    EXPECT_EQ(code, 5) << err;  // ExitCode::NoDisplay
    EXPECT_NE(err.find("display"), std::string::npos) << err;
    EXPECT_NE(err.find("DISPLAY is not set"), std::string::npos) << err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/x.png"));
}

TEST(View, BadSceneIsAnInputError) {
    const std::string dir = test::tempDir();
    std::string err;
    const int code = shell(std::string(CUTSIM_BINARY) + " view " + dir + "/missing.json --frames 1", dir, &err);
    EXPECT_EQ(code, 2) << err;
    EXPECT_NE(err.find("missing.json"), std::string::npos) << err;
}

}  // namespace
}  // namespace cutsim
