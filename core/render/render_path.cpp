// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/render_path.h"

#include <tbb/enumerable_thread_specific.h>

#include <array>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <span>
#include <thread>
#include <vector>

#include "core/math/stopwatch.h"
#include "core/path/diffuse_lanes.h"
#include "core/render/film_buffer.h"
#include "core/render/pixel_passes.h"
#include "core/render/splat_film.h"
#include "core/sampling/pcg_lanes.h"
#include "core/sampling/rng.h"

namespace gdmlt {
namespace {

/// Calls `report` every `interval_s` from a background thread until stopped.
class ProgressReporter {
  public:
    ProgressReporter(std::function<void()> report, double interval_s)
        : report_(std::move(report)), interval_(interval_s) {
        if (report_) thread_ = std::thread([this] { run(); });
    }
    ~ProgressReporter() { stop(); }
    void stop() {
        {
            std::lock_guard<std::mutex> lock(mutex_);
            stop_ = true;
        }
        wake_.notify_all();
        if (thread_.joinable()) thread_.join();
    }

  private:
    void run() {
        std::unique_lock<std::mutex> lock(mutex_);
        while (!wake_.wait_for(lock, std::chrono::duration<double>(interval_),
                               [this] { return stop_; }))
            report_();
    }
    std::function<void()> report_;
    double interval_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    std::thread thread_;
};

/// Paths advanced together. Enough that the rays of one bounce fill packets of 16 even after
/// Russian roulette and escapes have ended most paths; few enough that their state (about
/// 120 bytes each) stays in the L1/L2 caches.
constexpr std::size_t kWavefrontPaths = 256;
constexpr int kPacket = Accelerator::kPacketSize;
static_assert(kWavefrontPaths <= DiffuseLanes::kCapacity && kWavefrontPaths <= PcgLanes::kCapacity);
static_assert(kDimensionsPerBounce <= static_cast<int>(PcgLanes::kMaxDraws));

struct WavefrontLane {
    int x = 0, y = 0;                     // crop-window pixel
    int sample = 0;                       // the sample's index in its pixel
    Vec2f film_position = Vec2f::Zero();  // full-film position
    PathState state;  // its random numbers: the Wavefront's `streams`, same index
};

/// The path tracer's wavefront (Laine et al. 2013, "Megakernels considered harmful", in its
/// simplest form): every path of a batch takes one vertex, their rays traced in packets of 16,
/// then their shadow rays likewise. Each path's arithmetic and random numbers are those of
/// sample_path_radiance (begin_vertex and finish_vertex, or for diffuse vertices DiffuseLanes,
/// which computes the same in SIMD lanes; the numbers come from the same PCG streams, drawn for
/// all paths at once by PcgLanes), so the image is the same as tracing path after path, up to
/// Embree's packet and single-ray kernels rounding a hit differently. Per thread, reused across
/// tiles so that its buffers are allocated once.
struct Wavefront {
    std::vector<WavefrontLane> lanes;
    // The random streams of the active paths, in `active`'s order (compacted with it, so that
    // only live paths draw), and this vertex's numbers: numbers[d][j] for active[j].
    PcgLanes streams;
    PcgLanes::Draws numbers;
    std::optional<DiffuseLanes> diffuse;  // built on the first run
    std::vector<std::uint32_t> active;    // lanes still tracing, in lane order
    struct Shadow {
        std::uint32_t lane;
        NextEventRay ray;
    };
    // The shadow rays of one bounce (at most one per path), shadow_count of them.
    std::vector<Shadow> shadows = std::vector<Shadow>(kWavefrontPaths);
    std::size_t shadow_count = 0;
    // The queued paths' stream identifiers (start), their film positions and camera rays.
    PcgLanes::Keys pixel_keys{}, sample_keys{};
    std::array<float, kWavefrontPaths> film_x{}, film_y{};
    std::array<Ray, kWavefrontPaths> queued_rays{};

