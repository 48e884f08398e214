// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// GradientBuffers: what a gradient-domain integrator (G-PT, GDMLT) hands to reconstruction.
// Plain data owned by core: integrators in mlt/ fill it, reconstruct/ reads it,
// so neither module needs the other.
//
// Sign convention (the same everywhere in gdmlt): a difference on the edge from pixel a to
// pixel b estimates I(b) - I(a). For the lattice layers that means
//     dx(x, y) ~ I(x + 1, y) - I(x, y)     (last column unused, keep it 0)
//     dy(x, y) ~ I(x, y + 1) - I(x, y)     (last row unused, keep it 0)
// which is the forward-difference operator D of Lehtinen et al. 2013 and of the screened Poisson
// problem (Lehtinen et al. 2013; Kettunen et al. 2015). Pixel (x, y) has index y * width + x.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace gdmlt {

/// An edge beyond the 4-neighbour lattice (ADAP, Manzi et al. 2014): pixel indices y*width+x.
/// Its difference estimates I(to) - I(from).
struct GradientEdge {
    std::int32_t from = -1;
    std::int32_t to = -1;
    bool operator==(const GradientEdge&) const = default;
};

struct GradientBuffers {
    /// Primal (coarse) estimate of the image, RGB. Non-finite pixels are treated as missing.
    Image primal;
    /// Lattice differences, RGB, same size as primal (see the sign convention above). Either may
    /// be empty when the integrator estimates no lattice edges in that direction.
    Image dx;
    Image dy;

    /// Extra edges, e.g. chosen by ADAP; `extra_differences` holds 3 floats (RGB) per edge.
    std::vector<GradientEdge> extra_edges;
    std::vector<float> extra_differences;

    /// Optional variance estimates (empty = unknown). Variance images have 1 channel (luminance
    /// or channel mean) or 3 (per RGB channel; reconstruction uses their mean).
    Image primal_variance;
    Image dx_variance;
    Image dy_variance;
    std::vector<float> extra_variances;  // one per extra edge, or empty

    /// Optional per-pixel sample counts (1 channel). When no primal variance is given,
    /// reconstruction models Var(primal) as proportional to 1 / count.
    Image sample_count;

    /// Optional "very direct" light (emitters seen directly from the camera), RGB: never part of
    /// the gradients, added to the reconstruction's result (G-PT's BUFFER_VERY_DIRECT).
    Image very_direct;

    /// Optional feature layers by name ("albedo", "normal", "depth"), same size as primal.
    std::map<std::string, Image> features;
};

}  // namespace gdmlt
