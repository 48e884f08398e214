// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/geometry/shape.h"

#include "core/geometry/triangle_tangent.h"
#include "core/math/trig.h"
#include "core/sampling/warp.h"

namespace gdmlt {
namespace {

float triangle_area(const TriangleMesh& mesh, std::size_t triangle) {
    const Vec3f& p0 = mesh.positions[mesh.indices[3 * triangle]];
    const Vec3f& p1 = mesh.positions[mesh.indices[3 * triangle + 1]];
    const Vec3f& p2 = mesh.positions[mesh.indices[3 * triangle + 2]];
    return 0.5f * (p1 - p0).cross(p2 - p0).norm();
}

Vec3f face_normal(const TriangleMesh& mesh, std::size_t triangle) {
    const Vec3f& p0 = mesh.positions[mesh.indices[3 * triangle]];
    const Vec3f& p1 = mesh.positions[mesh.indices[3 * triangle + 1]];
    const Vec3f& p2 = mesh.positions[mesh.indices[3 * triangle + 2]];
    const float sign = mesh.flip_normals ? -1.f : 1.f;
    return sign * (p1 - p0).cross(p2 - p0).normalized();
}

Vec3f frame_tangent(const TriangleMesh& mesh, std::size_t triangle) {
    const std::uint32_t* index = &mesh.indices[3 * triangle];
    const bool uvs = !mesh.uvs.empty();
    return triangle_frame_tangent(mesh.positions[index[0]], mesh.positions[index[1]],
                                  mesh.positions[index[2]], uvs ? &mesh.uvs[index[0]] : nullptr,
                                  uvs ? &mesh.uvs[index[1]] : nullptr,
                                  uvs ? &mesh.uvs[index[2]] : nullptr);
}

/// Fills `si` (default-constructed) for barycentrics `b` on `triangle`; `n_face` and `tangent`
/// are the triangle's precomputed face_normal() and frame_tangent(). Writes into the caller's
/// object rather than returning one: SurfaceInteraction is 136 bytes and this runs once per
/// ray hit.
void fill_mesh_interaction(const TriangleMesh& mesh, const Vec3f& n_face, const Vec3f& tangent,
                           std::uint32_t triangle, const Vec2f& b, SurfaceInteraction& si) {
    const std::uint32_t* index = &mesh.indices[3 * static_cast<std::size_t>(triangle)];
    const std::uint32_t i0 = index[0], i1 = index[1], i2 = index[2];
    const float b0 = 1.f - b.x() - b.y();
    const Vec3f& p0 = mesh.positions[i0];
    const Vec3f& p1 = mesh.positions[i1];
    const Vec3f& p2 = mesh.positions[i2];

    si.primitive = triangle;
    si.surface_param = b;
    // Rebuilt from barycentrics rather than o + t*d: the error is then relative to the
    // triangle's coordinates, not to the ray length (Pharr, Jakob, Humphreys, PBR 4th ed.,
    // sec. 6.8).
    si.p = b0 * p0 + b.x() * p1 + b.y() * p2;
    si.dp_du = p1 - p0;
    si.dp_dv = p2 - p0;
    si.n_geometric = n_face;

    if (mesh.normals.empty()) {
        // Flat triangle: the shading normal is the face normal and dn/du = dn/dv = 0 (the
        // defaults), so only the tangent frame is left to build.
        si.shading = Frame::from_normal_and_tangent(n_face, tangent);
    } else {
        const float sign = mesh.flip_normals ? -1.f : 1.f;
        Vec3f n_shading = n_face;
        const Vec3f& n0 = mesh.normals[i0];
        const Vec3f& n1 = mesh.normals[i1];
        const Vec3f& n2 = mesh.normals[i2];
        const Vec3f n_interp = b0 * n0 + b.x() * n1 + b.y() * n2;
        const float length = n_interp.norm();
        if (length > 1e-20f) {
            const float inv_length = 1.f / length;
            const Vec3f n = n_interp * inv_length;
            // d(N/|N|) = (I - n n^T) dN / |N|
            const Vec3f dN_du = n1 - n0, dN_dv = n2 - n0;
            n_shading = sign * n;
            si.dn_du = (sign * inv_length) * (dN_du - n * n.dot(dN_du));
            si.dn_dv = (sign * inv_length) * (dN_dv - n * n.dot(dN_dv));
        }
        si.shading = Frame::from_normal_and_tangent(n_shading, tangent);
    }
    if (!mesh.uvs.empty()) {
        si.uv = b0 * mesh.uvs[i0] + b.x() * mesh.uvs[i1] + b.y() * mesh.uvs[i2];
        si.duv_du = mesh.uvs[i1] - mesh.uvs[i0];
        si.duv_dv = mesh.uvs[i2] - mesh.uvs[i0];
    } else {
        si.uv = b;
    }
}

/// Sphere parametrised by u = phi / 2pi, v = theta / pi around the world z axis; fills `si`
/// (default-constructed) at unit direction `dir` from the centre.
///
/// Angles from core/math/trig.h's atan2 (within 2e-7 rad) and the sines and cosines of phi as
/// ratios, not from libm's atan2f, acosf and sincosf (5% of the path tracer's time on
/// rough_metal_glass, perf). theta = atan2(rho, z) with rho = |(x, y)| stays accurate near the
/// poles, where acos(z) loses digits; rho is also sin(theta), without 1 - z^2's cancellation.
void fill_sphere_interaction(const Sphere& sphere, const Vec3f& dir, SurfaceInteraction& si) {
    const float r = sphere.radius;
    const float cos_theta = std::clamp(dir.z(), -1.f, 1.f);
    const float sin_theta = std::sqrt(dir.x() * dir.x() + dir.y() * dir.y());
    float phi = atan2_approx(dir.y(), dir.x());
    if (phi < 0.f) phi += 2.f * kPi;
    // On the axis phi is 0 (atan2(0, 0)), so cos phi = 1 and sin phi = 0 there.
    const bool on_axis = !(sin_theta > 0.f);
    const float cos_phi = on_axis ? 1.f : dir.x() / sin_theta;
    const float sin_phi = on_axis ? 0.f : dir.y() / sin_theta;

    si.p = sphere.center + r * dir;
    si.surface_param = Vec2f(phi / (2.f * kPi), atan2_approx(sin_theta, cos_theta) / kPi);
    si.uv = si.surface_param;
    si.dp_du = (2.f * kPi * r) * Vec3f(-sin_theta * sin_phi, sin_theta * cos_phi, 0.f);
    si.dp_dv = (kPi * r) * Vec3f(cos_theta * cos_phi, cos_theta * sin_phi, -sin_theta);
    const float sign = sphere.flip_normals ? -1.f : 1.f;
    si.n_geometric = sign * dir;
    si.dn_du = sign * si.dp_du / r;
    si.dn_dv = sign * si.dp_dv / r;
    si.shading = Frame::from_normal_and_tangent(si.n_geometric, si.dp_du);
}

}  // namespace

Shape::Shape(TriangleMesh mesh, int bsdf, std::string id)
    : geometry_(std::move(mesh)), bsdf_(bsdf), id_(std::move(id)) {
    const auto& m = std::get<TriangleMesh>(geometry_);
    std::vector<float> areas(m.triangle_count());
    face_normals_.resize(m.triangle_count());
    frame_tangents_.resize(m.triangle_count());
    double total = 0.0;
    for (std::size_t t = 0; t < areas.size(); ++t) {
        areas[t] = triangle_area(m, t);
        face_normals_[t] = face_normal(m, t);
        frame_tangents_[t] = frame_tangent(m, t);
        total += areas[t];
    }
    area_ = static_cast<float>(total);
    pdf_area_ = area_ > 0.f ? 1.f / area_ : 0.f;
    triangle_areas_ = AliasTable(areas);
}

Shape::Shape(MeshInstance instance, int bsdf, std::string id)
    : geometry_(std::move(instance)), bsdf_(bsdf), id_(std::move(id)) {
    // The world area, for anyone who asks: |L e1 x L e2| = |det L| |L^-T (e1 x e2)|.
    const auto& inst = std::get<MeshInstance>(geometry_);
    const TriangleMesh& mesh = inst.mesh();
    const float det = std::abs(inst.linear.determinant());
    double total = 0.0;
    for (std::size_t t = 0; t < mesh.triangle_count(); ++t) {
        const Vec3f& p0 = mesh.positions[mesh.indices[3 * t]];
        const Vec3f& p1 = mesh.positions[mesh.indices[3 * t + 1]];
        const Vec3f& p2 = mesh.positions[mesh.indices[3 * t + 2]];
        total += 0.5 * det * (inst.normal_linear * (p1 - p0).cross(p2 - p0)).norm();
    }
    area_ = static_cast<float>(total);
}

Shape::Shape(Cylinder cylinder, int bsdf, std::string id)
    : geometry_(cylinder), bsdf_(bsdf), id_(std::move(id)) {
    area_ = 2.f * kPi * cylinder.radius * cylinder.length;
    pdf_area_ = area_ > 0.f ? 1.f / area_ : 0.f;
}

Shape::Shape(Sphere sphere, int bsdf, std::string id)
    : geometry_(sphere), bsdf_(bsdf), id_(std::move(id)) {
    area_ = 4.f * kPi * sphere.radius * sphere.radius;
    pdf_area_ = area_ > 0.f ? 1.f / area_ : 0.f;
}

namespace {

/// Fills `si` for the point `local` on the unit cylinder (x^2 + y^2 = 1) of `cylinder`'s object
/// space (Mitsuba 3's cylinder.cpp parametrisation: u = phi / 2 pi, v = z).
void fill_cylinder_interaction(const Cylinder& cylinder, const Vec3f& local,
                               SurfaceInteraction& si) {
    float phi = std::atan2(local.y(), local.x());
    if (phi < 0.f) phi += 2.f * kPi;
    si.p = cylinder.origin + cylinder.linear * local;
    si.uv = Vec2f(phi * (0.5f * kInvPi), local.z());
    si.surface_param = si.uv;
    si.dp_du = cylinder.linear * Vec3f(-2.f * kPi * local.y(), 2.f * kPi * local.x(), 0.f);
    si.dp_dv = cylinder.linear * Vec3f(0.f, 0.f, 1.f);
    const float sign = cylinder.flip_normals ? -1.f : 1.f;
    const Vec3f n = sign * si.dp_du.cross(si.dp_dv).normalized();
    si.n_geometric = n;
    si.shading = Frame::from_normal_and_tangent(n, si.dp_du);
    // The normal turns along the circle only: dn/du = dp/du / r (the cylinder is straight).
    si.dn_du = si.dp_du * (sign / cylinder.radius);
    si.dn_dv = Vec3f::Zero();
}

/// Maps `si`, filled in `instance`'s object space, to world space. Points and tangents by the
/// linear part, normals by its inverse transpose; the shading normal's derivatives are those of
/// normalize(L^-T n(u, v)), i.e. (I - n n^T) L^-T dn / |L^-T n| for the unit object normal n
/// (the interpolated normal is linear in the corners, so this is the same field a mesh
/// flattened with transformed vertex normals has, before their per-vertex normalisation).
/// The frame's reference tangent is the object's mapped, as a flattened mesh computes it.
void to_world(const MeshInstance& instance, const Vec3f& object_frame_tangent,
              SurfaceInteraction& si) {
    const Mat3f& l = instance.linear;
    const Mat3f& n_map = instance.normal_linear;
    si.p = instance.to_world(si.p);
    si.dp_du = l * si.dp_du;
    si.dp_dv = l * si.dp_dv;
    si.n_geometric = (n_map * si.n_geometric).normalized();
    const Vec3f n_scaled = n_map * si.shading.n;
    const float length = n_scaled.norm();
    const Vec3f n = n_scaled / length;
    const auto project = [&](const Vec3f& dn_object) -> Vec3f {
        const Vec3f d = n_map * dn_object;
        return (d - n * n.dot(d)) / length;
    };
    si.dn_du = project(si.dn_du);
    si.dn_dv = project(si.dn_dv);
    si.shading = Frame::from_normal_and_tangent(n, l * object_frame_tangent);
}

}  // namespace

SurfaceInteraction Shape::interaction(std::uint32_t primitive, const Vec2f& barycentric,
                                      const Vec3f& ray_origin, const Vec3f& ray_direction,
                                      float t) const {
    // One object filled in place and returned by name (NRVO): no 136-byte copies per hit.
    SurfaceInteraction si;
    if (const auto* mesh = std::get_if<TriangleMesh>(&geometry_)) {
        fill_mesh_interaction(*mesh, face_normals_[primitive], frame_tangents_[primitive],
                              primitive, barycentric, si);
    } else if (const auto* instance = std::get_if<MeshInstance>(&geometry_)) {
        // Barycentrics and t are the same in object and world space (an affine map).
        si = instance->object->interaction_at(primitive, barycentric);
        to_world(*instance, instance->object->triangle_frame_tangent(primitive), si);
    } else if (const auto* cylinder = std::get_if<Cylinder>(&geometry_)) {
        // Back onto the unit cylinder in object space, as Mitsuba 3 reprojects its hits.
        Vec3f local = cylinder->to_object(ray_origin + t * ray_direction);
        const float r = std::hypot(local.x(), local.y());
        if (r > 0.f) {
            local.x() /= r;
            local.y() /= r;
        } else {
            local = Vec3f(1.f, 0.f, local.z());
        }
        fill_cylinder_interaction(*cylinder, local, si);
        si.primitive = primitive;
    } else {
        const auto& sphere = std::get<Sphere>(geometry_);
        // Project the hit back onto the sphere: exact normal, position error ~ ulp(|p|).
        const Vec3f hit = ray_origin + t * ray_direction;
        Vec3f dir = hit - sphere.center;
        const float length = dir.norm();
        dir = length > 0.f ? Vec3f(dir / length) : Vec3f::UnitZ();
        fill_sphere_interaction(sphere, dir, si);
    }
    si.t = t;
    return si;
}

SurfaceInteraction Shape::interaction_at(std::uint32_t primitive, const Vec2f& param) const {
    SurfaceInteraction si;
    if (const auto* mesh = std::get_if<TriangleMesh>(&geometry_)) {
        fill_mesh_interaction(*mesh, face_normals_[primitive], frame_tangents_[primitive],
                              primitive, param, si);
    } else if (const auto* instance = std::get_if<MeshInstance>(&geometry_)) {
        si = instance->object->interaction_at(primitive, param);
        to_world(*instance, instance->object->triangle_frame_tangent(primitive), si);
    } else if (const auto* cylinder = std::get_if<Cylinder>(&geometry_)) {
        const float phi = 2.f * kPi * param.x();
        fill_cylinder_interaction(*cylinder, Vec3f(std::cos(phi), std::sin(phi), param.y()), si);
        si.primitive = primitive;
    } else {
        const auto& sphere = std::get<Sphere>(geometry_);
        const float phi = 2.f * kPi * param.x(), theta = kPi * param.y();
        const Vec3f dir(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                        std::cos(theta));
        fill_sphere_interaction(sphere, dir, si);
    }
    return si;
}

}  // namespace gdmlt
