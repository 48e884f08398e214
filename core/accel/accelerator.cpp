// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/accel/accelerator.h"

#include <embree3/rtcore.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/geometry/sphere_intersect.h"

namespace gdmlt {

struct Accelerator::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    // The spheres' own copies, which their Embree geometries point to (reserved once: the
    // addresses never move, whatever happens to the shapes the accelerator was built from).
    std::vector<Sphere> spheres;
    std::vector<Cylinder> cylinders;
    /// One scene per mesh that instances share (its single triangle geometry has id 0), traced
    /// through RTC_GEOMETRY_TYPE_INSTANCE geometries whose ids are the instances' shape indices.
    struct InstancedMesh {
        RTCScene scene = nullptr;
        Eigen::AlignedBox3f bounds;  // object space
    };
    std::map<const Shape*, InstancedMesh> instanced_meshes;
    bool has_instances = false;
};

namespace {

void throw_on_error(RTCDevice device, const char* what) {
    const RTCError error = rtcGetDeviceError(device);
    if (error != RTC_ERROR_NONE)
        throw std::runtime_error(std::string("Embree error ") + std::to_string(error) + " in " +
                                 what);
}

// The sphere geometry's callbacks. Embree calls them with N = 1 for single-ray queries and
// N = 16 for packets, `valid` marking the rays to test; they read and write Embree's SoA
// records directly (no filter functions are registered, so no rtcFilterIntersection).

void sphere_bounds(const RTCBoundsFunctionArguments* args) {
    const auto& sphere = *static_cast<const Sphere*>(args->geometryUserPtr);
    RTCBounds& b = *args->bounds_o;
    b.lower_x = sphere.center.x() - sphere.radius;
    b.lower_y = sphere.center.y() - sphere.radius;
    b.lower_z = sphere.center.z() - sphere.radius;
    b.upper_x = sphere.center.x() + sphere.radius;
    b.upper_y = sphere.center.y() + sphere.radius;
    b.upper_z = sphere.center.z() + sphere.radius;
}

float sphere_distance(const Sphere& sphere, RTCRayN* ray, unsigned n, unsigned i) {
    return intersect_sphere(sphere.center.x(), sphere.center.y(), sphere.center.z(), sphere.radius,
                            RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i),
                            RTCRayN_org_z(ray, n, i), RTCRayN_dir_x(ray, n, i),
                            RTCRayN_dir_y(ray, n, i), RTCRayN_dir_z(ray, n, i),
                            RTCRayN_tnear(ray, n, i), RTCRayN_tfar(ray, n, i));
}

// Lane by lane over the valid rays only: Embree calls these for every packet whose traversal
// reaches the sphere's leaf, often with a few of the 16 lanes valid, and computing all 16 in
// SIMD (SSE2, the build's baseline) halved the packet rates on cbox_glass_sphere's random rays.
void sphere_intersect(const RTCIntersectFunctionNArguments* args) {
    const auto& sphere = *static_cast<const Sphere*>(args->geometryUserPtr);
    const unsigned n = args->N;
    RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, n);
    RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, n);
    for (unsigned i = 0; i < n; ++i) {
        if (!args->valid[i]) continue;
        const float t = sphere_distance(sphere, ray, n, i);
        if (!(t < kInfinity)) continue;  // else t < tfar
        RTCRayN_tfar(ray, n, i) = t;
        // Shape::interaction rebuilds the point and normal from t; Ng is the outward normal
        // for anyone who reads it, u and v are unused.
        RTCHitN_Ng_x(hit, n, i) =
            RTCRayN_org_x(ray, n, i) + t * RTCRayN_dir_x(ray, n, i) - sphere.center.x();
        RTCHitN_Ng_y(hit, n, i) =
            RTCRayN_org_y(ray, n, i) + t * RTCRayN_dir_y(ray, n, i) - sphere.center.y();
        RTCHitN_Ng_z(hit, n, i) =
            RTCRayN_org_z(ray, n, i) + t * RTCRayN_dir_z(ray, n, i) - sphere.center.z();
        RTCHitN_u(hit, n, i) = 0.f;
        RTCHitN_v(hit, n, i) = 0.f;
        RTCHitN_primID(hit, n, i) = args->primID;
        RTCHitN_geomID(hit, n, i) = args->geomID;
        RTCHitN_instID(hit, n, i, 0) = args->context->instID[0];
    }
}

