// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Independent estimates of the same gradient-domain quantities (a primal per pixel and a
// difference per edge; e.g. GDMLT's chains and a GDPT pass over the same scene, neighbours and
// very-direct split) combined slot by slot with inverse-variance weights, the minimum-variance
// linear combination of independent unbiased estimates.
//
// Weights from a slot's own variance estimate would be correlated with its own value (a bright
// outlier comes with a large sample variance, is down-weighted, and the image darkens: the bias
// of inverse-variance weighting with estimated variances). Here each part's weight at a slot
// comes from its variance averaged over the (2r+1)^2 window around the slot *without the slot
// itself* (leave-one-out), so the weight does not depend on the slot's own samples, and a
// pixel a chain never visited (variance +inf, value 0) gets the weight its surroundings earn.
// Neighbouring slots of a chain are correlated, so the weights are not exactly independent of
// the value; the test of the combination measures what is left.
#include <span>
#include <vector>

#include "core/image/gradient_buffers.h"

namespace gdmlt {

/// Per pixel of a 1-channel image, the mean of its finite values over the (2r+1)^2 window
/// around the pixel, the pixel itself left out; +inf where the window holds no finite value.
/// The smoothed variance combine_by_inverse_variance weighs by.
std::vector<double> leave_one_out_window_mean(const Image& image, int radius);

/// Whether `buffers` has the variance layers combine_by_inverse_variance needs: a primal
/// variance, one for each lattice layer it holds, one per extra edge.
bool has_variance_layers(const GradientBuffers& buffers);

/// What combine_by_inverse_variance did, for the stats.
struct CombineSummary {
    /// Per part, its mean weight over the primal's pixels and over the lattice edges.
    std::vector<double> primal_weight, difference_weight;
};

/// Combines `parts` (at least one; all of one size, with primal_variance and, for each lattice
/// layer they hold, its variance layer, and the same extra edges with extra_variances) into one
/// GradientBuffers: value sum_k w_k x_k, variance sum_k w_k^2 V_k (+inf where a part with
/// weight > 0 has +inf). Extra (non-lattice) edges take the weights of their `from` pixel's
/// primal. `very_direct`, `sample_count` and `features` are not combined: the result has the
/// first part's very_direct and features and no sample_count. Throws std::invalid_argument on
/// parts that do not match. `summary`, when given, receives the mean weights.
GradientBuffers combine_by_inverse_variance(std::span<const GradientBuffers* const> parts,
                                            int radius, CombineSummary* summary = nullptr);

}  // namespace gdmlt
