// What the subcommands of `cutsim bench` share in their options and results: one call registers a
// subcommand with its arguments, the options most of them take are added by name, and the JSON and
// CSV results are written one way.
#pragma once

#include "app/commands.hpp"
#include "bench/bench.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json_fwd.hpp>

#include <memory>
#include <string>
#include <vector>

namespace cutsim::bench {

// Adds `cutsim bench NAME`: options(command, args) adds the options into a fresh Args that lives
// as long as the command, which runs run(args) through benchGuarded (its code the exit code).
template <class Args>
void addSubcommand(const std::string& name, const std::string& description, void (*options)(CLI::App&, Args&),
                   int (*run)(const Args&)) {
    addBenchSubcommand([name, description, options, run](CLI::App& bench) {
        auto a = std::make_shared<Args>();
        CLI::App* c = bench.add_subcommand(name, description);
        options(*c, *a);
        c->callback([a, run] { app::setExitCode(benchGuarded([&] { return run(*a); })); });
    });
}

// --json: "Print " + keys (the result's JSON on stdout, printJson); machine: the result also names
// the machine it ran on (printResult).
void jsonFlag(CLI::App& c, bool& json, const std::string& keys, bool machine = false);
// --tiny: "Test size: " + what.
void tinyFlag(CLI::App& c, bool& tiny, const std::string& what);
// --csv FILE: "Write the " + what + " to this CSV file" (writeCsv).
void csvOption(CLI::App& c, std::string& path, const std::string& what);
// --plot PNG: "Draw " + what + " to this PNG (needs gnuplot)".
void plotOption(CLI::App& c, std::string& path, const std::string& what);
// --threads N, N from least to 1024.
CLI::Option* threadsOption(CLI::App& c, int& threads, const std::string& description, int least);

// The result on stdout, as --json prints it.
void printJson(const nlohmann::json& j);
// The same with the machine it ran on: machine (machineJson(), taken as the run started) and the
// load averages at its end (load_average_end).
void printResult(nlohmann::json j, const nlohmann::json& machine);
// rows (an array of objects) as CSV lines, with the header line first when header: as writeCsv writes them.
std::string csvText(const nlohmann::json& rows, const std::vector<std::string>& columns, bool header = true);
// rows (an array of objects) as CSV into path, written whole or not at all: a header, then a line
// per row. A column is a key or a path of keys ("stages/cut", headed by its last key "cut"); a
// string cell is written as it is, any other as JSON, a missing one empty.
void writeCsv(const std::string& path, const nlohmann::json& rows, const std::vector<std::string>& columns);

}  // namespace cutsim::bench
