// Frame comparison by the renderdiff rule: a pixel fails when one of its channels differs by more
// than a tolerance, a frame fails when more than a share of its pixels fail. Used by `cutsim
// check` and by the project's own golden-image tests.
#pragma once

#include "image.hpp"

namespace cutsim::render {

struct ImageDiff {
    int maxChannel = 0;     // largest channel difference over the image
    long failing = 0;       // pixels with a channel differing by more than the tolerance
    double fraction = 0.0;  // failing / pixels
    bool sameSize = true;   // false: nothing compared, fraction 1
    Image diff;             // failing pixels red, the rest the reference dimmed (empty without makeImage)
};

// Compares img with ref; makeImage false skips the diff image (the fast path for passing frames).
ImageDiff diffImages(const Image& ref, const Image& img, int channelTol, bool makeImage = true);

// ref | img | diff side by side, for a reader to see what moved (heights may differ: padded).
Image sideBySide(const Image& ref, const Image& img, const Image& diff);

}  // namespace cutsim::render
