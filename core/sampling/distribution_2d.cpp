// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/sampling/distribution_2d.h"

#include <cmath>
#include <stdexcept>

namespace gdmlt {

Distribution2D::Distribution2D(const std::vector<float>& weights, int width, int height)
    : width_(width), height_(height) {
    if (width < 1 || height < 1 ||
        weights.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height))
        throw std::invalid_argument("Distribution2D: weights do not match the grid size");
    std::vector<float> row_sums(static_cast<std::size_t>(height), 0.f);
    conditional_.reserve(static_cast<std::size_t>(height));
    for (int y = 0; y < height; ++y) {
        const auto begin = weights.begin() + static_cast<std::ptrdiff_t>(y) * width;
        conditional_.emplace_back(std::vector<float>(begin, begin + width));
        row_sums[static_cast<std::size_t>(y)] = static_cast<float>(conditional_.back().total());
    }
    marginal_ = Distribution1D(row_sums);
    // Every cell's density, the one sample() reports and pdf_area() reads.
    pdf_area_.assign(weights.size(), 0.f);
    if (!valid()) return;
    for (int y = 0; y < height; ++y) {
        const Distribution1D& columns = conditional_[static_cast<std::size_t>(y)];
        if (!columns.valid()) continue;
        for (int x = 0; x < width; ++x)
            pdf_area_[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                      static_cast<std::size_t>(x)] = marginal_.pmf(static_cast<std::size_t>(y)) *
                                                     columns.pmf(static_cast<std::size_t>(x)) *
                                                     static_cast<float>(width_) *
                                                     static_cast<float>(height_);
    }
}

Vec2f Distribution2D::sample(const Vec2f& u, float* pdf_area) const {
    float v_in_row = 0.f, u_in_cell = 0.f;
    const std::size_t row = marginal_.sample(u.y(), &v_in_row);
    const Distribution1D& columns = conditional_[row];
    const std::size_t column = columns.sample(u.x(), &u_in_cell);
    *pdf_area = pdf_area_[row * static_cast<std::size_t>(width_) + column];
    // The remapped numbers place the point uniformly inside the chosen cell.
    return {inside_cell(column, u_in_cell, width_), inside_cell(row, v_in_row, height_)};
}

float Distribution2D::inside_cell(std::size_t cell, float u_in_cell, int cells) {
    // (cell + u) / cells with u just below 1 rounds to the next cell's edge (at cell 32 of 64
    // for u > 1 - 2e-6), where pdf_area() would read the neighbour's density: step back to
    // the last float that pdf_area() maps to this cell, so that a sample's density is the
    // density of the point it returns.
    const auto n = static_cast<float>(cells);
    float x = (static_cast<float>(cell) + u_in_cell) / n;
    while (x > 0.f && static_cast<std::size_t>(x * n) > cell) x = std::nextafter(x, 0.f);
    return x;
}

float Distribution2D::pdf_area(const Vec2f& p) const {
    if (!valid() || !(p.x() >= 0.f && p.x() <= 1.f && p.y() >= 0.f && p.y() <= 1.f)) return 0.f;
    const int x = std::min(static_cast<int>(p.x() * static_cast<float>(width_)), width_ - 1);
    const int y = std::min(static_cast<int>(p.y() * static_cast<float>(height_)), height_ - 1);
    return pdf_area_[static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) +
                     static_cast<std::size_t>(x)];
}

}  // namespace gdmlt
