// An 8-bit RGBA image, top row first (PNG order).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cutsim::render {

struct Image {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> rgba;  // 4 bytes per pixel, row-major, top row first (4 * width * height)

    std::array<std::uint8_t, 4> pixel(int x, int y) const {
        const std::uint8_t* p =
            &rgba[4 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x))];
        return {p[0], p[1], p[2], p[3]};
    }
};

}  // namespace cutsim::render
