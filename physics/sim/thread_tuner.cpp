#include "sim/thread_tuner.hpp"

#include "fem/forces.hpp"

#include <algorithm>
#include <cmath>

namespace cutsim {

ThreadTuner::ThreadTuner(int n) : cores(n), many(n) { setThreads(1); }

void ThreadTuner::use(int n) {
    if (n != current) settle = kSettle;
    current = n;
    setThreads(n);
}

void ThreadTuner::after(double stepSeconds) {
    if (!measuring) {
        if (++held < hold) return;
        held = 0;
        // A core the other processes kept more than half busy over the hold is not ours: a
        // parallel step waits for its descheduled thread. With no second core free, one
        // thread is held again without measuring (each turn on both cores cost a busy
        // machine about twice a step).
        const double load = others.sample();
        many = load > 0.5 ? std::max(1, cores - static_cast<int>(std::ceil(load - 0.5))) : cores;
        if (many == 1) return use(1);
        measuring = true, inChunk = 0, steps[0] = steps[1] = 0, seconds[0] = seconds[1] = 0;
        return;
    }
    if (settle > 0) {
        --settle;
        return;
    }
    const int k = current == 1 ? 0 : 1;
    ++steps[k];
    seconds[k] += stepSeconds;
    if (++inChunk < kChunk) return;
    inChunk = 0;
    if (steps[0] == 0 || steps[1] == 0) return use(current == 1 ? many : 1);
    const double per[2] = {seconds[0] / double(steps[0]), seconds[1] / double(steps[1])};
    const bool clear = per[1] > kClearLoss * per[0] || per[0] > kClearLoss * per[1];
    if (!clear && !(steps[0] >= kMinSteps && steps[1] >= kMinSteps && seconds[0] + seconds[1] >= kWindowSeconds))
        return use(current == 1 ? many : 1);
    const int win = per[1] < kMargin * per[0] ? 1 : 0;
    use(win == 1 ? many : 1);
    measuring = false;
    held = 0;
    others.sample();  // the hold's load is counted from here
    const double lost = double(steps[1 - win] + kSettle) * std::max(0.0, per[1 - win] - per[win]);
    hold = std::max(kHoldFactor * (steps[0] + steps[1]), static_cast<long>(lost / (kCost * per[win])));
}

}  // namespace cutsim
