// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/splat_film.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

#include "core/scene/spectrum_rgb.h"

namespace gdmlt {

SplatFilm::SplatFilm(int width, int height, const PixelFilter& filter)
    : width_(width),
      height_(height),
      filter_(filter),
      reach_(static_cast<int>(std::ceil(filter.radius()))),
      weight_sum_(static_cast<std::size_t>(width) * height, 0.0),
      value_sum_(static_cast<std::size_t>(width) * height * 3, 0.0) {}

void SplatFilm::begin_pass(int first_sample, int sample_count) {
    first_sample_ = first_sample;
    sample_count_ = sample_count;
    const std::size_t records = static_cast<std::size_t>(width_) * height_ * sample_count;
    // A larger pass frees the old records before taking the new ones (assign alone would hold
    // both at once: the render's peak memory).
    if (records_.capacity() < records) {
        records_ = {};
        records_.reserve(records);
    }
    records_.assign(records, Record{});
    if (track_squares_ && square_sum_.empty())
        square_sum_.assign(static_cast<std::size_t>(width_) * height_ * 3, 0.0);
}

void SplatFilm::record(int x, int y, int sample, const Vec2f& position, const Rgb& value) {
    const std::size_t pixel = static_cast<std::size_t>(y) * width_ + x;
    Record& r = records_[pixel * static_cast<std::size_t>(sample_count_) +
                         static_cast<std::size_t>(sample - first_sample_)];
    r.x = position.x();
    r.y = position.y();
    r.value = value;
    r.valid = true;
}

void SplatFilm::end_pass() {
    if (sample_count_ == 0) return;
    const auto count = static_cast<std::size_t>(sample_count_);
    // Gather: every pixel reads the records of the pixels within reach, so no two tasks write
    // the same sums. Per pixel: sample by sample, then neighbour by neighbour in raster order.
    tbb::parallel_for(tbb::blocked_range<int>(0, height_), [&](const tbb::blocked_range<int>&
                                                                   rows) {
        for (int py = rows.begin(); py != rows.end(); ++py)
            for (int px = 0; px < width_; ++px) {
                const std::size_t pixel = static_cast<std::size_t>(py) * width_ + px;
                const float cx = static_cast<float>(px) + 0.5f, cy = static_cast<float>(py) + 0.5f;
                // Straight into the pixel's sums, term by term: the same additions in the same
                // order whatever the passes (a per-pass subtotal would round differently).
                double& weight = weight_sum_[pixel];
                double* sum = &value_sum_[3 * pixel];
                double* squares = track_squares_ ? &square_sum_[3 * pixel] : nullptr;
                for (std::size_t s = 0; s < count; ++s)
                    for (int qy = std::max(py - reach_, 0);
                         qy <= std::min(py + reach_, height_ - 1); ++qy)
                        for (int qx = std::max(px - reach_, 0);
                             qx <= std::min(px + reach_, width_ - 1); ++qx) {
                            const Record& r =
                                records_[(static_cast<std::size_t>(qy) * width_ + qx) * count + s];
                            if (!r.valid) continue;
                            const float w =
                                filter_.eval_tabulated(r.x - cx) * filter_.eval_tabulated(r.y - cy);
                            if (!(w > 0.f)) continue;
                            const double wd = w;
                            weight += wd;
                            for (int c = 0; c < 3; ++c) sum[c] += wd * r.value[c];
                            if (squares) {
                                const Vec3f xyz = linear_srgb_to_xyz(r.value);
                                for (int c = 0; c < 3; ++c)
                                    squares[c] += wd * static_cast<double>(xyz[c]) * xyz[c];
                            }
                        }
            }
    });
    for (const Record& r : records_) samples_ += r.valid ? 1 : 0;
    sample_count_ = 0;
    records_.clear();
}

Image SplatFilm::mean() const {
    Image image(width_, height_, 3);
    for (std::size_t i = 0; i < weight_sum_.size(); ++i)
        if (weight_sum_[i] > 0.0)
            for (int c = 0; c < 3; ++c)
                image.pixels[3 * i + c] =
                    static_cast<float>(value_sum_[3 * i + c] / weight_sum_[i]);
    return image;
}

Image SplatFilm::second_moment() const {
    if (!track_squares_) return {};
    Image image(width_, height_, 3);
    for (std::size_t i = 0; i < weight_sum_.size(); ++i)
        if (weight_sum_[i] > 0.0 && !square_sum_.empty())
            for (int c = 0; c < 3; ++c)
                image.pixels[3 * i + c] =
                    static_cast<float>(square_sum_[3 * i + c] / weight_sum_[i]);
    return image;
}

}  // namespace gdmlt
