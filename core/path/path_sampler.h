// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Unidirectional path sampling with next-event estimation and MIS (power heuristic, Veach 1997
// ch. 9), Russian roulette and delta lobes: the estimator every integrator builds on. It reads
// uniform numbers only from a SampleStream, so PSSMLT drives it unchanged.
#include <cstdint>

#include "core/geometry/ray.h"
#include "core/math/types.h"
#include "core/sampling/sample_stream.h"
#include "core/scene/scene.h"

namespace gdmlt {

struct PathSamplerSettings {
    int max_depth = -1;  // Mitsuba's meaning: longest contributing path in segments; -1 = none
    int rr_depth = 5;    // Russian roulette from this depth on
    bool hide_emitters = false;
    /// Shortest contributing path, in segments: 3 leaves out emitters seen directly and direct
    /// lighting (PSSMLT renders those separately when asked, as Mitsuba's pssmlt does).
    int min_depth = 1;
};

/// Counters a path sampler increments; one per thread, summed at the end.
struct PathCounters {
    std::uint64_t camera_rays = 0;
    std::uint64_t bounce_rays = 0;
    std::uint64_t shadow_rays = 0;
    std::uint64_t paths = 0;

    PathCounters& operator+=(const PathCounters& o) {
        camera_rays += o.camera_rays;
        bounce_rays += o.bounce_rays;
        shadow_rays += o.shadow_rays;
        paths += o.paths;
        return *this;
    }
    std::uint64_t rays() const { return camera_rays + bounce_rays + shadow_rays; }
};

/// Number of stream dimensions each bounce consumes, whether it uses them or not, so that a
/// primary-sample coordinate always drives the same decision (Kelemen et al. 2002, sec. 4).
/// Layout per bounce: emitter choice (1), point on emitter (2), BSDF lobe (1), BSDF direction
/// (2), Russian roulette (1).
inline constexpr int kDimensionsPerBounce = 7;
/// Dimensions the camera uses before the first bounce: position inside the pixel (2).
inline constexpr int kCameraDimensions = 2;

/// Radiance arriving along `camera_ray` (towards the camera), estimated from one path.
/// May return a non-finite value only if the scene data are broken; callers drop and count
/// non-finite samples.
Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, SampleStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters);

/// The same estimator driven by an IndependentStream without virtual calls (the path tracer's
/// inner loop); gives bit-identical results to the overload above for the same stream state.
Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, IndependentStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters);

/// One path's estimator state between two vertices, for drivers that advance many paths at once
/// and trace their rays in packets (render_path). sample_path_radiance is the one-path loop:
///
///     PathState state = start_path(camera_ray, counters);
///     do {
///         const SurfaceInteraction si = scene.intersect(state.ray);
///         const VertexNumbers u = draw_vertex_numbers(stream);
///         if (begin_vertex(scene, si, settings, state))
///             finish_vertex(scene, si, u, settings, counters, state, next_event);
///         if (next_event.requested && !scene.occluded(next_event.shadow))
///             state.radiance += next_event.contribution;
///     } while (state.active);
struct PathState {
    Ray ray;                       // the ray to trace next (valid while active)
    Rgb radiance = Rgb::Zero();    // the estimate so far
    Rgb throughput = Rgb::Ones();  // path throughput weight up to the ray's origin
    float eta_product = 1.f;       // product of relative IORs crossed, for Russian roulette
    // What produced the current ray: MIS for emitters hit by it needs the BSDF pdf and the
    // point it left from. The camera ray counts as a delta "sample".
    float prev_pdf_bsdf = 0.f;
    bool prev_delta = true;
    Vec3f prev_p = Vec3f::Zero();
    int depth = 0;  // segments before the current ray
    bool active = true;
};

/// A shadow ray next-event estimation asks the driver to trace: when it is unblocked,
/// `contribution` is added to the path's radiance (before the path's next vertex).
struct NextEventRay {
    Ray shadow;
    Rgb contribution = Rgb::Zero();
    bool requested = false;
};

