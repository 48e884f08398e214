// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The film's reconstruction filter, as Mitsuba 3's hdrfilm applies it: a pixel's value is the
// filter-weighted mean of the image around its centre,
//     I(p) = integral h_p(x) L(x) dx,   h_p(x) = w(x - c_p) / integral_crop w(y - c_p) dy,
// w separable (w(dx) w(dy)) and the integral taken over the crop window only (Mitsuba's film
// samples inside it and normalises by the weights it saw: hdrfilm without sample_border). The
// box filter (radius 1/2) makes h_p the pixel's indicator.
//
// Integrators estimate I(p) in one of three ways:
//  - the path tracer does as Mitsuba's film: positions uniform in their pixel, each sample
//    weighted into every pixel within the radius, a pixel the ratio of its weighted sums
//    (core/render/splat_film.h; consistent, and much less noisy at equal spp);
//  - the other pixel passes draw the sample's film position from h_p itself (filter importance
//    sampling, as pbrt-v4 does: unbiased, one pixel per sample);
//  - splatting integrators (light tracing, BDPT's t = 1 strategies, the Markov chains), whose
//    positions come from elsewhere, add h_p(x) times the value to every pixel p near x.
// Filters with negative lobes (Mitsuba's mitchell, catmullrom, lanczos) are not supported.
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace gdmlt {

class PixelFilter {
  public:
    enum class Kind { Box, Tent, Gaussian };

    /// Mitsuba's `box` (radius 1/2).
    PixelFilter() = default;
    /// Mitsuba's `tent`: w(x) = max(0, 1 - |x| / radius) (radius 1 by default).
    static PixelFilter tent(float radius);
    /// Mitsuba's `gaussian`: w(x) = max(0, exp(-x^2 / (2 stddev^2)) - exp(-radius^2 /
    /// (2 stddev^2))), radius = 4 stddev (stddev 0.5 by default: Mitsuba's default filter).
    static PixelFilter gaussian(float stddev);

    Kind kind() const { return kind_; }
    bool is_box() const { return kind_ == Kind::Box; }
    float radius() const { return radius_; }
    std::string name() const;

    /// The one-dimensional weight w(x) at offset x from a pixel's centre (unnormalised).
    float eval(float x) const;
    /// w(x) interpolated linearly in a table of 4096 values over [0, radius] (within 1e-7 of
    /// eval for these smooth shapes): the splatting film evaluates it tens of times per sample,
    /// and the Gaussian's exp made that twice the cost of the path itself.
    float eval_tabulated(float x) const {
        if (kind_ == Kind::Box) return eval(x);
        const float t = std::abs(x) * table_scale_;
        if (!(t < static_cast<float>(kWeightBins))) return 0.f;
        const auto i = static_cast<std::size_t>(t);
        const float f = t - static_cast<float>(i);
        const std::vector<float>& w = *weights_;
        return w[i] + f * (w[i + 1] - w[i]);
    }
    /// Integral of w over [lo, hi] (clamped to [-radius, radius]).
    double integral(float lo, float hi) const;
    /// An offset in [lo, hi] (clamped to [-radius, radius]; lo < hi, the interval must hold
    /// weight) with density w(x) / integral(lo, hi), from u in [0, 1).
    float sample(float u, float lo, float hi) const;

    /// Weights of the pixels dx = -n .. n around a pixel (n = ceil(radius - 1/2)) for an image
    /// of pixel means: k(dx) = integral of w over [dx - 1/2, dx + 1/2], exact when the image is
    /// constant inside each pixel (filter_image's kernel).
    std::vector<double> pixel_kernel() const;

  private:
    static constexpr int kBins = 512;
    /// cdf_[i]: integral of w from -radius to -radius + i * (2 radius / kBins) (Simpson's rule
    /// per bin, exact to ~1e-12 for these smooth pieces). sample() is uniform inside a bin, so
    /// the density it draws is w averaged over bins of 1/128 pixel (gaussian, tent of radius
    /// 1: 1/256): every bin gets its exact share, and the image differs from w's by a blur far
    /// below a pixel.
    void tabulate();
    double cdf_at(float x) const;

    static constexpr int kWeightBins = 4096;
    Kind kind_ = Kind::Box;
    float radius_ = 0.5f;
    float table_scale_ = 0.f;                            // kWeightBins / radius
    std::shared_ptr<const std::vector<float>> weights_;  // w at i radius / kWeightBins, i <= bins
    float stddev_ = 0.f;
    std::shared_ptr<const std::vector<double>> cdf_;  // kBins + 1 values (not for box)
};

/// `image` (pixel means, any channel count) filtered by `filter`'s pixel_kernel in x and then
/// in y, each pixel normalised by the kernel weights inside the image (as h_p is normalised
/// over the crop window). How the gradient-domain integrators apply the film's filter: they
/// sample and reconstruct with the box filter and filter the result, since a filter spread
/// over several pixels would mix the pairs their differences are taken between.
Image filter_image(const Image& image, const PixelFilter& filter);

}  // namespace gdmlt
