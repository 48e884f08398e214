// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/render_ptracer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "core/path/bidirectional.h"
#include "core/sampling/rng.h"
#include "core/sampling/sample_stream.h"

namespace gdmlt {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

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

class LightTracer {
  public:
    LightTracer(const Scene& scene, const PathSamplerSettings& path)
        : scene_(scene), camera_(scene.camera()), path_(path) {}

    /// Traces light path `index` and appends its splats (unnormalised: sum over paths, then
    /// divide by their number).
    void trace(std::uint64_t seed, std::uint64_t index, ChunkResult& out) const {
        IndependentStream stream(derive_stream(seed, kLightPathStream, index));
        const float u_select = stream.next_1d();
        const Vec2f u_position = stream.next_2d();
        const Vec2f u_direction = stream.next_2d();
        const EmittedRay emitted = scene_.sample_emitted_ray(u_select, u_position, u_direction);
        ++out.counters.paths;
        if (!emitted.valid()) return;

        // s = 1, t = 1: the emitter's point seen by the pinhole (one segment), a pixel value
        // Le cos_light / d^2 W / p_A(origin). Lights at infinity have no point to see, and
        // point and spot lights are invisible to a camera (a delta in position cannot be hit
        // by a camera ray; the path tracer and Mitsuba never show them either).
        if (!emitted.at_infinity && !emitted.delta_position && !path_.hide_emitters &&
            path_.min_depth <= 1) {
            // Only area lights remain here; their emission is diffuse (the same radiance
            // in every direction of the front side).
            const CameraConnection c = camera_.connect(emitted.origin);
            const float cos_light = emitted.n_geometric.dot(-c.direction);
            if (c.valid() && cos_light > 0.f)
                connect(emitted.origin, emitted.n_geometric, c,
                        emitted.radiance * (cos_light * c.importance /
                                            (c.distance * c.distance * emitted.pdf_position)),
                        out);
        }

        Rgb beta = emitted.weight;
        Ray ray = emitted.n_geometric.isZero()
                      ? Ray{emitted.origin, emitted.direction, kInfinity}
                      : spawn_ray(emitted.origin, emitted.n_geometric, emitted.direction);
        // `vertices` light-subpath vertices after the emitter: connecting vertex k to the
        // pinhole makes a path of k + 1 segments (Mitsuba's depth).
        for (int vertices = 1;; ++vertices) {
            const SurfaceInteraction si = scene_.intersect(ray);
            ++out.counters.bounce_rays;
            if (!si.valid()) return;
            const Bsdf& bsdf = scene_.bsdf_of(si);
            const Vec3f wo = -ray.direction;
            const Vec3f wo_local = si.shading.to_local(wo);
            const int segments = vertices + 1;
            const bool within_depth = path_.max_depth < 0 || segments <= path_.max_depth;
            if (!within_depth) return;
            if (!bsdf.is_delta() && segments >= path_.min_depth) {
                const CameraConnection c = camera_.connect(si.p);
                const Vec3f to_camera = -c.direction;
                // As the path tracer: the geometric sides must agree with what the shading
                // frame calls reflection or transmission (no light through a smooth-shaded
                // wall).
                const Vec3f wi_local = si.shading.to_local(to_camera);
                const bool sides_agree =
                    (wo_local.z() * wi_local.z() > 0.f) ==
                    (si.n_geometric.dot(wo) * si.n_geometric.dot(to_camera) > 0.f);
                if (c.valid() && sides_agree) {
                    const Rgb f = bsdf.eval(si.uv, wo_local, wi_local, TransportMode::Importance) *
                                  adjoint_shading_correction(si, wo, to_camera);
                    if (!is_black(f))
                        connect(si.p, si.n_geometric, c,
                                beta * f * (c.importance / (c.distance * c.distance)), out);
                }
            }
            if (path_.max_depth >= 0 && segments >= path_.max_depth) return;

            const float u_lobe = stream.next_1d();
            const Vec2f u = stream.next_2d();
            const float u_rr = stream.next_1d();
            const BsdfSample bs =
                bsdf.sample(si.uv, wo_local, u_lobe, u, TransportMode::Importance);
            if (!bs.valid()) return;
            const Vec3f wi = si.shading.to_world(bs.wi);
            const float side = si.n_geometric.dot(wi) * si.n_geometric.dot(wo);
            if (bs.transmission ? side > 0.f : side < 0.f) return;
            beta *= bs.weight * adjoint_shading_correction(si, wo, wi);
            if (is_black(beta)) return;
            // Russian roulette as the path tracer's (Mitsuba's rule: continue with the
            // throughput's largest channel, at most 0.95) from rr_depth on.
            if (vertices >= path_.rr_depth) {
                const float q = std::min(beta.maxCoeff(), 0.95f);
                if (!(u_rr < q)) return;
                beta /= q;
            }
            ray = spawn_ray(si.p, si.n_geometric, wi);
        }
    }

  private:
    /// Splats `value` at the connection's pixel when the segment to the pinhole is free.
    void connect(const Vec3f& p, const Vec3f& n_geometric, const CameraConnection& c,
                 const Rgb& value, ChunkResult& out) const {
        const Ray shadow = spawn_ray_to(p, n_geometric, camera_.position(), Vec3f::Zero());
        ++out.counters.shadow_rays;
        if (scene_.occluded(shadow)) return;
        if (!is_finite(value)) {
            ++out.nonfinite;
            return;
        }
        out.splats.push_back({crop_pixel_index(camera_.film(), c.film_position), value});
    }

    const Scene& scene_;
    const PerspectiveCamera& camera_;
    PathSamplerSettings path_;
};

}  // namespace

RenderOutput render_ptracer(const Scene& scene, const RenderSettings& settings,
                            const std::atomic<bool>* cancel,
                            const std::function<void(const RenderProgress&)>& progress) {
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
    const LightTracer tracer(scene, settings.path);
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
                const std::uint64_t begin = chunk * kPathsPerChunk;
                const std::uint64_t end = std::min(begin + kPathsPerChunk, batch);
                for (std::uint64_t i = begin; i < end; ++i) {
                    if ((i & 255u) == 0 && cancelled()) return;
                    tracer.trace(settings.seed, paths_done + i, result);
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
                    const Ray ray = scene.camera().generate_ray(Vec2f(
                        static_cast<float>(x) + jitter.x(), static_cast<float>(y) + jitter.y()));
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
