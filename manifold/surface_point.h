// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Double-precision differential geometry of a point on a scene shape, for the manifold walk.
//
// Why a second copy of what Shape::interaction_at computes: the core keeps geometry in float
// (Embree), but a Newton walk that should converge to 1e-9 of the chain's size, and the finite-
// difference tests of its Jacobians, need positions, normals and their derivatives in double
// (the precision policy of core/math/types.h). The float accelerator only tells us which primitive
// a ray hits; refine_hit() then intersects that primitive again in double. The formulas mirror
// core/geometry/shape.cpp (same parametrisation, same orientation rules) so that surface_param
// and the shading frame agree with the float SurfaceInteraction up to float round-off.
#include <array>
#include <cstdint>
#include <optional>

#include "core/geometry/interaction.h"
#include "core/geometry/shape.h"
#include "core/math/types.h"

namespace gdmlt::manifold {

using Mat2d = Eigen::Matrix2d;
/// An orthonormal pair of tangent vectors: "tangent coordinates" (a, b) mean the displacement
/// a * tangents[0] + b * tangents[1]. Area in tangent coordinates is area on the surface.
using Tangents = std::array<Vec3d, 2>;

struct SurfacePoint {
    Vec3d p = Vec3d::Zero();
    Vec3d n_geometric = Vec3d::UnitZ();  // unit, oriented like the float SurfaceInteraction
    Vec3d n_shading = Vec3d::UnitZ();    // unit (interpolated normal on meshes)
    Vec3d dp_du = Vec3d::Zero(), dp_dv = Vec3d::Zero();  // w.r.t. surface_param
    Vec3d dn_du = Vec3d::Zero(), dn_dv = Vec3d::Zero();  // of n_shading, w.r.t. surface_param
    /// Orthonormal basis of the geometric tangent plane (tangents[0] along dp_du where defined);
    /// positions move in this plane to first order.
    Tangents tangents{Vec3d::UnitX(), Vec3d::UnitY()};
    /// Derivatives of n_shading along tangents[0] and tangents[1] (per unit length).
    Tangents dn_shading_dtangent{Vec3d::Zero(), Vec3d::Zero()};
    /// The reference direction of the shading frame (Frame::from_normal_and_tangent): on a
    /// triangle its texture coordinates' dp/du, or its first edge (core/geometry/
    /// triangle_tangent.h, as the renderer's surface interaction), on a sphere dp_du.
    Vec3d frame_reference = Vec3d::UnitX();
    /// Derivatives of frame_reference along the tangents, which constraint blocks
    /// differentiate with the frame (zero on a triangle, where it is constant).
    Tangents dframe_reference_dtangent{Vec3d::Zero(), Vec3d::Zero()};
    Vec2d surface_param = Vec2d::Zero();  // barycentrics (b1, b2), or (phi/2pi, theta/pi)
    std::int32_t shape = -1;
    std::uint32_t primitive = 0;

    bool valid() const { return shape >= 0; }
};

/// Differential geometry of shape `shape_index` at surface parameters (triangle barycentrics
/// may lie slightly outside the triangle: the walk extrapolates by round-off amounts). Empty for
/// a degenerate triangle (zero area) or an out-of-range primitive.
std::optional<SurfacePoint> surface_point_at(const Shape& shape, std::int32_t shape_index,
                                             std::uint32_t primitive, const Vec2d& surface_param);

/// The double-precision version of a float interaction (re-evaluated at its surface_param).
std::optional<SurfacePoint> surface_point_from(const Shape& shape, const SurfaceInteraction& si);

/// Intersects the ray origin + t * direction (direction unit) with one primitive in double.
/// `t_hint` (the float accelerator's distance) selects between the two roots of a sphere.
/// Empty if the ray misses the primitive by more than a round-off margin.
std::optional<SurfacePoint> refine_hit(const Shape& shape, std::int32_t shape_index,
                                       std::uint32_t primitive, const Vec3d& origin,
                                       const Vec3d& direction, double t_hint);

/// Moves a point along its surface by tangent coordinates `offset` through a chart that is
/// exact to first order (linear in barycentrics on a triangle, a normalised radial projection
/// on a sphere). Used by finite-difference tests and by callers that perturb vertices.
std::optional<SurfacePoint> move_on_surface(const Shape& shape, const SurfacePoint& point,
                                            const Vec2d& offset);

/// An orthonormal tangent pair around unit `n` (Duff et al. 2017, as Frame::from_normal).
Tangents tangents_around(const Vec3d& n);

/// The float SurfaceInteraction the core would compute at the same surface parameters (for BSDF
/// evaluation and ray spawning by callers).
SurfaceInteraction to_interaction(const Shape& shape, const SurfacePoint& point);

}  // namespace gdmlt::manifold
