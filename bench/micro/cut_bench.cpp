// Cut latency on the SOFA liver (596 tets, 181 nodes, set up as tests/cut/random_cuts.hpp's
// randomCutModel): the requirement is cut plus time-step update under 1 ms for a blade step that
// crosses up to 50 elements.
//   BM_CutBladeStep/N     one blade step (CutEngine::sweep between two poses) whose swept area
//                         crosses about N = 10, 25, 50 elements, plus TimestepAnalyzer::update;
//                         time = both and the step floor's local pass (timestep/floor.hpp, 0.95
//                         of the uncut exact step), counters cut_us, update_us and floor_us split
//                         it, crossed = count.
//   BM_CutPlane           a plane through the whole liver (CutEngine::cut) plus the update.
//   BM_CutExactDt/k       the exact dt (Lanczos) of the model after the 50-element step (k = 0)
//                         or the plane cut (k = 1), for comparison with the local update.
// Every iteration starts from an uncut copy (model, state, prepared engine, analyzer) made
// outside the timed region; only the cut and the update are timed (manual wall time; the counter
// thread_cpu_us is the same span in CPU time of the thread). Medians of 5. The analyzer's update
// runs its loops in parallel above 256 items: OMP_NUM_THREADS=1 measures it serially.
// Run: build/bench/cutsim_bench --benchmark_filter=Cut
// No main here: cutsim_bench's main lives in another file of this folder.
#include "bench/random_cuts.hpp"
#include "cut/xfem.hpp"
#include "fem/model.hpp"
#include "fem/state.hpp"
#include "mesh/io.hpp"
#include "timestep/analyzer.hpp"
#include "timestep/cut_response.hpp"
#include "timestep/floor.hpp"

#include <benchmark/benchmark.h>

#include <chrono>
#include <ctime>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

