// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Gradient-domain path tracing (Kettunen, Manzi, Aittala, Lehtinen, Durand, Zwicker 2015): per
// sample a base path and its shifts to the pixel's neighbours (a NeighbourSet: the lattice by
// default); the primal image and the per-edge differences are estimated with MIS between the two
// shift directions (mlt/gradient_sample.h), then reconstructed (reconstruct/). Very direct light
// goes to its own layer. The oracle the GDMLT chain is checked against.
#include <atomic>
#include <functional>

#include "core/image/gradient_buffers.h"
#include "core/image/neighbour_set.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"
#include "manifold/shift.h"
#include "mlt/gradient_sample.h"

namespace gdmlt::mlt {

struct GdptSettings {
    int spp = 16;
    double time_budget_s = 0.0;
    std::uint64_t seed = 0;
    PathSamplerSettings path;  // max_depth -1 is capped at kUnboundedDepthCap
    manifold::ShiftKind shift = manifold::ShiftKind::Auto;
};

struct GdptStats {
    PathCounters counters;
    manifold::ShiftCounters shifts;
    std::uint64_t samples = 0;
    std::uint64_t nonfinite_dropped = 0;
    int spp_completed = 0;
    double render_s = 0.0;
    bool interrupted = false;
};

struct GdptOutput {
    /// primal, dx, dy (+ extra edges), very_direct, sample_count, and the variances of the
    /// primal's and of every edge's estimate (primal_variance, dx_variance, dy_variance,
    /// extra_variances: 1 channel, the channel mean of the variance of the per-pixel mean /
    /// of the edge's difference; +inf where a pixel has fewer than 2 samples; left empty when
    /// no pixel has 2).
    GradientBuffers buffers;
    GdptStats stats;
};

/// Renders with the lattice neighbours.
GdptOutput render_gdpt(const Scene& scene, const GdptSettings& settings,
                       const std::atomic<bool>* cancel = nullptr,
                       const std::function<void(double fraction, double elapsed_s)>& progress = {});

/// Renders with any neighbour set over the crop window (its size must be the crop's).
GdptOutput render_gdpt(const Scene& scene, const GdptSettings& settings,
                       const NeighbourSet& neighbours, const std::atomic<bool>* cancel = nullptr,
                       const std::function<void(double fraction, double elapsed_s)>& progress = {});

}  // namespace gdmlt::mlt
