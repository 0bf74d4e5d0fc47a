// The thread count of a run whose scene leaves it open: all cores or one, chosen by measuring.
#pragma once

#include "util/cpu_load.hpp"

namespace cutsim {

// Chooses between all cores and one by measuring: on a machine whose other cores are busy, a
// parallel step waits at every barrier for a descheduled thread and can be several times slower
// than a serial one (BENCHMARKS.md, step). The two counts take turns in chunks of steps (a step's
// cost drifts as the body deforms, so back-to-back windows would be biased) until each has run
// kMinSteps steps and kWindowSeconds have passed, or sooner when one is over kClearLoss times
// slower per step; all cores must win by kMargin (one thread is the choice that cannot collapse).
// The winner is then held until the time the measurement lost (the loser's steps at the
// difference per step) is at most kCost of the time held, and at least kHoldFactor times the
// measured steps: the turns cost at most about kCost against always running the better count.
// Results do not depend on the count (the force stage is bitwise the same on any number of threads).
struct ThreadTuner {
    static constexpr double kWindowSeconds = 0.03, kMargin = 0.9, kClearLoss = 2, kCost = 0.04;
    static constexpr long kChunk = 16, kMinSteps = 64, kHoldFactor = 30;
    static constexpr int kSettle = 2;  // steps after a switch that are not timed (threads waking up)
    int cores = 2;
    int many = 2;  // the cores the other processes leave free
    int current = 1;
    bool measuring = true;
    long inChunk = 0, hold = 0, held = 0;
    int settle = 0;
    long steps[2] = {0, 0};  // timed steps on one thread [0] and on `many` [1]
    double seconds[2] = {0, 0};
    OtherProcessesLoad others;

    explicit ThreadTuner(int n);
    void use(int n);
    // After a step that took stepSeconds of wall time.
    void after(double stepSeconds);
};

}  // namespace cutsim
