#include "commands.hpp"
#include "bench.hpp"
#include "cmd_render.hpp"

#include <CLI/CLI.hpp>

namespace cutsim::app {
namespace {
int g_exit = 0;
}

int exitCode() { return g_exit; }
void setExitCode(int code) { g_exit = code; }

void registerCommands(CLI::App& app) {
    addDtCommand(app);
    addMeshCommand(app);
    addRunCommand(app);
    addSweepCommand(app);
    addMiCommand(app);
    addRenderCommand(app);
    addViewCommand(app);
    addBenchCommand(app);
}

}  // namespace cutsim::app
