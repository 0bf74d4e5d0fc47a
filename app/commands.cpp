#include "commands.hpp"
#include "cmd_render.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

namespace cutsim::app {
namespace {
int g_exit = 0;
}

int exitCode() { return g_exit; }
void setExitCode(int code) { g_exit = code; }

void runCommand(const std::function<int()>& body) {
    try {
        setExitCode(body());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        setExitCode(2);
    }
}

void needsRenderer() {
    std::fprintf(stderr, "error: this cutsim was built without the renderer (-DCUTSIM_RENDER=OFF)\n");
    setExitCode(2);
}

void registerCommands(CLI::App& app) {
    addDtCommand(app);
    addMeshCommand(app);
    addRunCommand(app);
    addSweepCommand(app);
    addMiCommand(app);
    addImproveCommand(app);
    addTetraCommand(app);
    addRenderCommand(app);
    addViewCommand(app);
    addCheckCommand(app);
}

}  // namespace cutsim::app
