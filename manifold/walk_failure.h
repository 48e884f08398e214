// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Why a manifold walk, a chain projection or a chain construction failed (a failed
// walk returns a named reason that stats count, never a NaN). The names follow the failure
// counters of Mitsuba 0.6's manifold walk (Jakob and Marschner 2012, sec. 4-5).
#include <cstddef>
#include <cstdint>

namespace gdmlt::manifold {

enum class WalkFailure : std::uint8_t {
    None = 0,
    /// The iteration cap was reached while steps were still being accepted.
    NotConverged,
    /// Steps were rejected because the projected end moved away from the target, until the
    /// step size fell below ManifoldConfig::min_step or the iteration cap was reached.
    DistanceIncreased,
    /// The converged chain's last segment (to the end point) is blocked.
    Occluded,
    /// A projection ray missed the next surface of the chain, hit a different shape first,
    /// crossed to the other side of an interface, or the end-plane intersection failed.
    LeftManifold,
    /// A refraction vertex of the chain cannot refract the projected ray.
    TotalInternalReflection,
    /// The block-tridiagonal constraint system is singular (a caustic focal configuration or a
    /// degenerate parametrisation).
    SingularMatrix,
    /// Invalid input: zero-length segments, a collapsed last segment, a diffuse vertex inside the
    /// chain, a degenerate triangle or surface frame.
    DegenerateChain,
};

inline constexpr std::size_t kWalkFailureCount = 8;

inline constexpr const char* to_string(WalkFailure f) {
    switch (f) {
        case WalkFailure::None:
            return "none";
        case WalkFailure::NotConverged:
            return "not_converged";
        case WalkFailure::DistanceIncreased:
            return "distance_increased";
        case WalkFailure::Occluded:
            return "occluded";
        case WalkFailure::LeftManifold:
            return "left_manifold";
        case WalkFailure::TotalInternalReflection:
            return "total_internal_reflection";
        case WalkFailure::SingularMatrix:
            return "singular_matrix";
        case WalkFailure::DegenerateChain:
            return "degenerate_chain";
    }
    return "unknown";
}

}  // namespace gdmlt::manifold
