// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Ray queries against the scene's shapes. Embree 3 is used in accelerator.cpp only; this header
// exposes nothing of it.
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

    /// World-space bounds of everything.
    Eigen::AlignedBox3f bounds() const { return bounds_; }

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    Eigen::AlignedBox3f bounds_;
};

}  // namespace gdmlt
