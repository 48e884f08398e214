// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The chain runner: everything a primary-sample-space Metropolis integrator does apart from
// evaluating a state. PSSMLT and GDMLT are ChainTargets; the
// runner owns the bootstrap (normalisation b and start states proportional to the target,
// Kelemen et al. 2002, sec. 5), the chains in deterministic rounds, the time budget and Ctrl-C,
// Kelemen's or Veach's splat weights, and per-chain statistics. Tungsten's Kelemen tracer with
// its splat queue is the model: a chain state hands over a target value and a short list of
// splat records, and the records of a round are merged in chain order, so the result is
// bit-identical whatever the thread count.
//
// Estimator. The chain's stationary density over primary sample space U = [0,1)^n is
// f(u) / b with b = integral of f over U. For any contribution g with g != 0 only where f > 0,
//     integral of g du = E_chain[ g(u) b / f(u) ],
// so each slot's accumulated splats divided by the number of mutations N estimate the integral
// of that slot's g. Integrators turn that into pixel values (PSSMLT: times the pixel count).
// b is only known from samples: the chains run with the bootstrap's, and the chain part of the
// estimate (linear in b) is rescaled at the end to b from the bootstrap and all large steps.
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/camera/camera.h"
#include "core/math/types.h"
#include "core/path/path_sampler.h"
#include "core/sampling/sample_stream.h"
#include "manifold/shift.h"
#include "mlt/mutation.h"

namespace gdmlt::mlt {

/// One contribution of a state: `value` (RGB) into slot `slot` of the accumulation buffer.
struct Splat {
    std::uint32_t slot = 0;
    Rgb value = Rgb::Zero();
};

/// A state's evaluation, filled by ChainTarget::evaluate.
struct ChainState {
    /// The chain's unnormalised target f(u) >= 0. It must be > 0 wherever a splat is non-zero.
    double target = 0.0;
    /// The state's value was not finite: dropped (target 0, no splats) and counted.
    bool nonfinite = false;
    /// Where the state lies for the sample-density layer (a pixel index), or -1.
    std::int32_t density_slot = -1;
    std::vector<Splat> splats;

    void clear() {
        target = 0.0;
        nonfinite = false;
        density_slot = -1;
        splats.clear();
    }
};

/// Where a state's first two primary samples put it on the film (the convention of every
/// ChainTarget): the crop-window pixel and its index y * crop_width + x, and the full-film raster
/// position a camera ray goes through.
struct FilmSample {
    int x = 0, y = 0;
    std::size_t pixel = 0;
    Vec2f film_position = Vec2f::Zero();
};
inline FilmSample film_sample(const Film& film, SampleStream& stream) {
    const Vec2f u = stream.next_2d();
    const float fx = u.x() * static_cast<float>(film.crop_width);
    const float fy = u.y() * static_cast<float>(film.crop_height);
    FilmSample s;
    s.x = std::min(static_cast<int>(fx), film.crop_width - 1);
    s.y = std::min(static_cast<int>(fy), film.crop_height - 1);
    s.pixel = static_cast<std::size_t>(s.y) * static_cast<std::size_t>(film.crop_width) +
              static_cast<std::size_t>(s.x);
    s.film_position = Vec2f(static_cast<float>(film.crop_offset_x) + fx,
                            static_cast<float>(film.crop_offset_y) + fy);
    return s;
}

/// Work counters a target's evaluations add to.
struct ChainCounters {
    PathCounters paths;
    manifold::ShiftCounters shifts;
    ChainCounters& operator+=(const ChainCounters& o) {
        paths += o.paths;
        shifts += o.shifts;
        return *this;
    }
};

/// What PSSMLT, GDMLT (and later bidirectional variants) differ in: how a state is evaluated.
class ChainTarget {
  public:
    virtual ~ChainTarget() = default;
    /// Number of RGB slots of the accumulation buffer.
    virtual std::size_t slot_count() const = 0;
    /// Number of density slots (pixels), 0 for none.
    virtual std::size_t density_slot_count() const { return 0; }
    /// Evaluates the state the primary samples of `stream` describe (the first two are the film
    /// position over the crop window, by convention). Must be a deterministic function of the
    /// samples it reads: chains start by replaying bootstrap samples. `state` arrives cleared.
    virtual void evaluate(SampleStream& stream, ChainState& state,
                          ChainCounters& counters) const = 0;
};

struct ChainRunnerSettings {
    MutationSettings mutation;
    /// Film size in pixels (crop window), for MutationSettings::image_s2_pixels.
    int image_width = 1, image_height = 1;
    int chains = 16;
    /// Independent samples estimating b; raised to 10 x chains.
    std::uint64_t bootstrap_samples = 100000;
    /// > 0: the bootstrap grows (in steps of its initial size, up to 16x, and with a time budget
    /// to at most bootstrap_time_fraction of it) until b's standard error is at most this
    /// fraction of b.
    double bootstrap_relative_error = 0.0;
    /// Measured on cbox_glass_sphere at 16 s: a GDMLT bootstrap grown for 5 s (a third of the
    /// budget) left the chains too little time; b's error costs far less relMSE than that.
    double bootstrap_time_fraction = 0.1;
    std::uint64_t mutations = 0;  // total over all chains (an upper bound with a time budget)
    double time_budget_s = 0.0;   // 0: none; else the whole run, bootstrap included
    std::uint64_t seed = 0;
    /// Kelemen's MIS of large steps with the chain (Kelemen et al. 2002, sec. 5; unbiased with
    /// p_large > 0); false: Veach's expected values only (Veach 1997, sec. 11.5).
    bool kelemen_weights = true;
    /// Estimate each slot's variance by batch means (ChainRunnerOutput::variance).
    bool batch_variance = false;
};

struct ChainStats {
    // Normalisation b = E_u[f(u)] over uniform primary samples: the final estimate, from the
    // bootstrap's samples and every large step's, which the estimate is scaled to.
    double b = 0.0;
    double b_standard_error = 0.0;
    std::uint64_t b_samples = 0;
    // The bootstrap's alone, which the chains' MIS weights used.
    double b_bootstrap = 0.0;
    double b_bootstrap_standard_error = 0.0;
    std::uint64_t bootstrap_samples = 0;
    std::uint64_t bootstrap_nonzero = 0;
    // An independent estimate of the same quantity, as a check of b (reported, not used).
    double b_independent = 0.0;
    double b_independent_standard_error = 0.0;

