// Golden-image comparison for render tests (the renderdiff rule of render/image_diff.hpp, also
// `cutsim check`'s): each scene has an explicit
// tolerance, a failure writes the actual frame and a diff image under golden_diff/ in the test's
// working folder (the build tree), and one command accepts new references:
//
//   CUTSIM_UPDATE_GOLDEN=1 ctest -R '^RenderGolden'        (from the build folder)
//
// References live in tests/golden/<scene>.png; see tests/golden/README.md.
#pragma once

#include "image.hpp"
#include "image_diff.hpp"
#include "png_writer.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

namespace cutsim::test {

struct GoldenTolerance {
    int channel = 0;        // a pixel differs when one of its channels differs by more than this
    double fraction = 0.0;  // the scene passes when at most this fraction of pixels differ
};

using render::diffImages;
using render::ImageDiff;

inline bool updatingGolden() {
    const char* u = std::getenv("CUTSIM_UPDATE_GOLDEN");
    return u && std::string(u) == "1";
}

// Compares img with tests/golden/<scene>.png; with CUTSIM_UPDATE_GOLDEN=1 writes it instead.
inline void expectGolden(const std::string& scene, const render::Image& img, const GoldenTolerance& tol) {
    const std::string ref = source("tests/golden/" + scene + ".png");
    if (updatingGolden()) {
        render::writePng(ref, img);
        std::cout << "[ golden   ] updated " << ref << "\n";
        return;
    }
    if (!std::filesystem::exists(ref)) {
        ADD_FAILURE() << "no reference " << ref << "; create it with CUTSIM_UPDATE_GOLDEN=1 ctest -R '^RenderGolden'";
        return;
    }
    const render::Image want = render::readPng(ref);
    const std::filesystem::path out = std::filesystem::current_path() / "golden_diff";
    if (want.width != img.width || want.height != img.height) {
        std::filesystem::create_directories(out);
        render::writePng((out / (scene + ".actual.png")).string(), img);
        ADD_FAILURE() << scene << ": size " << img.width << "x" << img.height << ", reference " << want.width << "x"
                      << want.height;
        return;
    }
    const ImageDiff d = diffImages(want, img, tol.channel);
    if (d.fraction > tol.fraction) {
        std::filesystem::create_directories(out);
        render::writePng((out / (scene + ".actual.png")).string(), img);
        render::writePng((out / (scene + ".diff.png")).string(), d.diff);
        ADD_FAILURE() << scene << ": " << d.fraction * 100 << "% of pixels differ by more than " << tol.channel
                      << " (allowed " << tol.fraction * 100 << "%), max difference " << d.maxChannel
                      << "; actual and diff images in " << out.string()
                      << "; accept with CUTSIM_UPDATE_GOLDEN=1 ctest -R '^RenderGolden'";
    }
}

}  // namespace cutsim::test
