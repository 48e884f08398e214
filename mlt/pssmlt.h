// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Primary sample space MLT (Kelemen et al. 2002) on the path tracer's path sampler: the
// baseline and correctness oracle for the gradient-domain chain. See also
// Veach 1997, ch. 11 (expected values) and pbrt-v4's MLTIntegrator.
#include <atomic>
#include <cstdint>
#include <functional>

#include "core/image/image.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"
#include "mlt/chain_runner.h"
#include "mlt/chain_settings.h"
#include "mlt/mutation.h"

namespace gdmlt::mlt {

/// Every PSSMLT knob with its default: the shared chain knobs (chains: 0 = one per 16384
/// mutations, at least 16) and its own. Read from the scene's <integrator type="pssmlt">
/// (pssmlt_settings_from_scene) and overridden by the command line.
struct PssmltSettings : MarkovChainSettings {
    /// > 0: emitters seen directly and direct lighting are rendered separately by the path
    /// tracer with this many samples per pixel, and the chains see only longer paths (Mitsuba's
    /// pssmlt `directSamples`). -1 (default): the chains render everything.
    int direct_samples = -1;
    /// Kelemen's PSSMLT over BDPT (as Mitsuba 0.6's pssmlt with its bidirectional sampler):
    /// each state is a camera and a light subpath with every (s, t) strategy, MIS-weighted;
    /// the target is the luminance of all of them together, light tracing splats included.
    bool bidirectional = false;
    /// Multiplexed MLT (Hachisuka et al. 2014; `--integrator mmlt`): each state is one BDPT
    /// strategy, its path length and (s, t) chosen by two more primary samples, MIS-weighted,
    /// so the chains spend their time on the strategies that carry the light. Needs a
    /// max_depth. Here the choice of length is a coordinate like any other (the paper's
    /// formulation), not a chain per length as pbrt-v4 runs it.
    bool multiplexed = false;
};

/// The chain runner's statistics (b, acceptance, streaks, ...) plus the separate direct pass.
struct PssmltStats : ChainStats {
    double direct_s = 0.0;
};

struct PssmltOutput {
    Image image;
    PssmltStats stats;
};

/// Reads the knobs of a <integrator type="pssmlt"> element (Mitsuba 0.6/3 names where they
/// exist: p_large, mutation_size_low, mutation_size_high, luminance_samples, ...; plus
/// chains, bootstrap_samples, mutations_per_pixel, image_mutation_size). Unknown properties
/// throw InputError with the location.
PssmltSettings pssmlt_settings_from_scene(const IntegratorSettings& integrator);

/// Throws InputError (at `loc`) when a knob is out of range.
void validate_pssmlt_settings(const PssmltSettings& settings, const FileLoc& loc);

/// Renders with PSSMLT on the chain runner. `cancel` is polled every few hundred mutations;
/// `progress` gets the fraction done.
PssmltOutput render_pssmlt(
    const Scene& scene, const PssmltSettings& settings, const std::atomic<bool>* cancel = nullptr,
    const std::function<void(double fraction, double elapsed_s)>& progress = {});

}  // namespace gdmlt::mlt
