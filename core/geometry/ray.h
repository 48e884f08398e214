// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Rays, and the only place where self-intersection offsets are computed.
#include "core/math/types.h"

namespace gdmlt {

struct Ray {
    Vec3f origin = Vec3f::Zero();
    Vec3f direction = Vec3f::UnitZ();  // unit length
    float t_max = kInfinity;
};

/// Offset scale: Embree works in float and we rebuild hit points from barycentrics, so the
/// error of a surface point is a few ulps of its largest coordinate. 2^-24 is one ulp at 1;
/// the factor leaves margin for the triangle interpolation and the sphere projection.
inline constexpr float kRayOffsetUlps = 1024.f * 0x1p-24f;  // about 6e-5 relative
/// Connection rays stop this fraction short of their target, for the same reason.
inline constexpr float kShadowRayShorten = 1e-4f;

/// Position offset along the geometric normal `n_geometric`, to the side `direction` points
/// to, scaled to the magnitude of `p` (Mitsuba 3 and pbrt-v4 both scale with |p|).
inline Vec3f offset_position(const Vec3f& p, const Vec3f& n_geometric, const Vec3f& direction) {
    const float magnitude = (1.f + p.cwiseAbs().maxCoeff()) * kRayOffsetUlps;
    return p + n_geometric * std::copysign(magnitude, n_geometric.dot(direction));
}

/// A ray leaving surface point `p` in unit direction `direction`.
inline Ray spawn_ray(const Vec3f& p, const Vec3f& n_geometric, const Vec3f& direction) {
    return Ray{offset_position(p, n_geometric, direction), direction, kInfinity};
}

/// A ray from surface point `p` towards point `target` (an emitter sample or another vertex),
/// ending just before it; `n_target` is the target's geometric normal, or zero for a point
/// that is not on a surface (point light). Both ends are offset (pbrt-v4's SpawnRayTo).
inline Ray spawn_ray_to(const Vec3f& p, const Vec3f& n_geometric, const Vec3f& target,
                        const Vec3f& n_target) {
    const Vec3f origin = offset_position(p, n_geometric, target - p);
    const Vec3f end =
        n_target.isZero() ? target : offset_position(target, n_target, origin - target);
    Vec3f d = end - origin;
    const float distance = d.norm();
    if (!(distance > 0.f)) return Ray{origin, n_geometric, 0.f};
    d /= distance;
    return Ray{origin, d, distance * (1.f - kShadowRayShorten)};
}

}  // namespace gdmlt
