// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/gdpt.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <stdexcept>

#include "core/math/stopwatch.h"
#include "core/render/pixel_passes.h"

namespace gdmlt::mlt {
namespace {

/// Per-pixel sums of the samples based in this pixel. The per-link difference sums live in one
/// flat array indexed like the NeighbourSet's links, so every pixel writes only its own memory
/// and the edges are combined from both ends only at the end.
struct PixelSums {
    RgbD primal = RgbD::Zero();
    RgbD very_direct = RgbD::Zero();
    /// Sum over samples of the primal's squared RGB norm: with `primal` it gives the sample
    /// variance averaged over the channels (variance_of_mean), one FMA per channel and sample.
    double primal_squares = 0.0;
    std::uint32_t samples = 0;
};

/// Variance of the mean of n independent RGB samples, averaged over the three channels, from
/// their per-channel sum and the sum over samples and channels of their squares: the unbiased
/// sample variance s_c^2 = (sum x_c^2 - (sum x_c)^2 / n) / (n - 1) of each channel, divided by n
/// (Var of a mean of n i.i.d. samples is sigma^2 / n). Summing the channels first is exact:
/// the channel mean of s_c^2 only needs sum_c sum x_c^2. In double the cancellation of the
/// two sums costs about log10(mean^2 / variance) of its 16 digits, far below the float that is
/// stored. Fewer than 2 samples say nothing about the spread: +infinity, which reconstruction
/// reads as "no trust" (the same value its 1/sample_count model gives an empty pixel).
double variance_of_mean(const RgbD& sum, double squares, std::uint32_t n) {
    if (n < 2) return std::numeric_limits<double>::infinity();
    const double count = n;
    const double deviations = std::max(squares - sum.square().sum() / count, 0.0);
    return deviations / (3.0 * (count - 1.0) * count);
}

}  // namespace

GdptOutput render_gdpt(const Scene& scene, const GdptSettings& settings,
                       const std::atomic<bool>* cancel,
                       const std::function<void(double, double)>& progress) {
    const Film& film = scene.camera().film();
    return render_gdpt(scene, settings, NeighbourSet::lattice(film.crop_width, film.crop_height),
                       cancel, progress);
}

GdptOutput render_gdpt(const Scene& scene, const GdptSettings& settings,
                       const NeighbourSet& neighbours, const std::atomic<bool>* cancel,
                       const std::function<void(double, double)>& progress) {
    const Clock::time_point start = Clock::now();
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    if (neighbours.width() != width || neighbours.height() != height)
        throw std::invalid_argument("render_gdpt: the neighbour set is not the crop window's size");
    const bool timed = settings.time_budget_s > 0.0;

    std::vector<PixelSums> sums(static_cast<std::size_t>(width) * height);
    std::vector<RgbD> link_sums(neighbours.link_count(), RgbD::Zero());
    std::vector<double> link_squares(neighbours.link_count(), 0.0);
    tbb::enumerable_thread_specific<PathCounters> counters;
    tbb::enumerable_thread_specific<manifold::ShiftCounters> shift_counters;
    tbb::enumerable_thread_specific<std::uint64_t> dropped(0);
    tbb::enumerable_thread_specific<std::vector<LinkEstimate>> scratch(
        std::vector<LinkEstimate>(neighbours.max_links()));

    GdptOutput out;
    const PixelPassSettings passes = pixel_pass_settings(settings, 16);
    const PixelPassResult done = run_pixel_passes(
        film, passes, cancel,
        [&](int x, int y, const Vec2f& film_position, IndependentStream& stream) {
            const std::size_t pixel = static_cast<std::size_t>(y) * width + x;
            PixelSums& sum = sums[pixel];
            const std::span<const NeighbourLink> links = neighbours.links(pixel);
            std::vector<LinkEstimate>& estimates = scratch.local();
            const GradientSample g = sample_gradients(
                scene, film_position, stream, settings.path, settings.shift, links,
                {estimates.data(), links.size()}, counters.local(), shift_counters.local());
            ++sum.samples;
            bool finite = is_finite(g.primal) && is_finite(g.very_direct);
            for (std::size_t k = 0; k < links.size(); ++k)
                finite = finite && is_finite(estimates[k].difference());
            if (!finite) {
                ++dropped.local();
                return;
            }
            // A dropped sample counts as a zero in the means and so also in the variances.
            const RgbD primal = g.primal.cast<double>();
            sum.primal += primal;
            sum.primal_squares += primal.square().sum();
            sum.very_direct += g.very_direct.cast<double>();
            const std::size_t first = neighbours.first_link(pixel);
            for (std::size_t k = 0; k < links.size(); ++k) {
                const RgbD difference = estimates[k].difference().cast<double>();
                link_sums[first + k] += difference;
                link_squares[first + k] += difference.square().sum();
            }
        },
        [&](int spp_completed) {
            if (progress)
                progress(timed ? std::min(1.0, seconds_since(start) / settings.time_budget_s)
                               : static_cast<double>(spp_completed) / std::max(settings.spp, 1),
                         seconds_since(start));
        });

    GradientBuffers& b = out.buffers;
    b.primal = Image(width, height, 3);
    b.very_direct = Image(width, height, 3);
    b.sample_count = Image(width, height, 1);
    // Variances need two samples: a render where no pixel got them (1 spp) leaves the variance
    // layers empty, and reconstruction falls back to its 1/sample_count model rather than
    // trusting no pixel at all.
    std::uint32_t most_samples = 0;
    for (const PixelSums& p : sums) most_samples = std::max(most_samples, p.samples);
    const bool with_variance = most_samples >= 2;
    if (with_variance) b.primal_variance = Image(width, height, 1);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const PixelSums& p = sums[static_cast<std::size_t>(y) * width + x];
            b.sample_count(x, y) = static_cast<float>(p.samples);
            if (with_variance)
                b.primal_variance(x, y) =
                    static_cast<float>(variance_of_mean(p.primal, p.primal_squares, p.samples));
            if (p.samples == 0) continue;
            for (int c = 0; c < 3; ++c) {
                b.primal(x, y, c) = static_cast<float>(p.primal[c] / p.samples);
                b.very_direct(x, y, c) = static_cast<float>(p.very_direct[c] / p.samples);
            }
        }
    // Edge (a, b): I(b) - I(a) from the a->b shifts of pixel a and the b->a shifts of pixel b,
    // each an estimator of its own sign.
    //
    // Its variance: the two means are summed, not averaged. The MIS weights of a pair of paths
    // sum to one over the two shift directions (mlt/gradient_sample.h), so each end's mean
    // estimates only its share of the difference, E_a[D_ab] - E_b[D_ba] = I(b) - I(a). The
    // ends' samples are independent (every sample has its own stream from (seed, pixel,
    // index)), so
    //     Var = Var(D_ab) / n_a + Var(D_ba) / n_b,
    // each term variance_of_mean of that end's link sums (channel mean), with no 1/4 that an
    // average of two full estimates would have. +infinity when an end has fewer than 2 samples.
    std::vector<RgbD> edge_differences(neighbours.edges().size(), RgbD::Zero());
    std::vector<double> edge_variances(with_variance ? neighbours.edges().size() : 0,
                                       std::numeric_limits<double>::infinity());
    for (std::size_t e = 0; e < edge_differences.size(); ++e) {
        const GradientEdge& edge = neighbours.edges()[e];
        const auto [at_from, at_to] = neighbours.edge_links(e);
        const std::uint32_t n_from = sums[static_cast<std::size_t>(edge.from)].samples;
        const std::uint32_t n_to = sums[static_cast<std::size_t>(edge.to)].samples;
        if (with_variance)
            edge_variances[e] =
                variance_of_mean(link_sums[at_from], link_squares[at_from], n_from) +
                variance_of_mean(link_sums[at_to], link_squares[at_to], n_to);
        if (n_from == 0 || n_to == 0) continue;
        edge_differences[e] = link_sums[at_from] / n_from - link_sums[at_to] / n_to;
    }
    store_edge_differences(neighbours, edge_differences, b, edge_variances);

    GdptStats& s = out.stats;
    for (const PathCounters& c : counters) s.counters += c;
    for (const manifold::ShiftCounters& c : shift_counters) s.shifts += c;
    for (std::uint64_t d : dropped) s.nonfinite_dropped += d;
    for (const PixelSums& p : sums) s.samples += p.samples;
    s.spp_completed = done.spp_completed;
    s.render_s = seconds_since(start);
    s.interrupted = done.interrupted;
    return out;
}

}  // namespace gdmlt::mlt
