// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/pssmlt.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <chrono>
#include <iostream>

#include "core/render/render_path.h"
#include "core/sampling/distribution_1d.h"
#include "core/scene/properties.h"
#include "mlt/primary_sample_vector.h"

namespace gdmlt::mlt {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Stream identifiers: each purpose gets its own family of PCG streams, so bootstrap samples,
// the independent check and the chains never share random numbers.
constexpr std::uint64_t kBootstrapStreams = 0xB0075;
constexpr std::uint64_t kIndependentStreams = 0x1D3B;
constexpr std::uint64_t kChainStreams = 0xC4A1;

Pcg32 generator(std::uint64_t key) {
    return Pcg32(key, mix_bits(key));
}

/// One path through primary sample space: its pixel, radiance and scalar contribution I (the
/// luminance, the target function of the chain).
struct Evaluation {
    int x = 0, y = 0;
    Rgb radiance = Rgb::Zero();
    double luminance = 0.0;
    bool nonfinite = false;
};

Evaluation evaluate(const Scene& scene, SampleStream& stream, const PathSamplerSettings& path,
                    PathCounters& counters) {
    const Film& film = scene.camera().film();
    // The first two primary samples are the film position over the crop window.
    const Vec2f u = stream.next_2d();
    const float fx = u.x() * static_cast<float>(film.crop_width);
    const float fy = u.y() * static_cast<float>(film.crop_height);
    Evaluation e;
    e.x = std::min(static_cast<int>(fx), film.crop_width - 1);
    e.y = std::min(static_cast<int>(fy), film.crop_height - 1);
    const Ray ray = scene.camera().generate_ray(Vec2f(static_cast<float>(film.crop_offset_x) + fx,
                                                      static_cast<float>(film.crop_offset_y) + fy));
    const Rgb radiance = sample_path_radiance(scene, ray, stream, path, counters);
    const double lum = static_cast<double>(luminance(radiance));
    if (!is_finite(radiance) || !std::isfinite(lum)) {
        // Dropped and counted; a zero-contribution state is never splatted (pbrt-v4 once
        // produced NaN here by dividing by a zero luminance).
        e.nonfinite = true;
        return e;
    }
    if (lum > 0.0) {
        e.radiance = radiance;
        e.luminance = lum;
    }
    return e;
}

/// An independent sample with the given generator, drawn exactly as a chain's first (large)
/// step draws it, so that a chain can start from it by replaying the generator.
Evaluation independent_sample(const Scene& scene, const PssmltSettings& settings, std::uint64_t key,
                              PathCounters& counters) {
    const Film& film = scene.camera().film();
    PrimarySampleVector psv(settings.mutation, generator(key), film.crop_width, film.crop_height);
    psv.start_iteration(true);
    return evaluate(scene, psv, settings.path, counters);
}

struct MeanEstimate {
    double mean = 0.0, standard_error = 0.0;
    std::uint64_t nonzero = 0, nonfinite = 0;
};

/// Luminances of `count` independent samples from stream family `family`, in index order.
std::vector<double> independent_luminances(const Scene& scene, const PssmltSettings& settings,
                                           std::uint64_t family, std::size_t count,
                                           tbb::enumerable_thread_specific<PathCounters>& counters,
                                           std::uint64_t& nonfinite) {
    std::vector<double> lum(count, 0.0);
    std::vector<char> bad(count, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          PathCounters& local = counters.local();
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const Evaluation e = independent_sample(
                                  scene, settings, derive_stream(settings.seed, family, i), local);
                              lum[i] = e.luminance;
                              bad[i] = e.nonfinite ? 1 : 0;
                          }
                      });
    for (char b : bad) nonfinite += static_cast<std::uint64_t>(b);
    return lum;
}

MeanEstimate mean_of(const std::vector<double>& values) {
    MeanEstimate m;
    double sum = 0.0, sum2 = 0.0;
    for (double v : values) {  // in index order: deterministic
        sum += v;
        sum2 += v * v;
        if (v > 0.0) ++m.nonzero;
    }
    const auto n = static_cast<double>(values.size());
    m.mean = sum / n;
    m.standard_error = n > 1 ? std::sqrt(std::max(0.0, sum2 / n - m.mean * m.mean) / (n - 1)) : 0.0;
    return m;
}

struct Chain {
    PrimarySampleVector psv;
    Pcg32 control;  // large-step choices and acceptance
    Evaluation current;
    std::uint64_t streak = 0, longest_streak = 0;
    double brightness_sum = 0.0;
    std::uint64_t iterations = 0;
    std::uint64_t large_proposed = 0, large_accepted = 0, small_proposed = 0, small_accepted = 0;
    std::uint64_t nonfinite = 0;
    PathCounters counters;
    std::size_t start_index = 0;  // the bootstrap sample it started from
};

