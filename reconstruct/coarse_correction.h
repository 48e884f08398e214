// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Energy-keeping reconstruction: give back to a solved image the primal's coarse scales.
//
// A robust (L1) screened Poisson solve discards heavy-tailed outliers of the differences and
// of the primal. Both are unbiased estimates, so what it discards is energy: on scenes with
// caustics the L1 image kept 59-73% of the light (GDPT and GDMLT at 16 s on
// caustic_glass_light). The primal p is unbiased per pixel, and so is any fixed low-pass of
// it; the correction
//     x' = x + B (p - x)
// keeps the solve's high frequencies and takes the low ones from the primal, whose noise a
// wide low-pass averages away. With B symmetric and row-stochastic (so also column-
// stochastic), sum(x') = sum(p): the image's energy is exactly the primal's. (The coarse-scale
// "mean-preserving correction" of issue 11; Manzi et al. 2016 regularise towards features
// instead, which needs feature layers.)
#include "core/image/image.h"

namespace gdmlt::reconstruct {

/// B: three passes of a (2 r + 1)-wide box filter per axis with mirrored borders (the edge
/// pixel repeated), an approximate Gaussian of standard deviation r. Per channel; a radius of 0
/// is the identity; radii beyond the image are clamped to it.
void box_blur3(Image& image, int radius);

/// x' = x + B_radius(p - x) for an RGB image x and its RGB primal p (same size). Pixels whose
/// primal is not finite take no part (their difference counts as 0).
void restore_coarse_scales(Image& image, const Image& primal, int radius);

}  // namespace gdmlt::reconstruct
