#include "bench/machine.hpp"

#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

namespace cutsim {

namespace {

// The "model name" of /proc/cpuinfo's first processor; empty elsewhere.
std::string cpuModel() {
    std::ifstream f("/proc/cpuinfo");
    std::string line;
    while (std::getline(f, line))
        if (line.rfind("model name", 0) == 0) {
            const size_t colon = line.find(':');
            return colon == std::string::npos ? "" : line.substr(line.find_first_not_of(' ', colon + 1));
        }
    return "";
}

// The widest vector instructions of /proc/cpuinfo's flags ("AVX-512", "AVX2", "SSE4.2"): the
// step's kernels run on them, so timings of two machines compare only at the same width.
std::string vectorWidth() {
    std::ifstream f("/proc/cpuinfo");
    std::string line;
    while (std::getline(f, line))
        if (line.rfind("flags", 0) == 0) {
            const std::string flags = line + ' ';
            for (const auto& [flag, name] :
                 {std::pair{" avx512f ", "AVX-512"}, {" avx2 ", "AVX2"}, {" sse4_2 ", "SSE4.2"}})
                if (flags.find(flag) != std::string::npos) return name;
            return "";
        }
    return "";
}

}  // namespace

nlohmann::json loadAverage() {
    double l[3];
    nlohmann::json j = nlohmann::json::array();
    if (getloadavg(l, 3) == 3)
        for (double v : l) j.push_back(v);
    return j;
}

nlohmann::json machineJson() {
    return {{"cpu", cpuModel()},
            {"vector", vectorWidth()},
            {"cores", std::thread::hardware_concurrency()},
            {"load_average", loadAverage()}};
}

BusyCore::BusyCore() {
    const pid_t parent = ::getpid();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("cannot start a busy process (fork failed)");
    if (pid_ == 0) {
        // the child: killed with its parent, however the parent ends
        ::prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (::getppid() != parent) ::_exit(0);
        volatile unsigned long spin = 0;
        for (;;) spin = spin + 1;
    }
}

BusyCore::~BusyCore() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
}

}  // namespace cutsim
