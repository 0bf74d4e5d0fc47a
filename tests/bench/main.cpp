// Benchmark programs (DESIGN.md convention 9): run with `build/tests/cutsim_bench`, never as tests.
#include <benchmark/benchmark.h>

BENCHMARK_MAIN();
