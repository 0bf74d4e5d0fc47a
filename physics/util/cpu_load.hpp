// How busy the other processes keep the machine's cores, for choosing a thread count.
#pragma once

namespace cutsim {

// The CPU time the other processes of the machine used since the last call (or construction),
// in cores (1.0: one core busy all the while), from the machine's counters (Linux /proc/stat)
// less this process's own time. Negative when unknown: no counters, or under 0.05 s since the
// last call (the counters tick every 10 ms).
class OtherProcessesLoad {
public:
    OtherProcessesLoad();
    double sample();

private:
    bool read(double& wall, double& busy, double& self) const;
    double wall_ = 0, busy_ = 0, self_ = 0;
    bool known_ = false;
};

}  // namespace cutsim
