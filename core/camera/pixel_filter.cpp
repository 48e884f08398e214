// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/camera/pixel_filter.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace gdmlt {

PixelFilter PixelFilter::tent(float radius) {
    if (!(radius > 0.f && std::isfinite(radius)))
        throw std::invalid_argument("the tent filter's radius must be positive and finite");
    PixelFilter f;
    f.kind_ = Kind::Tent;
    f.radius_ = radius;
    f.tabulate();
    return f;
}

PixelFilter PixelFilter::gaussian(float stddev) {
    if (!(stddev > 0.f && std::isfinite(stddev)))
        throw std::invalid_argument("the gaussian filter's stddev must be positive and finite");
    PixelFilter f;
    f.kind_ = Kind::Gaussian;
    f.stddev_ = stddev;
    f.radius_ = 4.f * stddev;  // Mitsuba 3 cuts it off at four standard deviations
    f.tabulate();
    return f;
}

std::string PixelFilter::name() const {
    switch (kind_) {
        case Kind::Box:
            return "box";
        case Kind::Tent:
            return "tent";
        case Kind::Gaussian:
            return "gaussian";
    }
    return "box";
}

float PixelFilter::eval(float x) const {
    switch (kind_) {
        case Kind::Box:
            return std::abs(x) <= 0.5f ? 1.f : 0.f;
        case Kind::Tent:
            return std::max(0.f, 1.f - std::abs(x) / radius_);
        case Kind::Gaussian: {
            // Shifted down by its value at the radius so that it reaches zero there.
            const double alpha = -1.0 / (2.0 * static_cast<double>(stddev_) * stddev_);
            const double r = radius_;
            const double v = std::exp(alpha * x * x) - std::exp(alpha * r * r);
            return static_cast<float>(std::max(v, 0.0));
        }
    }
    return 0.f;
}

void PixelFilter::tabulate() {
    auto weights = std::make_shared<std::vector<float>>(kWeightBins + 1, 0.f);
    for (int i = 0; i <= kWeightBins; ++i)
        (*weights)[static_cast<std::size_t>(i)] =
            eval(static_cast<float>(static_cast<double>(radius_) * i / kWeightBins));
    weights_ = weights;
    table_scale_ = static_cast<float>(kWeightBins) / radius_;

    auto cdf = std::make_shared<std::vector<double>>(kBins + 1, 0.0);
    const double h = 2.0 * radius_ / kBins;
    for (int i = 0; i < kBins; ++i) {
        const double a = -radius_ + i * h;
        // Simpson's rule on 8 sub-intervals of the bin.
        constexpr int kSub = 8;
        const double step = h / kSub;
        double sum = 0.0;
        for (int k = 0; k <= kSub; ++k) {
            const double weight = (k == 0 || k == kSub) ? 1.0 : (k % 2 == 1 ? 4.0 : 2.0);
            sum += weight * eval(static_cast<float>(a + k * step));
        }
        (*cdf)[static_cast<std::size_t>(i) + 1] =
            (*cdf)[static_cast<std::size_t>(i)] + sum * step / 3.0;
    }
    cdf_ = std::move(cdf);
}

double PixelFilter::cdf_at(float x) const {
    const double clamped = std::clamp(static_cast<double>(x), -static_cast<double>(radius_),
                                      static_cast<double>(radius_));
    if (is_box()) return clamped + 0.5;
    const std::vector<double>& cdf = *cdf_;
    const double t = (clamped + radius_) / (2.0 * radius_) * kBins;
    const int i = std::clamp(static_cast<int>(t), 0, kBins - 1);
    const double f = t - i;
    return (1.0 - f) * cdf[static_cast<std::size_t>(i)] + f * cdf[static_cast<std::size_t>(i) + 1];
}

std::vector<double> PixelFilter::pixel_kernel() const {
    const int n = static_cast<int>(std::ceil(radius_ - 0.5f));
    std::vector<double> kernel(static_cast<std::size_t>(2 * n + 1));
    for (int dx = -n; dx <= n; ++dx)
        kernel[static_cast<std::size_t>(dx + n)] =
            integral(static_cast<float>(dx) - 0.5f, static_cast<float>(dx) + 0.5f);
    return kernel;
}

double PixelFilter::integral(float lo, float hi) const {
    return std::max(cdf_at(hi) - cdf_at(lo), 0.0);
}

float PixelFilter::sample(float u, float lo, float hi) const {
    lo = std::max(lo, -radius_);
    hi = std::min(hi, radius_);
    const double c_lo = cdf_at(lo), c_hi = cdf_at(hi);
    const double target = c_lo + static_cast<double>(u) * (c_hi - c_lo);
    double x = 0.0;
    if (is_box()) {
        x = target - 0.5;
    } else {
        const std::vector<double>& cdf = *cdf_;
        // The bin whose CDF interval holds the target; uniform inside it.
        const auto upper = std::upper_bound(cdf.begin() + 1, cdf.end() - 1, target);
        const auto i = static_cast<std::size_t>(upper - cdf.begin()) - 1;
        const double mass = cdf[i + 1] - cdf[i];
        const double f = mass > 0.0 ? (target - cdf[i]) / mass : 0.5;
        x = -radius_ + (static_cast<double>(i) + f) * (2.0 * radius_ / kBins);
    }
    return std::clamp(static_cast<float>(x), lo, hi);
}

Image filter_image(const Image& image, const PixelFilter& filter) {
    if (filter.is_box()) return image;
    const std::vector<double> kernel = filter.pixel_kernel();
    const int n = static_cast<int>(kernel.size() / 2);
    const int w = image.width, h = image.height, channels = image.channels;
    // One pass per axis; `along_x` picks the neighbour's index.
    const auto pass = [&](const Image& in, bool along_x) {
        Image out(w, h, channels);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const int at = along_x ? x : y, size = along_x ? w : h;
                double norm = 0.0;
                for (int d = std::max(-n, -at); d <= std::min(n, size - 1 - at); ++d)
                    norm += kernel[static_cast<std::size_t>(d + n)];
                for (int c = 0; c < channels; ++c) {
                    double sum = 0.0;
                    for (int d = std::max(-n, -at); d <= std::min(n, size - 1 - at); ++d)
                        sum += kernel[static_cast<std::size_t>(d + n)] *
                               (along_x ? in(x + d, y, c) : in(x, y + d, c));
                    out(x, y, c) = static_cast<float>(norm > 0.0 ? sum / norm : 0.0);
                }
            }
        return out;
    };
    return pass(pass(image, true), false);
}

}  // namespace gdmlt
