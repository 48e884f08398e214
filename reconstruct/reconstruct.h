// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// One entry point for the CLI and the integrators: pick the method from the config.
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
