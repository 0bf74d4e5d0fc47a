// Shared by the fuzz targets: scratch files in a private temporary folder, and the rule that bad
// input ends in InputError (or a refused eigen-solve) and never in another exception.
#pragma once

#include "mesh/io.hpp"
#include "sim/scene.hpp"

#include <cstdint>
#include <string>
#include <utility>

namespace cutsim::fuzz {

// A folder of this process's own, with `meshes` linking to the shipped meshes so scenes resolve.
const std::string& scratch();
std::pair<std::string, std::string> scratchPair(const std::string& a, const std::string& b);
std::string sceneFile();  // scratch()/scenes/fuzz.json
std::string shippedScene(const std::string& name);
void writeFile(const std::string& path, const std::string& bytes);

// Runs `f`; InputError and EigenSolveError are expected outcomes, any other exception aborts
// (libFuzzer reports it with the input).
template <class F>
void expectInputError(F&& f);

// Builds the Simulation (one thread, no output) and steps it at most 50 times or 2e5 tet-steps;
// aborts when it still reports running with non-finite positions.
void simulateBriefly(const SceneDef& scene);

[[noreturn]] void finding(const std::string& what);

}  // namespace cutsim::fuzz

#include "timestep/timestep.hpp"

#include <exception>

template <class F>
void cutsim::fuzz::expectInputError(F&& f) {
    try {
        f();
    } catch (const InputError&) {
    } catch (const EigenSolveError&) {
    } catch (const std::exception& e) {
        finding(std::string("unexpected exception: ") + e.what());
    }
}
