// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/render_path.h"

#include <tbb/enumerable_thread_specific.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "core/math/stopwatch.h"
#include "core/render/film_buffer.h"
#include "core/render/pixel_passes.h"
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
    const PixelPassSettings passes = pixel_pass_settings(settings, 64);
    const PixelPassResult done = run_pixel_passes(
        film, passes, cancel,
        [&](int x, int y, const Vec2f& film_position, IndependentStream& stream) {
            const Ray ray = scene.camera().generate_ray(film_position);
            const Rgb L = sample_path_radiance(scene, ray, stream, settings.path, counters.local());
            if (is_finite(L)) {
                buffer.add(x, y, L);
            } else {
                buffer.add_dropped(x, y);
                ++dropped.local();
            }
        },
        [](int) {}, &samples_done);
    stats.passes = done.passes;
    reporter.stop();

    stats.render_s = seconds_since(start);
    stats.interrupted = done.interrupted;
    stats.spp_completed = done.spp_completed;
    for (const PathCounters& c : counters) stats.counters += c;
    for (std::uint64_t d : dropped) stats.nonfinite_samples_dropped += d;
    stats.samples = buffer.total_count();
    return RenderOutput{buffer.mean(), stats};
}

}  // namespace gdmlt
