// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/image/combine_buffers.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace gdmlt {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

}  // namespace

std::vector<double> leave_one_out_window_mean(const Image& variance, int radius) {
    const int w = variance.width, h = variance.height;
    const auto at = [w](int x, int y) { return static_cast<std::size_t>(y) * w + x; };
    // Separable box sums of the finite values and of their count.
    std::vector<double> row_sum(variance.pixels.size(), 0.0), row_count(row_sum.size(), 0.0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double s = 0.0, n = 0.0;
            for (int dx = -radius; dx <= radius; ++dx) {
                const int xx = x + dx;
                if (xx < 0 || xx >= w) continue;
                const double v = variance.pixels[at(xx, y)];
                if (!std::isfinite(v)) continue;
                s += v;
                n += 1.0;
            }
            row_sum[at(x, y)] = s;
            row_count[at(x, y)] = n;
        }
    std::vector<double> mean(row_sum.size(), kInfinity);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double s = 0.0, n = 0.0;
            for (int dy = -radius; dy <= radius; ++dy) {
                const int yy = y + dy;
                if (yy < 0 || yy >= h) continue;
                s += row_sum[at(x, yy)];
                n += row_count[at(x, yy)];
            }
            const double own = variance.pixels[at(x, y)];
            if (std::isfinite(own)) {
                s -= own;
                n -= 1.0;
            }
            if (n > 0.0) mean[at(x, y)] = std::max(s / n, 0.0);
        }
    return mean;
}

namespace {

/// Per pixel the weight of each part (parts x pixels, part-major) from their smoothed
/// variances: w_k proportional to 1 / S_k; equal where every S_k is +inf; shared among the
/// parts with S_k = 0 where some are.
std::vector<double> weights_from(const std::vector<std::vector<double>>& smoothed) {
    const std::size_t parts = smoothed.size(), pixels = smoothed.front().size();
    std::vector<double> weights(parts * pixels, 0.0);
    for (std::size_t i = 0; i < pixels; ++i) {
        std::size_t zeros = 0, finite = 0;
        double total = 0.0;
        for (std::size_t k = 0; k < parts; ++k) {
            const double s = smoothed[k][i];
            zeros += s == 0.0;
            if (std::isfinite(s) && s > 0.0) {
                ++finite;
                total += 1.0 / s;
            }
        }
        for (std::size_t k = 0; k < parts; ++k) {
            const double s = smoothed[k][i];
            double& out = weights[k * pixels + i];
            if (zeros > 0)
                out = s == 0.0 ? 1.0 / static_cast<double>(zeros) : 0.0;
            else if (finite > 0)
                out = std::isfinite(s) ? (1.0 / s) / total : 0.0;
            else
                out = 1.0 / static_cast<double>(parts);
        }
    }
    return weights;
}

/// Combines one layer (RGB values and 1-channel variances) of every part with `weights`.
void combine_layer(std::span<const GradientBuffers* const> parts, Image GradientBuffers::*values,
                   Image GradientBuffers::*variances, const std::vector<double>& weights,
                   GradientBuffers& out) {
    const Image& first = (*parts.front()).*values;
    Image combined(first.width, first.height, 3), combined_variance(first.width, first.height, 1);
    const std::size_t pixels = first.pixel_count();
    for (std::size_t i = 0; i < pixels; ++i) {
        double value[3] = {0.0, 0.0, 0.0}, variance = 0.0;
        for (std::size_t k = 0; k < parts.size(); ++k) {
            const double w = weights[k * pixels + i];
            if (w == 0.0) continue;
            for (int c = 0; c < 3; ++c) value[c] += w * ((*parts[k]).*values).pixels[3 * i + c];
            variance += w * w * ((*parts[k]).*variances).pixels[i];
        }
        for (int c = 0; c < 3; ++c) combined.pixels[3 * i + c] = static_cast<float>(value[c]);
        combined_variance.pixels[i] = static_cast<float>(variance);
    }
    out.*values = std::move(combined);
    out.*variances = std::move(combined_variance);
}

std::vector<double> layer_weights(std::span<const GradientBuffers* const> parts,
                                  Image GradientBuffers::*variances, int radius) {
    std::vector<std::vector<double>> smoothed;
    for (const GradientBuffers* p : parts)
        smoothed.push_back(leave_one_out_window_mean(p->*variances, radius));
    return weights_from(smoothed);
}

double mean_weight(const std::vector<double>& weights, std::size_t part, std::size_t pixels) {
    double sum = 0.0;
    for (std::size_t i = 0; i < pixels; ++i) sum += weights[part * pixels + i];
    return pixels > 0 ? sum / static_cast<double>(pixels) : 0.0;
}

}  // namespace

