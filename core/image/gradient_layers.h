// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// A gradient-domain render's raw buffers as named EXR layers, and back: what `gdmlt render`
// writes beside the final image and `gdmlt reconstruct` reads, so that re-solving a file offline
// sees exactly the system the render solved (same edges, same order, same values).
//
// Layers: primal, very_direct (RGB); dx, dy (RGB, present only for a complete lattice
// direction, core/image/neighbour_set.h); per non-lattice offset (ox, oy) of the graph a layer
// `edge_<ox>_<oy>` (RGB) whose pixel p holds the difference I(p + o) - I(p) of the edge from p,
// NaN where p has no such edge (offsets with oy > 0, or oy = 0 and ox > 0); the optional
// `primal_variance`, `dx_variance`, `dy_variance`, `edge_<ox>_<oy>_variance` and `sample_count`
// (one channel, Y).
#include <string>
#include <vector>

#include "core/image/gradient_buffers.h"
#include "core/image/image_io.h"

namespace gdmlt {

/// The layers of `buffers` (empty ones left out). Extra edges must be oriented from the smaller
/// pixel index (as store_edge_differences leaves them).
std::vector<ExrLayer> gradient_layers(const GradientBuffers& buffers);

/// Buffers from the layers of a file (`file` names it in errors). Extra edges come back
/// ordered by offset (dy, dx), then by pixel: the order store_edge_differences gives them.
/// Throws InputError when the primal or every difference layer is missing, or for a layer
/// with the wrong channels.
GradientBuffers gradient_buffers_from_layers(const std::vector<ExrLayer>& layers,
                                             const std::string& file);

}  // namespace gdmlt
