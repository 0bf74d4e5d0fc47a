// The machine a benchmark ran on, recorded in its JSON result: results are committed per machine,
// and every time in them is a wall time on a machine other work may share.
#pragma once

#include <nlohmann/json_fwd.hpp>

namespace cutsim {

// {cpu, cores, load_average: [1, 5, 15 min]} now.
nlohmann::json machineJson();
// The 1, 5 and 15 minute load averages now (empty where the system gives none).
nlohmann::json loadAverage();

// A core kept busy while it lives: a child process spinning until the destructor kills it (it also
// dies with this process), so that a benchmark measures a machine whose other core is taken, as a
// shell's `yes > /dev/null &` would take it, without leaving a loop behind.
class BusyCore {
public:
    BusyCore();
    ~BusyCore();
    BusyCore(const BusyCore&) = delete;
    BusyCore& operator=(const BusyCore&) = delete;
    int pid() const { return pid_; }

private:
    int pid_ = -1;
};

}  // namespace cutsim
