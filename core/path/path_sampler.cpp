// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/path/path_sampler.h"

namespace gdmlt {
namespace {

/// The numbers of one vertex (see VertexNumbers), generic over the stream type so that the path
/// tracer's IndependentStream (a final class) is inlined: seven virtual calls per bounce
/// otherwise cost about as much as the PCG itself.
template <class Stream>
VertexNumbers draw_numbers(Stream& stream) {
    // Every bounce draws its fixed block of dimensions up front, used or not.
    return VertexNumbers::in_draw_order([&](int) { return stream.next_1d(); });
}

/// Whether a vertex at state.depth may have a successor: one more would make the path longer
/// than max_depth segments.
bool below_max_depth(const PathSamplerSettings& settings, const PathState& state) {
    return !(settings.max_depth >= 0 && state.depth + 1 >= settings.max_depth);
}

/// One vertex of the estimator, for the one-path loop (trace_path); the wavefront
/// (render_path) runs the same parts.
template <class Stream>
void path_vertex(const Scene& scene, const SurfaceInteraction& si, Stream& stream,
                 const PathSamplerSettings& settings, PathCounters& counters, PathState& state,
                 NextEventRay& next_event) {
    next_event.requested = false;
    const VertexNumbers u = draw_numbers(stream);
    if (begin_vertex(scene, si, settings, state))
        finish_vertex(scene, si, u, settings, counters, state, next_event);
}

/// One path from start to end, each ray traced as it is needed.
template <class Stream>
Rgb trace_path(const Scene& scene, const Ray& camera_ray, Stream& stream,
               const PathSamplerSettings& settings, PathCounters& counters) {
    PathState state = start_path(camera_ray, counters);
    NextEventRay next_event;
    do {
        const SurfaceInteraction si = scene.intersect(state.ray);
        path_vertex(scene, si, stream, settings, counters, state, next_event);
        if (next_event.requested && !scene.occluded(next_event.shadow))
            state.radiance += next_event.contribution;
    } while (state.active);
    return state.radiance;
}

}  // namespace

bool sample_next_event(const Scene& scene, const SurfaceInteraction& si, const Vec3f& wo,
                       const VertexNumbers& u, const Rgb& throughput, NextEventRay& next_event) {
    next_event.requested = false;
    const EmitterSample es = scene.sample_emitter(si.p, u.emitter_choice, u.emitter);
    if (!es.valid() || is_black(es.radiance)) return false;
    const Bsdf& bsdf = scene.bsdf_of(si);
    const Vec3f wi = si.shading.to_local(es.wi);
    const Rgb f = bsdf.eval(si.texture_point(), wo, wi);
    if (is_black(f)) return false;
    next_event.shadow = std::isinf(es.distance)
                            ? spawn_ray(si.p, si.n_geometric, es.wi)
                            : spawn_ray_to(si.p, si.n_geometric, es.p, es.n_geometric);
    const float w =
        es.delta ? 1.f : power_heuristic(es.pdf_solid_angle, bsdf.pdf(si.texture_point(), wo, wi));
    next_event.contribution = throughput * f * es.radiance * (w / es.pdf_solid_angle);
    next_event.requested = true;
    return true;
}

void finish_vertex(const Scene& scene, const SurfaceInteraction& si, const VertexNumbers& u,
                   const PathSamplerSettings& settings, PathCounters& counters, PathState& state,
                   NextEventRay& next_event) {
    next_event.requested = false;
    state.active = false;  // until a continuation ray is found
    const int depth = state.depth;
    const Vec3f wo_world = -state.ray.direction;
    const Bsdf& bsdf = scene.bsdf_of(si);
    const Vec3f wo = si.shading.to_local(wo_world);

    // Next-event estimation: only where some lobe has a density.
    if (!bsdf.is_delta() && depth + 2 >= settings.min_depth &&
        sample_next_event(scene, si, wo, u, state.throughput, next_event))
        ++counters.shadow_rays;

    const BsdfSample bs = bsdf.sample(si.texture_point(), wo, u.lobe, u.bsdf);
    if (!bs.valid()) return;
    const Vec3f wi_world = si.shading.to_world(bs.wi);
    // Light leaks through shading normals: a direction on the wrong side of the geometric
    // surface for the chosen lobe is rejected (Veach 1997, sec. 5.3).
    const float side = si.n_geometric.dot(wi_world) * si.n_geometric.dot(wo_world);
    if (bs.transmission ? side > 0.f : side < 0.f) return;

    state.throughput *= bs.weight;
    state.eta_product *= bs.eta;
    state.prev_pdf_bsdf = bs.pdf_solid_angle;
    state.prev_delta = bs.delta;
    state.prev_p = si.p;
    state.ray = spawn_ray(si.p, si.n_geometric, wi_world);

    // Russian roulette on the throughput with the eta^2 factor removed, as Mitsuba 3 does,
    // so that radiance compression inside glass does not kill paths.
    if (depth + 1 >= settings.rr_depth) {
        const float q =
            std::min(state.throughput.maxCoeff() * state.eta_product * state.eta_product, 0.95f);
        if (!(u.roulette < q)) return;
        state.throughput /= q;
    }
    if (state.throughput.maxCoeff() <= 0.f) return;
    state.depth = depth + 1;
    state.active = true;
    ++counters.bounce_rays;
}

VertexNumbers draw_vertex_numbers(IndependentStream& stream) {
    return draw_numbers(stream);
}

bool begin_vertex(const Scene& scene, const SurfaceInteraction& si,
                  const PathSamplerSettings& settings, PathState& state) {
    const int depth = state.depth;
    const Ray& ray = state.ray;
    state.active = false;  // until a continuation ray is found
    // An emitter hit here ends a path of depth + 1 segments, next-event estimation from
    // here one of depth + 2.
    const bool count_emission =
        !(depth == 0 && settings.hide_emitters) && depth + 1 >= settings.min_depth;

    if (!si.valid()) {
        if (scene.has_environment() && count_emission) {
            const Scene::EnvironmentValue env = scene.environment_with_pdf(ray.direction);
            const float w =
                state.prev_delta ? 1.f : power_heuristic(state.prev_pdf_bsdf, env.pdf_solid_angle);
            state.radiance += state.throughput * env.radiance * w;
        }
        return false;
    }

    if (count_emission) {
        const Rgb emitted = scene.emitted(si, -ray.direction);
        if (!is_black(emitted)) {
            const float w = state.prev_delta
                                ? 1.f
                                : power_heuristic(state.prev_pdf_bsdf,
                                                  scene.pdf_emitter_solid_angle(state.prev_p, si));
            state.radiance += state.throughput * emitted * w;
        }
    }
    return below_max_depth(settings, state);
}

bool begin_vertex_without_emission(const PathSamplerSettings& settings, PathState& state) {
    state.active = false;
    return below_max_depth(settings, state);
}

Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, SampleStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters) {
    return trace_path(scene, camera_ray, stream, settings, counters);
}

Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, IndependentStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters) {
    return trace_path(scene, camera_ray, stream, settings, counters);
}

}  // namespace gdmlt
