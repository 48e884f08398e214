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
#include <functional>
#include <utility>

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
    bool limit_every_pass = false;  // max_pass_spp also without a time budget
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

/// One tile's share of a pass: crop-window pixels [x0, x1) x [y0, y1), each with the sample
/// indices [first_sample, first_sample + sample_count).
struct PixelTile {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    int first_sample = 0, sample_count = 0;
};

/// The random stream of sample `index` of crop-window pixel (x, y), and its film position
/// (the pixel's corner plus a jitter drawn first from the stream).
struct PixelSample {
    IndependentStream stream;
    Vec2f film_position;
};
/// The first identifier of pixel_sample's streams for crop-window pixel (x, y): the pixel's
/// row-major index in the full film (the second is the sample's index).
inline std::uint64_t pixel_stream_id(const Film& film, int x, int y) {
    return static_cast<std::uint64_t>(y + film.crop_offset_y) * film.width +
           static_cast<std::uint64_t>(x + film.crop_offset_x);
}
/// Full-film position of a sample of crop-window pixel (x, y), uniform in the pixel: its
/// corner plus `jitter` in [0, 1)^2.
inline Vec2f uniform_film_position(const Film& film, int x, int y, float jitter_x, float jitter_y) {
    return {static_cast<float>(x + film.crop_offset_x) + jitter_x,
            static_cast<float>(y + film.crop_offset_y) + jitter_y};
}
/// Full-film position of a sample of crop-window pixel (x, y) from `jitter` in [0, 1)^2: with
/// the box filter the pixel's corner plus the jitter; with another filter, drawn from the
/// pixel's filter h_p (core/camera/pixel_filter.h), each axis by inverting its distribution.
inline Vec2f jittered_film_position(const Film& film, int x, int y, float jitter_x,
                                    float jitter_y) {
    if (film.filter.is_box()) return uniform_film_position(film, x, y, jitter_x, jitter_y);
    const float cx = static_cast<float>(x) + 0.5f, cy = static_cast<float>(y) + 0.5f;
    const float dx = film.filter.sample(jitter_x, -cx, static_cast<float>(film.crop_width) - cx);
    const float dy = film.filter.sample(jitter_y, -cy, static_cast<float>(film.crop_height) - cy);
    return {static_cast<float>(film.crop_offset_x) + cx + dx,
            static_cast<float>(film.crop_offset_y) + cy + dy};
}
inline PixelSample pixel_sample(const Film& film, std::uint64_t seed, int x, int y, int index) {
    PixelSample s{IndependentStream(derive_stream(seed, pixel_stream_id(film, x, y),
                                                  static_cast<std::uint64_t>(index))),
                  Vec2f::Zero()};
    const Vec2f jitter = s.stream.next_2d();
    s.film_position = jittered_film_position(film, x, y, jitter.x(), jitter.y());
    return s;
}

/// Runs the passes: calls `sample_tile(tile)` for every tile of every pass, on all cores;
/// `sample_tile` returns false if it stopped early because `cancel` was set, and must only
/// write state owned by the tile's pixels, drawing sample s of pixel (x, y) from
/// pixel_sample(film, settings.seed, x, y, s). `on_pass_start(first_sample, sample_count)`
/// (optional) before each pass, `on_pass_done(spp_completed)` after each complete one;
/// `samples_done` (optional) counts samples as tiles finish.
template <typename TileFn, typename PassFn>
PixelPassResult run_tile_passes(const Film& film, const PixelPassSettings& settings,
                                const std::atomic<bool>* cancel, TileFn&& sample_tile,
                                PassFn&& on_pass_done,
                                std::atomic<std::uint64_t>* samples_done = nullptr,
                                const std::function<void(int, int)>& on_pass_start = {}) {
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
        if (settings.limit_every_pass) pass = std::min(settings.max_pass_spp, pass);
        const double fit = seconds_per_spp > 0.0 ? pass_seconds / seconds_per_spp : 1.0;
        pass = static_cast<int>(std::clamp(fit, 1.0, static_cast<double>(pass)));
        const int first = result.spp_completed;
        if (on_pass_start) on_pass_start(first, pass);
        const Clock::time_point pass_start = Clock::now();
        tbb::parallel_for(
            tbb::blocked_range<int>(0, tile_count), [&](const tbb::blocked_range<int>& r) {
                for (int tile_index = r.begin(); tile_index != r.end(); ++tile_index) {
                    PixelTile tile;
                    tile.x0 = (tile_index % tiles_x) * kTileSize;
                    tile.y0 = (tile_index / tiles_x) * kTileSize;
                    tile.x1 = std::min(tile.x0 + kTileSize, width);
                    tile.y1 = std::min(tile.y0 + kTileSize, height);
                    tile.first_sample = first;
                    tile.sample_count = pass;
                    if (!sample_tile(std::as_const(tile))) return;
                    if (samples_done)
                        samples_done->fetch_add(
                            static_cast<std::uint64_t>((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) *
                                pass,
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

/// Calls `sample(x, y, film_position, stream)` for every crop-window pixel (x, y) and sample
/// index, in passes (run_tile_passes); `sample` must only write state owned by pixel (x, y).
template <typename SampleFn, typename PassFn>
PixelPassResult run_pixel_passes(const Film& film, const PixelPassSettings& settings,
                                 const std::atomic<bool>* cancel, SampleFn&& sample,
                                 PassFn&& on_pass_done,
                                 std::atomic<std::uint64_t>* samples_done = nullptr) {
    const auto cancelled = [&] { return cancel && cancel->load(std::memory_order_relaxed); };
    return run_tile_passes(
        film, settings, cancel,
        [&](const PixelTile& tile) {
            for (int y = tile.y0; y < tile.y1; ++y)
                for (int x = tile.x0; x < tile.x1; ++x) {
                    // Per pixel, not per tile: a tile of a high-spp pass can take minutes.
                    if (cancelled()) return false;
                    for (int s = tile.first_sample; s < tile.first_sample + tile.sample_count;
                         ++s) {
                        PixelSample ps = pixel_sample(film, settings.seed, x, y, s);
                        sample(x, y, ps.film_position, ps.stream);
                    }
                }
            return true;
        },
        std::forward<PassFn>(on_pass_done), samples_done);
}

}  // namespace gdmlt
