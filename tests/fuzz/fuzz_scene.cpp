// libFuzzer target: the scene loader, from the file's bytes to a Simulation that has taken a few
// steps. Bad input must end in InputError; a run may also stop as diverged or refused, never with
// another exception, a crash or non-finite state reported as running.
#include "fuzz_support.hpp"
#include "sim/simulation.hpp"

#include <cmath>

using namespace cutsim;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string path = fuzz::sceneFile();
    fuzz::writeFile(path, std::string(reinterpret_cast<const char*>(data), size));
    fuzz::expectInputError([&] { fuzz::simulateBriefly(loadScene(path, {})); });
    return 0;
}
