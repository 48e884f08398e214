// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The path tracer's vertex on diffuse surfaces, for many paths at once in structure-of-arrays
// form, computed with SIMD instructions: 16 lanes per instruction with AVX-512, 8 with AVX2, 4
// with SSE2, the widest the processor has (chosen at run time).
//
// Why: the one-path estimator (finish_vertex) is straight-line scalar float arithmetic, about
// 1,000 instructions per diffuse vertex once BSDF dispatch and emitter sampling are counted,
// several times Embree's own work per ray; Mitsuba 3 runs the same arithmetic 16 lanes per
// instruction (a JIT-compiled wavefront). Lanes here are the wavefront's paths whose vertex is
// on a constant-reflectance diffuse surface, the most common vertex; every other vertex goes
// through finish_vertex. A lane's next-event estimation is computed in the lanes when the
// emitter chosen is a constant-radiance area light on a mesh (the choice of emitter and triangle
// is made per lane, Scene::emitter_triangle) and by finish_vertex's own code
// (sample_next_event) otherwise.
//
// The result is finish_vertex's, bit for bit: the kernel (diffuse_lanes_kernel.inc) performs
// the same IEEE operations in the same order, without fused multiply-adds, and the concentric
// map's sine and cosine are one polynomial shared with the scalar code
// (warp::sincos_quarter_pi). tests/core/test_diffuse_lanes.cpp checks it vertex by vertex on
// every instruction set the processor has.
#include <array>
#include <cstdint>
#include <vector>

#include "core/accel/accelerator.h"
#include "core/math/simd.h"
#include "core/path/path_sampler.h"

namespace gdmlt {

class DiffuseLanes {
  public:
    /// Most lanes run() takes at once (the wavefront's batch).
    static constexpr std::size_t kCapacity = 256;

    explicit DiffuseLanes(const Scene& scene);

    /// Whether the vertex `si` (valid) is one these lanes compute: its BSDF is diffuse with a
    /// constant reflectance on both sides it has.
    bool handles(const SurfaceInteraction& si) const {
        return diffuse_[static_cast<std::size_t>(
                            scene_->shapes()[static_cast<std::size_t>(si.shape)].bsdf())]
            .handled;
    }

    /// Whether hits on shape `shape` can be queued with push_hit, without a SurfaceInteraction:
    /// handled BSDF, a triangle mesh without vertex normals (the shading frame is the face's,
    /// built in the lanes) and no emitter (nothing to add where the path arrives).
    bool handles_hit(std::int32_t shape) const {
        return from_hit_[static_cast<std::size_t>(shape)] != 0;
    }

    /// Queues the vertex `si` of a path after begin_vertex returned true for it; `id` is the
    /// caller's name for the path. At most kCapacity vertices between two clear()s.
    void push(std::uint32_t id, const SurfaceInteraction& si, const VertexNumbers& u,
              const PathState& state, const PathSamplerSettings& settings);
    /// The same for the vertex `hit` found by state.ray on a shape handles_hit accepts, after
    /// begin_vertex_without_emission returned true: the lanes rebuild what Shape::interaction
    /// gives (the point from the barycentrics, Frame::from_normal_and_tangent), saving the
    /// 136-byte SurfaceInteraction per hit.
    void push_hit(std::uint32_t id, const RayHit& hit, const VertexNumbers& u,
                  const PathState& state, const PathSamplerSettings& settings);
    /// Computes every queued vertex, with the kernel built for `isa` (core/math/simd.h).
    void run(SimdIsa isa = best_simd_isa());
    /// The result for the i-th queued vertex, as finish_vertex would leave `state`,
    /// `next_event` and `counters` (where the path ends, `state` has only its radiance and
    /// `active` false to go by, and a shadow ray not requested is only that: finish_vertex
    /// leaves other values in the fields unused then).
    void finish(std::size_t i, PathState& state, NextEventRay& next_event,
                PathCounters& counters) const;

    std::size_t size() const { return count_; }
    std::uint32_t id(std::size_t i) const { return ids_[i]; }
    void clear() { count_ = 0; }

