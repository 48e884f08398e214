// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Gradient-domain path tracing (Kettunen, Manzi, Aittala, Lehtinen, Durand, Zwicker 2015): per
// sample a base path and four offsets to the neighbouring pixels; the primal image and the
// lattice differences are estimated with MIS between the two directions of each shift, then
// reconstructed (reconstruct/). The oracle the GDMLT chain is checked against.
#include <atomic>
#include <functional>

#include "core/image/gradient_buffers.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"
#include "manifold/shift.h"

namespace gdmlt::mlt {

struct GdptSettings {
    int spp = 16;
    double time_budget_s = 0.0;
    std::uint64_t seed = 0;
    PathSamplerSettings path;  // max_depth -1 is capped at kUnboundedDepthCap
    manifold::ShiftKind shift = manifold::ShiftKind::Auto;
};

/// Paths are not Russian-rouletted (a shift needs the whole base path): an unbounded
/// max_depth becomes this many segments.
inline constexpr int kUnboundedDepthCap = 64;

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
    GradientBuffers buffers;  // primal, dx, dy, sample_count
    GdptStats stats;
};

GdptOutput render_gdpt(const Scene& scene, const GdptSettings& settings,
                       const std::atomic<bool>* cancel = nullptr,
                       const std::function<void(double fraction, double elapsed_s)>& progress = {});

/// One base sample's estimates, as GDMLT's target function also needs them: the primal
/// contribution and the difference to each neighbour (+x, -x, +y, -y), each already weighted
/// by the MIS between the two shift directions.
struct GradientSample {
    Rgb primal = Rgb::Zero();
    std::array<Rgb, 4> difference{Rgb::Zero(), Rgb::Zero(), Rgb::Zero(), Rgb::Zero()};
    std::array<bool, 4> used{false, false, false, false};
};
inline const std::array<Vec2f, 4> kNeighbourOffsets = {Vec2f(1.f, 0.f), Vec2f(-1.f, 0.f),
                                                       Vec2f(0.f, 1.f), Vec2f(0.f, -1.f)};

/// Samples a base path through `film_position` and shifts it to the neighbours for which
/// `neighbour_inside[i]` is true.
GradientSample sample_gradients(const Scene& scene, const Vec2f& film_position,
                                SampleStream& stream, const GdptSettings& settings,
                                const std::array<bool, 4>& neighbour_inside, PathCounters& counters,
                                manifold::ShiftCounters& shift_counters);

}  // namespace gdmlt::mlt
