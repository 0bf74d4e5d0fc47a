// `cutsim run` writes its folder whole: a new run replaces an earlier one, a folder of other files
// is refused, and a run stopped by SIGINT leaves --out as it was and its partial outputs marked.
#include "test_support.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

namespace cutsim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::workDir;

std::string barSagPath() { return test::source("assets/scenes/bar_sag.json"); }

int countTmp(const fs::path& dir) {
    int n = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        n += e.path().string().find(".tmp") != std::string::npos ||
             e.path().filename().string().find(".staging-") != std::string::npos;
    return n;
}

TEST(OutputFolder, ANewRunReplacesTheEarlierOneWhole) {
    const std::string dir = workDir(), out = dir + "/out";
    std::string err;
    ASSERT_EQ(test::runCutsim("run " + barSagPath() + " --out " + out + " --no-render --quiet --set duration=0.01",
                              nullptr, &err),
              0)
        << err;
    ASSERT_TRUE(fs::exists(out + "/final.vtu"));
    ASSERT_EQ(test::runCutsim("run " + barSagPath() + " --out " + out +
                                  " --no-render --quiet --set duration=0.01 --set output.vtu=false",
                              nullptr, &err),
              0)
        << err;
    EXPECT_FALSE(fs::exists(out + "/final.vtu")) << "a stale final.vtu of the earlier run was kept";
    EXPECT_TRUE(fs::exists(out + "/report.json"));
    EXPECT_EQ(countTmp(dir), 0);
}

TEST(OutputFolder, RefusesAFolderOfOtherFiles) {
    const std::string dir = workDir(), out = dir + "/mine";
    fs::create_directories(out);
    test::writeText(out + "/notes.txt", "keep me\n");
    std::string err;
    EXPECT_EQ(test::runCutsim("run " + barSagPath() + " --out " + out + " --no-render --quiet --set duration=0.01",
                              nullptr, &err),
              2);
    EXPECT_NE(err.find("not a cutsim run's"), std::string::npos) << err;
    EXPECT_EQ(test::readText(out + "/notes.txt"), "keep me\n");
}

// Runs bar_sag into `out` with frames (small) for `duration` seconds and sends SIGINT when a
// progress line holding `trigger` appears; the exit status and stderr.
struct Signalled {
    int status = 0;
    bool sent = false;
    std::string log;
};
Signalled runAndSignal(const std::string& out, const std::string& duration, const std::string& trigger,
                       const std::string& pngEvery = "1") {
    Signalled r;
    int errPipe[2];
    if (::pipe(errPipe) != 0) return r;
    const pid_t pid = ::fork();
    if (pid < 0) return r;
    if (pid == 0) {
        ::dup2(errPipe[1], 2);
        ::close(errPipe[0]);
        ::close(errPipe[1]);
        const std::string scene = barSagPath(), d = "duration=" + duration, p = "capture.png_every=" + pngEvery;
        ::execl(CUTSIM_BINARY, CUTSIM_BINARY, "run", scene.c_str(), "--out", out.c_str(), "--threads", "1", "--set",
                "capture.width=160", "--set", "capture.height=90", "--set", d.c_str(), "--set", p.c_str(), nullptr);
        ::_exit(127);
    }
    ::close(errPipe[1]);
    FILE* err = ::fdopen(errPipe[0], "r");
    char line[512];
    while (std::fgets(line, sizeof line, err)) {
        r.log += line;
        if (!r.sent && std::string(line).find(trigger) != std::string::npos) {
            ::kill(pid, SIGINT);
            r.sent = true;
        }
    }
    std::fclose(err);
    ::waitpid(pid, &r.status, 0);
    return r;
}

// The frames an interrupted run kept: its report counts them.
int keptFrames(const fs::path& dir) {
    int n = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        n += e.path().extension() == ".png" && e.path().filename().string().rfind("frame_", 0) == 0;
    return n;
}

// What every interrupted run leaves: exit 128 + SIGINT, --out untouched, FOLDER.incomplete with a
// report that says so and counts the frames kept, no temporary files. The report, for more checks.
json expectInterrupted(const std::string& dir, const std::string& out, const Signalled& s) {
    EXPECT_TRUE(s.sent) << s.log;
    EXPECT_TRUE(WIFEXITED(s.status)) << s.log;
    EXPECT_EQ(WEXITSTATUS(s.status), 128 + SIGINT) << s.log;
    EXPECT_FALSE(fs::exists(out)) << "an interrupted run must not create --out\n" << s.log;
    const std::string incomplete = out + ".incomplete";
    if (!fs::exists(incomplete + "/report.json")) {
        ADD_FAILURE() << "no report in " << incomplete << "\n" << s.log;
        return json();
    }
    const json r = json::parse(test::readText(incomplete + "/report.json"));
    EXPECT_EQ(r["status"], "interrupted");
    EXPECT_EQ(r["exit_code"], 128 + SIGINT);
    EXPECT_EQ(r["frames"].get<int>(), keptFrames(incomplete)) << "the report counts the frames it kept";
    EXPECT_EQ(countTmp(dir), 0) << "temporary files or a staging folder were left behind";
    return r;
}

// The kill test: SIGINT when the progress line says 30%.
TEST(OutputFolder, SigintAtThirtyPercentLeavesNoHalfWrittenOutput) {
    const std::string dir = workDir(), out = dir + "/out";
    const json r = expectInterrupted(dir, out, runAndSignal(out, "3", "progress  30%"));
    ASSERT_TRUE(r.is_object());
    EXPECT_LT(r["sim_time"].get<double>(), 3.0);
    // 30% of 3 s at 30 frames per second: about 27 frames drawn, each written as a PNG
    EXPECT_GT(r["frames"].get<int>(), 20);
    EXPECT_FALSE(fs::exists(out + ".incomplete/video.mp4"));
    EXPECT_FALSE(fs::exists(out + ".incomplete/final.vtu"));
}

// With a PNG every 2nd frame, or none, and the unfinished video removed, the report counts the
// frames kept (it counted the frames drawn: 27 beside 14 PNGs, 27 beside none).
TEST(OutputFolder, AnInterruptedReportCountsTheFramesKept) {
    const std::string dir = workDir();
    json r = expectInterrupted(dir, dir + "/half", runAndSignal(dir + "/half", "3", "progress  30%", "2"));
    ASSERT_TRUE(r.is_object());
    EXPECT_GT(r["frames"].get<int>(), 10);
    EXPECT_LE(r["capture"]["frames"].get<int>(), 2 * r["frames"].get<int>());  // drawn: every 2nd kept
    r = expectInterrupted(dir, dir + "/none", runAndSignal(dir + "/none", "3", "progress  30%", "0"));
    ASSERT_TRUE(r.is_object());
    EXPECT_EQ(r["frames"].get<int>(), 0);
    EXPECT_GT(r["capture"]["frames"].get<int>(), 20) << "frames were drawn, into the video the signal removed";
}

// A signal that arrives after the last step, while the frames and the report are written, is not
// swallowed: the run is "interrupted" (exit 130), never "ok" with exit 0.
TEST(OutputFolder, SigintAfterTheLastStepIsNotSwallowed) {
    const std::string dir = workDir(), out = dir + "/out";
    const json r = expectInterrupted(dir, out, runAndSignal(out, "0.5", "progress 100%"));
    ASSERT_TRUE(r.is_object());
    EXPECT_GE(r["sim_time"].get<double>(), 0.5 - 1e-9);
}

}  // namespace
}  // namespace cutsim
