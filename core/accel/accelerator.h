// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Ray queries against the scene's shapes. Embree 3 is used in accelerator.cpp only; this header
// exposes nothing of it.
#include <cstdint>
#include <memory>
#include <span>
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
    /// The closest hits of up to kPacketSize rays, traced together (rtcIntersect16): Embree
    /// traverses the BVH once for the packet, which on incoherent path-tracing rays is still
    /// 1.3-1.9x the rate of one-ray queries (bench_embree). hits.size() >= rays.size().
    /// `coherent` tells Embree the rays are nearly alike (camera rays through one pixel), which
    /// it then traces as one frustum: 2.5x the rate on such rays, but 0.3-0.6x on unrelated
    /// ones (bench_embree, packets of camera, bounce and shadow rays). Only a hint: the hits
    /// are the same up to rounding.
    void intersect_packet(std::span<const Ray> rays, std::span<RayHit> hits,
                          bool coherent = false) const;
    /// Shadow queries of up to kPacketSize rays (rtcOccluded16); occluded.size() >= rays.size().
    void occluded_packet(std::span<const Ray> rays, std::span<bool> occluded) const;

    /// World-space bounds of everything.
    Eigen::AlignedBox3f bounds() const { return bounds_; }

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    Eigen::AlignedBox3f bounds_;
};

}  // namespace gdmlt
