// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The reference tangent of a mesh triangle's shading frame (Frame::from_normal_and_tangent),
// shared by the float surface interaction (core/geometry/shape.cpp), the path tracer's lanes
// (through Shape::triangle_frame_tangent) and the manifold walk's double-precision surface
// points (manifold/surface_point.cpp), so that all three orient anisotropic BSDFs alike.
#include <cmath>

namespace gdmlt {

/// dp/du of the texture parametrisation where the triangle's texture coordinates span a
/// parallelogram (as Mitsuba 3's meshes compute it: an anisotropic BSDF's u axis follows the
/// texture's), else the edge p1 - p0. uv0 is null for a mesh without texture coordinates.
/// With dp0 = p1 - p0, dp1 = p2 - p0 and duv_k the same differences of uv,
///     dp0 = dp_du duv0.u + dp_dv duv0.v,  dp1 = dp_du duv1.u + dp_dv duv1.v
/// give dp_du = (duv1.v dp0 - duv0.v dp1) / (duv0.u duv1.v - duv0.v duv1.u).
template <class Vec3, class Vec2>
Vec3 triangle_frame_tangent(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec2* uv0,
                            const Vec2* uv1, const Vec2* uv2) {
    const Vec3 dp0 = p1 - p0;
    if (!uv0) return dp0;
    const Vec3 dp1 = p2 - p0;
    const Vec2 duv0 = *uv1 - *uv0, duv1 = *uv2 - *uv0;
    const auto det = duv0.x() * duv1.y() - duv0.y() * duv1.x();
    if (!(det != 0) || !std::isfinite(det)) return dp0;
    const Vec3 dp_du = (duv1.y() * dp0 - duv0.y() * dp1) / det;
    const auto length2 = dp_du.squaredNorm();
    if (!(length2 > 0) || !std::isfinite(length2)) return dp0;
    return dp_du;
}

}  // namespace gdmlt
