// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Weighted image-space control variates (Rousselle, Jarosz, Novak 2016, "Image-space Control
// Variates for Rendering", TOG 35(6) 169): every neighbour j of pixel i gives a control-variate
// estimate x_j + g_{j->i} of x_i; the pixel's own estimate and these are combined with
// inverse-variance weights and iterated (Rousselle et al. 2016, sec. 4):
//     x_i^{k+1} = (w_i x_i^k + sum_j w_ij (x_j^k + g_{j->i})) / (w_i + sum_j w_ij)
//     w_i  = 1 / (eps + Var(p_i) v_k),  w_ij = e_ij / (eps + Var(p_j) v_k + Var(g_ij))
//     v_k  = 1 / prod_{m=0..k} (1.01 + 4 * 0.5^m)    (how fast the iterate's variance shrinks)
// Without variances every weight is 1 ("uniform" CV: early-stopped Jacobi on the Poisson
// problem, the iteration count acting as regulariser).
#include "reconstruct/reconstruct_config.h"
#include "reconstruct/reconstruct_input.h"
#include "reconstruct/reconstruct_result.h"

namespace gdmlt::reconstruct {

/// Uses cv_iterations, cv_epsilon, cv_use_variance, block_size; input.primal_variance and the
/// graph's per-edge variances when present.
ReconstructResult solve_cv(const ReconstructInput& input, const ReconstructConfig& config);

}  // namespace gdmlt::reconstruct
