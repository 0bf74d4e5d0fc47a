// `cutsim run`: a thin driver of the library's Simulation (sim/simulation.hpp) that writes frames,
// a video, final.vtu and report.json into its output folder.
#pragma once

#include "sim/scene.hpp"

#include <string>

namespace cutsim {
class Simulation;
}

namespace cutsim::app {

struct RunOptions {
    std::string out;        // output folder
    bool render = true;     // false: no GL context, no frames
    int threads = 0;        // 0: chosen by measuring (sim/thread_tuner.hpp)
    bool quiet = false;     // no progress output
    bool pipelined = true;  // frames drawn while the physics steps on (false: each before the next step)
};

// The warnings the simulation raised, each once on stderr as "warning: ..." (report.json lists
// them with their counts).
void printWarnings(const Simulation& sim);

// Runs a scene; returns the process exit code (ExitCode: 0 ok, 3 diverged, 4 refused step).
// Throws InputError for bad input before anything is written.
int runScene(const SceneDef& scene, const RunOptions& opt);

}  // namespace cutsim::app
