// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// L2 screened Poisson reconstruction on a pixel graph (Lehtinen et al. 2013, section 4;
// Kettunen et al. 2015, eq. 10 for the screened form):
//     min_x  sum_e w_e |x_to - x_from - g_e|^2 + alpha^2 sum_i |x_i - p_i|^2
// solved matrix-free by Jacobi-preconditioned conjugate gradient in double precision on the
// normal equations (alpha^2 M + D^T W D) x = alpha^2 M p + D^T W g (M masks missing primals),
// warm-started from the primal, stopped by relative residual.
#include "reconstruct/reconstruct_config.h"
#include "reconstruct/reconstruct_input.h"
#include "reconstruct/reconstruct_result.h"

namespace gdmlt::reconstruct {

/// Uses alpha, warm_start, cg_max_iterations, cg_tolerance, block_size.
/// Throws std::invalid_argument for a bad graph (edge index out of range, sizes) or alpha.
ReconstructResult solve_l2(const ReconstructInput& input, const ReconstructConfig& config);

}  // namespace gdmlt::reconstruct
