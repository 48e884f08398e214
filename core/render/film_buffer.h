// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Per-pixel accumulation in double with a per-pixel sample count, so that an interrupted
// render (some pixels with more samples than others) still normalises every pixel correctly.
// Optionally also the samples' second moments in CIE XYZ (Mitsuba 3's `moment` integrator).
#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/math/types.h"
#include "core/scene/spectrum_rgb.h"

namespace gdmlt {

class FilmBuffer {
  public:
    FilmBuffer(int width, int height)
        : width_(width),
          height_(height),
          sum_(static_cast<std::size_t>(width) * height * 3, 0.0),
          count_(static_cast<std::size_t>(width) * height, 0) {}

    int width() const { return width_; }
    int height() const { return height_; }

    /// From now on also sums each sample's squared XYZ values (second_moment).
    void track_second_moment() {
        squares_.assign(static_cast<std::size_t>(width_) * height_ * 3, 0.0);
    }

    /// Adds one sample's radiance to pixel (x, y). Not thread-safe for the same pixel.
    void add(int x, int y, const Rgb& value) {
        const std::size_t i = static_cast<std::size_t>(y) * width_ + x;
        for (int c = 0; c < 3; ++c) sum_[3 * i + c] += static_cast<double>(value[c]);
        if (!squares_.empty()) {
            const Vec3f xyz = linear_srgb_to_xyz(value);
            for (int c = 0; c < 3; ++c)
                squares_[3 * i + c] += static_cast<double>(xyz[c]) * static_cast<double>(xyz[c]);
        }
        ++count_[i];
    }
    /// Counts a sample that was dropped (non-finite) as taken, contributing zero: dropping
    /// without counting would bias pixels upwards.
    void add_dropped(int x, int y) { ++count_[static_cast<std::size_t>(y) * width_ + x]; }

    std::uint32_t count(int x, int y) const {
        return count_[static_cast<std::size_t>(y) * width_ + x];
    }
    std::uint64_t total_count() const;
    /// Mean per pixel (zero where no sample landed).
    Image mean() const;
    /// Mean of the samples' squared XYZ values per pixel (after track_second_moment; empty
    /// before).
    Image second_moment() const;

  private:
    int width_, height_;
    std::vector<double> squares_;  // XYZ, when tracked
    std::vector<double> sum_;
    std::vector<std::uint32_t> count_;
};

}  // namespace gdmlt
