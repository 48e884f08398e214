// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Shapes in world space. Triangle meshes (obj, ply, rectangle, cube, disk), analytic spheres and
// cylinders.
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "core/geometry/interaction.h"
#include "core/math/types.h"
#include "core/sampling/alias_table.h"
#include "core/sampling/warp.h"
#include "core/texture/texture_point.h"

namespace gdmlt {

struct TriangleMesh {
    std::vector<Vec3f> positions;  // world space
    std::vector<Vec3f> normals;    // world space, per vertex; empty when face_normals
    std::vector<Vec2f> uvs;        // per vertex; may be empty
    std::vector<std::uint32_t> indices;
    bool flip_normals = false;
    /// A PLY file's vertex and face attributes (mesh_attribute textures read them), per
    /// triangle; shared, not copied, with the textures that read them.
    std::vector<std::shared_ptr<const MeshAttribute>> attributes;

    std::size_t triangle_count() const { return indices.size() / 3; }
    /// The attribute called `name`, or null.
    std::shared_ptr<const MeshAttribute> attribute(const std::string& name) const {
        for (const auto& a : attributes)
            if (a->name == name) return a;
        return nullptr;
    }
};

/// Sphere with exact normals and analytic differentials (Embree intersects it; we project the
/// hit point back onto the sphere).
struct Sphere {
    Vec3f center = Vec3f::Zero();
    float radius = 1.f;
    bool flip_normals = false;  // true: normals point inwards
};

/// Mitsuba's `cylinder`: the open unit cylinder x^2 + y^2 = 1, 0 <= z <= 1 of object space,
/// mapped by world_from_object (translation to p0, rotation, the radius along x and y, the
/// length along z; no shear and a round cross-section, checked when built). Normals point
/// outwards unless flip_normals; uv = (phi / 2 pi, z) and dp/du along the circle, as Mitsuba 3.
struct Cylinder {
    Vec3f origin = Vec3f::Zero();                 // world position of the object origin (p0)
    Mat3f linear = Mat3f::Identity();             // world_from_object's linear part
    Mat3f object_from_world = Mat3f::Identity();  // its inverse
    float radius = 1.f;
    float length = 1.f;
    bool flip_normals = false;

    Vec3f to_object(const Vec3f& world_point) const {
        return object_from_world * (world_point - origin);
    }
};

struct ShapeSample {
    Vec3f p = Vec3f::Zero();
    Vec3f n_geometric = Vec3f::UnitZ();
    float pdf_area = 0.f;
};

class Shape {
  public:
    Shape(TriangleMesh mesh, int bsdf, std::string id);
    Shape(Sphere sphere, int bsdf, std::string id);
    Shape(Cylinder cylinder, int bsdf, std::string id);

    const std::variant<TriangleMesh, Sphere, Cylinder>& geometry() const { return geometry_; }
    int bsdf() const { return bsdf_; }
    int emitter() const { return emitter_; }
    void set_emitter(int emitter) { emitter_ = emitter; }
    const std::string& id() const { return id_; }
    float surface_area() const { return area_; }
    bool is_mesh() const { return std::holds_alternative<TriangleMesh>(geometry_); }

    /// Full differential geometry at a hit found by the accelerator (primitive, barycentrics
    /// (b1, b2) for triangles; the ray is used for the sphere's hit position). This is the
    /// path tracer's per-hit cost, so triangle data that do not depend on the hit point (the
    /// unit geometric normal) are precomputed once per triangle.
    SurfaceInteraction interaction(std::uint32_t primitive, const Vec2f& barycentric,
                                   const Vec3f& ray_origin, const Vec3f& ray_direction,
                                   float t) const;

    /// Differential geometry at surface parameters (the manifold walk's move along a surface).
    SurfaceInteraction interaction_at(std::uint32_t primitive, const Vec2f& surface_param) const;

