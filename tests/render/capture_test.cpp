// `cutsim run` captures: PNG frames can be decimated or left to the video alone; frames drawn
// beside the physics are those drawn one by one.
#include "png_writer.hpp"
#include "video.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <unistd.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;

// Its own folder: runCutsim would wipe test::tempDir().
std::string outDir(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("cutsim_capture_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    return dir.string();
}

int framesOf(const std::string& out) {
    std::ifstream in(out + "/report.json");
    return nlohmann::json::parse(in)["frames"].get<int>();
}

int pngsIn(const std::string& dir) {
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ".png";
    return n;
}

const std::string kSmall =
    " --quiet --set duration=0.2 --set capture.width=64 --set capture.height=48 --set capture.video=false";

TEST(Capture, PngEveryTwoWritesEveryOtherFrame) {
    const std::string out = outDir("every2");
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out + kSmall +
                                  " --set capture.png_every=2",
                              nullptr, &err),
              0)
        << err;
    const int frames = framesOf(out);
    ASSERT_GE(frames, 7);  // t = 0, 1/30, ..., 6/30 and the last state
    EXPECT_EQ(pngsIn(out + "/frames"), (frames + 1) / 2);
    EXPECT_TRUE(fs::exists(out + "/frames/frame_000000.png"));
    EXPECT_FALSE(fs::exists(out + "/frames/frame_000001.png"));
    const render::Image img = render::readPng(out + "/frames/frame_000002.png");
    EXPECT_EQ(img.width, 64);
    EXPECT_EQ(img.height, 48);
}

TEST(Capture, PngEveryZeroWritesNoPng) {
    const std::string out = outDir("every0");
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out + kSmall +
                                  " --set capture.png_every=0",
                              nullptr, &err),
              0)
        << err;
    EXPECT_GE(framesOf(out), 7);
    EXPECT_EQ(fs::exists(out + "/frames") ? pngsIn(out + "/frames") : 0, 0);
}

// capture.playback_fps: the video plays at that rate, slower than the 30 frames per simulated
// second it captures (ffprobe reads the stream's frame rate).
TEST(Capture, PlaybackFpsSetsTheVideoRate) {
    if (render::findOnPath("ffmpeg").empty() || render::findOnPath("ffprobe").empty())
        GTEST_SKIP() << "ffmpeg not installed";
    const std::string out = outDir("playback");
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + test::source("assets/scenes/bar_sag.json") + " --out " + out +
                                  " --quiet --set duration=0.2 --set capture.width=64 --set capture.height=48"
                                  " --set capture.png_every=0 --set capture.playback_fps=10",
                              nullptr, &err),
              0)
        << err;
    const std::string rate = out + "/rate.txt";
    ASSERT_EQ(std::system(("ffprobe -v error -select_streams v:0 -show_entries stream=r_frame_rate -of csv=p=0 " + out +
                           "/video.mp4 > " + rate)
                              .c_str()),
              0);
    std::ifstream in(rate);
    std::string r;
    in >> r;
    EXPECT_EQ(r, "10/1");
}

// critical_cuts through its first cut (t = 0.3 s): the pipelined capture draws each frame's own
// state, so its PNGs are byte for byte those of frames drawn before the next step.
TEST(Capture, PipelinedFramesAreTheSerialOnes) {
    const std::string pipelined = outDir("pipelined"), serial = outDir("serial");
    const std::string run = "bench capture " + test::source("assets/scenes/critical_cuts.json") +
                            " --width 64 --height 48 --no-video --set duration=0.4 --keep ";
    std::string out, err;
    ASSERT_EQ(test::runCutsim(run + pipelined, &out, &err), 0) << err;
    EXPECT_NE(out.find(",pipelined,"), std::string::npos) << out;
    ASSERT_EQ(test::runCutsim(run + serial + " --serial", &out, &err), 0) << err;
    EXPECT_NE(out.find(",serial,"), std::string::npos) << out;
    auto report = [](const std::string& dir) {
        std::ifstream in(dir + "/report.json");
        return nlohmann::json::parse(in);
    };
    const auto a = report(pipelined), b = report(serial);
    EXPECT_EQ(a["state_hash"], b["state_hash"]);
    ASSERT_EQ(a["frames"], b["frames"]);
    ASSERT_GE(a["frames"].get<int>(), 13);  // t = 0, 1/30, ..., 12/30 and the last state
    EXPECT_EQ(a["cuts"].size(), 1u);
    EXPECT_TRUE(a["capture"]["pipelined"].get<bool>());
    EXPECT_FALSE(b["capture"]["pipelined"].get<bool>());
    EXPECT_EQ(a["capture"]["frames"], a["frames"]);
    for (int f = 0; f < a["frames"].get<int>(); ++f) {
        char name[40];
        std::snprintf(name, sizeof name, "/frames/frame_%06d.png", f);
        EXPECT_EQ(test::readText(pipelined + name), test::readText(serial + name)) << name;
    }
    fs::remove_all(pipelined);
    fs::remove_all(serial);
}

}  // namespace
}  // namespace cutsim
