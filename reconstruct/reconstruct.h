// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// One entry point for the CLI and the integrators: pick the method from the config.
#include "reconstruct/control_variates.h"
#include "reconstruct/poisson_l1.h"
#include "reconstruct/poisson_l2.h"

namespace gdmlt::reconstruct {

/// Dispatches on config.method to solve_l2 / solve_l1 / solve_cv.
ReconstructResult reconstruct(const ReconstructInput& input, const ReconstructConfig& config);

}  // namespace gdmlt::reconstruct