void sphere_occluded(const RTCOccludedFunctionNArguments* args) {
    const auto& sphere = *static_cast<const Sphere*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
        if (!args->valid[i]) continue;
        // Embree's convention for a blocked ray: tfar = -inf.
        if (sphere_distance(sphere, args->ray, args->N, i) < kInfinity)
            RTCRayN_tfar(args->ray, args->N, i) = -std::numeric_limits<float>::infinity();
    }
}

// The cylinder geometry's callbacks: the ray in the cylinder's object space (an affine map keeps
// t), the unit circle's quadratic in double precision, the nearer root whose height is within
// [0, 1] (the cylinder is open: a ray can enter through an end and leave through the wall).

/// World bounds of the cylinder: its object-space box [-1, 1]^2 x [0, 1] mapped.
Eigen::AlignedBox3f cylinder_box(const Cylinder& c) {
    Eigen::AlignedBox3f box;
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3f local((corner & 1) ? 1.f : -1.f, (corner & 2) ? 1.f : -1.f,
                          (corner & 4) ? 1.f : 0.f);
        box.extend(c.origin + c.linear * local);
    }
    return box;
}

void cylinder_bounds(const RTCBoundsFunctionArguments* args) {
    const Eigen::AlignedBox3f box =
        cylinder_box(*static_cast<const Cylinder*>(args->geometryUserPtr));
    RTCBounds& b = *args->bounds_o;
    b.lower_x = box.min().x();
    b.lower_y = box.min().y();
    b.lower_z = box.min().z();
    b.upper_x = box.max().x();
    b.upper_y = box.max().y();
    b.upper_z = box.max().z();
}

/// Distance to the first hit within (tnear, tfar), or infinity.
float cylinder_distance(const Cylinder& c, RTCRayN* ray, unsigned n, unsigned i) {
    const Vec3f origin(RTCRayN_org_x(ray, n, i), RTCRayN_org_y(ray, n, i),
                       RTCRayN_org_z(ray, n, i));
    const Vec3f direction(RTCRayN_dir_x(ray, n, i), RTCRayN_dir_y(ray, n, i),
                          RTCRayN_dir_z(ray, n, i));
    const Vec3d o = c.to_object(origin).cast<double>();
    const Vec3d d = (c.object_from_world * direction).cast<double>();
    const double a = d.x() * d.x() + d.y() * d.y();
    if (!(a > 0.0)) return kInfinity;                // along the axis
    const double b = o.x() * d.x() + o.y() * d.y();  // half the linear coefficient
    const double cc = o.x() * o.x() + o.y() * o.y() - 1.0;
    const double discriminant = b * b - a * cc;
    if (!(discriminant >= 0.0)) return kInfinity;
    // The root without cancellation first, the other from the product of the roots.
    const double q = -(b + std::copysign(std::sqrt(discriminant), b));
    double t0 = q / a, t1 = q != 0.0 ? cc / q : t0;
    if (t0 > t1) std::swap(t0, t1);
    const double tnear = RTCRayN_tnear(ray, n, i), tfar = RTCRayN_tfar(ray, n, i);
    for (const double t : {t0, t1}) {
        if (!(t > tnear) || !(t < tfar)) continue;
        const double z = o.z() + t * d.z();
        if (z >= 0.0 && z <= 1.0) return static_cast<float>(t);
    }
    return kInfinity;
}

