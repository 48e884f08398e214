// SPDX-License-Identifier: GPL-3.0-or-later
#include "mlt/primary_sample_vector.h"

#include <algorithm>
#include <cmath>

namespace gdmlt::mlt {

namespace {
constexpr std::int64_t kExactCatchUp = 8;
}  // namespace

PrimarySampleVector::PrimarySampleVector(const MutationSettings& settings, Pcg32 rng,
                                         int image_width, int image_height)
    : settings_(settings), rng_(rng), log_s2_over_s1_(std::log(settings.s2 / settings.s1)) {
    // Room for a path of four bounces (2 + 4 x 7 coordinates) at once: the bootstrap builds a
    // fresh vector per sample, and growing one coordinate at a time cost five or six
    // allocations each. 32 coordinates are 1 KiB, which glibc still serves from its per-thread
    // cache (64 cost four times as many instructions per allocation).
    samples_.reserve(32);
    const int size[2] = {image_width, image_height};
    for (int k = 0; k < 2; ++k) {
        // The image coordinates keep the ratio s2/s1 and rescale s2 to the given pixel count.
        image_s2_[k] = settings.image_s2_pixels > 0.0
                           ? std::min(settings.image_s2_pixels / std::max(size[k], 1), 0.5)
                           : settings.s2;
    }
}

void PrimarySampleVector::start_iteration(bool large_step) {
    ++iteration_;
    large_step_ = large_step;
    next_index_ = 0;
}

void PrimarySampleVector::accept() {
    if (large_step_) last_large_step_ = iteration_;
}

void PrimarySampleVector::reject() {
    for (Coordinate& c : samples_) {
        if (c.modified == iteration_) {
            c.value = c.value_backup;
            c.modified = c.modified_backup;
        }
    }
    // The iteration did not happen: coordinates not read in it stay exactly as stale as before.
    --iteration_;
}

void PrimarySampleVector::ensure_ready(std::size_t index) {
    if (index >= samples_.size()) samples_.resize(index + 1);
    Coordinate& c = samples_[index];
    // A large step accepted since this coordinate was last read owns it: its value then was a
    // fresh uniform number, drawn now (lazily) as if drawn then.
    if (c.modified < last_large_step_) {
        c.value = rng_.next_double();
        c.modified = last_large_step_;
    }
    c.value_backup = c.value;
    c.modified_backup = c.modified;
    if (large_step_) {
        c.value = rng_.next_double();
    } else {
        // Catch up on the small steps this coordinate missed (counted in accepted iterations
        // only: a rejected proposal's unread coordinates never mattered). Up to
        // kExactCatchUp missed steps are applied one by one; beyond that, one step of the
        // same shape with both sizes scaled by sqrt(n), the spread of n steps. Any symmetric
        // kernel keeps detailed balance (the proposal stays T(x->y) = T(y->x) coordinate by
        // coordinate), and this bounds the cost of stale deep coordinates, which otherwise
        // dominate the chain's run time (Kelemen et al. 2002, sec. 4, lazy evaluation).
        const double s2 = index < 2 ? image_s2_[index] : settings_.s2;
        const std::int64_t missed = iteration_ - c.modified;
        if (missed <= kExactCatchUp) {
            for (std::int64_t n = 0; n < missed; ++n) {
                const double u_magnitude = rng_.next_double();
                const double u_sign = rng_.next_double();
                c.value = kelemen_small_step(c.value, s2, log_s2_over_s1_, u_magnitude, u_sign);
            }
        } else {
            const double s2_n = std::min(s2 * std::sqrt(static_cast<double>(missed)), 0.5);
            const double u_magnitude = rng_.next_double();
            const double u_sign = rng_.next_double();
            c.value = kelemen_small_step(c.value, s2_n, log_s2_over_s1_, u_magnitude, u_sign);
        }
    }
    c.modified = iteration_;
}

double PrimarySampleVector::next_double() {
    const std::size_t index = next_index_++;
    ensure_ready(index);
    return samples_[index].value;
}

float PrimarySampleVector::next_1d() {
    // Round down into [0, 1) in float: rounding to nearest could produce 1.0f.
    const auto v = static_cast<float>(next_double());
    return v < 1.f ? v : 0x1.fffffep-1f;
}

std::vector<double> PrimarySampleVector::values() const {
    std::vector<double> v(samples_.size());
    std::transform(samples_.begin(), samples_.end(), v.begin(),
                   [](const Coordinate& c) { return c.value; });
    return v;
}

}  // namespace gdmlt::mlt
