// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/accel/accelerator.h"

#include <embree3/rtcore.h>

#include <cstring>
#include <stdexcept>
#include <string>

namespace gdmlt {

struct Accelerator::Impl {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
};

namespace {

void throw_on_error(RTCDevice device, const char* what) {
    const RTCError error = rtcGetDeviceError(device);
    if (error != RTC_ERROR_NONE)
        throw std::runtime_error(std::string("Embree error ") + std::to_string(error) + " in " +
                                 what);
}

}  // namespace

Accelerator::Accelerator(const std::vector<Shape>& shapes) : impl_(std::make_unique<Impl>()) {
    impl_->device = rtcNewDevice("verbose=0");
    if (!impl_->device) throw std::runtime_error("cannot create an Embree device");
    impl_->scene = rtcNewScene(impl_->device);
    rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
    bounds_.setEmpty();

    for (std::size_t i = 0; i < shapes.size(); ++i) {
        const Shape& shape = shapes[i];
        RTCGeometry geometry = nullptr;
        if (const auto* mesh = std::get_if<TriangleMesh>(&shape.geometry())) {
            geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
            auto* vertices = static_cast<float*>(
                rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                        3 * sizeof(float), mesh->positions.size()));
            for (std::size_t v = 0; v < mesh->positions.size(); ++v) {
                for (int k = 0; k < 3; ++k) vertices[3 * v + k] = mesh->positions[v][k];
                bounds_.extend(mesh->positions[v]);
            }
            auto* indices = static_cast<unsigned*>(
                rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                        3 * sizeof(unsigned), mesh->triangle_count()));
            for (std::size_t k = 0; k < mesh->indices.size(); ++k) indices[k] = mesh->indices[k];
        } else {
            const auto& sphere = std::get<Sphere>(shape.geometry());
            geometry = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
            auto* point = static_cast<float*>(rtcSetNewGeometryBuffer(
                geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
            point[0] = sphere.center.x();
            point[1] = sphere.center.y();
            point[2] = sphere.center.z();
            point[3] = sphere.radius;
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
    hit.shape = static_cast<std::int32_t>(rayhit.hit.geomID);
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