namespace {

using namespace cutsim;
using Clock = std::chrono::steady_clock;

double secondsBetween(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }
// CPU time of this thread [s]: on a shared machine it shows the work apart from preemption.
double threadSeconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Everything a cut starts from; copied before each iteration.
struct Scene {
    Model m;
    State s;
    CutEngine eng;
    TimestepAnalyzer an;
    double dt0 = 0;  // exact step of the uncut liver [s]
};

// The liver fixed at its back under gravity, as randomCutModel(true), with a prepared engine.
const Scene& uncut() {
    static std::unique_ptr<Scene> sc;
    if (!sc) {
        sc = std::make_unique<Scene>();
        Model& m = sc->m;
        m = randomCutLiverModel(readTetMesh(std::string(CUTSIM_DATA_DIR) + "/tet/sofa_liver.msh"), kSceneLiverClampZ);
        sc->s = makeState(m);
        sc->eng.prepare(m);
        sc->an.compute(m);
        sc->dt0 = sc->an.exact(m).dt;
    }
    return *sc;
}

// A scalpel in the plane x = centre of the liver, its edge along z and longer than the liver,
// entering from below (y) and moving up to height y.
BladeEdge edgeAt(double y) {
    const Model& m = uncut().m;
    const Eigen::Vector3d lo = m.X.rowwise().minCoeff(), hi = m.X.rowwise().maxCoeff();
    const double x = 0.5 * (lo.x() + hi.x()), dz = 0.1 * (hi.z() - lo.z());
    return {{x, y, lo.z() - dz}, {x, y, hi.z() + dz}};
}
double startY() {
    const Model& m = uncut().m;
    return m.X.row(1).minCoeff() - 0.05 * (m.X.row(1).maxCoeff() - m.X.row(1).minCoeff());
}

int crossedBy(double y) {
    Scene sc = uncut();
    return sc.eng.sweep(sc.m, sc.s, edgeAt(startY()), edgeAt(y)).crossed;
}

// End height of the step from startY() that first crosses at least `target` elements (bisection
// on the monotone count), found once per target.
double stepEndFor(int target) {
    static std::map<int, double> cache;
    if (auto it = cache.find(target); it != cache.end()) return it->second;
    const Model& m = uncut().m;
    double lo = startY(), hi = m.X.row(1).maxCoeff();
    if (crossedBy(hi) < target) throw std::runtime_error("no blade step of the liver crosses that many elements");
    for (int it = 0; it < 60 && hi - lo > 1e-9; ++it) {
        const double mid = 0.5 * (lo + hi);
        (crossedBy(mid) >= target ? hi : lo) = mid;
    }
    return cache[target] = hi;
}

CutSurface centrePlane() {
    const Model& m = uncut().m;
    CutSurface cs;
    cs.point = 0.5 * (m.X.rowwise().minCoeff() + m.X.rowwise().maxCoeff());
    cs.normal = Eigen::Vector3d::UnitX();
    return cs;
}

// Cut (a blade step or the plane) plus the analyzer's update, timed separately.
template <class CutFn>
void runCut(benchmark::State& st, CutFn cutFn) {
    double sweepSum = 0, updateSum = 0, floorSum = 0, cpuSum = 0;
    CutResult last;
    TimestepAnalyzer::UpdateStats lastStats;
    for (auto _ : st) {
        st.PauseTiming();
        Scene sc = uncut();
        st.ResumeTiming();
        const double c0 = threadSeconds();
        const auto t0 = Clock::now();
        CutResult r = cutFn(sc);
        const auto t1 = Clock::now();
        // the product's after-cut response, its exact solve measured apart (BM_CutExactDt)
        CutResponseOptions ro;
        ro.dtFloor = 0.95 * sc.dt0;
        ro.exact = false;
        const CutResponseResult res = CutResponse(ro).apply(sc.m, sc.an, r.changedElements, r.changedNodes);
        const auto t3 = Clock::now();
        cpuSum += threadSeconds() - c0;
        benchmark::DoNotOptimize(sc.an.certifiedLambda());
        st.SetIterationTime(secondsBetween(t0, t3));
        sweepSum += secondsBetween(t0, t1);
        updateSum += res.updateSeconds - res.floor.seconds;
        floorSum += res.floor.seconds;
        last = std::move(r);
        lastStats = sc.an.lastUpdate();
    }
    const double n = static_cast<double>(st.iterations());
    st.counters["cut_us"] = 1e6 * sweepSum / n;
    st.counters["update_us"] = 1e6 * updateSum / n;
    st.counters["floor_us"] = 1e6 * floorSum / n;
    st.counters["thread_cpu_us"] = 1e6 * cpuSum / n;  // cut + update + floor, CPU time of the thread
    st.counters["crossed"] = last.crossed;
    st.counters["new_elems"] = static_cast<double>(last.newElements.size());
    st.counters["new_nodes"] = static_cast<double>(last.newNodes.size());
    st.counters["est_elems"] = lastStats.elements;  // elements the update re-estimated
    st.counters["rows"] = lastStats.nodes;          // stiffness rows it rebuilt
}

void BM_CutBladeStep(benchmark::State& st) {
    const BladeEdge from = edgeAt(startY()), to = edgeAt(stepEndFor(static_cast<int>(st.range(0))));
    runCut(st, [&](Scene& sc) { return sc.eng.sweep(sc.m, sc.s, from, to); });
}
BENCHMARK(BM_CutBladeStep)
    ->Arg(10)
    ->Arg(25)
    ->Arg(50)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

void BM_CutPlane(benchmark::State& st) {
    const CutSurface cs = centrePlane();
    runCut(st, [&](Scene& sc) { return sc.eng.cut(sc.m, sc.s, cs); });
}
BENCHMARK(BM_CutPlane)->UseManualTime()->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

// Exact dt of the cut model: 0 after the 50-element blade step, 1 after the plane cut.
void BM_CutExactDt(benchmark::State& st) {
    Scene sc = uncut();
    const CutResult r = st.range(0) == 0 ? sc.eng.sweep(sc.m, sc.s, edgeAt(startY()), edgeAt(stepEndFor(50)))
                                         : sc.eng.cut(sc.m, sc.s, centrePlane());
    sc.an.update(sc.m, r.changedElements, r.changedNodes);
    ExactResult ex;
    for (auto _ : st) {
        ex = sc.an.exact(sc.m);
        benchmark::DoNotOptimize(ex.lambdaMax);
    }
    st.counters["crossed"] = r.crossed;
    st.counters["matvecs"] = ex.matvecs;
    st.counters["dt_us"] = ex.dt * 1e6;
    st.counters["certified_dt_us"] = sc.an.certifiedDt() * 1e6;
}
BENCHMARK(BM_CutExactDt)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

}  // namespace
