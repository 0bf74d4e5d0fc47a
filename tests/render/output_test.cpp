// PNG and video output: round trips, background writing, clear errors.
#include "png_writer.hpp"
#include "test_support.hpp"
#include "video.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace cutsim {
namespace {

using render::Image;

Image pattern(int w, int h, int seed) {
    Image img;
    img.width = w;
    img.height = h;
    img.rgba.resize(4 * size_t(w) * h);
    for (size_t i = 0; i < img.rgba.size(); ++i) img.rgba[i] = static_cast<std::uint8_t>((i * 7 + seed * 13) % 251);
    return img;
}

TEST(RenderOutput, PngRoundTrip) {
    const std::string dir = test::tempDir();
    const Image img = pattern(33, 17, 1);
    render::writePng(dir + "/a.png", img);
    EXPECT_FALSE(std::filesystem::exists(dir + "/a.png.tmp"));
    const Image back = render::readPng(dir + "/a.png");
    EXPECT_EQ(back.width, 33);
    EXPECT_EQ(back.height, 17);
    EXPECT_EQ(back.rgba, img.rgba);
}

// An opaque image is written as RGB (a quarter less to compress) and reads back the same.
TEST(RenderOutput, OpaquePngRoundTrip) {
    const std::string dir = test::tempDir();
    Image img = pattern(64, 9, 2);
    for (size_t i = 3; i < img.rgba.size(); i += 4) img.rgba[i] = 255;
    render::writePng(dir + "/o.png", img);
    EXPECT_EQ(render::readPng(dir + "/o.png").rgba, img.rgba);
    std::ifstream f(dir + "/o.png", std::ios::binary);
    std::vector<char> head(26);
    f.read(head.data(), 26);
    EXPECT_EQ(head[25], 2);  // IHDR colour type 2: truecolour without alpha
}

TEST(RenderOutput, PngToUnwritableFolderThrows) {
    const std::string dir = test::tempDir();
    // A regular file where a folder should be: unwritable even for root.
    std::ofstream(dir + "/file") << "x";
    EXPECT_THROW(render::writePng(dir + "/file/a.png", pattern(4, 4, 0)), std::runtime_error);
    try {
        render::writePng(dir + "/missing/a.png", pattern(4, 4, 0));
        FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("missing/a.png"), std::string::npos) << e.what();
    }
}

TEST(RenderOutput, BackgroundWriterWritesEveryFrame) {
    const std::string dir = test::tempDir();
    render::PngWriter w(2);
    for (int i = 0; i < 10; ++i) w.push(dir + "/f" + std::to_string(i) + ".png", pattern(40, 30, i));
    w.flush();
    EXPECT_EQ(w.written(), 10u);
    for (int i = 0; i < 10; ++i)
        EXPECT_EQ(render::readPng(dir + "/f" + std::to_string(i) + ".png").rgba, pattern(40, 30, i).rgba);
}

// Reserved spares are frames of the size asked, as many as asked up to the writer's capacity.
TEST(RenderOutput, BackgroundWriterReservesSpareFrames) {
    render::PngWriter w(3);
    w.reserve(5, 40, 30);
    for (int i = 0; i < 3; ++i) {
        const render::Image img = w.spare();
        EXPECT_EQ(img.width, 40);
        EXPECT_EQ(img.height, 30);
        EXPECT_EQ(img.rgba.size(), 4u * 40 * 30);
    }
    EXPECT_TRUE(w.spare().rgba.empty());
}

TEST(RenderOutput, BackgroundWriterReportsErrors) {
    const std::string dir = test::tempDir();
    render::PngWriter w(2);
    w.push(dir + "/missing/a.png", pattern(4, 4, 0));
    EXPECT_THROW(w.flush(), std::runtime_error);
    w.push(dir + "/ok.png", pattern(4, 4, 0));  // the writer keeps working after an error
    w.flush();
    EXPECT_TRUE(std::filesystem::exists(dir + "/ok.png"));
}

// Restores PATH when the test ends.
struct PathGuard {
    std::string old = std::getenv("PATH") ? std::getenv("PATH") : "";
    ~PathGuard() { setenv("PATH", old.c_str(), 1); }
};

TEST(RenderOutput, MissingFfmpegIsReportedClearly) {
    PathGuard guard;
    setenv("PATH", "", 1);
    const std::string dir = test::tempDir();
    try {
        render::VideoEncoder enc(dir + "/v.mp4", 64, 48, 30);
        FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("ffmpeg"), std::string::npos) << msg;
        EXPECT_NE(msg.find("PATH"), std::string::npos) << msg;
    }
    EXPECT_FALSE(std::filesystem::exists(dir + "/v.mp4"));
}

// BT.601 studio range in 8 bits: white Y 235, black Y 16, both U = V = 128; pure red Y 82,
// U 90, V 240 (16 + 65.738 * 255 / 256 = 81.5, 128 - 37.945 * 255 / 256 = 90.2, 128 + 112.439 * 255 / 256
// = 240.0, ITU-R BT.601 sec. 2.5); chroma of the mean colour of each 2x2 block.
TEST(RenderOutput, Yuv420OfKnownColours) {
    render::Image img;
    img.width = 4;
    img.height = 2;
    img.rgba.assign(4 * 4 * 2, 0);
    auto set = [&](int x, int y, int r, int g, int b) {
        std::uint8_t* p = &img.rgba[4 * (static_cast<size_t>(y) * 4 + static_cast<size_t>(x))];
        p[0] = static_cast<std::uint8_t>(r), p[1] = static_cast<std::uint8_t>(g), p[2] = static_cast<std::uint8_t>(b);
        p[3] = 255;
    };
    // Left block: white over black; right block: red, all four.
    set(0, 0, 255, 255, 255), set(1, 0, 255, 255, 255), set(0, 1, 0, 0, 0), set(1, 1, 0, 0, 0);
    for (int x : {2, 3})
        for (int y : {0, 1}) set(x, y, 255, 0, 0);
    std::vector<std::uint8_t> yuv;
    render::rgbaToYuv420(img, yuv);
    ASSERT_EQ(yuv.size(), 8u + 2u + 2u);
    EXPECT_EQ(std::vector<std::uint8_t>(yuv.begin(), yuv.begin() + 8),
              (std::vector<std::uint8_t>{235, 235, 82, 82, 16, 16, 82, 82}));
    // Mean of white and black: grey (128, 128, 128), no chroma.
    EXPECT_EQ(yuv[8], 128);
    EXPECT_EQ(yuv[10], 128);
    EXPECT_EQ(yuv[9], 90);    // U of red
    EXPECT_EQ(yuv[11], 240);  // V of red
}

TEST(RenderOutput, VideoEncodes) {
    if (render::findOnPath("ffmpeg").empty()) GTEST_SKIP() << "ffmpeg not installed";
    const std::string dir = test::tempDir();
    render::VideoEncoder enc(dir + "/v.mp4", 64, 48, 30);
    for (int i = 0; i < 15; ++i) enc.addFrame(pattern(64, 48, i));
    EXPECT_FALSE(std::filesystem::exists(dir + "/v.mp4"));  // only the temporary file so far
    enc.finish();
    EXPECT_EQ(enc.frames(), 15);
    EXPECT_GT(std::filesystem::file_size(dir + "/v.mp4"), 100u);
    EXPECT_FALSE(std::filesystem::exists(dir + "/v.mp4.tmp"));
    EXPECT_THROW(render::VideoEncoder(dir + "/odd.mp4", 63, 48, 30), std::runtime_error);
}

}  // namespace
}  // namespace cutsim
