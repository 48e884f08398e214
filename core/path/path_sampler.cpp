// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/path/path_sampler.h"

namespace gdmlt {
namespace {

/// The estimator, generic over the stream type so that the path tracer's IndependentStream
/// (a final class) is inlined: seven virtual calls per bounce otherwise cost about as much as
/// the PCG itself. Both public overloads instantiate this one body, so they cannot drift apart.
template <class Stream>
Rgb trace_path(const Scene& scene, const Ray& camera_ray, Stream& stream,
               const PathSamplerSettings& settings, PathCounters& counters) {
    ++counters.paths;
    ++counters.camera_rays;
    Rgb radiance = Rgb::Zero();
    Rgb throughput = Rgb::Ones();
    float eta_product = 1.f;  // product of relative IORs crossed, for Russian roulette
    Ray ray = camera_ray;
    // What produced the current ray: MIS for emitters hit by it needs the BSDF pdf and the
    // point it left from. The camera ray counts as a delta "sample".
    float prev_pdf_bsdf = 0.f;
    bool prev_delta = true;
    Vec3f prev_p = camera_ray.origin;

    for (int depth = 0;; ++depth) {
        if (depth > 0) ++counters.bounce_rays;
        const SurfaceInteraction si = scene.intersect(ray);
        // Every bounce draws its fixed block of dimensions up front, used or not.
        const float u_emitter_choice = stream.next_1d();
        const Vec2f u_emitter = stream.next_2d();
        const float u_lobe = stream.next_1d();
        const Vec2f u_bsdf = stream.next_2d();
        const float u_roulette = stream.next_1d();
        // An emitter hit here ends a path of depth + 1 segments, next-event estimation from
        // here one of depth + 2.
        const bool count_emission =
            !(depth == 0 && settings.hide_emitters) && depth + 1 >= settings.min_depth;

        if (!si.valid()) {
            if (scene.has_environment() && count_emission) {
                const float w =
                    prev_delta ? 1.f
                               : power_heuristic(prev_pdf_bsdf,
                                                 scene.pdf_environment_solid_angle(ray.direction));
                radiance += throughput * scene.environment(ray.direction) * w;
            }
            break;
        }

        const Vec3f wo_world = -ray.direction;
        if (count_emission) {
            const Rgb emitted = scene.emitted(si, wo_world);
            if (!is_black(emitted)) {
                const float w =
                    prev_delta
                        ? 1.f
                        : power_heuristic(prev_pdf_bsdf, scene.pdf_emitter_solid_angle(prev_p, si));
                radiance += throughput * emitted * w;
            }
        }

        // A further vertex would make the path longer than max_depth segments.
        if (settings.max_depth >= 0 && depth + 1 >= settings.max_depth) break;

        const Bsdf& bsdf = scene.bsdf_of(si);
        const Vec3f wo = si.shading.to_local(wo_world);

        // Next-event estimation: only where some lobe has a density.
        if (!bsdf.is_delta() && depth + 2 >= settings.min_depth) {
            const EmitterSample es = scene.sample_emitter(si.p, u_emitter_choice, u_emitter);
            if (es.valid()) {
                const Vec3f wi = si.shading.to_local(es.wi);
                const Rgb f = bsdf.eval(si.uv, wo, wi);
                if (!is_black(f)) {
                    const Ray shadow =
                        std::isinf(es.distance)
                            ? spawn_ray(si.p, si.n_geometric, es.wi)
                            : spawn_ray_to(si.p, si.n_geometric, es.p, es.n_geometric);
                    ++counters.shadow_rays;
                    if (!scene.occluded(shadow)) {
                        const float w =
                            es.delta ? 1.f
                                     : power_heuristic(es.pdf_solid_angle, bsdf.pdf(si.uv, wo, wi));
                        radiance += throughput * f * es.radiance * (w / es.pdf_solid_angle);
                    }
                }
            }
        }

        const BsdfSample bs = bsdf.sample(si.uv, wo, u_lobe, u_bsdf);
        if (!bs.valid()) break;
        const Vec3f wi_world = si.shading.to_world(bs.wi);
        // Light leaks through shading normals: a direction on the wrong side of the geometric
        // surface for the chosen lobe is rejected (Veach 1997, sec. 5.3).
        const float side = si.n_geometric.dot(wi_world) * si.n_geometric.dot(wo_world);
        if (bs.transmission ? side > 0.f : side < 0.f) break;

        throughput *= bs.weight;
        eta_product *= bs.eta;
        prev_pdf_bsdf = bs.pdf_solid_angle;
        prev_delta = bs.delta;
        prev_p = si.p;
        ray = spawn_ray(si.p, si.n_geometric, wi_world);

        // Russian roulette on the throughput with the eta^2 factor removed, as Mitsuba 3 does,
        // so that radiance compression inside glass does not kill paths.
        if (depth + 1 >= settings.rr_depth) {
            const float q = std::min(throughput.maxCoeff() * eta_product * eta_product, 0.95f);
            if (!(u_roulette < q)) break;
            throughput /= q;
        }
        if (throughput.maxCoeff() <= 0.f) break;
    }
    return radiance;
}

}  // namespace

Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, SampleStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters) {
    return trace_path(scene, camera_ray, stream, settings, counters);
}

Rgb sample_path_radiance(const Scene& scene, const Ray& camera_ray, IndependentStream& stream,
                         const PathSamplerSettings& settings, PathCounters& counters) {
    return trace_path(scene, camera_ray, stream, settings, counters);
}

}  // namespace gdmlt
