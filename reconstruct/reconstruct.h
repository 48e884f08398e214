// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// One entry point for the CLI and the integrators: pick the method from the config.
//
// What each method does with variances (GradientBuffers' primal_variance, dx_variance,
// dy_variance, extra_variances, which GDPT and GDMLT fill, else 1 / sample_count for the primal):
//   l2  ignores them: every edge has its graph weight (1 from buffers) and every primal alpha^2,
//       the unweighted screened Poisson problem of Lehtinen et al. 2013 / Kettunen et al. 2015.
//   l1  ignores them too: IRLS weights come from the residuals of the previous iterate, which
//       already downweights outlying differences and primals whatever their variance.
//   cv  (Rousselle et al. 2016) weights the pixel's own estimate by 1 / (eps + Var(p_i) v_k)
//       and each neighbour's control-variate estimate x_j + g_ji by
//       1 / (eps + Var(p_j) v_k + Var(g_ji)). With only sample counts, Var(p) = 1 / n and every
//       Var(g) = 0 (the differences count as exact); with the variance layers both are the
//       render's estimates. cv_use_variance = false makes all weights 1.
// The coarse-scale correction (coarse_correction.h) after any method uses none of them.
#include "reconstruct/control_variates.h"
#include "reconstruct/poisson_l1.h"
#include "reconstruct/poisson_l2.h"
#include "reconstruct/reconstruct_input.h"

namespace gdmlt::reconstruct {

/// Dispatches on config.method to solve_l2 / solve_l1 / solve_cv.
ReconstructResult reconstruct(const ReconstructInput& input, const ReconstructConfig& config);

/// The final image of a gradient-domain render: the solve of make_reconstruct_input(buffers),
/// plus buffers.very_direct when present (light seen directly from the camera is never part of
/// the gradients, G-PT's BUFFER_VERY_DIRECT). Throws std::invalid_argument on inconsistent
/// sizes.
ReconstructResult reconstruct_buffers(const GradientBuffers& buffers,
                                      const ReconstructConfig& config);

}  // namespace gdmlt::reconstruct