bool has_variance_layers(const GradientBuffers& b) {
    const auto matches = [&](const Image& values, const Image& variances) {
        return values.pixels.empty() || variances.pixel_count() == values.pixel_count();
    };
    return !b.primal.pixels.empty() && b.primal_variance.pixel_count() == b.primal.pixel_count() &&
           matches(b.dx, b.dx_variance) && matches(b.dy, b.dy_variance) &&
           b.extra_variances.size() == b.extra_edges.size();
}

GradientBuffers combine_by_inverse_variance(std::span<const GradientBuffers* const> parts,
                                            int radius, CombineSummary* summary) {
    if (parts.empty()) throw std::invalid_argument("combine_by_inverse_variance: no parts");
    const GradientBuffers& first = *parts.front();
    const int w = first.primal.width, h = first.primal.height;
    const auto fits = [&](const Image& image, int channels) {
        return image.width == w && image.height == h && image.channels == channels;
    };
    for (const GradientBuffers* p : parts) {
        const bool dx = !first.dx.pixels.empty(), dy = !first.dy.pixels.empty();
        if (!fits(p->primal, 3) || !fits(p->primal_variance, 1) || dx != !p->dx.pixels.empty() ||
            dy != !p->dy.pixels.empty() || (dx && (!fits(p->dx, 3) || !fits(p->dx_variance, 1))) ||
            (dy && (!fits(p->dy, 3) || !fits(p->dy_variance, 1))) ||
            p->extra_edges != first.extra_edges ||
            p->extra_variances.size() != p->extra_edges.size())
            throw std::invalid_argument(
                "combine_by_inverse_variance: parts of different sizes, edges or without "
                "variance layers");
    }
    GradientBuffers out;
    out.very_direct = first.very_direct;
    out.features = first.features;
    const std::size_t pixels = first.primal.pixel_count();
    const std::vector<double> primal_weights =
        layer_weights(parts, &GradientBuffers::primal_variance, radius);
    combine_layer(parts, &GradientBuffers::primal, &GradientBuffers::primal_variance,
                  primal_weights, out);
    std::vector<double> difference_weight_sums(parts.size(), 0.0);
    double lattice_layers = 0.0;
    for (auto [values, variances] :
         {std::pair{&GradientBuffers::dx, &GradientBuffers::dx_variance},
          std::pair{&GradientBuffers::dy, &GradientBuffers::dy_variance}}) {
        if ((first.*values).pixels.empty()) continue;
        const std::vector<double> weights = layer_weights(parts, variances, radius);
        combine_layer(parts, values, variances, weights, out);
        for (std::size_t k = 0; k < parts.size(); ++k)
            difference_weight_sums[k] += mean_weight(weights, k, pixels);
        lattice_layers += 1.0;
    }
    out.extra_edges = first.extra_edges;
    out.extra_differences.assign(first.extra_differences.size(), 0.0f);
    out.extra_variances.assign(first.extra_edges.size(), 0.0f);
    for (std::size_t e = 0; e < first.extra_edges.size(); ++e) {
        const auto from = static_cast<std::size_t>(first.extra_edges[e].from);
        double variance = 0.0;
        for (std::size_t k = 0; k < parts.size(); ++k) {
            const double wk = primal_weights[k * pixels + from];
            if (wk == 0.0) continue;
            for (int c = 0; c < 3; ++c)
                out.extra_differences[3 * e + c] +=
                    static_cast<float>(wk * parts[k]->extra_differences[3 * e + c]);
            variance += wk * wk * parts[k]->extra_variances[e];
        }
        out.extra_variances[e] = static_cast<float>(variance);
    }
    if (summary) {
        summary->primal_weight.clear();
        summary->difference_weight.clear();
        for (std::size_t k = 0; k < parts.size(); ++k) {
            summary->primal_weight.push_back(mean_weight(primal_weights, k, pixels));
            summary->difference_weight.push_back(
                lattice_layers > 0.0 ? difference_weight_sums[k] / lattice_layers : 0.0);
        }
    }
    return out;
}

}  // namespace gdmlt
