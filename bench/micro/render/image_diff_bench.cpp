// Cost of `cutsim check`'s frame comparison on a 1280x720 frame: the renderdiff rule over every
// pixel (a passing frame: no diff image; a failing one: with it), and decoding a golden PNG.
//   build/bench/cutsim_render_bench
#include "image_diff.hpp"
#include "png_writer.hpp"

#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

namespace {

using cutsim::render::Image;

// A frame-like image: smooth gradients (as a rendered surface) with some noise.
Image frame(unsigned seed) {
    Image img;
    img.width = 1280;
    img.height = 720;
    img.rgba.resize(4u * 1280u * 720u);
    std::mt19937 rng(seed);
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) {
            std::uint8_t* p = &img.rgba[4u * (static_cast<unsigned>(y) * 1280u + static_cast<unsigned>(x))];
            p[0] = static_cast<std::uint8_t>((x / 5 + rng() % 3) & 255);
            p[1] = static_cast<std::uint8_t>((y / 3 + rng() % 3) & 255);
            p[2] = static_cast<std::uint8_t>(((x + y) / 8) & 255);
            p[3] = 255;
        }
    return img;
}

void BM_DiffPassing(benchmark::State& state) {
    const Image a = frame(1), b = frame(2);
    for (auto _ : state) benchmark::DoNotOptimize(cutsim::render::diffImages(a, b, 5, false));
}
BENCHMARK(BM_DiffPassing)->Unit(benchmark::kMillisecond);

void BM_DiffWithImage(benchmark::State& state) {
    const Image a = frame(1), b = frame(2);
    for (auto _ : state) benchmark::DoNotOptimize(cutsim::render::diffImages(a, b, 1, true));
}
BENCHMARK(BM_DiffWithImage)->Unit(benchmark::kMillisecond);

void BM_ReadPng(benchmark::State& state) {
    const std::string path = (std::filesystem::temp_directory_path() / "cutsim_bench_frame.png").string();
    cutsim::render::writePng(path, frame(1));
    for (auto _ : state) benchmark::DoNotOptimize(cutsim::render::readPng(path));
    std::filesystem::remove(path);
}
BENCHMARK(BM_ReadPng)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
