// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Ray queries against the scene's shapes. Embree 3 is used in accelerator.cpp only; this header
// exposes nothing of it.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/geometry/ray.h"
#include "core/geometry/shape.h"

namespace gdmlt {

/// What the accelerator reports; Shape::interaction turns it into full differential geometry.
struct RayHit {
    float t = kInfinity;
    Vec2f barycentric = Vec2f::Zero();
    std::int32_t shape = -1;
    std::uint32_t primitive = 0;
    bool valid() const { return shape >= 0; }
};

/// Up to 16 rays (Accelerator::kPacketSize) in structure-of-arrays form, the layout of
/// Embree's packet queries: a caller that keeps its rays elsewhere writes each ray once,
/// and the accelerator copies whole arrays (before, the wavefront copied its rays into a list
/// and the accelerator transposed that lane by lane: about 4% of the path tracer's time).
/// Lanes past `count` are ignored; they start as zeros and keep finite old rays.
struct RayPacket {
    static constexpr int kSize = 16;
    using Lanes = std::array<float, kSize>;
    alignas(64) Lanes origin_x{}, origin_y{}, origin_z{};
    alignas(64) Lanes direction_x{}, direction_y{}, direction_z{};
    alignas(64) Lanes t_max{};
    int count = 0;

    void set(int i, const Ray& ray) {
        const auto k = static_cast<std::size_t>(i);
        origin_x[k] = ray.origin.x();
        origin_y[k] = ray.origin.y();
        origin_z[k] = ray.origin.z();
        direction_x[k] = ray.direction.x();
        direction_y[k] = ray.direction.y();
        direction_z[k] = ray.direction.z();
        t_max[k] = ray.t_max;
    }
};

/// The closest hits of a RayPacket's rays, in Embree's layout; hit(i) is lane i's RayHit.
struct HitPacket {
    static constexpr int kSize = RayPacket::kSize;
    alignas(64) std::array<float, kSize> t{}, u{}, v{};
    alignas(64) std::array<std::int32_t, kSize> shape{};  // -1: no hit
    alignas(64) std::array<std::uint32_t, kSize> primitive{};

    RayHit hit(int i) const {
        const auto k = static_cast<std::size_t>(i);
        if (shape[k] < 0) return RayHit{};
        return RayHit{t[k], Vec2f(u[k], v[k]), shape[k], primitive[k]};
    }
};

class Accelerator {
  public:
    /// Builds the BVH over `shapes` (shape index = Embree geometry id). Immutable afterwards;
    /// queries are thread-safe.
    explicit Accelerator(const std::vector<Shape>& shapes);
    ~Accelerator();
    Accelerator(const Accelerator&) = delete;
    Accelerator& operator=(const Accelerator&) = delete;

    RayHit intersect(const Ray& ray) const;
    bool occluded(const Ray& ray) const;

    /// Largest number of rays the packet queries take at once (Embree's 16-wide queries). Widths
    /// 8 and 4 (rtcIntersect8/4) were measured too: 0.86-0.97x and 0.62-0.92x the rate per ray
    /// of 16 on an AVX-512 machine, for every kind of ray.
    static constexpr int kPacketSize = 16;
    static_assert(RayPacket::kSize == kPacketSize);
    /// The closest hits of a packet's rays, traced together (rtcIntersect16): Embree
    /// traverses the BVH once for the packet, which on incoherent path-tracing rays is still
    /// 1.3-1.9x the rate of one-ray queries (bench_embree). `coherent` tells Embree the rays
    /// are nearly alike (camera rays through one pixel), which it then traces as one frustum:
    /// 2.5x the rate on such rays, but 0.3-0.6x on unrelated ones (bench_embree, packets of
    /// camera, bounce and shadow rays). Only a hint: the hits are the same up to rounding.
    void intersect_packet(const RayPacket& rays, HitPacket& hits, bool coherent = false) const;
    /// Shadow queries of a packet's rays (rtcOccluded16): occluded[i] for ray i < rays.count.
    void occluded_packet(const RayPacket& rays, std::array<bool, kPacketSize>& occluded) const;

    /// World-space bounds of everything.
    Eigen::AlignedBox3f bounds() const { return bounds_; }

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    Eigen::AlignedBox3f bounds_;
};

}  // namespace gdmlt
