// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/pssmlt.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>

#include "core/math/stopwatch.h"
#include "core/path/bidirectional.h"
#include "core/render/render_path.h"
#include "core/scene/properties.h"

namespace gdmlt::mlt {
namespace {

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
        const Ray ray = scene_.camera().generate_ray(where.film_position,
                                                     draw_lens_sample(scene_.camera(), stream));
        const Rgb radiance = sample_path_radiance(scene_, ray, stream, path_, counters.paths);
        const double lum = static_cast<double>(luminance(radiance));
        if (!is_finite(radiance) || !std::isfinite(lum)) {
            state.nonfinite = true;
            return;
        }
        if (!(lum > 0.0)) return;
        state.target = lum;
        // Every pixel whose filter reaches the position (the one pixel with the box filter).
        for_each_filtered_pixel(scene_.camera().film(), where.film_position,
                                [&](std::uint32_t pixel, float weight) {
                                    state.splats.push_back({pixel, radiance * weight});
                                });
    }

  private:
    const Scene& scene_;
    PathSamplerSettings path_;
};

/// Kelemen's PSSMLT over BDPT: one state is a whole bidirectional sample (core/path/
/// bidirectional.h lays its numbers out in fixed blocks, so that mutations keep their
/// meaning). Its contributions to its own pixel are splatted as they are; light tracing splats
/// land on other pixels and are divided by the pixel count P, since the image is P times each
/// slot's integral and a light path estimates every pixel at once (render_bdpt divides them by
/// the number of light paths, P per sample per pixel). The target is the luminance of the
/// whole image contribution.
///
/// Multiplexed (MMLT, Hachisuka et al. 2014): two more numbers choose a path length k in
/// [1, max_depth] and a strategy s in [0, k] (t = k + 1 - s) uniformly; the state is that one
/// strategy, MIS-weighted against the others of its length and divided by the probability of
/// the choice, with subpaths of exactly s and t vertices and no Russian roulette (which would
/// only end subpaths before the chosen strategy could connect).
class BidirectionalTarget final : public ChainTarget {
  public:
    BidirectionalTarget(const Scene& scene, const PathSamplerSettings& path, bool multiplexed)
        : scene_(scene), multiplexed_(multiplexed) {
        bdpt_.max_depth = path.max_depth;
        bdpt_.rr_depth = multiplexed ? std::numeric_limits<int>::max() : path.rr_depth;
        bdpt_.hide_emitters = path.hide_emitters;
        const Film& film = scene.camera().film();
        pixels_ = static_cast<float>(film.crop_width) * static_cast<float>(film.crop_height);
    }

    std::size_t slot_count() const override {
        const Film& film = scene_.camera().film();
        return static_cast<std::size_t>(film.crop_width) * film.crop_height;
    }

    void evaluate(SampleStream& stream, ChainState& state, ChainCounters& counters) const override {
        const Film& film = scene_.camera().film();
        const FilmSample where = film_sample(film, stream);
        // Evaluations run concurrently on the chains' threads: one scratch per thread.
        thread_local BdptScratch scratch;
        thread_local BdptSample sample;
        BdptSettings bdpt = bdpt_;
        float inverse_choice = 1.f;
        if (multiplexed_) {
            const float u_length = stream.next_1d();
            const float u_strategy = stream.next_1d();
            const int lengths = bdpt_.max_depth;
            const int k =
                1 + std::min(static_cast<int>(u_length * static_cast<float>(lengths)), lengths - 1);
            const int s = std::min(static_cast<int>(u_strategy * static_cast<float>(k + 1)), k);
            bdpt.only_s = s;
            bdpt.only_t = k + 1 - s;
            bdpt.weight_only = true;
            inverse_choice = static_cast<float>(lengths) * static_cast<float>(k + 1);
        }
        sample_bdpt(scene_, where.film_position, stream, stream, bdpt, scratch, sample,
                    counters.paths);
        sample.pixel *= inverse_choice;
        if (sample.nonfinite > 0) {
            state.nonfinite = true;
            return;
        }
        double target = static_cast<double>(luminance(sample.pixel));
        if (!is_black(sample.pixel))
            for_each_filtered_pixel(film, where.film_position,
                                    [&](std::uint32_t pixel, float weight) {
                                        state.splats.push_back({pixel, sample.pixel * weight});
                                    });
        for (const BdptSample::Splat& s : sample.splats) {
            const Rgb value = s.value * (inverse_choice / pixels_);
            target += static_cast<double>(luminance(value));
            for_each_filtered_pixel(film, s.film_position, [&](std::uint32_t pixel, float weight) {
                state.splats.push_back({pixel, value * weight});
            });
        }
        if (!std::isfinite(target)) {
            state.nonfinite = true;
            state.splats.clear();
            return;
        }
        if (!(target > 0.0)) {
            state.splats.clear();
            return;
        }
        state.target = target;
    }

  private:
    const Scene& scene_;
    bool multiplexed_ = false;
    BdptSettings bdpt_;
    float pixels_ = 1.f;
};

}  // namespace

PssmltSettings pssmlt_settings_from_scene(const IntegratorSettings& integrator) {
    PssmltSettings s;
    s.multiplexed = integrator.desc.type == "mmlt";
    if (integrator.desc.type != "pssmlt" && integrator.desc.type != "mmlt") {
        read_chain_settings(integrator, nullptr, s);
        return s;
    }
    PropertyReader props(integrator.desc);
    read_chain_settings(integrator, &props, s);
    s.direct_samples = props.get_int32("direct_samples", s.direct_samples);
    s.bidirectional = props.get_bool("bidirectional", s.bidirectional);
    props.check_all_read();
    validate_pssmlt_settings(s, integrator.desc.loc);
    return s;
}

void validate_pssmlt_settings(const PssmltSettings& s, const FileLoc& loc) {
    validate_chain_settings(s, loc);
    if (s.multiplexed && s.path.max_depth < 1)
        throw InputError(loc,
                         "mmlt needs a max_depth of at least 1 (it chooses a path length "
                         "uniformly up to it)");
    if ((s.bidirectional || s.multiplexed) && s.direct_samples > 0)
        throw InputError(loc,
                         "direct_samples cannot be used with bidirectional: BDPT renders direct "
                         "light with its own strategies");
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
    const PathTracerTarget unidirectional(scene, settings.path);
    const BidirectionalTarget bidirectional(scene, settings.path, settings.multiplexed);
    const ChainTarget& target = settings.bidirectional || settings.multiplexed
                                    ? static_cast<const ChainTarget&>(bidirectional)
                                    : static_cast<const ChainTarget&>(unidirectional);
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
