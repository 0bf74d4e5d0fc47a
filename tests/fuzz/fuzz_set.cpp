// libFuzzer target: `--set key.path=value` overrides on a shipped scene. The input is split into
// assignments at newlines, applied in order, and the scene is loaded and stepped briefly.
#include "fuzz_support.hpp"
#include "sim/simulation.hpp"

#include <sstream>

using namespace cutsim;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> sets;
    std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
    for (std::string line; std::getline(in, line) && sets.size() < 16;) sets.push_back(line);
    static const std::string base = fuzz::shippedScene("bar_sag.json");
    fuzz::expectInputError([&] { fuzz::simulateBriefly(loadScene(base, sets)); });
    return 0;
}
