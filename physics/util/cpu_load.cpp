#include "util/cpu_load.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <string>

namespace cutsim {

OtherProcessesLoad::OtherProcessesLoad() { known_ = read(wall_, busy_, self_); }

bool OtherProcessesLoad::read(double& wall, double& busy, double& self) const {
    std::ifstream in("/proc/stat");
    std::string cpu;
    // user nice system idle iowait irq softirq steal, in clock ticks
    double t[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    if (!(in >> cpu) || cpu != "cpu") return false;
    for (double& v : t)
        if (!(in >> v)) return false;
    const double hz = static_cast<double>(sysconf(_SC_CLK_TCK));
    if (!(hz > 0)) return false;
    busy = (t[0] + t[1] + t[2] + t[5] + t[6] + t[7]) / hz;
    rusage ru{};
    if (getrusage(RUSAGE_SELF, &ru) != 0) return false;
    self = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
    wall = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    return true;
}

double OtherProcessesLoad::sample() {
    double wall = 0, busy = 0, self = 0;
    if (!read(wall, busy, self)) {
        known_ = false;
        return -1;
    }
    const double dWall = wall - wall_;
    if (known_ && dWall < 0.05) return -1;  // too short to read: the interval runs on
    const double load = known_ ? (busy - busy_ - (self - self_)) / dWall : -1;
    wall_ = wall, busy_ = busy, self_ = self, known_ = true;
    return load;
}

}  // namespace cutsim
