// Benchmark programs: run with `build/tests/cutsim_bench`, never as tests.
#include <benchmark/benchmark.h>

BENCHMARK_MAIN();
