#include "fuzz_support.hpp"

#include "sim/simulation.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace cutsim::fuzz {

namespace fs = std::filesystem;

// Removed with the process: the folder's own destructor, not atexit (which would run after the
// static string is gone).
struct Scratch {
    std::string dir;
    Scratch() {
        const fs::path d = fs::temp_directory_path() / ("cutsim-fuzz-" + std::to_string(::getpid()));
        fs::create_directories(d / "scenes");
        std::error_code ec;
        fs::create_directory_symlink(fs::path(CUTSIM_SOURCE_DIR) / "assets" / "meshes", d / "meshes", ec);
        dir = d.string();
    }
    ~Scratch() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
};

const std::string& scratch() {
    static const Scratch s;
    return s.dir;
}

std::pair<std::string, std::string> scratchPair(const std::string& a, const std::string& b) {
    return {scratch() + "/" + a, scratch() + "/" + b};
}

std::string sceneFile() { return scratch() + "/scenes/fuzz.json"; }

std::string shippedScene(const std::string& name) { return std::string(CUTSIM_SOURCE_DIR) + "/assets/scenes/" + name; }

void writeFile(const std::string& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

void finding(const std::string& what) {
    std::fprintf(stderr, "FUZZ FINDING: %s\n", what.c_str());
    std::abort();
}

void simulateBriefly(const SceneDef& scene) {
    Simulation::Options so;
    so.threads = 1;
    Simulation sim(scene, so);
    const int steps = std::clamp(200000 / std::max(1, sim.model().elements()), 1, 50);
    for (int i = 0; i < steps && sim.status() == RunStatus::Running && !sim.finished(); ++i) sim.step();
    if (sim.status() == RunStatus::Running && !sim.state().x.allFinite())
        finding("non-finite positions while the run reports running");
}

}  // namespace cutsim::fuzz
