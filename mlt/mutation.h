// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Primary-sample-space mutations (Kelemen, Szirmay-Kalos, Antal, Csonka 2002, sec. 4).
#include <cmath>

namespace gdmlt::mlt {

struct MutationSettings {
    /// Probability of a large step (every coordinate redrawn uniformly); Kelemen's and
    /// Mitsuba's default.
    double p_large = 0.3;
    /// Kelemen small step: the perturbation's magnitude is log-uniform in [s1, s2].
    double s1 = 1.0 / 1024.0;
    double s2 = 1.0 / 64.0;
    /// Optional separate s2 for the two image-plane coordinates, in pixels (0: use s2 for
    /// them too). s1 scales with it, keeping s2/s1.
    double image_s2_pixels = 0.0;
};

/// Kelemen's exponential perturbation of one coordinate: offset = s2 * exp(-ln(s2/s1) * u),
/// i.e. ln(offset) uniform on [ln s1, ln s2], added or subtracted with probability 1/2, wrapped
/// onto [0, 1). Wrapping is a translation on the torus, so the proposal is exactly symmetric:
/// T(x -> y) = T(y -> x); do not clamp instead.
/// `log_s2_over_s1` = ln(s2 / s1), precomputed by the caller (this runs per coordinate per
/// missed iteration, the hottest loop of the chain).
inline double kelemen_small_step(double value, double s2, double log_s2_over_s1, double u_magnitude,
                                 double u_sign) {
    const double offset = s2 * std::exp(-log_s2_over_s1 * u_magnitude);
    double v = u_sign < 0.5 ? value + offset : value - offset;
    v -= std::floor(v);
    // floor() can leave exactly 1.0 for tiny negative v; [0, 1) is required.
    return v < 1.0 ? v : 0.0;
}

}  // namespace gdmlt::mlt
