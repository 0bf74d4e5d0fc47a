// OtherProcessesLoad (util/cpu_load.hpp): the CPU time of the machine's other processes, which the
// thread count leaves their cores to.
#include "util/cpu_load.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <ctime>

namespace cutsim {
namespace {

double ownCpuSeconds() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

TEST(OtherProcessesLoad, CountsAnotherProcesssCpuTime) {
    OtherProcessesLoad load;
    EXPECT_LT(load.sample(), 0);  // under 0.05 s since construction: unknown
    const auto t0 = std::chrono::steady_clock::now();
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {  // another process: 0.3 s of its own CPU time
        const double start = ownCpuSeconds();
        while (ownCpuSeconds() - start < 0.3) {}
        _exit(0);
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cores = load.sample();
    ASSERT_GE(cores, 0);
    // its 0.3 s, less the counters' ticks (10 ms) and what this process spent (waiting, little)
    EXPECT_GE(cores * wall, 0.25);
}

}  // namespace
}  // namespace cutsim