void cylinder_intersect(const RTCIntersectFunctionNArguments* args) {
    const auto& c = *static_cast<const Cylinder*>(args->geometryUserPtr);
    const unsigned n = args->N;
    RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, n);
    RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, n);
    for (unsigned i = 0; i < n; ++i) {
        if (!args->valid[i]) continue;
        const float t = cylinder_distance(c, ray, n, i);
        if (!(t < kInfinity) || !(t < RTCRayN_tfar(ray, n, i))) continue;
        RTCRayN_tfar(ray, n, i) = t;
        // Shape::interaction rebuilds the point and normal from t; Ng is the outward normal
        // for anyone who reads it.
        const Vec3f p(RTCRayN_org_x(ray, n, i) + t * RTCRayN_dir_x(ray, n, i),
                      RTCRayN_org_y(ray, n, i) + t * RTCRayN_dir_y(ray, n, i),
                      RTCRayN_org_z(ray, n, i) + t * RTCRayN_dir_z(ray, n, i));
        const Vec3f local = c.to_object(p);
        const Vec3f ng = c.object_from_world.transpose() * Vec3f(local.x(), local.y(), 0.f);
        RTCHitN_Ng_x(hit, n, i) = ng.x();
        RTCHitN_Ng_y(hit, n, i) = ng.y();
        RTCHitN_Ng_z(hit, n, i) = ng.z();
        RTCHitN_u(hit, n, i) = 0.f;
        RTCHitN_v(hit, n, i) = 0.f;
        RTCHitN_primID(hit, n, i) = args->primID;
        RTCHitN_geomID(hit, n, i) = args->geomID;
        RTCHitN_instID(hit, n, i, 0) = args->context->instID[0];
    }
}

void cylinder_occluded(const RTCOccludedFunctionNArguments* args) {
    const auto& c = *static_cast<const Cylinder*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
        if (!args->valid[i]) continue;
        if (cylinder_distance(c, args->ray, args->N, i) < kInfinity)
            RTCRayN_tfar(args->ray, args->N, i) = -std::numeric_limits<float>::infinity();
    }
}

/// A committed triangle geometry holding `mesh`'s vertices and indices.
RTCGeometry new_triangle_geometry(RTCDevice device, const TriangleMesh& mesh) {
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* vertices = static_cast<float*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                3 * sizeof(float), mesh.positions.size()));
    for (std::size_t v = 0; v < mesh.positions.size(); ++v)
        for (int k = 0; k < 3; ++k) vertices[3 * v + k] = mesh.positions[v][k];
    auto* indices = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(unsigned), mesh.triangle_count()));
    for (std::size_t k = 0; k < mesh.indices.size(); ++k) indices[k] = mesh.indices[k];
    return geometry;
}

/// An instance's hits name the instance (instID, its shape index), not the shared mesh inside
/// it (geomID 0 of its own scene).
std::int32_t shape_of_hit(unsigned geometry_id, unsigned instance_id) {
    return static_cast<std::int32_t>(instance_id != RTC_INVALID_GEOMETRY_ID ? instance_id
                                                                            : geometry_id);
}

}  // namespace