    void run(const Scene& scene, const PathSamplerSettings& path, PathCounters& counters) {
        if (!diffuse) diffuse.emplace(scene);  // a wavefront lives for one render
        active.clear();
        for (std::uint32_t i = 0; i < lanes.size(); ++i) active.push_back(i);
        RayPacket rays;
        HitPacket hits;
        std::array<bool, kPacket> blocked;
        // The first rays of a batch are camera rays, and consecutive lanes are samples of one
        // pixel (or, at one sample per pixel, of neighbouring pixels): coherent packets, which
        // Embree traces 2.5x faster when told so. Later bounces scatter and are left
        // incoherent (the flag would slow them 2-3x).
        bool camera_rays = true;
        while (!active.empty()) {
            shadow_count = 0;
            // Every path draws its vertex's kDimensionsPerBounce numbers (whether it uses them
            // or not), 8 streams per instruction with AVX-512.
            streams.next_floats(active.size(), kDimensionsPerBounce, numbers);
            for (std::size_t first = 0; first < active.size(); first += kPacket) {
                const std::size_t count = std::min<std::size_t>(kPacket, active.size() - first);
                rays.count = static_cast<int>(count);
                for (std::size_t k = 0; k < count; ++k)
                    rays.set(static_cast<int>(k), lanes[active[first + k]].state.ray);
                scene.intersect_packet(rays, hits, camera_rays);
                for (std::size_t k = 0; k < count; ++k) {
                    const std::uint32_t index = active[first + k];
                    WavefrontLane& lane = lanes[index];
                    const VertexNumbers u = vertex_numbers(first + k);
                    // The most common vertex, a flat diffuse surface that does not emit, goes
                    // to the lanes without a SurfaceInteraction.
                    const RayHit hit = hits.hit(static_cast<int>(k));
                    if (hit.valid() && diffuse->handles_hit(hit.shape)) {
                        if (begin_vertex_without_emission(path, lane.state))
                            diffuse->push_hit(index, hit, u, lane.state, path);
                        continue;
                    }
                    const SurfaceInteraction si = scene.interaction(lane.state.ray, hit);
                    if (!begin_vertex(scene, si, path, lane.state)) continue;
                    if (diffuse->handles(si)) {
                        diffuse->push(index, si, u, lane.state, path);
                        continue;
                    }
                    Shadow shadow{index, {}};
                    finish_vertex(scene, si, u, path, counters, lane.state, shadow.ray);
                    if (shadow.ray.requested) shadows[shadow_count++] = shadow;
                }
            }
            // The diffuse vertices of this bounce, all at once.
            diffuse->run();
            for (std::size_t i = 0; i < diffuse->size(); ++i) {
                // Written in place, kept when requested: no branch on it (see finish), and no
                // copy of a Shadow just written field by field (the store-forwarding stall of
                // such a copy was 1-2% of the render's time in perf).
                Shadow& shadow = shadows[shadow_count];
                shadow.lane = diffuse->id(i);
                diffuse->finish(i, lanes[shadow.lane].state, shadow.ray, counters);
                shadow_count += shadow.ray.requested ? 1 : 0;
            }
            diffuse->clear();
            // Shadow rays before any path's next vertex: each path's radiance then sums its
            // terms in the order sample_path_radiance does.
            for (std::size_t first = 0; first < shadow_count; first += kPacket) {
                const std::size_t count = std::min<std::size_t>(kPacket, shadow_count - first);
                rays.count = static_cast<int>(count);
                for (std::size_t k = 0; k < count; ++k)
                    rays.set(static_cast<int>(k), shadows[first + k].ray.shadow);
                scene.occluded_packet(rays, blocked);
                // Without branches: whether a shadow ray is blocked, and below whether a path
                // goes on, are as random as the paths (a branch on them mispredicts often).
                // Adding +0 leaves a radiance unchanged (a -0 component would become +0:
                // the same pixel value).
                for (std::size_t k = 0; k < count; ++k) {
                    const Shadow& shadow = shadows[first + k];
                    lanes[shadow.lane].state.radiance +=
                        blocked[k] ? Rgb(Rgb::Zero()) : shadow.ray.contribution;
                }
            }
            std::size_t kept = 0;
            for (std::size_t j = 0; j < active.size(); ++j) {
                streams.move(j, kept);
                active[kept] = active[j];
                kept += lanes[active[j]].state.active ? 1 : 0;
            }
            active.resize(kept);
            camera_rays = false;
        }
    }