void splat(ImageD& image, const Evaluation& e, double weight) {
    for (int c = 0; c < 3; ++c) image(e.x, e.y, c) += weight * static_cast<double>(e.radiance[c]);
}

/// Advances one chain by `mutations` iterations, splatting into `image` (unnormalised).
void run_chain(Chain& chain, const Scene& scene, const PssmltSettings& settings, double b,
               std::uint64_t mutations, ImageD& image) {
    const double p_large = settings.mutation.p_large;
    for (std::uint64_t m = 0; m < mutations; ++m) {
        const bool large = chain.control.next_double() < p_large;
        chain.psv.start_iteration(large);
        const Evaluation proposal = evaluate(scene, chain.psv, settings.path, chain.counters);
        if (proposal.nonfinite) ++chain.nonfinite;
        const Evaluation& current = chain.current;
        // Symmetric proposals: a = min(1, I(y) / I(x)) (Metropolis-Hastings).
        const double accept =
            current.luminance > 0.0 ? std::min(1.0, proposal.luminance / current.luminance) : 1.0;

        // Splat both states with expected-value weights (Veach 1997, sec. 11.5), optionally
        // MIS-combined with the large steps as an independent estimator (Kelemen et al. 2002):
        // proposal (a + [large]) C(y) / (I(y)/b + p_L), current (1 - a) C(x) / (I(x)/b + p_L).
        if (settings.kelemen_weights) {
            if (proposal.luminance > 0.0)
                splat(image, proposal,
                      (accept + (large ? 1.0 : 0.0)) / (proposal.luminance / b + p_large));
            if (current.luminance > 0.0 && accept < 1.0)
                splat(image, current, (1.0 - accept) / (current.luminance / b + p_large));
        } else {
            if (proposal.luminance > 0.0) splat(image, proposal, accept * b / proposal.luminance);
            if (current.luminance > 0.0 && accept < 1.0)
                splat(image, current, (1.0 - accept) * b / current.luminance);
        }

        (large ? chain.large_proposed : chain.small_proposed) += 1;
        if (chain.control.next_double() < accept) {
            chain.psv.accept();
            chain.current = proposal;
            (large ? chain.large_accepted : chain.small_accepted) += 1;
            chain.streak = 0;
        } else {
            chain.psv.reject();
            chain.longest_streak = std::max(chain.longest_streak, ++chain.streak);
        }
        chain.brightness_sum += chain.current.luminance;
        ++chain.iterations;
    }
}

void add_into(ImageD& target, const ImageD& source) {
    for (std::size_t i = 0; i < target.pixels.size(); ++i) target.pixels[i] += source.pixels[i];
}

}  // namespace

PssmltSettings pssmlt_settings_from_scene(const IntegratorSettings& integrator) {
    PssmltSettings s;
    s.path.max_depth = integrator.max_depth;
    s.path.rr_depth = integrator.rr_depth;
    s.path.hide_emitters = integrator.hide_emitters;
    if (integrator.desc.type != "pssmlt") return s;
    PropertyReader props(integrator.desc);
    props.mark_read({"max_depth", "rr_depth", "hide_emitters"});
    s.mutation.p_large = props.get_float("p_large", s.mutation.p_large);
    s.mutation.s1 = props.get_float("mutation_size_low", s.mutation.s1);
    s.mutation.s2 = props.get_float("mutation_size_high", s.mutation.s2);
    s.mutation.image_s2_pixels = props.get_float("image_mutation_size", s.mutation.image_s2_pixels);
    s.chains = static_cast<int>(props.get_int("chains", s.chains));
    // Mitsuba 0.6 calls the bootstrap "luminanceSamples".
    s.bootstrap_samples = static_cast<int>(props.get_int("luminance_samples", s.bootstrap_samples));
    s.bootstrap_samples = static_cast<int>(props.get_int("bootstrap_samples", s.bootstrap_samples));
    s.mutations_per_pixel = props.get_float("mutations_per_pixel", s.mutations_per_pixel);
    s.kelemen_weights = props.get_bool("kelemen_style_weights", s.kelemen_weights);
    s.direct_samples = static_cast<int>(props.get_int("direct_samples", s.direct_samples));
    props.check_all_read();
    validate_pssmlt_settings(s, integrator.desc.loc);
    return s;
}