Accelerator::Accelerator(const std::vector<Shape>& shapes) : impl_(std::make_unique<Impl>()) {
    impl_->device = rtcNewDevice("verbose=0");
    if (!impl_->device) throw std::runtime_error("cannot create an Embree device");
    impl_->scene = rtcNewScene(impl_->device);
    rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
    bounds_.setEmpty();
    impl_->spheres.reserve(shapes.size());
    impl_->cylinders.reserve(shapes.size());

    for (std::size_t i = 0; i < shapes.size(); ++i) {
        const Shape& shape = shapes[i];
        RTCGeometry geometry = nullptr;
        if (const auto* mesh = std::get_if<TriangleMesh>(&shape.geometry())) {
            geometry = new_triangle_geometry(impl_->device, *mesh);
            for (const Vec3f& p : mesh->positions) bounds_.extend(p);
        } else if (const auto* instance = std::get_if<MeshInstance>(&shape.geometry())) {
            // The shared mesh's scene, built once for all its instances.
            Impl::InstancedMesh& object = impl_->instanced_meshes[instance->object.get()];
            RTCScene& object_scene = object.scene;
            if (!object_scene) {
                object.bounds.setEmpty();
                for (const Vec3f& p : instance->mesh().positions) object.bounds.extend(p);
                object_scene = rtcNewScene(impl_->device);
                rtcSetSceneBuildQuality(object_scene, RTC_BUILD_QUALITY_HIGH);
                RTCGeometry triangles = new_triangle_geometry(impl_->device, instance->mesh());
                rtcCommitGeometry(triangles);
                rtcAttachGeometryByID(object_scene, triangles, 0);
                rtcReleaseGeometry(triangles);
                rtcCommitScene(object_scene);
                throw_on_error(impl_->device, "instanced mesh setup");
            }
            geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_INSTANCE);
            rtcSetGeometryInstancedScene(geometry, object_scene);
            // Embree's 3x4 column-major affine map: the linear part's columns, then the
            // translation.
            float world_from_object[12];
            for (int column = 0; column < 3; ++column)
                for (int row = 0; row < 3; ++row)
                    world_from_object[3 * column + row] = instance->linear(row, column);
            for (int row = 0; row < 3; ++row)
                world_from_object[9 + row] = instance->translation[row];
            rtcSetGeometryTransform(geometry, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR,
                                    world_from_object);
            for (int corner = 0; corner < 8; ++corner)
                bounds_.extend(instance->to_world(
                    object.bounds.corner(static_cast<Eigen::AlignedBox3f::CornerType>(corner))));
            impl_->has_instances = true;
        } else if (const auto* cylinder = std::get_if<Cylinder>(&shape.geometry())) {
            const Cylinder& c = impl_->cylinders.emplace_back(*cylinder);
            geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_USER);
            rtcSetGeometryUserPrimitiveCount(geometry, 1);
            rtcSetGeometryUserData(geometry, impl_->cylinders.data() + impl_->cylinders.size() - 1);
            rtcSetGeometryBoundsFunction(geometry, cylinder_bounds, nullptr);
            rtcSetGeometryIntersectFunction(geometry, cylinder_intersect);
            rtcSetGeometryOccludedFunction(geometry, cylinder_occluded);
            bounds_.extend(cylinder_box(c));
        } else {
            // A sphere is a user geometry with our own intersection (sphere_intersect.h), not
            // Embree's RTC_GEOMETRY_TYPE_SPHERE_POINT, which runs through the curve machinery:
            // on cbox_glass_sphere's random rays (bench_embree random, 2 threads, packets) it
            // traced 21.0 M rays/s against 28.5 for the user geometry (Mitsuba 3, whose
            // spheres are built this way: 33.0 with bench/mitsuba_rays.py).
            const Sphere& sphere = impl_->spheres.emplace_back(std::get<Sphere>(shape.geometry()));
            geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_USER);
            rtcSetGeometryUserPrimitiveCount(geometry, 1);
            rtcSetGeometryUserData(geometry, impl_->spheres.data() + impl_->spheres.size() - 1);
            rtcSetGeometryBoundsFunction(geometry, sphere_bounds, nullptr);
            rtcSetGeometryIntersectFunction(geometry, sphere_intersect);
            rtcSetGeometryOccludedFunction(geometry, sphere_occluded);
            bounds_.extend(sphere.center - Vec3f::Constant(sphere.radius));
            bounds_.extend(sphere.center + Vec3f::Constant(sphere.radius));
        }
        rtcCommitGeometry(geometry);
        rtcAttachGeometryByID(impl_->scene, geometry, static_cast<unsigned>(i));
        rtcReleaseGeometry(geometry);
        throw_on_error(impl_->device, "geometry setup");
    }
    rtcCommitScene(impl_->scene);
    throw_on_error(impl_->device, "scene commit");
}

Accelerator::~Accelerator() {
    if (impl_->scene) rtcReleaseScene(impl_->scene);
    for (const auto& [shape, object] : impl_->instanced_meshes) rtcReleaseScene(object.scene);
    if (impl_->device) rtcReleaseDevice(impl_->device);
}

RayHit Accelerator::intersect(const Ray& ray) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRayHit rayhit;
    rayhit.ray.org_x = ray.origin.x();
    rayhit.ray.org_y = ray.origin.y();
    rayhit.ray.org_z = ray.origin.z();
    rayhit.ray.dir_x = ray.direction.x();
    rayhit.ray.dir_y = ray.direction.y();
    rayhit.ray.dir_z = ray.direction.z();
    rayhit.ray.tnear = 0.f;
    rayhit.ray.tfar = ray.t_max;
    rayhit.ray.mask = ~0u;
    rayhit.ray.flags = 0;
    rayhit.ray.time = 0.f;
    rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(impl_->scene, &context, &rayhit);

    RayHit hit;
    if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    hit.t = rayhit.ray.tfar;
    hit.barycentric = Vec2f(rayhit.hit.u, rayhit.hit.v);
    hit.shape = shape_of_hit(rayhit.hit.geomID, rayhit.hit.instID[0]);
    hit.primitive = rayhit.hit.primID;
    return hit;
}

