// Subcommands of the cutsim executable. Each add* function registers one subcommand; its
// callback runs it and stores the exit code (bad input: message on stderr, code 1 or 2).
#pragma once

#include <functional>

namespace CLI {
class App;
}

namespace cutsim::app {

void registerCommands(CLI::App& app);
int exitCode();
void setExitCode(int code);
// Sets the exit code to body's, or on an exception to 2 with its message on stderr.
void runCommand(const std::function<int()>& body);
// For a command that needs the renderer in a build without it: the message and exit code 2.
void needsRenderer();

void addDtCommand(CLI::App& app);       // cmd_dt.cpp: time-step analysis of a mesh
void addMeshCommand(CLI::App& app);     // cmd_mesh.cpp: mesh conversion and checks
void addRunCommand(CLI::App& app);      // cmd_run.cpp: run a scene
void addViewCommand(CLI::App& app);     // cmd_view.cpp: run a scene live in a window
void addCheckCommand(CLI::App& app);    // cmd_check.cpp: compare a scene's frames with golden images
void addMiCommand(CLI::App& app);       // cmd_mi.cpp: mesh intersection of a surface
void addSweepCommand(CLI::App& app);    // cmd_sweep.cpp: a scene over a product of overrides
void addImproveCommand(CLI::App& app);  // cmd_improve.cpp: mesh improvement for a larger step
void addTetraCommand(CLI::App& app);    // cmd_tetra.cpp: a surface to a simulation-ready tet mesh

}  // namespace cutsim::app
