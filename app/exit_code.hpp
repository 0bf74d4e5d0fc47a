// The process exit codes of the cutsim program (README, docs/commands.md): the library reports a
// run's status (sim/simulation.hpp RunStatus); the program maps it to its exit.
#pragma once

#include "sim/simulation.hpp"

namespace cutsim::app {

enum class ExitCode : int {
    Ok = 0,           // the run reached its end with every check passed
    BadInput = 2,     // a bad scene, mesh or flag; nothing was simulated or written
    Diverged = 3,     // a check found the state non-finite or outside its physical bounds
    RefusedStep = 4,  // the step was above the stable limit and integrator.dt.on_limit is refuse
    NoDisplay = 5,    // cutsim view found no display
};

inline ExitCode exitCodeOf(RunStatus s) {
    switch (s) {
    case RunStatus::Diverged: return ExitCode::Diverged;
    case RunStatus::Refused: return ExitCode::RefusedStep;
    default: return ExitCode::Ok;
    }
}

}  // namespace cutsim::app
