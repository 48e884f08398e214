// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// A plain image: row-major, interleaved channels, value type. Pixel (x, y) has x to the right
// and y downwards, as in the EXR files we write.
#include <cassert>
#include <cstddef>
#include <vector>

namespace gdmlt {

template <typename T>
struct ImageT {
    int width = 0;
    int height = 0;
    int channels = 0;
    std::vector<T> pixels;

    ImageT() = default;
    ImageT(int width_, int height_, int channels_, T fill = T(0))
        : width(width_),
          height(height_),
          channels(channels_),
          pixels(static_cast<std::size_t>(width_) * height_ * channels_, fill) {}

    std::size_t pixel_count() const { return static_cast<std::size_t>(width) * height; }
    std::size_t index(int x, int y, int c = 0) const {
        assert(x >= 0 && x < width && y >= 0 && y < height && c >= 0 && c < channels);
        return (static_cast<std::size_t>(y) * width + x) * channels + c;
    }
    T& operator()(int x, int y, int c = 0) { return pixels[index(x, y, c)]; }
    const T& operator()(int x, int y, int c = 0) const { return pixels[index(x, y, c)]; }

    bool operator==(const ImageT&) const = default;
};

using Image = ImageT<float>;
using ImageD = ImageT<double>;

}  // namespace gdmlt
