// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/film_buffer.h"

namespace gdmlt {

std::uint64_t FilmBuffer::total_count() const {
    std::uint64_t total = 0;
    for (std::uint32_t c : count_) total += c;
    return total;
}

Image FilmBuffer::mean() const {
    Image image(width_, height_, 3);
    for (std::size_t i = 0; i < count_.size(); ++i) {
        if (count_[i] == 0) continue;
        const double inv = 1.0 / static_cast<double>(count_[i]);
        for (int c = 0; c < 3; ++c)
            image.pixels[3 * i + c] = static_cast<float>(sum_[3 * i + c] * inv);
    }
    return image;
}

Image FilmBuffer::second_moment() const {
    if (squares_.empty()) return Image();
    Image image(width_, height_, 3);
    for (std::size_t i = 0; i < count_.size(); ++i) {
        if (count_[i] == 0) continue;
        const double inv = 1.0 / static_cast<double>(count_[i]);
        for (int c = 0; c < 3; ++c)
            image.pixels[3 * i + c] = static_cast<float>(squares_[3 * i + c] * inv);
    }
    return image;
}

}  // namespace gdmlt
