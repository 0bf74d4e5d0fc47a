#include "image_diff.hpp"

#include <algorithm>
#include <cstdlib>

namespace cutsim::render {

ImageDiff diffImages(const Image& ref, const Image& img, int channelTol, bool makeImage) {
    ImageDiff d;
    if (ref.width != img.width || ref.height != img.height || ref.rgba.size() != img.rgba.size()) {
        d.sameSize = false;
        d.fraction = 1;
        return d;
    }
    const std::size_t n = img.rgba.size();
    const std::uint8_t* a = ref.rgba.data();
    const std::uint8_t* b = img.rgba.data();
    if (makeImage) {
        d.diff.width = img.width;
        d.diff.height = img.height;
        d.diff.rgba.resize(n);
    }
    long bad = 0;
    int worst = 0;
    for (std::size_t p = 0; p < n; p += 4) {
        int m = 0;
        for (int c = 0; c < 4; ++c) m = std::max(m, std::abs(int(b[p + c]) - int(a[p + c])));
        worst = std::max(worst, m);
        const bool fails = m > channelTol;
        bad += fails;
        if (makeImage) {
            std::uint8_t* o = &d.diff.rgba[p];
            for (int c = 0; c < 3; ++c) o[c] = fails ? (c == 0 ? 255 : 0) : a[p + c] / 4;
            o[3] = 255;
        }
    }
    d.maxChannel = worst;
    d.failing = bad;
    d.fraction = n ? double(bad) / double(n / 4) : 0.0;
    return d;
}

Image sideBySide(const Image& ref, const Image& img, const Image& diff) {
    const Image* parts[] = {&ref, &img, &diff};
    Image out;
    for (const Image* p : parts) {
        out.width += p->width;
        out.height = std::max(out.height, p->height);
    }
    out.rgba.assign(4 * static_cast<std::size_t>(out.width) * static_cast<std::size_t>(out.height), 0);
    for (std::size_t i = 3; i < out.rgba.size(); i += 4) out.rgba[i] = 255;
    int x0 = 0;
    for (const Image* p : parts) {
        for (int y = 0; y < p->height; ++y)
            std::copy_n(&p->rgba[4 * static_cast<std::size_t>(y) * static_cast<std::size_t>(p->width)],
                        4 * static_cast<std::size_t>(p->width),
                        &out.rgba[4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(out.width) +
                                       static_cast<std::size_t>(x0))]);
        x0 += p->width;
    }
    return out;
}

}  // namespace cutsim::render
