// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/surface_point.h"

#include <array>
#include <cmath>

#include "core/geometry/triangle_tangent.h"

namespace gdmlt::manifold {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

/// Barycentric slack accepted by refine_hit: the float accelerator and the double intersection
/// may disagree about which of two neighbouring triangles a ray hits when it passes within
/// round-off of their shared edge; extrapolating the hit triangle by that much is harmless.
constexpr double kBarycentricSlack = 1e-5;

Vec3d to_double(const Vec3f& v) {
    return v.cast<double>();
}

/// Solves dp_du * du + dp_dv * dv = e for e in the tangent plane (least squares through the
/// 2x2 Gram matrix; exact for e in the plane).
std::optional<Vec2d> param_offset(const Vec3d& dp_du, const Vec3d& dp_dv, const Vec3d& e) {
    const double a = dp_du.squaredNorm(), b = dp_du.dot(dp_dv), c = dp_dv.squaredNorm();
    const double det = a * c - b * b;
    if (!(det > 1e-300) || !(det > 1e-24 * a * c)) return std::nullopt;
    const double r0 = dp_du.dot(e), r1 = dp_dv.dot(e);
    return Vec2d((c * r0 - b * r1) / det, (a * r1 - b * r0) / det);
}

/// A mesh triangle's corners in world space, in double: a stored mesh's as they are, an
/// instance's mapped by its world_from_object (normals by the inverse transpose and not
/// normalised, so that the interpolated normal is the image of the object's, as
/// Shape::interaction computes it).
struct TriangleCorners {
    std::array<Vec3d, 3> p;
    std::array<Vec3d, 3> n;   // valid when has_normals
    std::array<Vec2d, 3> uv;  // valid when has_uvs
    bool has_normals = false, has_uvs = false;
    double normal_sign = 1.0;   // flip_normals
    double winding_sign = 1.0;  // the geometric normal's sign on p1-p0 x p2-p0: flip_normals,
                                // and a mirroring instance's reversed winding
};

std::optional<TriangleCorners> triangle_corners(const Shape& shape, std::uint32_t triangle) {
    const TriangleMesh* mesh = shape.object_mesh();
    if (!mesh || triangle >= mesh->triangle_count()) return std::nullopt;
    const auto* instance = std::get_if<MeshInstance>(&shape.geometry());
    TriangleCorners c;
    c.has_normals = !mesh->normals.empty();
    c.has_uvs = !mesh->uvs.empty();
    c.normal_sign = mesh->flip_normals ? -1.0 : 1.0;
    c.winding_sign = instance && instance->mirrored ? -c.normal_sign : c.normal_sign;
    for (std::size_t k = 0; k < 3; ++k) {
        const std::uint32_t i = mesh->indices[3 * triangle + k];
        c.p[k] = to_double(mesh->positions[i]);
        if (c.has_normals) c.n[k] = to_double(mesh->normals[i]);
        if (c.has_uvs) c.uv[k] = mesh->uvs[i].cast<double>();
        if (instance) {
            c.p[k] =
                instance->linear.cast<double>() * c.p[k] + instance->translation.cast<double>();
            if (c.has_normals) c.n[k] = instance->normal_linear.cast<double>() * c.n[k];
        }
    }
    return c;
}

std::optional<SurfacePoint> mesh_point(const Shape& shape, std::uint32_t triangle, const Vec2d& b) {
    const std::optional<TriangleCorners> corners = triangle_corners(shape, triangle);
    if (!corners) return std::nullopt;
    const Vec3d &p0 = corners->p[0], &p1 = corners->p[1], &p2 = corners->p[2];
    const double b0 = 1.0 - b.x() - b.y();

    SurfacePoint sp;
    sp.primitive = triangle;
    sp.surface_param = b;
    sp.p = b0 * p0 + b.x() * p1 + b.y() * p2;
    sp.dp_du = p1 - p0;
    sp.dp_dv = p2 - p0;
    const Vec3d cross = sp.dp_du.cross(sp.dp_dv);
    const double cross_norm = cross.norm();
    if (!(cross_norm > 0.0) || !std::isfinite(cross_norm)) return std::nullopt;
    sp.n_geometric = corners->winding_sign * cross / cross_norm;
    sp.n_shading = sp.n_geometric;
    if (corners->has_normals) {
        const double sign = corners->normal_sign;
        const Vec3d &n0 = corners->n[0], &n1 = corners->n[1], &n2 = corners->n[2];
        const Vec3d n_interp = b0 * n0 + b.x() * n1 + b.y() * n2;
        const double length = n_interp.norm();
        if (length > 1e-20) {
            const Vec3d n = n_interp / length;
            // d(N/|N|) = (I - n n^T) dN / |N|, as in core/geometry/shape.cpp.
            const Vec3d dN_du = n1 - n0, dN_dv = n2 - n0;
            sp.n_shading = sign * n;
            sp.dn_du = sign * (dN_du - n * n.dot(dN_du)) / length;
            sp.dn_dv = sign * (dN_dv - n * n.dot(dN_dv)) / length;
        }
    }
    if (!corners->has_uvs) {
        sp.frame_reference = sp.dp_du;
    } else {
        sp.frame_reference =
            triangle_frame_tangent(p0, p1, p2, &corners->uv[0], &corners->uv[1], &corners->uv[2]);
    }
    sp.tangents[0] = sp.dp_du.normalized();
    sp.tangents[1] = sp.n_geometric.cross(sp.tangents[0]);
    for (int k = 0; k < 2; ++k) {
        const std::optional<Vec2d> duv = param_offset(sp.dp_du, sp.dp_dv, sp.tangents[k]);
        if (!duv) return std::nullopt;
        sp.dn_shading_dtangent[k] = sp.dn_du * duv->x() + sp.dn_dv * duv->y();
        sp.dframe_reference_dtangent[k] = Vec3d::Zero();  // constant on a triangle
    }
    return sp;
}

/// Sphere parametrised by u = phi / 2pi, v = theta / pi around the world z axis (shape.cpp);
/// `dir` is the unit direction from the centre.
SurfacePoint sphere_point(const Sphere& sphere, const Vec3d& dir) {
    const double r = sphere.radius;
    const Vec3d center = to_double(sphere.center);
    const double cos_theta = std::clamp(dir.z(), -1.0, 1.0);
    const double sin_theta = std::hypot(dir.x(), dir.y());
    double phi = std::atan2(dir.y(), dir.x());
    if (phi < 0.0) phi += kTwoPi;
    const double cos_phi = sin_theta > 0.0 ? dir.x() / sin_theta : 1.0;
    const double sin_phi = sin_theta > 0.0 ? dir.y() / sin_theta : 0.0;

    SurfacePoint sp;
    sp.p = center + r * dir;
    sp.surface_param = Vec2d(phi / kTwoPi, std::acos(cos_theta) / std::numbers::pi);
    // dp_du = 2 pi r (z x dir): written without phi so that it stays smooth near the poles.
    sp.dp_du = (kTwoPi * r) * Vec3d(-dir.y(), dir.x(), 0.0);
    sp.dp_dv = (std::numbers::pi * r) * Vec3d(cos_theta * cos_phi, cos_theta * sin_phi, -sin_theta);
    const double sign = sphere.flip_normals ? -1.0 : 1.0;
    sp.n_geometric = sign * dir;
    sp.n_shading = sp.n_geometric;
    sp.dn_du = sign * sp.dp_du / r;
    sp.dn_dv = sign * sp.dp_dv / r;
    sp.frame_reference = sp.dp_du;
    const Vec3d u_dir = Vec3d(-dir.y(), dir.x(), 0.0);
    if (u_dir.squaredNorm() > 1e-20) {
        sp.tangents[0] = u_dir.normalized();
        sp.tangents[1] = sp.n_geometric.cross(sp.tangents[0]);
    } else {
        sp.tangents = tangents_around(sp.n_geometric);
    }
    for (int k = 0; k < 2; ++k) {
        const Vec3d& e = sp.tangents[k];
        sp.dn_shading_dtangent[k] = sign * e / r;  // d(dir)/de = e / r
        sp.dframe_reference_dtangent[k] = kTwoPi * Vec3d(-e.y(), e.x(), 0.0);
    }
    return sp;
}

/// Cylinder parametrised by u = phi / 2pi, v = z of its object space (shape.cpp): the point at
/// angle `phi` and height `z` on the unit circle, mapped by world_from_object.
SurfacePoint cylinder_point(const Cylinder& cylinder, double phi, double z) {
    const Eigen::Matrix3d linear = cylinder.linear.cast<double>();
    const double r = cylinder.radius;
    const double c = std::cos(phi), s = std::sin(phi);
    SurfacePoint sp;
    sp.p = to_double(cylinder.origin) + linear * Vec3d(c, s, z);
    double u = phi / kTwoPi;
    u -= std::floor(u);
    sp.surface_param = Vec2d(u, z);
    sp.dp_du = linear * Vec3d(-kTwoPi * s, kTwoPi * c, 0.0);
    sp.dp_dv = linear * Vec3d(0.0, 0.0, 1.0);
    // Outward normal: the radial direction, |L (c, s, 0)| = r for a round cross-section.
    const Vec3d outward = linear * Vec3d(c, s, 0.0) / r;
    const double sign = cylinder.flip_normals ? -1.0 : 1.0;
    sp.n_geometric = sign * outward;
    sp.n_shading = sp.n_geometric;
    sp.dn_du = sign * sp.dp_du / r;  // the normal turns with the circle only
    sp.dn_dv = Vec3d::Zero();
    sp.frame_reference = sp.dp_du;
    const Vec3d along_circle = sp.dp_du.normalized();
    sp.tangents[0] = along_circle;
    sp.tangents[1] = sp.n_geometric.cross(along_circle);
    for (int k = 0; k < 2; ++k) {
        // Per unit length along e, phi changes by (e . t0) / r: n turns by that times
        // t0 (sign included) and dp_du by that times -2 pi r outward.
        const double dphi = sp.tangents[k].dot(along_circle) / r;
        sp.dn_shading_dtangent[k] = sign * dphi * along_circle;
        sp.dframe_reference_dtangent[k] = -kTwoPi * r * dphi * outward;
    }
    return sp;
}

Vec3d sphere_direction_from_param(const Vec2d& param) {
    const double phi = kTwoPi * param.x(), theta = std::numbers::pi * param.y();
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

}  // namespace

Tangents tangents_around(const Vec3d& n) {
    const double sign = std::copysign(1.0, n.z());
    const double a = -1.0 / (sign + n.z());
    const double b = n.x() * n.y() * a;
    return {Vec3d(1.0 + sign * n.x() * n.x() * a, sign * b, -sign * n.x()),
            Vec3d(b, sign + n.y() * n.y() * a, -n.y())};
}

std::optional<SurfacePoint> surface_point_at(const Shape& shape, std::int32_t shape_index,
                                             std::uint32_t primitive, const Vec2d& param) {
    std::optional<SurfacePoint> sp;
    if (const auto* cylinder = std::get_if<Cylinder>(&shape.geometry())) {
        sp = cylinder_point(*cylinder, kTwoPi * param.x(), param.y());
        sp->primitive = primitive;
        sp->shape = shape_index;
        return sp;
    }
    if (shape.has_triangles()) {
        sp = mesh_point(shape, primitive, param);
    } else {
        sp = sphere_point(std::get<Sphere>(shape.geometry()), sphere_direction_from_param(param));
        sp->primitive = primitive;
    }
    if (sp) sp->shape = shape_index;
    return sp;
}

std::optional<SurfacePoint> surface_point_from(const Shape& shape, const SurfaceInteraction& si) {
    if (!si.valid()) return std::nullopt;
    if (const auto* cylinder = std::get_if<Cylinder>(&shape.geometry())) {
        // From the position, as for the sphere.
        const Vec3d local = cylinder->linear.cast<double>().inverse() *
                            (to_double(si.p) - to_double(cylinder->origin));
        SurfacePoint sp = cylinder_point(*cylinder, std::atan2(local.y(), local.x()), local.z());
        sp.shape = si.shape;
        sp.primitive = si.primitive;
        return sp;
    }
    if (const auto* sphere = std::get_if<Sphere>(&shape.geometry())) {
        // From the position rather than from (phi, theta): no pole trouble, same float point.
        const Vec3d d = to_double(si.p) - to_double(sphere->center);
        const double length = d.norm();
        if (!(length > 0.0)) return std::nullopt;
        SurfacePoint sp = sphere_point(*sphere, d / length);
        sp.shape = si.shape;
        sp.primitive = si.primitive;
        return sp;
    }
    return surface_point_at(shape, si.shape, si.primitive, si.surface_param.cast<double>());
}

std::optional<SurfacePoint> refine_hit(const Shape& shape, std::int32_t shape_index,
                                       std::uint32_t primitive, const Vec3d& origin,
                                       const Vec3d& direction, double t_hint) {
    if (shape.has_triangles()) {
        const std::optional<TriangleCorners> corners = triangle_corners(shape, primitive);
        if (!corners) return std::nullopt;
        const Vec3d &p0 = corners->p[0], &p1 = corners->p[1], &p2 = corners->p[2];
        // Moeller-Trumbore in double.
        const Vec3d e1 = p1 - p0, e2 = p2 - p0;
        const Vec3d pvec = direction.cross(e2);
        const double det = e1.dot(pvec);
        if (!(std::abs(det) > 1e-14 * e1.norm() * e2.norm())) return std::nullopt;  // parallel
        const double inv_det = 1.0 / det;
        const Vec3d svec = origin - p0;
        const double b1 = svec.dot(pvec) * inv_det;
        const Vec3d qvec = svec.cross(e1);
        const double b2 = direction.dot(qvec) * inv_det;
        const double t = e2.dot(qvec) * inv_det;
        if (!std::isfinite(t) || !(t > 0.0)) return std::nullopt;
        if (b1 < -kBarycentricSlack || b2 < -kBarycentricSlack || b1 + b2 > 1.0 + kBarycentricSlack)
            return std::nullopt;
        return surface_point_at(shape, shape_index, primitive, Vec2d(b1, b2));
    }
    if (const auto* cylinder = std::get_if<Cylinder>(&shape.geometry())) {
        // The unit circle's quadratic in object space (an affine map keeps t), the root nearer
        // the hint within the cylinder's height. The inverse is taken in double: the float one
        // the renderer keeps undoes `linear` only to ~1e-7, and points projected with it sat
        // off the surface cylinder_point rebuilds, so walks stalled above their 1e-8 tolerance.
        const Eigen::Matrix3d to_object = cylinder->linear.cast<double>().inverse();
        const Vec3d o = to_object * (origin - to_double(cylinder->origin));
        const Vec3d d = to_object * direction;
        const double a = d.x() * d.x() + d.y() * d.y();
        const double b = o.x() * d.x() + o.y() * d.y();
        const double c = o.x() * o.x() + o.y() * o.y() - 1.0;
        const double discriminant = b * b - a * c;
        if (!(a > 0.0) || discriminant < -1e-10 * a) return std::nullopt;
        const double q = -(b + std::copysign(safe_sqrt(discriminant), b));
        const double t0 = q / a, t1 = q != 0.0 ? c / q : t0;
        double t = std::abs(t0 - t_hint) <= std::abs(t1 - t_hint) ? t0 : t1;
        if (!(t > 0.0)) t = std::max(t0, t1);
        if (!(t > 0.0) || !std::isfinite(t)) return std::nullopt;
        const Vec3d local = o + t * d;
        if (local.z() < 0.0 || local.z() > 1.0) return std::nullopt;  // past an open end
        SurfacePoint sp = cylinder_point(*cylinder, std::atan2(local.y(), local.x()), local.z());
        sp.shape = shape_index;
        sp.primitive = primitive;
        return sp;
    }
    if (!std::holds_alternative<Sphere>(shape.geometry())) return std::nullopt;
    const auto& sphere = std::get<Sphere>(shape.geometry());
    const Vec3d center = to_double(sphere.center);
    const double r = sphere.radius;
    // Closest approach first, then the half chord: avoids the cancellation of the textbook
    // quadratic when the origin is far away (Haines et al., Ray Tracing Gems ch. 7).
    const double t_mid = (center - origin).dot(direction);
    const Vec3d closest = origin + t_mid * direction;
    const double d2 = (closest - center).squaredNorm();
    const double half2 = r * r - d2;
    if (half2 < -1e-10 * r * r) return std::nullopt;  // misses the sphere
    const double half = safe_sqrt(half2);
    const double t0 = t_mid - half, t1 = t_mid + half;
    double t = std::abs(t0 - t_hint) <= std::abs(t1 - t_hint) ? t0 : t1;
    if (!(t > 0.0)) t = t1;
    if (!(t > 0.0) || !std::isfinite(t)) return std::nullopt;
    const Vec3d d = origin + t * direction - center;
    const double length = d.norm();
    if (!(length > 0.0)) return std::nullopt;
    SurfacePoint sp = sphere_point(sphere, d / length);
    sp.shape = shape_index;
    sp.primitive = primitive;
    return sp;
}

std::optional<SurfacePoint> move_on_surface(const Shape& shape, const SurfacePoint& point,
                                            const Vec2d& offset) {
    const Vec3d e = offset.x() * point.tangents[0] + offset.y() * point.tangents[1];
    if (shape.has_triangles()) {
        const std::optional<Vec2d> duv = param_offset(point.dp_du, point.dp_dv, e);
        if (!duv) return std::nullopt;
        return surface_point_at(shape, point.shape, point.primitive, point.surface_param + *duv);
    }
    if (const auto* cylinder = std::get_if<Cylinder>(&shape.geometry())) {
        // Along the circle by arc length, along the axis by height: exact on the surface.
        const double phi = kTwoPi * point.surface_param.x() +
                           e.dot(point.tangents[0]) / static_cast<double>(cylinder->radius);
        const double z = point.surface_param.y() + e.dot(point.dp_dv) / point.dp_dv.squaredNorm();
        if (z < 0.0 || z > 1.0) return std::nullopt;
        SurfacePoint sp = cylinder_point(*cylinder, phi, z);
        sp.shape = point.shape;
        sp.primitive = point.primitive;
        return sp;
    }
    if (!std::holds_alternative<Sphere>(shape.geometry())) return std::nullopt;
    const auto& sphere = std::get<Sphere>(shape.geometry());
    const Vec3d dir = (point.p - to_double(sphere.center)) / sphere.radius + e / sphere.radius;
    const double length = dir.norm();
    if (!(length > 0.0)) return std::nullopt;
    SurfacePoint sp = sphere_point(sphere, dir / length);
    sp.shape = point.shape;
    sp.primitive = point.primitive;
    return sp;
}

SurfaceInteraction to_interaction(const Shape& shape, const SurfacePoint& point) {
    SurfaceInteraction si =
        shape.interaction_at(point.primitive, point.surface_param.cast<float>());
    si.shape = point.shape;
    return si;
}

}  // namespace gdmlt::manifold