    /// Unit face normal of mesh triangle `triangle` (flip_normals applied; zero if degenerate).
    const Vec3f& triangle_normal(std::uint32_t triangle) const { return face_normals_[triangle]; }
    /// Reference tangent of mesh triangle `triangle`'s shading frame (triangle_tangent.h: dp/du
    /// of its texture coordinates, or its first edge).
    const Vec3f& triangle_frame_tangent(std::uint32_t triangle) const {
        return frame_tangents_[triangle];
    }
    /// A mesh's triangle chosen by area with `u_primitive`, as sample_area chooses it: its
    /// corners and unit face normal (null pointers for a sphere or a mesh without area).
    struct AreaTriangle {
        const Vec3f *a = nullptr, *b = nullptr, *c = nullptr;
        const Vec3f* n_geometric = nullptr;
    };
    AreaTriangle area_triangle(float u_primitive) const {
        AreaTriangle t;
        const auto* mesh = std::get_if<TriangleMesh>(&geometry_);
        if (!mesh || !triangle_areas_.valid()) return t;
        const auto triangle = static_cast<std::size_t>(area_triangle_index(u_primitive));
        const std::uint32_t* index = &mesh->indices[3 * triangle];
        t.a = &mesh->positions[index[0]];
        t.b = &mesh->positions[index[1]];
        t.c = &mesh->positions[index[2]];
        t.n_geometric = &face_normals_[triangle];
        return t;
    }
    /// The index of the triangle area_triangle chooses (valid only where it returns corners).
    std::uint32_t area_triangle_index(float u_primitive) const {
        return static_cast<std::uint32_t>(triangle_areas_.sample(u_primitive));
    }
    /// A point uniformly distributed by area (pdf_area = 1/area). Inline: next-event
    /// estimation calls it once per path vertex, as often as a ray is cast.
    ShapeSample sample_area(const Vec2f& u, float u_primitive) const {
        ShapeSample s;
        if (is_mesh()) {
            const AreaTriangle triangle = area_triangle(u_primitive);
            if (!triangle.a) return s;
            // Only the point and the face normal: an emitter sample needs no shading frame or
            // differentials.
            const Vec2f b = warp::square_to_uniform_triangle(u);
            s.p = (1.f - b.x() - b.y()) * *triangle.a + b.x() * *triangle.b + b.y() * *triangle.c;
            s.n_geometric = *triangle.n_geometric;
        } else if (const auto* sphere = std::get_if<Sphere>(&geometry_)) {
            const Vec3f dir = warp::square_to_uniform_sphere(u);
            s.p = sphere->center + sphere->radius * dir;
            s.n_geometric = sphere->flip_normals ? Vec3f(-dir) : dir;
        } else {
            // Uniform in (phi, z): the area element r dphi length dz is constant.
            const auto& cylinder = std::get<Cylinder>(geometry_);
            const float phi = 2.f * kPi * u.x();
            const Vec3f local(std::cos(phi), std::sin(phi), u.y());
            s.p = cylinder.origin + cylinder.linear * local;
            const Vec3f n = (cylinder.linear * Vec3f(local.x(), local.y(), 0.f)).normalized();
            s.n_geometric = cylinder.flip_normals ? Vec3f(-n) : n;
        }
        s.pdf_area = pdf_area_;
        return s;
    }

  private:
    std::variant<TriangleMesh, Sphere, Cylinder> geometry_;
    /// Unit geometric normal per triangle, flip_normals applied (zero for a degenerate
    /// triangle): computed once instead of a cross product and a square root per hit and per
    /// emitter sample. 12 bytes per triangle, half of what positions and indices take.
    std::vector<Vec3f> face_normals_;
    std::vector<Vec3f> frame_tangents_;
    AliasTable triangle_areas_;  // a triangle by area in constant time (alias_table.h)
    int bsdf_ = -1;
    int emitter_ = -1;
    float area_ = 0.f;
    float pdf_area_ = 0.f;  // 1 / area_ (0 for no area), once rather than per sample
    std::string id_;
};

}  // namespace gdmlt
