// Explicit corotational step throughput in tet-steps per second.
//   build/tests/cutsim_bench --benchmark_filter=BM_Step
#include "fem/forces.hpp"
#include "fem/integrate.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/Geometry>

using namespace cutsim;

namespace {

// Regular box of n x n x m cubes, 6 tets each (Kuhn split), slightly jittered.
TetMesh benchBox(int nx, int ny, int nz) {
    TetMesh m;
    const int px = nx + 1, py = ny + 1, pz = nz + 1;
    m.X.resize(3, px * py * pz);
    auto id = [&](int i, int j, int k) { return i + px * (j + py * k); };
    for (int k = 0; k < pz; ++k)
        for (int j = 0; j < py; ++j)
            for (int i = 0; i < px; ++i) m.X.col(id(i, j, k)) << 0.01 * i, 0.01 * j, 0.01 * k;
    static constexpr int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    m.tets.resize(4, 6 * nx * ny * nz);
    int t = 0;
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i)
                for (const auto& p : perms) {
                    int c[3] = {i, j, k}, v[4];
                    v[0] = id(i, j, k);
                    for (int s = 0; s < 3; ++s) { ++c[p[s]]; v[s + 1] = id(c[0], c[1], c[2]); }
                    m.tets.col(t) << v[0], v[1], v[2], v[3];
                    if (tetSignedVolume(m, t) < 0) std::swap(m.tets(2, t), m.tets(3, t));
                    ++t;
                }
    return m;
}

// args: cubes along x (tets = 6 n^3 / 4 for an n x n/2 x n/2 box... see below), threads
void BM_StepCorotational(benchmark::State& st) {
    const int n = static_cast<int>(st.range(0));
    setThreads(static_cast<int>(st.range(1)));
    Model m = buildModel(benchBox(n, n, n), Material{});
    std::vector<int> fixedNodes;
    for (int i = 0; i < m.nodes(); ++i)
        if (m.X(0, i) < 1e-9) fixedNodes.push_back(i);
    fixNodes(m, fixedNodes);
    m.gravity << 0, 0, -9.81;
    State s = makeState(m);
    // start from a rotated, bent state so the rotation extraction does real work
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
    s.x = R * m.X;
    Stepper stepper;
    const StepOptions opt{Integrator::SymplecticEuler, 1e-6};
    for (int k = 0; k < 5; ++k) stepper.step(m, s, opt);  // warm up
    for (auto _ : st) stepper.step(m, s, opt);
    st.counters["tets"] = m.elements();
    st.counters["tet_steps_per_s"] = benchmark::Counter(static_cast<double>(m.elements()) * st.iterations(),
                                                        benchmark::Counter::kIsRate);
    st.counters["hash"] = s.x.sum();
    setThreads(0);
}

} // namespace

// 12^3 * 6 = 10368 tets; 26^3 * 6 = 105456 tets
BENCHMARK(BM_StepCorotational)->Args({12, 1})->Args({12, 2})->Args({26, 1})->Args({26, 2})->UseRealTime()->Unit(benchmark::kMicrosecond);
