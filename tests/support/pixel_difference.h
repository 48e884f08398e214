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

/// The path tracer's luminance of pixel (x, y). Streams (seed, x, iteration).
MeanEstimate path_traced_pixel(const Scene& scene, const PathSamplerSettings& settings, int x,
                               int y, int samples, std::uint64_t seed);

}  // namespace gdmlt::test
