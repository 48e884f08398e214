// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The knobs every Markov-chain integrator on the chain runner shares (PSSMLT, GDMLT), how they
// are read from a scene's <integrator> element (Mitsuba 0.6/3 names where they exist) and
// checked.
#include <cstdint>

#include "core/path/path_sampler.h"
#include "core/scene/properties.h"
#include "core/scene/scene.h"
#include "mlt/chain_runner.h"
#include "mlt/mutation.h"

namespace gdmlt::mlt {

struct MarkovChainSettings {
    MutationSettings mutation;
    int chains = 0;                     // 0: chosen from the mutation budget by the integrator
    int bootstrap_samples = 100000;     // independent samples estimating b; raised to 10 x chains
    double mutations_per_pixel = 64.0;  // budget (upper bound when time_budget_s > 0)
    double time_budget_s = 0.0;
    std::uint64_t seed = 0;
    PathSamplerSettings path;
    /// Kelemen's MIS of large steps with the chain (Kelemen et al. 2002, sec. 5; unbiased with
    /// p_large > 0); false: Veach's expected values only.
    bool kelemen_weights = true;
};

/// The path settings of the scene's integrator, then, when `props` reads an element of the
/// integrator's own type, p_large, mutation_size_low, mutation_size_high, image_mutation_size,
/// chains, luminance_samples (Mitsuba 0.6's name) or bootstrap_samples, mutations_per_pixel and
/// kelemen_style_weights. The caller reads its own properties and calls check_all_read().
void read_chain_settings(const IntegratorSettings& integrator, PropertyReader* props,
                         MarkovChainSettings& settings);

/// The chain runner's settings for a crop window of `width` x `height` pixels: a budget of
/// mutations_per_pixel per pixel, or with `time_budget_s` > 0 that time alone; settings.chains,
/// or 0: one chain per `mutations_per_chain` mutations of the budget, at least `min_chains`,
/// at most 4096.
ChainRunnerSettings runner_settings(const MarkovChainSettings& settings, int width, int height,
                                    std::uint64_t mutations_per_chain, int min_chains,
                                    double time_budget_s);

/// Throws InputError (at `loc`) when a shared knob is out of range.
void validate_chain_settings(const MarkovChainSettings& settings, const FileLoc& loc);

}  // namespace gdmlt::mlt
