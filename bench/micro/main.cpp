// Benchmark programs: run with `build/bench/cutsim_bench`, never as tests.
#include <benchmark/benchmark.h>

BENCHMARK_MAIN();
