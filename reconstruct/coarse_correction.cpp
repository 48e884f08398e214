// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/coarse_correction.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace gdmlt::reconstruct {
namespace {

/// One box pass over a line of `n` values with stride `stride` (mirror padding: index -1 is 0,
/// n is n - 1). The padded operator is symmetric and its rows sum to 1.
void box_line(float* data, std::size_t n, std::size_t stride, int radius,
              std::vector<double>& prefix) {
    const auto r = static_cast<std::ptrdiff_t>(radius);
    const auto len = static_cast<std::ptrdiff_t>(n);
    prefix.assign(static_cast<std::size_t>(len + 2 * r + 1), 0.0);
    for (std::ptrdiff_t k = -r; k < len + r; ++k) {
        std::ptrdiff_t j = k < 0 ? -1 - k : k >= len ? 2 * len - 1 - k : k;
        const double v = static_cast<double>(data[static_cast<std::size_t>(j) * stride]);
        prefix[static_cast<std::size_t>(k + r + 1)] = prefix[static_cast<std::size_t>(k + r)] + v;
    }
    const double inv = 1.0 / static_cast<double>(2 * r + 1);
    for (std::ptrdiff_t i = 0; i < len; ++i)
        data[static_cast<std::size_t>(i) * stride] =
            static_cast<float>((prefix[static_cast<std::size_t>(i + 2 * r + 1)] -
                                prefix[static_cast<std::size_t>(i)]) *
                               inv);
}

}  // namespace

void box_blur3(Image& image, int radius) {
    if (radius <= 0 || image.pixels.empty()) return;
    const auto w = static_cast<std::size_t>(image.width),
               h = static_cast<std::size_t>(image.height);
    const auto ch = static_cast<std::size_t>(image.channels);
    // A mirror reaches at most one image length beyond each border.
    const int rx = std::min(radius, image.width - 1), ry = std::min(radius, image.height - 1);
    std::vector<double> prefix;
    for (int pass = 0; pass < 3; ++pass) {
        for (std::size_t c = 0; c < ch; ++c) {
            if (rx > 0)
                for (std::size_t y = 0; y < h; ++y)
                    box_line(&image.pixels[(y * w) * ch + c], w, ch, rx, prefix);
            if (ry > 0)
                for (std::size_t x = 0; x < w; ++x)
                    box_line(&image.pixels[x * ch + c], h, w * ch, ry, prefix);
        }
    }
}

void restore_coarse_scales(Image& image, const Image& primal, int radius) {
    if (radius <= 0) return;
    if (primal.width != image.width || primal.height != image.height || primal.channels != 3 ||
        image.channels != 3)
        throw std::invalid_argument("restore_coarse_scales: primal and image differ in size");
    Image residual(image.width, image.height, 3);
    for (std::size_t i = 0; i < residual.pixels.size(); ++i) {
        const float p = primal.pixels[i];
        residual.pixels[i] = std::isfinite(p) ? p - image.pixels[i] : 0.f;
    }
    box_blur3(residual, radius);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] += residual.pixels[i];
}

}  // namespace gdmlt::reconstruct
