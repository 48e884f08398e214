// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/render_ptracer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "core/math/stopwatch.h"
#include "core/path/bidirectional.h"
#include "core/render/pixel_passes.h"
#include "core/sampling/rng.h"
#include "core/sampling/sample_stream.h"

namespace gdmlt {
namespace {

/// Light paths per work item: each item collects its splats in order and the items are merged
/// in index order, so the sums do not depend on which thread ran what.
constexpr std::uint64_t kPathsPerChunk = 4096;
/// About 3 splats of 16 bytes per light path: 2^20 paths keep a batch's lists near 50 MB.
constexpr std::uint64_t kPathsPerBatch = std::uint64_t{1} << 20;
/// Stream tags: light paths and the camera rays that see the environment directly.
constexpr std::uint64_t kLightPathStream = 0x1197A0;
constexpr std::uint64_t kEnvironmentStream = 0xE7B1;

struct Splat {
    std::uint32_t pixel = 0;
    Rgb value = Rgb::Zero();
};

struct ChunkResult {
    std::vector<Splat> splats;
    PathCounters counters;
    std::uint64_t nonfinite = 0;
};

/// Light tracing is BDPT's strategy t = 1 alone, unweighted (or with BDPT's MIS weight,
/// PtracerWeights): the light subpath and the connection to the pinhole are BDPT's
/// (core/path/bidirectional.h), so the two integrators cannot disagree about a light path's
/// value.
class LightTracer {
  public:
    LightTracer(const Scene& scene, const PathSamplerSettings& path, const PtracerWeights& weights)
        : scene_(scene), path_(path), weights_(weights) {}

    /// Traces light path `index` and appends its splats (unnormalised: sum over paths, then
    /// divide by their number).
    void trace(std::uint64_t seed, std::uint64_t index, BdptScratch& scratch,
               ChunkResult& out) const {
        IndependentStream stream(derive_stream(seed, kLightPathStream, index));
        // Light subpath vertex s - 1 seen by the pinhole makes a path of s segments.
        const int max_vertices = path_.max_depth >= 0 ? path_.max_depth : kBdptUnboundedVertices;
        sample_light_subpath(scene_, stream, max_vertices, path_.rr_depth, scratch.light,
                             out.counters);
        ++out.counters.paths;
        static const std::vector<BdptVertex> kNoCameraSubpath;
        BdptConnectionInput in;
        // One lens point per light path (thin lens; unbiased, as each is uniform on the lens).
        in.u_lens = draw_lens_sample(scene_.camera(), stream);
        in.camera = &kNoCameraSubpath;
        in.light = &scratch.light;
        in.t = 1;
        in.mis = weights_.bdpt_mis;
        in.light_tracing_scale = weights_.light_tracing_scale;
        for (int s = 1; s <= static_cast<int>(scratch.light.size()); ++s) {
            // s = 1: the emitter's point itself (area lights; point and spot lights are
            // invisible to a camera, as in the path tracer and Mitsuba).
            if (s < path_.min_depth || (s == 1 && path_.hide_emitters)) continue;
            in.s = s;
            const BdptConnection c = connect_bdpt(scene_, in, scratch, out.counters);
            if (!is_finite(c.contribution)) {
                ++out.nonfinite;
                continue;
            }
            if (is_black(c.contribution)) continue;
            const Rgb value = weights_.bdpt_mis ? Rgb(c.contribution * c.weight) : c.contribution;
            if (is_black(value)) continue;
            for_each_filtered_pixel(scene_.camera().film(), c.film_position,
                                    [&](std::uint32_t pixel, float weight) {
                                        out.splats.push_back({pixel, value * weight});
                                    });
        }
    }

