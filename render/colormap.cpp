#include "colormap.hpp"

#include <algorithm>
#include <cmath>

namespace cutsim::render {
namespace {

constexpr Rgb8 kViridis[] = {{0x44, 0x01, 0x54}, {0x47, 0x2d, 0x7b}, {0x3b, 0x52, 0x8b},
                             {0x2c, 0x72, 0x8e}, {0x21, 0x91, 0x8c}, {0x28, 0xae, 0x80},
                             {0x5e, 0xc9, 0x62}, {0xad, 0xdc, 0x30}, {0xfd, 0xe7, 0x25}};
// Moreland 2009, "Diverging color maps for scientific visualization", cool-warm.
constexpr Rgb8 kCoolWarm[] = {{59, 76, 192}, {141, 176, 254}, {221, 221, 221}, {244, 154, 123}, {180, 4, 38}};

}  // namespace

std::span<const Rgb8> colorMapTable(ColorMapKind kind) {
    if (kind == ColorMapKind::Diverging) return kCoolWarm;
    return kViridis;
}

std::array<float, 3> colorMapLookup(ColorMapKind kind, double t) {
    auto table = colorMapTable(kind);
    const int n = static_cast<int>(table.size());
    // Same arithmetic as the fragment shader (renderer.cpp), in float.
    const float x = static_cast<float>(std::clamp(t, 0.0, 1.0)) * static_cast<float>(n - 1);
    const int i = std::min(static_cast<int>(std::floor(x)), n - 2);
    const float f = x - static_cast<float>(i);
    const Rgb8 a = table[static_cast<size_t>(i)], b = table[static_cast<size_t>(i + 1)];
    auto mix = [f](std::uint8_t u, std::uint8_t v) { return (u / 255.0f) * (1 - f) + (v / 255.0f) * f; };
    return {mix(a.r, b.r), mix(a.g, b.g), mix(a.b, b.b)};
}

}  // namespace cutsim::render