    /// The numbers of active[j] for this vertex: its draws in order.
    VertexNumbers vertex_numbers(std::size_t j) const {
        return VertexNumbers::in_draw_order(
            [&](int d) { return numbers[static_cast<std::size_t>(d)][j]; });
    }

    /// Queues sample `sample` of pixel (x, y) of the crop window; `start` then gives it its
    /// random stream and camera ray.
    void queue(const Film& film, int x, int y, int sample) {
        const std::size_t i = lanes.size();
        pixel_keys[i] = pixel_stream_id(film, x, y);  // pixel_sample's stream identifiers
        sample_keys[i] = static_cast<std::uint64_t>(sample);
        lanes.push_back(WavefrontLane{x, y, sample, Vec2f::Zero(), {}});
    }

    /// pixel_sample and generate_ray for every queued path at once, in SIMD lanes (one at a
    /// time they were about a tenth of the render: three 64-bit hashes, a seeding, two draws,
    /// a double-precision rotation and two square roots per path, all latency-bound):
    /// each path's stream (after its two jitter draws) and camera ray are those of
    /// pixel_sample(film, seed, x, y, sample) and generate_ray, bit for bit.
    /// `splat`: positions uniform in their pixel (the film splats them, SplatFilm), else drawn
    /// from the pixel's filter.
    void start(const Camera& camera, std::uint64_t seed, bool splat, PathCounters& counters) {
        const Film& film = camera.film();
        const std::size_t count = lanes.size();
        streams.seed_samples(count, seed, pixel_keys, sample_keys);
        // The jitter (pixel_sample's next_2d), then a thin lens's sample (draw_lens_sample).
        const bool lens = camera.needs_lens_sample();
        streams.next_floats(count, lens ? 4 : 2, numbers);
        for (std::size_t i = 0; i < count; ++i) {
            const Vec2f position = splat ? uniform_film_position(film, lanes[i].x, lanes[i].y,
                                                                 numbers[0][i], numbers[1][i])
                                         : jittered_film_position(film, lanes[i].x, lanes[i].y,
                                                                  numbers[0][i], numbers[1][i]);
            lanes[i].film_position = position;
            film_x[i] = position.x();
            film_y[i] = position.y();
        }
        if (camera.projection() == Projection::Pinhole) {
            camera.generate_rays(std::span(film_x.data(), count), std::span(film_y.data(), count),
                                 queued_rays);
        } else {
            for (std::size_t i = 0; i < count; ++i)
                queued_rays[i] = camera.generate_ray(
                    Vec2f(film_x[i], film_y[i]),
                    lens ? Vec2f(numbers[2][i], numbers[3][i]) : Vec2f(0.5f, 0.5f));
        }
        for (std::size_t i = 0; i < count; ++i)
            lanes[i].state = start_path(queued_rays[i], counters);
    }

