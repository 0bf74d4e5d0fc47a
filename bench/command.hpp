// `cutsim bench`: the benchmarks, apart from the program's own commands (app/). The program adds
// the whole command with this one call; nothing else of bench/ is seen from app/.
#pragma once

namespace CLI {
class App;
}

namespace cutsim::bench {

// Registers the `bench` command with its built-in and registered subcommands.
void addBenchCommand(CLI::App& app);

}  // namespace cutsim::bench
