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

// The kill test: SIGINT when the progress line says 30%.
TEST(OutputFolder, SigintAtThirtyPercentLeavesNoHalfWrittenOutput) {
    const std::string dir = workDir(), out = dir + "/out";
    int errPipe[2];
    ASSERT_EQ(::pipe(errPipe), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        ::dup2(errPipe[1], 2);
        ::close(errPipe[0]);
        ::close(errPipe[1]);
        const std::string scene = barSagPath();
        ::execl(CUTSIM_BINARY, CUTSIM_BINARY, "run", scene.c_str(), "--out", out.c_str(), "--threads", "1", "--set",
                "capture.width=160", "--set", "capture.height=90", "--set", "duration=3", nullptr);
        ::_exit(127);
    }
    ::close(errPipe[1]);
    FILE* err = ::fdopen(errPipe[0], "r");
    std::string log;
    char line[512];
    bool sent = false;
    while (std::fgets(line, sizeof line, err)) {
        log += line;
        if (!sent && std::string(line).find("progress  30%") != std::string::npos) {
            ::kill(pid, SIGINT);
            sent = true;
        }
    }
    std::fclose(err);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(sent) << log;
    ASSERT_TRUE(WIFEXITED(status)) << log;
    EXPECT_EQ(WEXITSTATUS(status), 128 + SIGINT) << log;
    EXPECT_FALSE(fs::exists(out)) << "an interrupted run must not create --out";
    const std::string incomplete = out + ".incomplete";
    ASSERT_TRUE(fs::exists(incomplete + "/report.json")) << log;
    const json r = json::parse(test::readText(incomplete + "/report.json"));
    EXPECT_EQ(r["status"], "interrupted");
    EXPECT_LT(r["sim_time"].get<double>(), 3.0);
    EXPECT_FALSE(fs::exists(incomplete + "/video.mp4"));
    EXPECT_FALSE(fs::exists(incomplete + "/final.vtu"));
    EXPECT_EQ(countTmp(dir), 0) << "temporary files or a staging folder were left behind";
}

}  // namespace
}  // namespace cutsim
