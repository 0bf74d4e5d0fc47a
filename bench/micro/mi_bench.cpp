// Mesh intersection set-up (lattice, hash, node classes, exact interface volumes, model, render
// surface) of the bunny at 32 cells across; target under 1 s (issue: MI set-up time).
// No main here: cutsim_bench's main lives in another file of this folder.
#include "embed/mi.hpp"
#include "mesh/io.hpp"

#include <benchmark/benchmark.h>

namespace {

using namespace cutsim;

void BM_MiSetupBunny32(benchmark::State& st) {
    const SurfaceMesh s = readSurfaceMesh(std::string(CUTSIM_DATA_DIR) + "/surface/igl_bunny.off");
    MiOptions o;
    o.cells = 32;
    double volume = 0;
    int interfaces = 0;
    for (auto _ : st) {
        const MiResult r = buildMi(s, Material{}, o);
        volume = r.embeddedVolume();
        interfaces = r.count(ElementClass::Interface);
        benchmark::DoNotOptimize(volume);
    }
    st.counters["interface_elements"] = interfaces;
    st.counters["volume_rel_error"] = volume / enclosedVolume(s) - 1;
}
BENCHMARK(BM_MiSetupBunny32)->Unit(benchmark::kMillisecond)->Iterations(5);

}  // namespace
