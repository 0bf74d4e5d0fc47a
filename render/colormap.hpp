// Colour maps as small tables of exact 8-bit control points, linearly interpolated in between,
// so a test can compute the colour of any value by hand.
#pragma once

#include <array>
#include <cstdint>
#include <span>

namespace cutsim::render {

enum class ColorMapKind : std::uint8_t {
    Sequential,  // viridis, 9 control points (matplotlib's viridis at 0, 1/8, ..., 1)
    Diverging,   // Moreland's cool-warm, 5 control points, light grey at the centre
};

struct Rgb8 {
    std::uint8_t r, g, b;
};

// Control points, evenly spaced over [0, 1].
std::span<const Rgb8> colorMapTable(ColorMapKind kind);

// Colour at t in [0, 1] (clamped), components in [0, 1].
std::array<float, 3> colorMapLookup(ColorMapKind kind, double t);

}  // namespace cutsim::render
