// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Estimates for checking the gradient estimator's unbiasedness on one pair of horizontally
// neighbouring pixels: GDPT's difference against two path-traced pixel values.
#include "core/path/path.h"
#include "core/scene/scene.h"
#include "manifold/shift.h"
#include "mlt/gdpt.h"
#include "mlt/gradient_sample.h"

namespace gdmlt::test {

struct MeanEstimate {
    double mean = 0.0;
    double standard_error = 0.0;
};

/// A camera path (max_depth 8) through a random film position at least one pixel from the
/// border, so that shifts to every neighbour stay on the film. Stream `key`.
Path sample_interior_camera_path(const Scene& scene, std::uint64_t key, PathCounters& counters);

/// GDPT's estimate of luminance I((xi, y) + offset) - I(xi, y): per iteration one base sample
/// in each pixel (a shift by +offset from (xi, y), by -offset from the other end, as GDPT
/// combines them). Streams (seed, side, iteration).
MeanEstimate gdpt_pixel_difference(const Scene& scene, const mlt::GdptSettings& settings, int xi,
                                   int y, int samples, std::uint64_t seed,
                                   manifold::ShiftCounters& shifts,
                                   const Vec2i& offset = Vec2i(1, 0));

/// Bidirectional GDMLT's estimator (mlt::sample_bidirectional_gradients, max_depth 8) of
/// luminance I_b((xi, y) + offset) - I_b(xi, y), combined from both ends as in
/// gdpt_pixel_difference; I_b is the image of its camera strategies (t >= 2, paths of >= 2
/// segments). Also the mean of its primal (I_b) at each end. Streams (seed, side, iteration).
struct BidirectionalDifference {
    MeanEstimate difference, primal_here, primal_there;
};
BidirectionalDifference bidirectional_pixel_difference(const Scene& scene,
                                                       manifold::ShiftKind shift, int xi, int y,
                                                       int samples, std::uint64_t seed,
                                                       manifold::ShiftCounters& shifts,
                                                       const Vec2i& offset = Vec2i(1, 0));

/// BDPT's (sample_bdpt, max_depth 8, no roulette) estimate of I_b at pixel (x, y): its camera
/// strategies without very direct light. Streams (seed, x, iteration).
MeanEstimate bdpt_camera_strategies_pixel(const Scene& scene, int x, int y, int samples,
                                          std::uint64_t seed);

/// The path tracer's luminance of pixel (x, y). Streams (seed, x, iteration).
MeanEstimate path_traced_pixel(const Scene& scene, const PathSamplerSettings& settings, int x,
                               int y, int samples, std::uint64_t seed);

}  // namespace gdmlt::test