    int chains = 0;
    std::uint64_t mutations = 0;
    std::uint64_t large_proposed = 0, large_accepted = 0;
    std::uint64_t small_proposed = 0, small_accepted = 0;
    std::uint64_t longest_rejection_streak = 0;     // over all chains
    double median_longest_rejection_streak = 0.0;   // median over chains of each one's longest
    double chain_brightness_mean = 0.0;             // mean over chains of each chain's mean f
    double chain_brightness_relative_spread = 0.0;  // their standard deviation / mean
    std::uint64_t nonfinite_dropped = 0;
    std::uint64_t replay_mismatches = 0;  // chain start != bootstrap value (non-determinism)
    PathCounters counters;
    manifold::ShiftCounters shifts;
    double bootstrap_s = 0.0, chains_s = 0.0, total_s = 0.0;
    bool interrupted = false;
    /// Stopped before any chain ran: the estimate is the mean of the bootstrap's samples.
    bool bootstrap_estimate = false;
};

struct ChainRunnerOutput {
    /// Per slot: the integral over primary sample space of that slot's contributions.
    std::vector<RgbD> estimate;
    /// With ChainRunnerSettings::batch_variance, per slot: the variance of `estimate`, the mean
    /// over the three channels, by batch means (Geyer 1992; Jones et al. 2006): a batch is one
    /// chain's splats in one round. Chains are independent and a round is a few hundred
    /// mutations per chain, far longer than a chain's correlation with p_large 0.7, so batches
    /// are treated as independent: Var(S) = sum_b (x_b - n_b S)^2 / N^2 * B / (B - 1) for the
    /// estimate S = sum_b x_b / N of N mutations in B batches of n_b. +inf where fewer than two
    /// batches splatted into the slot (nothing is known of its noise). The final rescaling to
    /// b (run_chains) is one factor for the whole image and not included: b's own error is
    /// ChainStats::b_standard_error. Empty without batch_variance or before any chain ran.
    std::vector<double> variance;
    /// Per density slot: the fraction of chain states that lay there (sums to 1).
    std::vector<double> density;
    /// Per chain: the density slot of its final state (-1: none). Chains are independent, so
    /// these are independent draws from the chain's distribution after its last mutation.
    std::vector<std::int32_t> final_density_slots;
    ChainStats stats;
};

/// Runs the chains. `cancel` is polled every few hundred mutations and between bootstrap batches;
/// `progress` gets the fraction done and the elapsed time after every round (and fraction 0
/// after every bootstrap batch). With a mutation budget (no time budget) the result depends only
/// on the settings, never on the thread count.
ChainRunnerOutput run_chains(
    const ChainTarget& target, const ChainRunnerSettings& settings,
    const std::atomic<bool>* cancel = nullptr,
    const std::function<void(double fraction, double elapsed_s)>& progress = {});

}  // namespace gdmlt::mlt