  private:
    const Scene& scene_;
    PathSamplerSettings path_;
    PtracerWeights weights_;
};

}  // namespace

RenderOutput render_ptracer(const Scene& scene, const RenderSettings& settings,
                            const std::atomic<bool>* cancel,
                            const std::function<void(const RenderProgress&)>& progress,
                            const PtracerWeights& weights) {
    const Clock::time_point start = Clock::now();
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    const auto pixels = static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(height);
    const auto cancelled = [&] { return cancel && cancel->load(std::memory_order_relaxed); };
    const bool timed = settings.time_budget_s > 0.0;
    const int budget = std::max(settings.spp, 1);
    const bool environment_visible =
        scene.has_environment() && !settings.path.hide_emitters && settings.path.min_depth <= 1;

    std::vector<RgbD> light_sums(pixels, RgbD::Zero());
    std::vector<RgbD> environment_sums(environment_visible ? pixels : 0, RgbD::Zero());
    const LightTracer tracer(scene, settings.path, weights);
    RenderOutput out;
    RenderStats& stats = out.stats;

    double seconds_per_spp = 0.0;
    int spp_done = 0;              // passes' light paths per pixel (and environment rays)
    std::uint64_t paths_done = 0;  // light paths merged into light_sums
    while (spp_done < budget && !cancelled()) {
        // Passes of about a second (sized by the last one's speed), as run_pixel_passes: the
        // time budget and Ctrl-C act within a second on a whole image.
        double pass_seconds = 1.0;
        if (timed) {
            const double remaining = settings.time_budget_s - seconds_since(start);
            if (remaining <= 0.0) break;
            pass_seconds = std::min(remaining, 1.0);
        }
        const double fit = seconds_per_spp > 0.0 ? pass_seconds / seconds_per_spp : 1.0;
        const int pass =
            static_cast<int>(std::clamp(fit, 1.0, static_cast<double>(budget - spp_done)));
        const Clock::time_point pass_start = Clock::now();
        // The pass in batches of at most kPathsPerBatch light paths, merged after each: the
        // splat lists stay under ~50 MB whatever the image size, and Ctrl-C keeps every batch
        // already merged. Splats are summed in light-path order (chunks in index order, each
        // in its own order), so neither threads nor pass and batch sizes change the sums.
        const std::uint64_t pass_end = paths_done + static_cast<std::uint64_t>(pass) * pixels;
        while (paths_done < pass_end && !cancelled()) {
            const std::uint64_t batch = std::min(pass_end - paths_done, kPathsPerBatch);
            const std::uint64_t chunk_count = (batch + kPathsPerChunk - 1) / kPathsPerChunk;
            std::vector<ChunkResult> chunks(chunk_count);
            tbb::parallel_for(std::uint64_t{0}, chunk_count, [&](std::uint64_t chunk) {
                ChunkResult& result = chunks[chunk];
                BdptScratch scratch;
                const std::uint64_t begin = chunk * kPathsPerChunk;
                const std::uint64_t end = std::min(begin + kPathsPerChunk, batch);
                for (std::uint64_t i = begin; i < end; ++i) {
                    if ((i & 255u) == 0 && cancelled()) return;
                    tracer.trace(settings.seed, paths_done + i, scratch, result);
                }
            });
            if (cancelled()) break;  // a batch is all or nothing: its paths are counted
            for (const ChunkResult& c : chunks) {
                for (const Splat& s : c.splats) light_sums[s.pixel] += s.value.cast<double>();
                stats.counters += c.counters;
                stats.nonfinite_samples_dropped += c.nonfinite;
            }
            paths_done += batch;
        }
        if (cancelled()) break;
        if (environment_visible) {
            // Directly visible environment: one jittered camera ray per pixel and light path
            // per pixel (a light path cannot reach a pinhole from infinity).
            tbb::parallel_for(std::uint64_t{0}, pixels, [&](std::uint64_t pixel) {
                const int x = static_cast<int>(pixel % static_cast<std::uint64_t>(width)) +
                              film.crop_offset_x;
                const int y = static_cast<int>(pixel / static_cast<std::uint64_t>(width)) +
                              film.crop_offset_y;
                for (int s = spp_done; s < spp_done + pass; ++s) {
                    IndependentStream stream(derive_stream(settings.seed ^ kEnvironmentStream,
                                                           pixel, static_cast<std::uint64_t>(s)));
                    const Vec2f jitter = stream.next_2d();
                    const Ray ray = scene.camera().generate_ray(
                        jittered_film_position(film, x - film.crop_offset_x, y - film.crop_offset_y,
                                               jitter.x(), jitter.y()),
                        draw_lens_sample(scene.camera(), stream));
                    if (!scene.intersect(ray).valid())
                        environment_sums[pixel] += scene.environment(ray.direction).cast<double>();
                }
            });
            stats.counters.camera_rays += static_cast<std::uint64_t>(pass) * pixels;
        }
        spp_done += pass;
        ++stats.passes;
        seconds_per_spp = seconds_since(pass_start) / pass;
        if (progress)
            progress({timed ? std::min(1.0, seconds_since(start) / settings.time_budget_s)
                            : static_cast<double>(spp_done) / budget,
                      static_cast<std::uint64_t>(spp_done) * pixels, seconds_since(start)});
    }

    // Pixel j = (1 / M) sum over the M light paths of their splats to j (each path estimates
    // every pixel's integral of W_j L), plus the camera rays' mean environment radiance.
    out.image = Image(width, height, 3);
    if (paths_done > 0) {
        const auto paths = static_cast<double>(paths_done);
        for (std::uint64_t i = 0; i < pixels; ++i) {
            RgbD v = light_sums[i] / paths;
            if (environment_visible && spp_done > 0) v += environment_sums[i] / spp_done;
            for (int c = 0; c < 3; ++c)
                out.image.pixels[3 * i + static_cast<std::size_t>(c)] = static_cast<float>(v[c]);
        }
    }
    stats.samples = paths_done;
    stats.spp_completed = spp_done;
    stats.render_s = seconds_since(start);
    stats.interrupted = cancelled();
    return out;
}

}  // namespace gdmlt
