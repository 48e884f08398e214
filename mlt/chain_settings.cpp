// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/chain_settings.h"

#include <algorithm>
#include <cmath>

namespace gdmlt::mlt {

void read_chain_settings(const IntegratorSettings& integrator, PropertyReader* props,
                         MarkovChainSettings& s) {
    s.path.max_depth = integrator.max_depth;
    s.path.rr_depth = integrator.rr_depth;
    s.path.hide_emitters = integrator.hide_emitters;
    if (!props) return;
    props->mark_read({"max_depth", "rr_depth", "hide_emitters"});
    s.mutation.p_large = props->get_float("p_large", s.mutation.p_large);
    s.mutation.s1 = props->get_float("mutation_size_low", s.mutation.s1);
    s.mutation.s2 = props->get_float("mutation_size_high", s.mutation.s2);
    s.mutation.image_s2_pixels =
        props->get_float("image_mutation_size", s.mutation.image_s2_pixels);
    s.chains = props->get_int32("chains", s.chains);
    // Mitsuba 0.6 calls the bootstrap "luminanceSamples".
    s.bootstrap_samples = props->get_int32("luminance_samples", s.bootstrap_samples);
    s.bootstrap_samples = props->get_int32("bootstrap_samples", s.bootstrap_samples);
    s.mutations_per_pixel = props->get_float("mutations_per_pixel", s.mutations_per_pixel);
    s.kelemen_weights = props->get_bool("kelemen_style_weights", s.kelemen_weights);
}

ChainRunnerSettings runner_settings(const MarkovChainSettings& settings, int width, int height,
                                    std::uint64_t mutations_per_chain, int min_chains,
                                    double time_budget_s) {
    ChainRunnerSettings runner;
    runner.mutation = settings.mutation;
    runner.image_width = width;
    runner.image_height = height;
    runner.mutations = static_cast<std::uint64_t>(
        std::llround(settings.mutations_per_pixel * static_cast<double>(width) * height));
    runner.chains = settings.chains > 0 ? settings.chains
                                        : static_cast<int>(std::clamp<std::uint64_t>(
                                              runner.mutations / mutations_per_chain,
                                              static_cast<std::uint64_t>(min_chains), 4096));
    runner.bootstrap_samples = static_cast<std::uint64_t>(settings.bootstrap_samples);
    if (time_budget_s > 0.0) {
        runner.mutations = 0;  // the time alone decides
        runner.time_budget_s = time_budget_s;
    }
    runner.seed = settings.seed;
    runner.kelemen_weights = settings.kelemen_weights;
    return runner;
}

void validate_chain_settings(const MarkovChainSettings& s, const FileLoc& loc) {
    if (!(s.mutation.p_large >= 0.0 && s.mutation.p_large <= 1.0))
        throw InputError(loc, "p_large must lie in [0, 1]");
    if (!(s.mutation.s1 > 0.0 && s.mutation.s1 < s.mutation.s2 && s.mutation.s2 < 1.0))
        throw InputError(loc, "mutation sizes must satisfy 0 < s1 < s2 < 1");
    if (!(s.mutation.image_s2_pixels >= 0.0 && std::isfinite(s.mutation.image_s2_pixels)))
        throw InputError(loc, "image_mutation_size must be finite and not negative");
    if (s.chains < 0) throw InputError(loc, "chains must not be negative");
    if (s.bootstrap_samples < 1) throw InputError(loc, "bootstrap_samples must be positive");
    // The upper bound keeps mutations_per_pixel x pixels far inside 64 bits at any image
    // size an int allows (1e30 used to overflow into a render that never ended); at a few
    // million mutations per second, 1e9 per pixel is decades for a single pixel anyway.
    if (!(s.mutations_per_pixel > 0.0 && s.mutations_per_pixel <= 1e9))
        throw InputError(loc, "mutations_per_pixel must be positive and at most 1e9");
}

}  // namespace gdmlt::mlt
