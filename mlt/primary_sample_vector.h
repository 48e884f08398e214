// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The Markov chain's state: a lazily extended vector of primary samples in [0,1) (Kelemen et
// al. 2002). It implements core's SampleStream, so the path tracer's path sampler runs on it
// unchanged. Coordinates are mutated only when read ("on demand"): each stores the iteration it
// was last brought up to date in, and catches up on the small steps it missed.
//
// A fresh vector's first iteration should be a large step: it then draws every coordinate it
// reads, in order, from its generator, exactly as an independent sample with the same generator
// would. That is how a chain starts from a bootstrap sample (replaying the same generator).
#include <cstdint>
#include <vector>

#include "core/sampling/rng.h"
#include "core/sampling/sample_stream.h"
#include "mlt/mutation.h"

namespace gdmlt::mlt {

class PrimarySampleVector final : public SampleStream {
  public:
    /// `image_size` (crop width, height) converts MutationSettings::image_s2_pixels for the
    /// first two coordinates, which the integrators use as the film position.
    PrimarySampleVector(const MutationSettings& settings, Pcg32 rng, int image_width = 1,
                        int image_height = 1);

    /// Begins a proposal: a large step redraws every coordinate it reads, a small step perturbs.
    void start_iteration(bool large_step);
    /// The proposal becomes the state.
    void accept();
    /// The proposal is discarded: every coordinate read in this iteration gets its old value.
    void reject();

    float next_1d() override;
    /// Skipped coordinates are not read: they stay as stale as unread ones (on-demand mutation).
    void skip(std::size_t count) override { next_index_ += count; }
    double next_double();

    /// Number of coordinates that exist so far.
    std::size_t size() const { return samples_.size(); }
    /// Current values (for tests and diagnostics).
    std::vector<double> values() const;
    bool large_step() const { return large_step_; }

  private:
    struct Coordinate {
        double value = 0.0;
        std::int64_t modified = 0;  // iteration the value is current for
        double value_backup = 0.0;
        std::int64_t modified_backup = 0;
    };
    void ensure_ready(std::size_t index);

    MutationSettings settings_;
    Pcg32 rng_;
    double image_s2_[2];
    double log_s2_over_s1_;
    std::vector<Coordinate> samples_;
    std::size_t next_index_ = 0;
    std::int64_t iteration_ = 0;
    std::int64_t last_large_step_ = 0;
    bool large_step_ = true;
};

}  // namespace gdmlt::mlt
