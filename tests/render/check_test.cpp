// `cutsim check`: goldens written with --update pass, bitwise, on another thread count; a changed
// material fails with a diff image and a JUnit failure; bad input is exit 2 naming what is wrong.
#include "png_writer.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sys/wait.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;

// Runs a shell command; returns its exit code, stdout in out and stderr in err.
int shell(const std::string& cmd, const std::string& dir, std::string* out, std::string* err) {
    const int status = std::system((cmd + " >" + dir + "/stdout.txt 2>" + dir + "/stderr.txt").c_str());
    *out = test::readText(dir + "/stdout.txt");
    *err = test::readText(dir + "/stderr.txt");
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// bar_sag small and short: 160x90, 0.4 s at 10 fps (5 frames), about 800 steps.
std::string check(const std::string& dir, const std::string& extra) {
    return std::string(CUTSIM_BINARY) + " check " + test::source("assets/scenes/bar_sag.json") + " --golden " + dir +
           "/golden --out " + dir + "/out" +
           " --set capture.width=160 --set capture.height=90 --set duration=0.4 --set capture.fps=10 " + extra;
}

TEST(Check, GoldensPassBitwiseOnAnotherThreadCountAndAMaterialChangeFails) {
    const std::string dir = test::tempDir();
    std::string out, err;
    ASSERT_EQ(shell(check(dir, "--update --threads 1"), dir, &out, &err), 0) << out << err;
    EXPECT_NE(out.find("5 golden frames"), std::string::npos) << out;
    const auto meta = nlohmann::json::parse(test::readText(dir + "/golden/golden.json"));
    EXPECT_EQ(meta["frames"].size(), 5u);
    EXPECT_FALSE(meta["renderer"]["renderer"].get<std::string>().empty()) << meta.dump();

    // Deterministic frames: two threads give bitwise the same PNGs (no pixel may differ at all).
    ASSERT_EQ(
        shell(check(dir, "--threads 2 --tolerance 0 --max-failing 0 --junit " + dir + "/pass.xml"), dir, &out, &err), 0)
        << out << err;
    for (int f = 0; f < 5; ++f) EXPECT_NE(out.find("frame " + std::to_string(f) + ": pass"), std::string::npos) << out;
    for (const char* name : {"frame_000000.png", "frame_000004.png"})
        EXPECT_EQ(test::readText(dir + "/golden/" + name), test::readText(dir + "/out/frames/" + name)) << name;
    EXPECT_NE(test::readText(dir + "/pass.xml").find("failures=\"0\""), std::string::npos);

    // A stiffer bar sags less: the last frame differs, with a diff image and a side-by-side.
    const int code =
        shell(check(dir, "--frames last --set material.E=3e6 --junit " + dir + "/fail.xml"), dir, &out, &err);
    EXPECT_EQ(code, 1) << out << err;
    EXPECT_NE(out.find("frame 4: FAIL"), std::string::npos) << out;
    ASSERT_TRUE(fs::exists(dir + "/out/frame_000004.diff.png")) << out;
    ASSERT_TRUE(fs::exists(dir + "/out/frame_000004.side.png")) << out;
    const render::Image side = render::readPng(dir + "/out/frame_000004.side.png");
    EXPECT_EQ(side.width, 3 * 160);
    EXPECT_EQ(side.height, 90);
    const std::string xml = test::readText(dir + "/fail.xml");
    EXPECT_NE(xml.find("failures=\"1\""), std::string::npos) << xml;
    EXPECT_NE(xml.find("<failure"), std::string::npos) << xml;

    // Goldens from another GL driver are named as such; a golden file gone is a failing frame.
    auto meta2 = meta;
    meta2["renderer"]["renderer"] = "another GPU";
    std::FILE* f = std::fopen((dir + "/golden/golden.json").c_str(), "w");
    ASSERT_TRUE(f);
    std::fputs(meta2.dump().c_str(), f);
    std::fclose(f);
    fs::remove(dir + "/golden/frame_000002.png");
    EXPECT_EQ(shell(check(dir, "--frames 1,2"), dir, &out, &err), 1) << out << err;
    EXPECT_NE(out.find("note: the goldens were made with renderer"), std::string::npos) << out;
    EXPECT_NE(out.find("another GPU / "), std::string::npos) << out;
    EXPECT_NE(out.find("frame 1: pass"), std::string::npos) << out;
    EXPECT_NE(out.find("frame 2: FAIL: no golden image"), std::string::npos) << out;
}

TEST(Check, BadInputIsExitTwoNamingIt) {
    const std::string dir = test::tempDir();
    std::string out, err;
    EXPECT_EQ(shell(check(dir, ""), dir, &out, &err), 2);  // no goldens yet
    EXPECT_NE(err.find("golden.json"), std::string::npos) << err;
    EXPECT_NE(err.find("--update"), std::string::npos) << err;
    EXPECT_EQ(shell(check(dir, "--update --frames 0,x"), dir, &out, &err), 2);
    EXPECT_NE(err.find("--frames"), std::string::npos) << err;
    EXPECT_EQ(shell(check(dir, "--update --frames 99 --set duration=0.1"), dir, &out, &err), 2);
    EXPECT_NE(err.find("frame 99"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(dir + "/golden/golden.json"));
    EXPECT_EQ(shell(check(dir, "--update --set 'capture.check={\"max_dif\":3}'"), dir, &out, &err), 2);
    EXPECT_NE(err.find("capture.check.max_dif"), std::string::npos) << err;
}

// Tolerances from the scene: capture.check sets them when no flag does.
TEST(Check, TolerancesComeFromTheScene) {
    const std::string dir = test::tempDir();
    std::string out, err;
    ASSERT_EQ(shell(check(dir, "--update --frames last --set duration=0.1"), dir, &out, &err), 0) << out << err;
    const std::string loose = " --set duration=0.1 --set material.E=1.1e6 "
                              "--set 'capture.check={\"max_diff\":255,\"max_failing\":0}'";
    EXPECT_EQ(shell(check(dir, loose), dir, &out, &err), 0) << out << err;
    EXPECT_NE(out.find("more than 255"), std::string::npos) << out;
    EXPECT_EQ(shell(check(dir, loose + " --tolerance 0"), dir, &out, &err), 1) << out << err;
}

}  // namespace
}  // namespace cutsim