    /// Adds the finished paths to the film in batch order (or records them in `splat`, when
    /// given) and empties the batch.
    void flush(FilmBuffer& buffer, SplatFilm* splat, const Film& film, std::uint64_t& dropped) {
        for (const WavefrontLane& lane : lanes) {
            const bool finite = is_finite(lane.state.radiance);
            dropped += finite ? 0 : 1;
            if (splat) {
                const Vec2f crop_position(
                    lane.film_position.x() - static_cast<float>(film.crop_offset_x),
                    lane.film_position.y() - static_cast<float>(film.crop_offset_y));
                splat->record(lane.x, lane.y, lane.sample, crop_position,
                              finite ? lane.state.radiance : Rgb(Rgb::Zero()));
            } else if (finite) {
                buffer.add(lane.x, lane.y, lane.state.radiance);
            } else {
                buffer.add_dropped(lane.x, lane.y);
            }
        }
        lanes.clear();
    }
};

}  // namespace

RenderOutput render_path(const Scene& scene, const RenderSettings& settings,
                         const std::atomic<bool>* cancel,
                         const std::function<void(const RenderProgress&)>& progress,
                         double progress_interval_s) {
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    const int spp_budget = std::max(settings.spp, 1);
    const bool timed = settings.time_budget_s > 0.0;

    FilmBuffer buffer(width, height);
    if (settings.second_moment) buffer.track_second_moment();
    // A filter wider than a pixel: Mitsuba 3's splatting film (splat_film.h), whose ratio of
    // weighted sums has much less noise at equal spp than positions drawn from the filter.
    std::optional<SplatFilm> splat;
    if (!film.filter.is_box()) {
        splat.emplace(width, height, film.filter);
        if (settings.second_moment) splat->track_second_moment();
    }
    tbb::enumerable_thread_specific<PathCounters> counters;
    tbb::enumerable_thread_specific<std::uint64_t> dropped(0);
    std::atomic<std::uint64_t> samples_done{0};

    const Clock::time_point start = Clock::now();
    const auto expected_samples = static_cast<double>(spp_budget) * width * height;
    ProgressReporter reporter(progress ? std::function<void()>([&] {
                                  RenderProgress p;
                                  p.samples = samples_done.load(std::memory_order_relaxed);
                                  p.elapsed_s = seconds_since(start);
                                  p.fraction =
                                      timed ? std::min(p.elapsed_s / settings.time_budget_s, 1.0)
                                            : static_cast<double>(p.samples) / expected_samples;
                                  progress(p);
                              })
                                       : std::function<void()>(),
                              progress_interval_s);

    RenderStats stats;
    PixelPassSettings passes = pixel_pass_settings(settings, 64);
    if (splat) {
        // The splatting film keeps a pass's samples (24 bytes each) until the pass ends.
        passes.max_pass_spp = 4;
        passes.limit_every_pass = true;
    }
    tbb::enumerable_thread_specific<Wavefront> wavefronts;
    const PixelPassResult done = run_tile_passes(
        film, passes, cancel,
        [&](const PixelTile& tile) {
            Wavefront& wavefront = wavefronts.local();
            PathCounters& tile_counters = counters.local();
            std::uint64_t& tile_dropped = dropped.local();
            const auto trace_batch = [&] {
                wavefront.start(scene.camera(), passes.seed, splat.has_value(), tile_counters);
                wavefront.run(scene, settings.path, tile_counters);
                wavefront.flush(buffer, splat ? &*splat : nullptr, film, tile_dropped);
            };
            // Whole pixels' samples in tile order, kWavefrontPaths at a time (a pixel's samples
            // may straddle two batches; the film adds them in sample order all the same).
            for (int y = tile.y0; y < tile.y1; ++y)
                for (int x = tile.x0; x < tile.x1; ++x) {
                    if (cancel && cancel->load(std::memory_order_relaxed)) {
                        // The unfinished batch is dropped (its pixels keep the samples already
                        // added; the film counts per pixel), not left for the next tile.
                        wavefront.lanes.clear();
                        return false;
                    }
                    for (int s = tile.first_sample; s < tile.first_sample + tile.sample_count;
                         ++s) {
                        wavefront.queue(film, x, y, s);
                        if (wavefront.lanes.size() == kWavefrontPaths) trace_batch();
                    }
                }
            trace_batch();
            return true;
        },
        [&](int) {
            if (splat) splat->end_pass();
        },
        &samples_done,
        [&](int first_sample, int sample_count) {
            if (splat) splat->begin_pass(first_sample, sample_count);
        });
    if (splat) splat->end_pass();  // an interrupted pass's samples
    stats.passes = done.passes;
    reporter.stop();

    stats.render_s = seconds_since(start);
    stats.interrupted = done.interrupted;
    stats.spp_completed = done.spp_completed;
    for (const PathCounters& c : counters) stats.counters += c;
    for (std::uint64_t d : dropped) stats.nonfinite_samples_dropped += d;
    if (splat) {
        stats.samples = splat->total_count();
        return RenderOutput{splat->mean(), stats, splat->second_moment()};
    }
    stats.samples = buffer.total_count();
    return RenderOutput{buffer.mean(), stats, buffer.second_moment()};
}

}  // namespace gdmlt
