// Explicit corotational step throughput in tet-steps per second.
//   build/bench/cutsim_bench --benchmark_filter=BM_Step
#include "bench/step_box.hpp"
#include "fem/forces.hpp"
#include "fem/integrate.hpp"
#include "mesh/generate.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/Geometry>

using namespace cutsim;

namespace {

// args: cubes per side n (6 n^3 tets), threads
void BM_StepCorotational(benchmark::State& st) {
    const int n = static_cast<int>(st.range(0));
    setThreads(static_cast<int>(st.range(1)));
    Model m = stepBox(n);
    State s = makeState(m);
    // start from a rotated, bent state so the rotation extraction does real work
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
    s.x = R * m.X;
    Stepper stepper;
    const StepOptions opt{Integrator::SymplecticEuler, 1e-6};
    for (int k = 0; k < 5; ++k) stepper.step(m, s, opt);  // warm up
    for (auto _ : st) stepper.step(m, s, opt);
    st.counters["tets"] = m.elements();
    st.counters["tet_steps_per_s"] =
        benchmark::Counter(static_cast<double>(m.elements()) * st.iterations(), benchmark::Counter::kIsRate);
    st.counters["hash"] = s.x.sum();
    setThreads(0);
}

}  // namespace

// 12^3 * 6 = 10368 tets; 26^3 * 6 = 105456 tets
BENCHMARK(BM_StepCorotational)
    ->Args({12, 1})
    ->Args({12, 2})
    ->Args({26, 1})
    ->Args({26, 2})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);
