#include "commands.hpp"

#include <CLI/CLI.hpp>

namespace cutsim::app {

void addMeshCommand(CLI::App& app) { app.add_subcommand("mesh", "not yet available"); }

} // namespace cutsim::app