/// The uniform numbers one vertex draws (kDimensionsPerBounce of them).
struct VertexNumbers {
    float emitter_choice = 0.f;
    Vec2f emitter = Vec2f::Zero();
    float lobe = 0.f;
    Vec2f bsdf = Vec2f::Zero();
    float roulette = 0.f;

    /// The vertex's numbers from `draw(d)`, called for d = 0 .. kDimensionsPerBounce - 1 in
    /// that order: the one order in which every driver hands them out (a stream's successive
    /// draws, or the wavefront's SIMD draws indexed by d).
    template <class Draw>
    static VertexNumbers in_draw_order(Draw&& draw) {
        VertexNumbers u;
        u.emitter_choice = draw(0);
        u.emitter.x() = draw(1);
        u.emitter.y() = draw(2);
        u.lobe = draw(3);
        u.bsdf.x() = draw(4);
        u.bsdf.y() = draw(5);
        u.roulette = draw(6);
        return u;
    }
};

/// A path starting with `camera_ray` (counted as a path and a camera ray). Inline: the
/// wavefront starts 256 paths at a time, and a call returning the state through the stack
/// cost it a store-forwarding stall per path.
inline PathState start_path(const Ray& camera_ray, PathCounters& counters) {
    ++counters.paths;
    ++counters.camera_rays;
    PathState state;
    state.ray = camera_ray;
    state.prev_p = camera_ray.origin;
    return state;
}

/// One vertex of the estimator in parts (the loop above), so that drivers can draw the numbers
/// or finish some vertices another way (the wavefront's SIMD streams and diffuse vertices:
/// core/sampling/pcg_lanes.h, core/path/diffuse_lanes.h). draw_vertex_numbers draws the
/// vertex's kDimensionsPerBounce numbers; begin_vertex adds what an emitter hit (or the
/// environment, on a miss) gives and returns whether the path goes on from `si` (false:
/// state.active is false and the vertex is done); finish_vertex does the rest: next-event
/// estimation (returned in `next_event` for the caller to trace), BSDF sampling and Russian
/// roulette, leaving state.active true with the next ray in state.ray, or false.
VertexNumbers draw_vertex_numbers(IndependentStream& stream);
bool begin_vertex(const Scene& scene, const SurfaceInteraction& si,
                  const PathSamplerSettings& settings, PathState& state);
void finish_vertex(const Scene& scene, const SurfaceInteraction& si, const VertexNumbers& u,
                   const PathSamplerSettings& settings, PathCounters& counters, PathState& state,
                   NextEventRay& next_event);
/// begin_vertex for a valid hit on a shape that has no emitter (there is nothing to add), for
/// drivers that do not build the SurfaceInteraction (DiffuseLanes::push_hit).
bool begin_vertex_without_emission(const PathSamplerSettings& settings, PathState& state);

/// finish_vertex's next-event estimation at `si` (wo: local direction the path came from): an
/// emitter sample, and when the BSDF does not vanish towards it, the shadow ray for the caller
/// to trace and the contribution `throughput * f * Le * w / pdf` (power heuristic, Veach 1997,
/// eq. 9.13) to add if it is unblocked. Returns next_event.requested.
bool sample_next_event(const Scene& scene, const SurfaceInteraction& si, const Vec3f& wo,
                       const VertexNumbers& u, const Rgb& throughput, NextEventRay& next_event);

/// Power heuristic with exponent 2 (Veach 1997, eq. 9.13), safe for zero and infinite pdfs.
inline float power_heuristic(float pdf_a, float pdf_b) {
    const float a2 = pdf_a * pdf_a, b2 = pdf_b * pdf_b;
    if (!(a2 > 0.f)) return 0.f;
    if (std::isinf(a2)) return 1.f;
    return a2 / (a2 + b2);
}

}  // namespace gdmlt
