// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/render_bdpt.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "core/math/stopwatch.h"
#include "core/render/film_buffer.h"
#include "core/render/pixel_passes.h"

namespace gdmlt {
namespace {

struct TileSplat {
    std::uint32_t pixel = 0;
    Rgb value = Rgb::Zero();
};

}  // namespace

RenderOutput render_bdpt(const Scene& scene, const BdptRenderSettings& settings,
                         const std::atomic<bool>* cancel,
                         const std::function<void(const RenderProgress&)>& progress) {
    const Clock::time_point start = Clock::now();
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    const bool timed = settings.time_budget_s > 0.0;
    const int tiles_x = (width + kPixelPassTileSize - 1) / kPixelPassTileSize;
    const int tiles_y = (height + kPixelPassTileSize - 1) / kPixelPassTileSize;

    FilmBuffer camera_buffer(width, height);
    std::vector<RgbD> light_sums(static_cast<std::size_t>(width) * height, RgbD::Zero());
    // Each tile is sampled by one task at a time (run_pixel_passes), so its list needs no lock.
    std::vector<std::vector<TileSplat>> tile_splats(static_cast<std::size_t>(tiles_x) * tiles_y);
    tbb::enumerable_thread_specific<PathCounters> counters;
    tbb::enumerable_thread_specific<std::uint64_t> dropped(0);
    tbb::enumerable_thread_specific<BdptScratch> scratch;
    tbb::enumerable_thread_specific<BdptSample> samples;
    std::atomic<std::uint64_t> samples_done{0};

    const auto merge_splats = [&] {
        for (std::vector<TileSplat>& list : tile_splats) {
            for (const TileSplat& s : list) light_sums[s.pixel] += s.value.cast<double>();
            list.clear();
        }
    };

    const PixelPassSettings passes = pixel_pass_settings(settings, 16);
    const PixelPassResult done = run_pixel_passes(
        film, passes, cancel,
        [&](int x, int y, const Vec2f& film_position, IndependentStream& stream) {
            BdptSample& sample = samples.local();
            // One stream for both subpaths: the camera's walk, then the light's, then the
            // next-event numbers, a fixed order per (seed, pixel, sample).
            sample_bdpt(scene, film_position, stream, stream, settings.bdpt, scratch.local(),
                        sample, counters.local());
            dropped.local() += static_cast<std::uint64_t>(sample.nonfinite);
            camera_buffer.add(x, y, sample.pixel);
            std::vector<TileSplat>& list = tile_splats[static_cast<std::size_t>(
                (y / kPixelPassTileSize) * tiles_x + x / kPixelPassTileSize)];
            for (const BdptSample::Splat& s : sample.splats)
                for_each_filtered_pixel(film, s.film_position,
                                        [&](std::uint32_t pixel, float weight) {
                                            list.push_back({pixel, s.value * weight});
                                        });
        },
        [&](int spp_completed) {
            merge_splats();
            if (progress)
                progress({timed ? std::min(1.0, seconds_since(start) / settings.time_budget_s)
                                : static_cast<double>(spp_completed) / std::max(settings.spp, 1),
                          samples_done.load(), seconds_since(start)});
        },
        &samples_done);
    merge_splats();  // an interrupted pass's splats: their light paths are counted below

    // Camera strategies: each pixel's mean over its samples. Light tracing: every light path
    // estimates every pixel, so the sum of the splats over M light paths, over M.
    RenderOutput out;
    out.image = camera_buffer.mean();
    const std::uint64_t light_paths = camera_buffer.total_count();
    if (light_paths > 0)
        for (std::size_t i = 0; i < light_sums.size(); ++i)
            for (int c = 0; c < 3; ++c)
                out.image.pixels[3 * i + static_cast<std::size_t>(c)] +=
                    static_cast<float>(light_sums[i][c] / static_cast<double>(light_paths));
    RenderStats& stats = out.stats;
    for (const PathCounters& c : counters) stats.counters += c;
    for (std::uint64_t d : dropped) stats.nonfinite_samples_dropped += d;
    stats.samples = light_paths;
    stats.passes = done.passes;
    stats.spp_completed = done.spp_completed;
    stats.render_s = seconds_since(start);
    stats.interrupted = done.interrupted;
    return out;
}

}  // namespace gdmlt
