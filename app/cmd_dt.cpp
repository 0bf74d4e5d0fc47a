#include "commands.hpp"

#include <CLI/CLI.hpp>

namespace cutsim::app {

void addDtCommand(CLI::App& app) { app.add_subcommand("dt", "not yet available"); }

} // namespace cutsim::app
