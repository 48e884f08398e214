// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// L1 screened Poisson reconstruction (Lehtinen et al. 2013 use L1 for their results; Kettunen et
// al. 2015 eq. 11):
//     min_x  sum_e w_e |(Dx - g)_e|_2 + alpha sum_i |x_i - p_i|_2      (RGB 2-norm per row)
// by iteratively reweighted least squares around the L2 solver, following the schedule of the
// NVIDIA solver shipped with the G-PT code (Kettunen et al. 2015): iteration 0 is the plain L2
// solve, iteration k >= 1 reweights every residual row by 1 / (|e_r| + rho_k),
// rho_k = rho0 * gamma^(k-1), weights rescaled to mean 1, and warm-starts CG from the previous x.
// Robust to outlier differences: an outlier edge's weight falls as 1/|residual|, so it pulls
// with a bounded force instead of spreading a dipole as L2 does.
#include "reconstruct/reconstruct_config.h"
#include "reconstruct/reconstruct_input.h"
#include "reconstruct/reconstruct_result.h"

namespace gdmlt::reconstruct {

/// Uses alpha, warm_start, irls_* (also for the initial L2 solve), l1_objective_tolerance,
/// block_size.
ReconstructResult solve_l1(const ReconstructInput& input, const ReconstructConfig& config);

}  // namespace gdmlt::reconstruct
