// Time-step analysis on regular boxes of ~10k and ~100k tets: exact (Lanczos), certified
// (Gershgorin), per-element estimators, and a local update after a small change.
// No main here: cutsim_bench's main lives in another file of this folder.
#include "fem/model.hpp"
#include "mesh/generate.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/timestep.hpp"

#include <benchmark/benchmark.h>

#include <map>
#include <memory>

namespace {

using namespace cutsim;

// Box of cubes 1/nx cm wide, 6 Kuhn tets each.
Model boxModel(int nx, int ny, int nz) {
    const double h = 0.1 / nx;
    return buildModel(boxMesh(h * nx, h * ny, h * nz, nx, ny, nz), Material{});
}

// Arg 0: ~10k tets (12x12x12 cubes), 1: ~100k tets (30x30x19).
const Model& model(int which) {
    static std::map<int, std::unique_ptr<Model>> cache;
    auto& slot = cache[which];
    if (!slot) slot = std::make_unique<Model>(which == 0 ? boxModel(12, 12, 12) : boxModel(30, 30, 19));
    return *slot;
}

void BM_TimestepExact(benchmark::State& st) {
    const Model& m = model(static_cast<int>(st.range(0)));
    double dt = 0, matvecs = 0;
    for (auto _ : st) {
        const ExactResult r = exactCriticalDt(m);
        benchmark::DoNotOptimize(r.lambdaMax);  // const overload: a non-const double may be clobbered
        dt = r.dt;
        matvecs = r.matvecs;
    }
    st.counters["tets"] = m.elements();
    st.counters["matvecs"] = matvecs;
    st.counters["dt_ms"] = dt * 1e3;
}
BENCHMARK(BM_TimestepExact)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_TimestepCertified(benchmark::State& st) {
    const Model& m = model(static_cast<int>(st.range(0)));
    double dt = 0;
    for (auto _ : st) {
        const double d = certifiedDt(m);
        benchmark::DoNotOptimize(d);
        dt = d;
    }
    st.counters["tets"] = m.elements();
    st.counters["dt_ms"] = dt * 1e3;
}
BENCHMARK(BM_TimestepCertified)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_TimestepEstimators(benchmark::State& st) {
    const Model& m = model(static_cast<int>(st.range(0)));
    ElementEstimates est;
    for (auto _ : st) {
        est = estimateElements(m);
        benchmark::DoNotOptimize(est.r1r.data());
    }
    st.counters["tets"] = m.elements();
    st.counters["r1r_ms"] = est.r1r.minCoeff() * 1e3;
}
BENCHMARK(BM_TimestepEstimators)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Everything the analyzer keeps (rows, estimators, shapes, Gershgorin rows), from scratch.
void BM_TimestepAnalyzerFull(benchmark::State& st) {
    const Model& m = model(static_cast<int>(st.range(0)));
    TimestepAnalyzer an;
    for (auto _ : st) {
        an.compute(m);
        benchmark::DoNotOptimize(an.certifiedLambda());
    }
    st.counters["tets"] = m.elements();
}
BENCHMARK(BM_TimestepAnalyzerFull)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Local update after the fractions of 20 neighbouring elements changed (a small cut).
void BM_TimestepLocalUpdate(benchmark::State& st) {
    Model m = model(static_cast<int>(st.range(0)));
    TimestepAnalyzer an(m);
    std::vector<int> changed;
    for (int e = m.elements() / 2; e < m.elements() / 2 + 20; ++e) changed.push_back(e);
    int flip = 0;
    for (auto _ : st) {
        for (int e : changed) m.fraction(e) = (flip & 1) ? 1.0 : 0.5;
        ++flip;
        updateMasses(m);
        an.update(m, changed);
        benchmark::DoNotOptimize(an.certifiedLambda());
    }
    st.counters["tets"] = m.elements();
    st.counters["elements_updated"] = an.lastUpdate().elements;
}
BENCHMARK(BM_TimestepLocalUpdate)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

}  // namespace
