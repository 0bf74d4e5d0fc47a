// The cutsim command: subcommands register themselves in commands.hpp.
#include "commands.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

int main(int argc, char** argv) {
    CLI::App app{"cutsim: explicit FEM soft-tissue cutting simulator"};
    app.require_subcommand(1);
    cutsim::app::registerCommands(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    }
    return cutsim::app::exitCode();
}