void validate_pssmlt_settings(const PssmltSettings& s, const FileLoc& loc) {
    if (!(s.mutation.p_large >= 0.0 && s.mutation.p_large <= 1.0))
        throw InputError(loc, "p_large must lie in [0, 1]");
    if (!(s.mutation.s1 > 0.0 && s.mutation.s1 < s.mutation.s2 && s.mutation.s2 < 1.0))
        throw InputError(loc, "mutation sizes must satisfy 0 < s1 < s2 < 1");
    if (s.mutation.image_s2_pixels < 0.0)
        throw InputError(loc, "image_mutation_size must not be negative");
    if (s.chains < 0) throw InputError(loc, "chains must not be negative");
    if (s.bootstrap_samples < 1) throw InputError(loc, "bootstrap_samples must be positive");
    if (!(s.mutations_per_pixel > 0.0))
        throw InputError(loc, "mutations_per_pixel must be positive");
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
    auto cancelled = [&] { return cancel && cancel->load(std::memory_order_relaxed); };
    const bool timed = settings.time_budget_s > 0.0;

    PssmltOutput out;
    PssmltStats& stats = out.stats;
    out.image = Image(width, height, 3);

    const auto total_mutations =
        static_cast<std::uint64_t>(std::llround(settings.mutations_per_pixel * pixels));
    const int chain_count =
        settings.chains > 0
            ? settings.chains
            : static_cast<int>(std::clamp<std::uint64_t>(total_mutations / 16384, 16, 4096));
    stats.chains = chain_count;

    // 1. Bootstrap (Kelemen et al. 2002, sec. 5): b from independent samples; chain start
    //    states resampled proportionally to I, which removes start-up bias.
    tbb::enumerable_thread_specific<PathCounters> counters;
    const std::size_t bootstrap_count =
        std::max<std::size_t>(static_cast<std::size_t>(settings.bootstrap_samples),
                              10 * static_cast<std::size_t>(chain_count));
    const std::vector<double> bootstrap = independent_luminances(
        scene, settings, kBootstrapStreams, bootstrap_count, counters, stats.nonfinite_dropped);
    const MeanEstimate b_estimate = mean_of(bootstrap);
    stats.b = b_estimate.mean;
    stats.b_standard_error = b_estimate.standard_error;
    stats.bootstrap_samples = bootstrap_count;
    stats.bootstrap_nonzero = b_estimate.nonzero;
    // An independent estimate of the same mean, to check b (reported, not used).
    const std::vector<double> check = independent_luminances(
        scene, settings, kIndependentStreams, std::max<std::size_t>(bootstrap_count / 4, 1),
        counters, stats.nonfinite_dropped);
    const MeanEstimate independent = mean_of(check);
    stats.b_independent = independent.mean;
    stats.b_independent_standard_error = independent.standard_error;
    stats.bootstrap_s = seconds_since(start);
    if (!(stats.b > 0.0)) {
        std::cerr << "pssmlt: every bootstrap sample was black; the image is black\n";
        for (const PathCounters& c : counters) stats.counters += c;
        stats.total_s = seconds_since(start);
        return out;
    }

    std::vector<float> weights(bootstrap.begin(), bootstrap.end());
    const Distribution1D start_states(weights);
    std::vector<Chain> chains;
    chains.reserve(static_cast<std::size_t>(chain_count));
    for (int c = 0; c < chain_count; ++c) {
        Pcg32 control =
            generator(derive_stream(settings.seed, kChainStreams, static_cast<std::uint64_t>(c)));
        const std::size_t index = start_states.sample(control.next_float());
        const std::uint64_t key = derive_stream(settings.seed, kBootstrapStreams, index);
        chains.push_back(
            Chain{PrimarySampleVector(settings.mutation, generator(key), width, height),
                  control,
                  {},
                  0,
                  0,
                  0.0,
                  0,
                  0,
                  0,
                  0,
                  0,
                  0,
                  {},
                  index});
    }
    // Replay each start state (parallel: each is one path).
    tbb::parallel_for(0, chain_count, [&](int c) {
        Chain& chain = chains[static_cast<std::size_t>(c)];
        chain.psv.start_iteration(true);
        chain.current = evaluate(scene, chain.psv, settings.path, chain.counters);
        chain.psv.accept();
    });
    for (const Chain& chain : chains) {
        // Mitsuba's guard: a start state that does not reproduce its bootstrap value means the
        // path sampler is not a deterministic function of its primary samples.
        const double recorded = bootstrap[chain.start_index];
        if (std::abs(chain.current.luminance - recorded) > 1e-6 * recorded)
            ++stats.replay_mismatches;
    }

    // 2. Chains, in rounds: a round advances every chain by the same number of mutations, so
    //    time budgets and Ctrl-C act between rounds. With a mutation budget the rounds are fixed,
    //    the leaves of the deterministic reduction are fixed, and so is the image, bit for bit.
    const Clock::time_point chains_start = Clock::now();
    const std::uint64_t per_chain_budget =
        timed ? std::numeric_limits<std::uint64_t>::max() / 4
              : (total_mutations + static_cast<std::uint64_t>(chain_count) - 1) /
                    static_cast<std::uint64_t>(chain_count);
    ImageD accumulated(width, height, 3);
    std::uint64_t per_chain_done = 0;
    std::uint64_t round_size = timed ? 64 : std::min<std::uint64_t>(per_chain_budget, 2048);
    const int grain = std::max(1, chain_count / 32);
    while (per_chain_done < per_chain_budget && !cancelled()) {
        if (timed) {
            const double remaining = settings.time_budget_s - seconds_since(start);
            if (remaining <= 0.0) break;
        }
        const std::uint64_t this_round = std::min(round_size, per_chain_budget - per_chain_done);
        const Clock::time_point round_start = Clock::now();
        ImageD round = tbb::parallel_deterministic_reduce(
            tbb::blocked_range<int>(0, chain_count, static_cast<std::size_t>(grain)), ImageD(),
            [&](const tbb::blocked_range<int>& r, ImageD partial) {
                if (partial.pixels.empty()) partial = ImageD(width, height, 3);
                for (int c = r.begin(); c != r.end(); ++c)
                    run_chain(chains[static_cast<std::size_t>(c)], scene, settings, stats.b,
                              this_round, partial);
                return partial;
            },
            [](ImageD a, const ImageD& b) {
                if (a.pixels.empty()) return b;
                if (!b.pixels.empty()) add_into(a, b);
                return a;
            });
        if (!round.pixels.empty()) add_into(accumulated, round);
        per_chain_done += this_round;
        if (timed) {
            // Aim for rounds of about half a second, never past the budget.
            const double per_mutation =
                seconds_since(round_start) / static_cast<double>(this_round);
            const double remaining = settings.time_budget_s - seconds_since(start);
            const double target = std::min(0.5, std::max(remaining, 0.0));
            round_size = std::clamp<std::uint64_t>(
                static_cast<std::uint64_t>(target / std::max(per_mutation, 1e-9)), 1, 1 << 16);
        }
        if (progress) {
            const double fraction =
                timed ? seconds_since(start) / settings.time_budget_s
                      : static_cast<double>(per_chain_done) / static_cast<double>(per_chain_budget);
            progress(std::min(fraction, 1.0), seconds_since(start));
        }
    }
    stats.interrupted = cancelled();
    stats.chains_s = seconds_since(chains_start);

    // 3. Normalise: every pixel covers 1/P of the image plane in primary sample space, so
    //    I_j = P / N * sum of splats into j.
    std::vector<double> longest;
    std::vector<double> brightness;
    for (const Chain& c : chains) {
        stats.mutations += c.iterations;
        stats.large_proposed += c.large_proposed;
        stats.large_accepted += c.large_accepted;
        stats.small_proposed += c.small_proposed;
        stats.small_accepted += c.small_accepted;
        stats.nonfinite_dropped += c.nonfinite;
        stats.longest_rejection_streak = std::max(stats.longest_rejection_streak, c.longest_streak);
        stats.counters += c.counters;
        longest.push_back(static_cast<double>(c.longest_streak));
        if (c.iterations > 0)
            brightness.push_back(c.brightness_sum / static_cast<double>(c.iterations));
    }
    for (const PathCounters& c : counters) stats.counters += c;
    if (!longest.empty()) {
        std::nth_element(longest.begin(),
                         longest.begin() + static_cast<std::ptrdiff_t>(longest.size() / 2),
                         longest.end());
        stats.median_longest_rejection_streak = longest[longest.size() / 2];
    }
    if (!brightness.empty()) {
        const MeanEstimate m = mean_of(brightness);
        stats.chain_brightness_mean = m.mean;
        const double sd = m.standard_error * std::sqrt(static_cast<double>(brightness.size()));
        stats.chain_brightness_relative_spread = m.mean > 0.0 ? sd / m.mean : 0.0;
    }
    if (stats.mutations > 0) {
        const double scale = pixels / static_cast<double>(stats.mutations);
        for (std::size_t i = 0; i < accumulated.pixels.size(); ++i)
            out.image.pixels[i] = static_cast<float>(accumulated.pixels[i] * scale);
    }
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
