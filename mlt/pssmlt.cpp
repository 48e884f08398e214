// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/pssmlt.h"

#include <algorithm>
#include <chrono>
#include <iostream>

#include "core/render/render_path.h"
#include "core/scene/properties.h"

namespace gdmlt::mlt {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

/// Kelemen's PSSMLT target: the path tracer's radiance through the film position the first two
/// primary samples give, splatted into its pixel; the target is its luminance I.
class PathTracerTarget final : public ChainTarget {
  public:
    PathTracerTarget(const Scene& scene, const PathSamplerSettings& path)
        : scene_(scene), path_(path) {}

    std::size_t slot_count() const override {
        const Film& film = scene_.camera().film();
        return static_cast<std::size_t>(film.crop_width) * film.crop_height;
    }

    void evaluate(SampleStream& stream, ChainState& state, ChainCounters& counters) const override {
        const FilmSample where = film_sample(scene_.camera().film(), stream);
        const Ray ray = scene_.camera().generate_ray(where.film_position);
        const Rgb radiance = sample_path_radiance(scene_, ray, stream, path_, counters.paths);
        const double lum = static_cast<double>(luminance(radiance));
        if (!is_finite(radiance) || !std::isfinite(lum)) {
            state.nonfinite = true;
            return;
        }
        if (!(lum > 0.0)) return;
        state.target = lum;
        state.splats.push_back({static_cast<std::uint32_t>(where.pixel), radiance});
    }

  private:
    const Scene& scene_;
    PathSamplerSettings path_;
};

}  // namespace

PssmltSettings pssmlt_settings_from_scene(const IntegratorSettings& integrator) {
    PssmltSettings s;
    if (integrator.desc.type != "pssmlt") {
        read_chain_settings(integrator, nullptr, s);
        return s;
    }
    PropertyReader props(integrator.desc);
    read_chain_settings(integrator, &props, s);
    s.direct_samples = props.get_int32("direct_samples", s.direct_samples);
    props.check_all_read();
    validate_pssmlt_settings(s, integrator.desc.loc);
    return s;
}

void validate_pssmlt_settings(const PssmltSettings& s, const FileLoc& loc) {
    validate_chain_settings(s, loc);
}

PssmltOutput render_pssmlt(const Scene& scene, const PssmltSettings& settings_in,
                           const std::atomic<bool>* cancel,
                           const std::function<void(double, double)>& progress) {
    PssmltSettings settings = settings_in;
    const bool separate_direct = settings.direct_samples > 0;
    if (separate_direct) settings.path.min_depth = 3;
    const Clock::time_point start = Clock::now();
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    const auto pixels = static_cast<double>(width) * height;

    // One chain per 16384 mutations, at least 16.
    const ChainRunnerSettings runner =
        runner_settings(settings, width, height, 16384, 16, settings.time_budget_s);
    const PathTracerTarget target(scene, settings.path);
    ChainRunnerOutput chains = run_chains(target, runner, cancel, progress);
    if (!(chains.stats.b > 0.0))
        std::cerr << "pssmlt: every bootstrap sample was black; the image is black\n";

    PssmltOutput out;
    static_cast<ChainStats&>(out.stats) = chains.stats;
    PssmltStats& stats = out.stats;
    // Every pixel covers 1/P of the image plane in primary sample space: I_j = P * integral.
    out.image = Image(width, height, 3);
    for (std::size_t i = 0; i < chains.estimate.size(); ++i)
        for (int c = 0; c < 3; ++c)
            out.image.pixels[3 * i + static_cast<std::size_t>(c)] =
                static_cast<float>(chains.estimate[i][c] * pixels);
    if (separate_direct && !stats.interrupted) {
        // Direct illumination (paths of 1 and 2 segments) by the path tracer.
        const Clock::time_point direct_start = Clock::now();
        RenderSettings direct;
        direct.spp = settings.direct_samples;
        direct.seed = settings.seed ^ 0xD1EC7ULL;
        direct.path = settings_in.path;
        direct.path.max_depth =
            settings_in.path.max_depth < 0 ? 2 : std::min(settings_in.path.max_depth, 2);
        const RenderOutput d = render_path(scene, direct, cancel);
        for (std::size_t i = 0; i < out.image.pixels.size(); ++i)
            out.image.pixels[i] += d.image.pixels[i];
        stats.counters += d.stats.counters;
        stats.direct_s = seconds_since(direct_start);
    }
    stats.total_s = seconds_since(start);
    return out;
}

}  // namespace gdmlt::mlt
