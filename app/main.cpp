// The cutsim command: its subcommands register themselves in commands.hpp, the benchmarks'
// `cutsim bench` in bench/command.hpp.
#include "bench/command.hpp"
#include "commands.hpp"
#include "util/memory.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <new>

int main(int argc, char** argv) {
    cutsim::mapLargeArrays();  // arrays a cut grows are remapped, not copied
    CLI::App app{"cutsim: explicit FEM soft-tissue cutting simulator"};
    app.require_subcommand(1);
    cutsim::app::registerCommands(app);
    cutsim::bench::addBenchCommand(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        // usage errors are bad input like any other (CLI11's own codes run past 100)
        app.exit(e);
        return 2;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "error: out of memory (the input asks for more than this machine has)\n");
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    }
    return cutsim::app::exitCode();
}
