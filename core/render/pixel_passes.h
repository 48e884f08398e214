// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The per-pixel sampling loop every pixel-based integrator shares (path tracing, GDPT): passes
// of samples per pixel over 16x16 tiles on all cores, one PCG stream per (seed, pixel, sample
// index), a time budget, and Ctrl-C polled per pixel. Because a sample's random numbers depend
// only on (seed, pixel, index) and each pixel is owned by one tile, results are bit-identical
// whatever the thread count, tiling or pass split.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>

#include "core/camera/camera.h"
#include "core/math/stopwatch.h"
#include "core/sampling/sample_stream.h"

namespace gdmlt {

/// Pixels are sampled in square tiles of this size, each tile by one task at a time; tile
/// index (y / size) * tiles_x + x / size, row-major over the crop window.
inline constexpr int kPixelPassTileSize = 16;

struct PixelPassSettings {
    int spp = 16;                // budget (upper bound with a time budget)
    double time_budget_s = 0.0;  // 0: none
    std::uint64_t seed = 0;
    int max_pass_spp = 64;  // with a time budget: the largest pass (without: passes of ~1 s)
};

/// The passes of an integrator whose settings have spp, time_budget_s and seed.
template <typename Settings>
PixelPassSettings pixel_pass_settings(const Settings& settings, int max_pass_spp) {
    PixelPassSettings passes;
    passes.spp = settings.spp;
    passes.time_budget_s = settings.time_budget_s;
    passes.seed = settings.seed;
    passes.max_pass_spp = max_pass_spp;
    return passes;
}

struct PixelPassResult {
    int spp_completed = 0;  // samples every pixel received
    int passes = 0;
    bool interrupted = false;
};

/// Calls `sample(x, y, film_position, stream)` for every crop-window pixel (x, y) and sample
/// index, in passes; `on_pass_done(spp_completed)` after each pass, `samples_done` (optional)
/// counts samples as tiles finish. `sample` must only write state owned by pixel (x, y).
template <typename SampleFn, typename PassFn>
PixelPassResult run_pixel_passes(const Film& film, const PixelPassSettings& settings,
                                 const std::atomic<bool>* cancel, SampleFn&& sample,
                                 PassFn&& on_pass_done,
                                 std::atomic<std::uint64_t>* samples_done = nullptr) {
    constexpr int kTileSize = kPixelPassTileSize;
    const auto cancelled = [&] { return cancel && cancel->load(std::memory_order_relaxed); };
    const int width = film.crop_width, height = film.crop_height;
    const int tiles_x = (width + kTileSize - 1) / kTileSize;
    const int tile_count = tiles_x * ((height + kTileSize - 1) / kTileSize);
    const int budget = std::max(settings.spp, 1);
    const bool timed = settings.time_budget_s > 0.0;
    const Clock::time_point start = Clock::now();

    PixelPassResult result;
    double seconds_per_spp = 0.0;
    while (result.spp_completed < budget && !cancelled()) {
        // Passes of about a second each, sized by the speed the previous pass measured (the
        // first is 1 spp): Ctrl-C, SIGTERM and the time budget act within about a second, and
        // an interrupted render still has every pixel sampled (one pass per budget used to
        // give each pixel all its samples at once: a partial image after a few seconds held
        // 0.05-0.5% of its pixels). The split does not change the result (header comment).
        int pass = budget - result.spp_completed;
        double pass_seconds = 1.0;
        if (timed) {
            const double remaining = settings.time_budget_s - seconds_since(start);
            if (remaining <= 0.0) break;
            pass_seconds = std::min(remaining, 1.0);
            // With a time budget also at most max_pass_spp, so that a change of machine load
            // between the speed measurement and the pass overshoots the budget by little
            // (equal-time comparisons depend on it).
            pass = std::min(settings.max_pass_spp, pass);
        }
        const double fit = seconds_per_spp > 0.0 ? pass_seconds / seconds_per_spp : 1.0;
        pass = static_cast<int>(std::clamp(fit, 1.0, static_cast<double>(pass)));
        const int first = result.spp_completed;
        const Clock::time_point pass_start = Clock::now();
        tbb::parallel_for(
            tbb::blocked_range<int>(0, tile_count), [&](const tbb::blocked_range<int>& r) {
                for (int tile = r.begin(); tile != r.end(); ++tile) {
                    const int x0 = (tile % tiles_x) * kTileSize, y0 = (tile / tiles_x) * kTileSize;
                    const int x1 = std::min(x0 + kTileSize, width),
                              y1 = std::min(y0 + kTileSize, height);
                    for (int y = y0; y < y1; ++y)
                        for (int x = x0; x < x1; ++x) {
                            // Per pixel, not per tile: a tile of a high-spp pass can take minutes.
                            if (cancelled()) return;
                            const int film_x = x + film.crop_offset_x,
                                      film_y = y + film.crop_offset_y;
                            const auto pixel =
                                static_cast<std::uint64_t>(film_y) * film.width + film_x;
                            for (int s = first; s < first + pass; ++s) {
                                IndependentStream stream(derive_stream(
                                    settings.seed, pixel, static_cast<std::uint64_t>(s)));
                                const Vec2f jitter = stream.next_2d();
                                sample(x, y,
                                       Vec2f(static_cast<float>(film_x) + jitter.x(),
                                             static_cast<float>(film_y) + jitter.y()),
                                       stream);
                            }
                        }
                    if (samples_done)
                        samples_done->fetch_add(
                            static_cast<std::uint64_t>((x1 - x0) * (y1 - y0)) * pass,
                            std::memory_order_relaxed);
                }
            });
        if (cancelled()) break;
        result.spp_completed += pass;
        ++result.passes;
        seconds_per_spp = seconds_since(pass_start) / pass;
        on_pass_done(result.spp_completed);
    }
    result.interrupted = cancelled();
    return result;
}

}  // namespace gdmlt
