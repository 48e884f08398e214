// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Piecewise-constant density on the unit square over a width x height grid of cells, sampled by
// a marginal distribution over rows and a conditional one per row (pbrt's Distribution2D
// construction; Pharr et al., "Physically Based Rendering", 4th ed., Sec. A.5.6).
#include <vector>

#include "core/math/types.h"
#include "core/sampling/distribution_1d.h"

namespace gdmlt {

class Distribution2D {
  public:
    Distribution2D() = default;
    /// `weights` row-major (weights[y * width + x]), non-negative; cell (x, y) covers
    /// [x / width, (x + 1) / width) x [y / height, (y + 1) / height).
    Distribution2D(const std::vector<float>& weights, int width, int height);

    bool valid() const { return marginal_.valid(); }
    int width() const { return width_; }
    int height() const { return height_; }

    /// A point of [0, 1)^2; `pdf_area` receives its density with respect to area on the square.
    Vec2f sample(const Vec2f& u, float* pdf_area) const;
    /// Density at a point of the square (zero outside it).
    float pdf_area(const Vec2f& p) const;

  private:
    /// The coordinate of the point `u_in_cell` of the way across cell `cell` of `cells`, never
    /// rounded into the next cell.
    static float inside_cell(std::size_t cell, float u_in_cell, int cells);

    int width_ = 0;
    int height_ = 0;
    Distribution1D marginal_;                  // over rows
    std::vector<Distribution1D> conditional_;  // over columns, per row
    std::vector<float> pdf_area_;              // per cell, row-major: pdf_area's table
};

}  // namespace gdmlt
