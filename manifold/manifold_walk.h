// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The manifold walk: move the end of a specular chain to a target while the start stays fixed
// and every interior vertex keeps satisfying its half-vector constraint (Jakob & Marschner 2012,
// sec. 4.3 and sec. 5, "manifold walk"; used by the offset-path construction of Manzi et al.
// 2014, sec. 4, with the light-side vertex pinned).
//
// Each iteration is a Newton predictor and an exact corrector:
//  1. predictor: solve the block-tridiagonal constraint system (constraints.h) for the tangent
//     displacement of x_1 that moves the end by `step` times the remaining distance, linearised;
//  2. corrector ("projection"): trace a ray from the fixed start towards the predicted x_1 and
//     scatter it through the chain (chain_trace.h), which satisfies all constraints exactly and
//     lands the end on the end plane;
//  3. accept when the end came closer (step grows), otherwise reject and halve the step.
// The end moves in a plane through its old position that also contains the target; its normal
// is built symmetrically from the old and new geometric normals (as Mitsuba's manifold
// perturbation does), so a walk back uses the same plane and reversibility checks are possible.
#include <array>

#include "manifold/specular_chain.h"
#include "manifold/walk_failure.h"

namespace gdmlt::manifold {

struct ManifoldConfig {
    /// Projections attempted, accepted or rejected (Mitsuba counts both, with a cap of 20).
    int max_iterations = 20;
    /// Converged when |end - target| <= relative_tolerance * length scale. Double precision
    /// geometry reaches about 1e-13; 1e-9 costs one Newton step more than 1e-6 (see the benchmark).
    double relative_tolerance = 1e-9;
    /// The length the tolerance refers to; 0 means the chain's length (sum of segment lengths,
    /// scale invariant). Callers that compare walks across a scene (reversibility checks) may
    /// pass the scene's bounding radius instead.
    double length_scale = 0.0;
    double step_shrink = 0.5;  // on a rejected step
    double step_grow = 2.0;    // on an accepted step
    double max_step = 1.0;     // fraction of the remaining distance a step aims for
    /// Give up when rejections shrink the step below this fraction (the failure is the reason of
    /// the last rejection).
    double min_step = 1.0 / 256.0;
    /// Relative pivot threshold of the block solver (block_tridiagonal.h).
    double singular_threshold = 1e-12;
    /// Check that the converged chain's last segment is unoccluded.
    bool check_visibility = true;
};

struct WalkResult {
    /// The walked chain when ok(): constraints hold to double round-off, the end lies within the
    /// tolerance of the target and carries the target's normal and shape.
    SpecularChain chain;
    WalkFailure failure = WalkFailure::None;
    int iterations = 0;              // projections attempted
    int accepted_steps = 0;          // projections accepted
    double relative_distance = 0.0;  // |end - target| / length scale at exit
    /// Rejected steps by reason (a walk can succeed after rejections).
    std::array<std::uint16_t, kWalkFailureCount> rejected_steps{};

    bool ok() const { return failure == WalkFailure::None; }
};

/// Walks `chain` so that its end reaches `target` (a surface point with its geometric normal, or
/// a free point), keeping chain.start fixed. To pin the other endpoint, walk chain.reversed().
/// Never returns non-finite values; failures carry a WalkFailure.
WalkResult walk(const Scene& scene, const SpecularChain& chain, const ChainEndpoint& target,
                const ManifoldConfig& config = {});

}  // namespace gdmlt::manifold
