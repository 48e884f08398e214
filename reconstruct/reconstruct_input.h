// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The input of every reconstruction, and how to get it from core's GradientBuffers.
#include "core/image/gradient_buffers.h"
#include "core/image/image.h"
#include "reconstruct/pixel_graph.h"

namespace gdmlt::reconstruct {

struct ReconstructInput {
    PixelGraph graph;
    /// RGB primal, graph.width x graph.height. Non-finite pixels are missing (no data term).
    Image primal;
    /// Optional 1-channel per-pixel variance of the primal (empty = unknown). Used by the
    /// weighted control variates.
    Image primal_variance;
};

/// Lattice edges from dx/dy (last column/row ignored), then the extra edges, with variances
/// when the buffers have them. Primal variance: `primal_variance` (channel mean), else
/// 1/sample_count (infinite where the count is 0), else empty. Throws std::invalid_argument
/// on inconsistent sizes.
ReconstructInput make_reconstruct_input(const GradientBuffers& buffers);

}  // namespace gdmlt::reconstruct
