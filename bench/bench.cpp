// `cutsim bench`: the command and what its subcommands share (the list they add themselves to,
// gnuplot, JSON numbers, the exit code of a failure). Each subcommand is a file of its own.
#include "bench/bench.hpp"
#include "bench/command.hpp"
#include "app/commands.hpp"
#include "util/input_error.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

namespace cutsim::bench {

namespace fs = std::filesystem;

namespace {

// The subcommands, as addBenchSubcommand added them.
std::vector<std::function<void(CLI::App&)>>& subcommands() {
    static std::vector<std::function<void(CLI::App&)>> s;
    return s;
}

// Every subcommand, in the order `cutsim bench --help` lists them.
void registerBenchExtensions() {
    addAccuracyBench();       // accuracy.cpp: error against cost on reference problems
    addStabilityBench();      // stability.cpp: dt sweeps, random cuts, energy drift
    addStepCostBench();       // step.cpp: step throughput, per-scene cost
    addMiBarBench();          // mibar.cpp: Table 6.1
    addContactBench();        // contact.cpp: contact cost and penetration
    addHapticBench();         // haptic.cpp: a 20k-tet liver and a probe at a haptic rate
    addCaptureBench();        // capture.cpp: capture frames per second
    addImproveBench();        // improve.cpp: mesh improvement against TetGen and Gmsh
    addCutStepBench();        // cutstep.cpp: Tables 5.5 and 5.6, the step through cuts
    addScaleBench();          // scale.cpp: how cost grows with the mesh
    addThreadsBench();        // threads.cpp: the thread count a run picks, idle and busy
    addCutAccuracyConfigs();  // cuts.cpp: MI, lumping after cuts, the liver
}

}  // namespace

bool haveGnuplot() {
    const char* path = std::getenv("PATH");
    if (!path) return false;
    std::stringstream ss(path);
    std::string dir;
    while (std::getline(ss, dir, ':'))
        if (!dir.empty() && ::access((fs::path(dir) / "gnuplot").c_str(), X_OK) == 0) return true;
    return false;
}

std::string plotDataDir(const std::string& tag) {
    const fs::path dir = fs::temp_directory_path() / ("cutsim_" + tag + "_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    return dir.string();
}

void runGnuplot(const std::string& dir, const std::string& terminal, const std::string& body, const std::string& out) {
    const fs::path d(dir);
    const std::string file = (d / "plot.gp").string();
    std::ofstream(file) << terminal << "\nset output '" << out << ".tmp.png'\n" << body;
    const int rc = std::system(("gnuplot '" + file + "' 2>'" + (d / "err.txt").string() + "'").c_str());
    std::string err;
    {
        std::ifstream e(d / "err.txt");
        std::getline(e, err, '\0');
    }
    fs::remove_all(d);
    if (rc != 0 || !fs::exists(out + ".tmp.png")) {
        fs::remove(out + ".tmp.png");
        throw std::runtime_error("gnuplot failed to draw " + out + ": " + err);
    }
    fs::rename(out + ".tmp.png", out);
}

void addBenchSubcommand(std::function<void(CLI::App&)> setup) { subcommands().push_back(std::move(setup)); }

nlohmann::json jsonNumber(double v) { return std::isfinite(v) && v >= 0 ? nlohmann::json(v) : nlohmann::json(nullptr); }

int benchGuarded(const std::function<int()>& f) {
    try {
        return f();
    } catch (const InputError& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}

void addBenchCommand(CLI::App& app) {
    registerBenchExtensions();
    CLI::App* bench =
        app.add_subcommand("bench", "Benchmarks: accuracy against cost, stability, step throughput, scene cost");
    bench->require_subcommand(1);
    for (auto& setup : subcommands()) setup(*bench);
}

}  // namespace cutsim::bench
