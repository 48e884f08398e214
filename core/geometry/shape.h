// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Shapes in world space. Triangle meshes (obj, ply, rectangle, cube, disk), analytic spheres and
// cylinders, and meshes placed by instances (stored once, in their shapegroup's space).
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

class Shape;

/// One of a shapegroup's meshes placed by Mitsuba 3's `instance`: the mesh is stored once, in
/// the group's object space (`object`, a TriangleMesh shape shared by every instance of the
/// group), and Embree traces it as an instance (accelerator.cpp), so memory does not grow with
/// the triangles times the instances. Its differential geometry is the object-space one mapped
/// by world_from_object (Shape::interaction); mirroring transforms keep the normals on the
/// side the object's winding gives them (as a flattened mesh whose corners are swapped).
struct MeshInstance {
    std::shared_ptr<const Shape> object;
    Mat3f linear = Mat3f::Identity();         // world_from_object's linear part
    Vec3f translation = Vec3f::Zero();        // and its translation
    Mat3f normal_linear = Mat3f::Identity();  // linear^-T: maps normals
    bool mirrored = false;                    // det(linear) < 0

    MeshInstance() = default;
    MeshInstance(std::shared_ptr<const Shape> object_mesh, const Mat3f& linear_part,
                 const Vec3f& translation_part)
        : object(std::move(object_mesh)),
          linear(linear_part),
          translation(translation_part),
          normal_linear(linear_part.inverse().transpose()),
          mirrored(linear_part.determinant() < 0.f) {}

    /// The shared mesh, in object space.
    const TriangleMesh& mesh() const;
    Vec3f to_world(const Vec3f& p_object) const { return linear * p_object + translation; }
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
    /// An instance's mesh; `instance.object` must hold a TriangleMesh. Instances do not emit
    /// (Mitsuba 3 forbids emitters in a shapegroup), so no per-triangle tables are built.
    Shape(MeshInstance instance, int bsdf, std::string id);

    using Geometry = std::variant<TriangleMesh, Sphere, Cylinder, MeshInstance>;
    const Geometry& geometry() const { return geometry_; }
    int bsdf() const { return bsdf_; }
    int emitter() const { return emitter_; }
    void set_emitter(int emitter) { emitter_ = emitter; }
    const std::string& id() const { return id_; }
    float surface_area() const { return area_; }
    bool is_mesh() const { return std::holds_alternative<TriangleMesh>(geometry_); }
    /// A triangle mesh, stored here or shared through an instance.
    bool has_triangles() const { return is_mesh() || is_instance(); }
    bool is_instance() const { return std::holds_alternative<MeshInstance>(geometry_); }
    /// The triangles' object-space mesh: the shape's own (world space) or its instance's.
    /// Null for spheres and cylinders.
    const TriangleMesh* object_mesh() const;

    /// Full differential geometry at a hit found by the accelerator (primitive, barycentrics
    /// (b1, b2) for triangles; the ray is used for the sphere's hit position). This is the
    /// path tracer's per-hit cost, so triangle data that do not depend on the hit point (the
    /// unit geometric normal) are precomputed once per triangle.
    SurfaceInteraction interaction(std::uint32_t primitive, const Vec2f& barycentric,
                                   const Vec3f& ray_origin, const Vec3f& ray_direction,
                                   float t) const;

    /// Differential geometry at surface parameters (the manifold walk's move along a surface).
    SurfaceInteraction interaction_at(std::uint32_t primitive, const Vec2f& surface_param) const;

    /// Unit face normal of mesh triangle `triangle` (flip_normals applied; zero if degenerate);
    /// stored meshes only (not instances).
    const Vec3f& triangle_normal(std::uint32_t triangle) const { return face_normals_[triangle]; }
    /// Reference tangent of mesh triangle `triangle`'s shading frame (triangle_tangent.h: dp/du
    /// of its texture coordinates, or its first edge); stored meshes only.
    const Vec3f& triangle_frame_tangent(std::uint32_t triangle) const {
        return frame_tangents_[triangle];
    }
    /// A mesh's triangle chosen by area with `u_primitive`, as sample_area chooses it: its
    /// corners and unit face normal (null pointers for a sphere, an instance or a mesh without
    /// area).
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
    /// estimation calls it once per path vertex, as often as a ray is cast. Emitting shapes
    /// only: never an instance.
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
        } else if (const auto* cylinder_ptr = std::get_if<Cylinder>(&geometry_)) {
            // Uniform in (phi, z): the area element r dphi length dz is constant.
            const Cylinder& cylinder = *cylinder_ptr;
            const float phi = 2.f * kPi * u.x();
            const Vec3f local(std::cos(phi), std::sin(phi), u.y());
            s.p = cylinder.origin + cylinder.linear * local;
            const Vec3f n = (cylinder.linear * Vec3f(local.x(), local.y(), 0.f)).normalized();
            s.n_geometric = cylinder.flip_normals ? Vec3f(-n) : n;
        } else {
            return s;  // an instance: never an emitter (pdf_area 0)
        }
        s.pdf_area = pdf_area_;
        return s;
    }

  private:
    Geometry geometry_;
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

inline const TriangleMesh& MeshInstance::mesh() const {
    return std::get<TriangleMesh>(object->geometry());
}

inline const TriangleMesh* Shape::object_mesh() const {
    if (const auto* mesh = std::get_if<TriangleMesh>(&geometry_)) return mesh;
    if (const auto* instance = std::get_if<MeshInstance>(&geometry_)) return &instance->mesh();
    return nullptr;
}

}  // namespace gdmlt
