// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The layers of a gradient-domain render's EXR and GradientBuffers, both ways: one list of
// layer names for the renderer that writes them and for `gdmlt reconstruct`, which must read
// back everything the render's own reconstruction used to re-solve to the same image.
//
// Layers (OpenEXR channel "layer.channel"):
//   primal, dx, dy, very_direct        RGB
//   sample_count                       Y
//   primal_variance, dx_variance,      Y (channel mean) or R, G, B (per channel); variance of
//   dy_variance                        the primal's per-pixel mean and of each lattice edge's
//                                      difference (core/image/gradient_buffers.h)
// Each is written only when the buffers have it. Features have no layer yet.
#include <string>
#include <vector>

#include "core/image/gradient_buffers.h"
#include "core/image/image_io.h"

namespace gdmlt {

/// The layers of `buffers` that are present, in the order above. Throws std::invalid_argument
/// for extra (non-lattice) edges, which have no layer: a file without them would re-solve to
/// another image.
std::vector<ExrLayer> gradient_layers(const GradientBuffers& buffers);

/// The buffers stored in `layers` (as read_exr returns them; other layers are ignored).
/// Throws InputError naming `file` when there is no primal, neither dx nor dy, or a layer
/// lacks its channels (R, G, B; a variance layer must have 1 channel or R, G, B).
GradientBuffers gradient_buffers_from_layers(const std::vector<ExrLayer>& layers,
                                             const std::string& file);

}  // namespace gdmlt
