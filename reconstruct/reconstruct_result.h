// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// What every reconstruction returns: the image and how it got there.
#include <cstdint>
#include <vector>

#include "core/image/image.h"

namespace gdmlt::reconstruct {

struct ReconstructStats {
    /// Edges dropped because a difference or the weight was not finite (never propagated).
    std::int64_t dropped_nonfinite_edges = 0;
    /// Edges dropped because the weight was negative (would make the system indefinite).
    std::int64_t dropped_negative_weight_edges = 0;
    /// Edges with zero weight or from == to: no information, ignored (not an error).
    std::int64_t ignored_edges = 0;
    /// Pixels whose primal was not finite: no screening term there, solved from neighbours only.
    std::int64_t missing_primal_pixels = 0;

    /// L2: CG iterations. L1: IRLS outer iterations done (including the initial L2 solve).
    /// CV: iterations done.
    int iterations = 0;
    /// Total CG iterations over all solves (L2, L1).
    int cg_iterations = 0;
    /// Max over channels of |r|/|b| at the end of the (last) CG solve.
    double final_relative_residual = 0.0;
    bool converged = false;
    /// L1 objective sum_i alpha |x_i - p_i| + sum_e w_e |(Dx - g)_e| (RGB 2-norms) after each
    /// IRLS outer iteration (index 0 = the initial L2 solution).
    std::vector<double> l1_objective;
    /// CG iterations of each IRLS outer iteration.
    std::vector<int> cg_iterations_per_outer;

    double seconds_setup = 0.0;  // graph compilation, right-hand side, preconditioner
    double seconds_solve = 0.0;  // CG / IRLS / CV iterations
    double seconds_total = 0.0;
};

struct ReconstructResult {
    Image image;  // RGB, same size as the primal
    ReconstructStats stats;
};

}  // namespace gdmlt::reconstruct
