// Wall-clock timing of stages and runs.
#pragma once

#include <chrono>

namespace cutsim {

using WallClock = std::chrono::steady_clock;

// Seconds since t.
inline double secondsSince(WallClock::time_point t) {
    return std::chrono::duration<double>(WallClock::now() - t).count();
}

// A stopwatch started at construction: seconds() since then, lap() since the last lap.
class Stopwatch {
public:
    Stopwatch() : start_(WallClock::now()), lap_(start_) {}
    double seconds() const { return secondsSince(start_); }
    double lap() {
        const auto now = WallClock::now();
        const double s = std::chrono::duration<double>(now - lap_).count();
        lap_ = now;
        return s;
    }
    void restart() { start_ = lap_ = WallClock::now(); }

private:
    WallClock::time_point start_, lap_;
};

}  // namespace cutsim
