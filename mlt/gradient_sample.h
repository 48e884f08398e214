// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// One base path and its shifts to a pixel's neighbours: the estimator both gradient-domain
// integrators share (GDPT draws base paths per pixel, GDMLT from its Markov chain).
//
// For a base path x through pixel i and a neighbour j = i + d, the shift T gives an offset path
// through j, and the difference I(j) - I(i) is estimated from both ends of the pair with MIS
// weights that sum to one over the two directions (Lehtinen et al. 2013, sec. 4; Kettunen et al.
// 2015, sec. 4.2):
//     D_{i->j}(x) = w_{i->j}(x) [ f(T x) |T'(x)| - f(x) ] / p(x),
// w from the sampler's pdfs of base and offset (never from a chain's target, which would be
// circular). I(j) - I(i) = E_i[D_{i->j}] - E_j[D_{j->i}].
//
// "Very direct" light, an emitter or the environment seen directly from the camera, is never
// shifted (G-PT and G-BDPT do the same): its edges are sharp and its differences would put halos
// around every light. It is returned separately and added to the image after reconstruction.
#include <span>

#include "core/image/neighbour_set.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"
#include "manifold/shift.h"

namespace gdmlt::mlt {

/// Paths are not Russian-rouletted (a shift needs the whole base path): an unbounded
/// max_depth becomes this many segments.
inline constexpr int kUnboundedDepthCap = 64;

struct GradientSample {
    /// The path tracer's estimate of the pixel (NEE and BSDF sampling, MIS) without very direct
    /// light.
    Rgb primal = Rgb::Zero();
    /// Emitters and environment seen directly from the camera.
    Rgb very_direct = Rgb::Zero();
};

/// The two halves of one link's difference D = offset - base: the base path's terms and the
/// offset path's (Jacobian included), each times the same MIS weight over both shift
/// directions (and both techniques, BSDF sampling and NEE). `base` is also pixel i's share of
/// its primal for this pair (the pair's weights for a path through i sum to one over "based in
/// i" and "shifted from j"), and `offset` is pixel j's share estimated from i: G-PT's "MIS
/// between pixels" primal, (1 / n_i) sum over i's n_i links of both (Kettunen et al. 2015).
struct LinkEstimate {
    Rgb base = Rgb::Zero();
    Rgb offset = Rgb::Zero();
    Rgb difference() const { return offset - base; }
};

/// Samples a base path through `film_position` (full-film raster coordinates) and, for every
/// link of its pixel, the MIS-weighted estimates towards the link's neighbour, written to
/// `estimates[k]` (same length as `links`).
GradientSample sample_gradients(const Scene& scene, const Vec2f& film_position,
                                SampleStream& stream, const PathSamplerSettings& path,
                                manifold::ShiftKind shift, std::span<const NeighbourLink> links,
                                std::span<LinkEstimate> estimates, PathCounters& counters,
                                manifold::ShiftCounters& shift_counters);

}  // namespace gdmlt::mlt