    /// Structure of arrays, one entry per queued vertex; public for the kernel only.
    struct Arrays {
        // One cache line more than kCapacity floats: arrays 1 KB apart would all fall in the
        // same 4 of the L1 cache's 64 sets (sets repeat every 4 KB), and with about 70 arrays
        // touched per lane every access would evict another (measured: push_hit took 16% of
        // the render's time before the padding).
        using Lane = std::array<float, kCapacity + 16>;
        using Lane3 = std::array<Lane, 3>;
        using Index = std::array<std::int32_t, kCapacity + 16>;
        // A vertex queued by push_hit (from_hit 1): its triangle and barycentrics; the kernel
        // derives p and the frame from them.
        Lane from_hit;
        Lane3 corner0, corner1, corner2;
        Lane3 frame_tangent;  // Shape::triangle_frame_tangent of the triangle
        Lane bary_u, bary_v;
        // The vertex (p and the frame: push only).
        Lane3 p, n_geometric, frame_s, frame_t, frame_n;
        Lane3 wo_world;    // towards where the path came from
        Index bsdf;        // the surface's entry in Tables' BSDF columns
        Lane3 throughput;  // before this vertex
        Lane eta_product;  // state.eta_product, for Russian roulette
        Lane u_bsdf_x, u_bsdf_y, u_roulette;
        Lane roulette;  // 1 where Russian roulette applies at this vertex
        // Next-event estimation: mode 0 none, 1 a triangle of a mesh emitter (sampled here),
        // 2 any other emitter (computed in push() by sample_next_event, the scalar code).
        Lane nee_mode;
        Index light;  // mode 1: the triangle's entry in Tables' light columns (else 0)
        Lane u_light_x, u_light_y;
        // Outputs (floats, 0 or 1 for yes/no: one lane width throughout lets every decision
        // be a vector mask). Shadow ray, its contribution when unblocked, whether it is traced.
        Lane3 shadow_origin, shadow_direction;
        Lane shadow_t_max;
        Lane3 contribution;
        Lane nee_requested;
        // The continuation: ray, throughput (in place), BSDF density, whether the path goes on.
        Lane3 ray_origin, ray_direction;
        Lane pdf_bsdf;
        Lane active;
    };

    /// What is the same for every vertex on one surface or towards one light triangle, in
    /// columns the kernel gathers from by index (one gather instruction per column and 16
    /// lanes with AVX-512), instead of push copying it into every lane (perf: push_hit's 24
    /// stores of these were about a third of its time). Public for the kernel only.
    struct Tables {
        // Per BSDF of the scene: 1 for two-sided, the reflectance of the front and the back.
        std::vector<float> two_sided;
        std::array<std::vector<float>, 3> albedo, albedo_back;
        // Per entry of Scene::emitter_triangles() (at least one, a dummy for scenes without):
        // corners, unit normal, radiance, the emitter's probability and its whole area.
        std::array<std::vector<float>, 3> light_a, light_b, light_c, light_n, light_radiance;
        std::vector<float> light_pmf, light_area;
    };

  private:
    struct Diffuse {
        bool handled = false;
        bool two_sided = false;
        Rgb front = Rgb::Zero(), back = Rgb::Zero();
    };
    /// What push and push_hit share: the surface's reflectance, the path's direction, state and
    /// numbers, next-event estimation
    /// (`interaction` gives the vertex's SurfaceInteraction when the emitter needs the scalar
    /// code).
    template <class Interaction>
    void push_path(std::size_t i, std::int32_t shape, const VertexNumbers& u,
                   const PathState& state, const PathSamplerSettings& settings,
                   const Interaction& interaction);

    const Scene* scene_;
    std::vector<Diffuse> diffuse_;        // per BSDF of the scene
    std::vector<std::uint8_t> from_hit_;  // per shape: handles_hit (bytes: no bit masking)
    std::size_t count_ = 0;
    std::array<std::uint32_t, kCapacity> ids_{};
    std::array<NextEventRay, kCapacity> given_{};  // next-event estimation of mode 2 lanes
    std::vector<Arrays> arrays_;                   // one element: 100 KB, kept off the stack
    Tables tables_;
};

}  // namespace gdmlt
