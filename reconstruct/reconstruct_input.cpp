// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/reconstruct_input.h"

#include <limits>
#include <stdexcept>

namespace gdmlt::reconstruct {
namespace {

bool same_size(const Image& a, const Image& b) {
    return a.width == b.width && a.height == b.height;
}

/// Mean over channels of a 1- or 3-channel variance image, as 1 channel.
Image channel_mean(const Image& v) {
    Image out(v.width, v.height, 1);
    for (std::size_t i = 0; i < v.pixel_count(); ++i) {
        double s = 0.0;
        for (int k = 0; k < v.channels; ++k)
            s += v.pixels[i * static_cast<std::size_t>(v.channels) + static_cast<std::size_t>(k)];
        out.pixels[i] = static_cast<float>(s / v.channels);
    }
    return out;
}

}  // namespace

ReconstructInput make_reconstruct_input(const GradientBuffers& buffers) {
    const Image& p = buffers.primal;
    if (p.pixels.empty() || p.channels != 3)
        throw std::invalid_argument("GradientBuffers: the primal must be a non-empty RGB image");
    for (const Image* layer : {&buffers.dx, &buffers.dy})
        if (!layer->pixels.empty() && (!same_size(*layer, p) || layer->channels != 3))
            throw std::invalid_argument("GradientBuffers: dx/dy must be RGB, primal's size");
    for (const Image* layer : {&buffers.primal_variance, &buffers.dx_variance, &buffers.dy_variance,
                               &buffers.sample_count})
        if (!layer->pixels.empty() && !same_size(*layer, p))
            throw std::invalid_argument("GradientBuffers: variance/count layers: primal's size");
    if (buffers.extra_differences.size() != 3 * buffers.extra_edges.size())
        throw std::invalid_argument("GradientBuffers: 3 extra differences per extra edge");
    if (!buffers.extra_variances.empty() &&
        buffers.extra_variances.size() != buffers.extra_edges.size())
        throw std::invalid_argument("GradientBuffers: one extra variance per extra edge");

    ReconstructInput in;
    in.primal = p;
    PixelGraph& g = in.graph;
    g.width = p.width;
    g.height = p.height;
    const int w = p.width, h = p.height;
    // Edge variances are kept only when every edge has one (dx, dy, extra as present).
    const bool lattice_var = (buffers.dx.pixels.empty() || !buffers.dx_variance.pixels.empty()) &&
                             (buffers.dy.pixels.empty() || !buffers.dy_variance.pixels.empty());
    const bool extra_var = buffers.extra_edges.empty() || !buffers.extra_variances.empty();
    const bool with_var =
        lattice_var && extra_var &&
        !(buffers.dx.pixels.empty() && buffers.dy.pixels.empty() && buffers.extra_edges.empty());
    const Image dxv = with_var && !buffers.dx_variance.pixels.empty()
                          ? channel_mean(buffers.dx_variance)
                          : Image();
    const Image dyv = with_var && !buffers.dy_variance.pixels.empty()
                          ? channel_mean(buffers.dy_variance)
                          : Image();
    if (!buffers.dx.pixels.empty())
        for (int y = 0; y < h; ++y)
            for (int x = 0; x + 1 < w; ++x) {
                const Image& d = buffers.dx;
                g.add_edge(y * w + x, y * w + x + 1, d(x, y, 0), d(x, y, 1), d(x, y, 2));
                if (with_var) g.variance.push_back(dxv(x, y));
            }
    if (!buffers.dy.pixels.empty())
        for (int y = 0; y + 1 < h; ++y)
            for (int x = 0; x < w; ++x) {
                const Image& d = buffers.dy;
                g.add_edge(y * w + x, (y + 1) * w + x, d(x, y, 0), d(x, y, 1), d(x, y, 2));
                if (with_var) g.variance.push_back(dyv(x, y));
            }
    for (std::size_t e = 0; e < buffers.extra_edges.size(); ++e) {
        const float* d = &buffers.extra_differences[3 * e];
        g.add_edge(buffers.extra_edges[e].from, buffers.extra_edges[e].to, d[0], d[1], d[2]);
        if (with_var) g.variance.push_back(buffers.extra_variances[e]);
    }

    if (!buffers.primal_variance.pixels.empty()) {
        in.primal_variance = channel_mean(buffers.primal_variance);
    } else if (!buffers.sample_count.pixels.empty()) {
        // Var of a mean of n samples is sigma^2 / n; with sigma unknown, 1/n keeps the ratios
        // between pixels, which is all the inverse-variance weights use.
        in.primal_variance = Image(w, h, 1);
        const Image& count = buffers.sample_count;
        for (std::size_t i = 0; i < count.pixel_count(); ++i) {
            const float n = count.pixels[i * static_cast<std::size_t>(count.channels)];
            in.primal_variance.pixels[i] =
                n > 0.f ? 1.f / n : std::numeric_limits<float>::infinity();
        }
    }
    return in;
}

}  // namespace gdmlt::reconstruct
