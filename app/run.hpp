// `cutsim run`: the run loop of a scene, its progress and its report.
#pragma once

#include "scene.hpp"

#include <string>

namespace cutsim::app {

struct RunOptions {
    std::string out;          // output folder
    bool render = true;       // false: no GL context, no frames
    int threads = 0;          // 0 = all cores
    bool quiet = false;       // no progress output
};

// Runs a scene; returns the process exit code (0 ok, 3 numerical failure). Throws InputError for
// bad input before anything is written.
int runScene(const SceneDef& scene, const RunOptions& opt);

} // namespace cutsim::app