bool Accelerator::occluded(const Ray& ray) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay r;
    r.org_x = ray.origin.x();
    r.org_y = ray.origin.y();
    r.org_z = ray.origin.z();
    r.dir_x = ray.direction.x();
    r.dir_y = ray.direction.y();
    r.dir_z = ray.direction.z();
    r.tnear = 0.f;
    r.tfar = ray.t_max;
    r.mask = ~0u;
    r.flags = 0;
    r.time = 0.f;
    rtcOccluded1(impl_->scene, &context, &r);
    // Embree sets tfar to -inf when the ray is blocked.
    return r.tfar < 0.f;
}

namespace {

/// Copies `rays` into Embree's packet, whole arrays at a time, and sets `valid` to its count.
void fill_packet(const RayPacket& rays, int (&valid)[Accelerator::kPacketSize], RTCRay16& packet) {
    constexpr std::size_t kBytes = sizeof(RayPacket::Lanes);
    static_assert(sizeof(packet.org_x) == kBytes);
    std::memcpy(packet.org_x, rays.origin_x.data(), kBytes);
    std::memcpy(packet.org_y, rays.origin_y.data(), kBytes);
    std::memcpy(packet.org_z, rays.origin_z.data(), kBytes);
    std::memcpy(packet.dir_x, rays.direction_x.data(), kBytes);
    std::memcpy(packet.dir_y, rays.direction_y.data(), kBytes);
    std::memcpy(packet.dir_z, rays.direction_z.data(), kBytes);
    std::memcpy(packet.tfar, rays.t_max.data(), kBytes);
    for (int i = 0; i < Accelerator::kPacketSize; ++i) {
        valid[i] = i < rays.count ? -1 : 0;
        packet.tnear[i] = 0.f;
        packet.mask[i] = ~0u;
        packet.flags[i] = 0;
        packet.time[i] = 0.f;
    }
}

}  // namespace

void Accelerator::intersect_packet(const RayPacket& rays, HitPacket& hits, bool coherent) const {
    if (rays.count <= 0) return;
    alignas(64) int valid[kPacketSize];
    alignas(64) RTCRayHit16 packet;
    fill_packet(rays, valid, packet.ray);
    for (int i = 0; i < kPacketSize; ++i) {
        packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        packet.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);  // flags: RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT
    if (coherent) context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    rtcIntersect16(valid, impl_->scene, &context, &packet);
    constexpr std::size_t kBytes = sizeof(hits.t);
    std::memcpy(hits.t.data(), packet.ray.tfar, kBytes);
    std::memcpy(hits.u.data(), packet.hit.u, kBytes);
    std::memcpy(hits.v.data(), packet.hit.v, kBytes);
    std::memcpy(hits.primitive.data(), packet.hit.primID, kBytes);
    // RTC_INVALID_GEOMETRY_ID is ~0u: -1 as a shape index, "no hit".
    static_assert(static_cast<std::int32_t>(RTC_INVALID_GEOMETRY_ID) == -1);
    std::memcpy(hits.shape.data(), packet.hit.geomID, kBytes);
    if (impl_->has_instances)
        for (int i = 0; i < rays.count; ++i)
            hits.shape[static_cast<std::size_t>(i)] =
                packet.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID
                    ? -1
                    : shape_of_hit(packet.hit.geomID[i], packet.hit.instID[0][i]);
}

void Accelerator::occluded_packet(const RayPacket& rays,
                                  std::array<bool, kPacketSize>& occluded) const {
    if (rays.count <= 0) return;
    alignas(64) int valid[kPacketSize];
    alignas(64) RTCRay16 packet;
    fill_packet(rays, valid, packet);
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    rtcOccluded16(valid, impl_->scene, &context, &packet);
    // Embree sets tfar to -inf when the ray is blocked.
    for (int i = 0; i < kPacketSize; ++i)
        occluded[static_cast<std::size_t>(i)] = packet.tfar[i] < 0.f;
}

}  // namespace gdmlt
