// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The path-tracing integrator: tiles over all cores, deterministic per (seed, pixel, sample).
#include <atomic>
#include <cstdint>
#include <functional>

#include "core/image/image.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"

namespace gdmlt {

struct RenderSettings {
    int spp = 16;                // samples per pixel (upper bound when time_budget_s > 0)
    double time_budget_s = 0.0;  // 0: no time limit; otherwise stop after the pass that exceeds it
    std::uint64_t seed = 0;
    PathSamplerSettings path;
    /// Also the samples' second moments in XYZ (RenderOutput::second_moment; the path tracer
    /// only, for Mitsuba 3's `moment` integrator).
    bool second_moment = false;
};

struct RenderProgress {
    double fraction = 0.0;  // of the sample budget
    std::uint64_t samples = 0;
    double elapsed_s = 0.0;
};

struct RenderStats {
    PathCounters counters;
    std::uint64_t samples = 0;
    std::uint64_t nonfinite_samples_dropped = 0;
    int passes = 0;
    int spp_completed = 0;  // samples every pixel received
    double render_s = 0.0;
    bool interrupted = false;
};

struct RenderOutput {
    Image image;  // crop window size, linear RGB
    RenderStats stats;
    /// With RenderSettings::second_moment: per pixel the mean of the samples' squared CIE XYZ
    /// values (Mitsuba 3's `moment` m2 channels); empty otherwise.
    Image second_moment;
};

/// Renders with the path tracer. `cancel` (optional) is polled between tiles; when it becomes
/// true the render stops and returns what has accumulated (stats.interrupted). `progress` is
/// called from a background thread about every `progress_interval_s` seconds.
RenderOutput render_path(const Scene& scene, const RenderSettings& settings,
                         const std::atomic<bool>* cancel = nullptr,
                         const std::function<void(const RenderProgress&)>& progress = {},
                         double progress_interval_s = 0.5);

}  // namespace gdmlt
