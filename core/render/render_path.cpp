// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/render_path.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "core/render/film_buffer.h"
#include "core/sampling/rng.h"

namespace gdmlt {
namespace {

constexpr int kTileSize = 16;

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

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

}  // namespace

RenderOutput render_path(const Scene& scene, const RenderSettings& settings,
                         const std::atomic<bool>* cancel,
                         const std::function<void(const RenderProgress&)>& progress,
                         double progress_interval_s) {
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    const int tiles_x = (width + kTileSize - 1) / kTileSize;
    const int tiles_y = (height + kTileSize - 1) / kTileSize;
    const int tile_count = tiles_x * tiles_y;
    const int spp_budget = std::max(settings.spp, 1);
    const bool timed = settings.time_budget_s > 0.0;

    FilmBuffer buffer(width, height);
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

    auto cancelled = [&] { return cancel && cancel->load(std::memory_order_relaxed); };

    RenderStats stats;
    int spp_done = 0;
    double seconds_per_spp = 0.0;
    while (spp_done < spp_budget && !cancelled()) {
        // Pass size: all at once without a time budget; with one, as many samples as the
        // measured speed says fit into the remaining time (at least 1, at most 64).
        int pass_spp = spp_budget - spp_done;
        if (timed) {
            const double remaining = settings.time_budget_s - seconds_since(start);
            if (remaining <= 0.0) break;
            int fit = seconds_per_spp > 0.0 ? static_cast<int>(remaining / seconds_per_spp) : 1;
            pass_spp = std::clamp(fit, 1, std::min(64, pass_spp));
        }
        const int first_sample = spp_done;
        const Clock::time_point pass_start = Clock::now();

        tbb::parallel_for(
            tbb::blocked_range<int>(0, tile_count), [&](const tbb::blocked_range<int>& range) {
                PathCounters& local = counters.local();
                for (int tile = range.begin(); tile != range.end(); ++tile) {
                    if (cancelled()) return;
                    const int x0 = (tile % tiles_x) * kTileSize, y0 = (tile / tiles_x) * kTileSize;
                    const int x1 = std::min(x0 + kTileSize, width),
                              y1 = std::min(y0 + kTileSize, height);
                    for (int y = y0; y < y1; ++y) {
                        for (int x = x0; x < x1; ++x) {
                            // Polled per pixel, not per tile: a tile of a high-spp pass can
                            // take minutes, and Ctrl-C must stop the render promptly.
                            if (cancelled()) return;
                            const int film_x = x + film.crop_offset_x,
                                      film_y = y + film.crop_offset_y;
                            const auto pixel =
                                static_cast<std::uint64_t>(film_y) * film.width + film_x;
                            for (int s = first_sample; s < first_sample + pass_spp; ++s) {
                                // One stream per (seed, pixel, sample index): the image does not
                                // depend on the thread count, the tiling or the pass split.
                                IndependentStream stream(derive_stream(
                                    settings.seed, pixel, static_cast<std::uint64_t>(s)));
                                const Vec2f jitter = stream.next_2d();
                                const Ray ray = scene.camera().generate_ray(
                                    Vec2f(static_cast<float>(film_x) + jitter.x(),
                                          static_cast<float>(film_y) + jitter.y()));
                                const Rgb L =
                                    sample_path_radiance(scene, ray, stream, settings.path, local);
                                if (is_finite(L)) {
                                    buffer.add(x, y, L);
                                } else {
                                    buffer.add_dropped(x, y);
                                    ++dropped.local();
                                }
                            }
                        }
                    }
                    samples_done.fetch_add(
                        static_cast<std::uint64_t>((x1 - x0) * (y1 - y0)) * pass_spp,
                        std::memory_order_relaxed);
                }
            });
        if (cancelled()) break;
        spp_done += pass_spp;
        ++stats.passes;
        seconds_per_spp = seconds_since(pass_start) / pass_spp;
    }
    reporter.stop();

    stats.render_s = seconds_since(start);
    stats.interrupted = cancelled();
    stats.spp_completed = spp_done;
    for (const PathCounters& c : counters) stats.counters += c;
    for (std::uint64_t d : dropped) stats.nonfinite_samples_dropped += d;
    stats.samples = buffer.total_count();
    return RenderOutput{buffer.mean(), stats};
}

}  // namespace gdmlt
