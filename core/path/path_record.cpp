// SPDX-License-Identifier: GPL-3.0-or-later
#include <algorithm>

#include "core/path/path.h"

namespace gdmlt {

void reset_keeping_capacity(Path& path) {
    std::vector<PathVertex> vertices = std::move(path.vertices);
    vertices.clear();
    path = Path{};
    path.vertices = std::move(vertices);
}

Path sample_camera_path(const Scene& scene, const Vec2f& film_position, SampleStream& stream,
                        const PathSamplerSettings& settings, PathCounters& counters) {
    Path path;
    sample_camera_path(scene, film_position, stream, settings, counters, path);
    return path;
}

void sample_camera_path(const Scene& scene, const Vec2f& film_position, SampleStream& stream,
                        const PathSamplerSettings& settings, PathCounters& counters, Path& path) {
    reset_keeping_capacity(path);
    // At most one allocation per path instead of a growing vector's four or five (GDMLT
    // samples a path and shifts it four times per proposal; the allocator was 10% of its
    // time), none when `path` is reused. Capped: a max_depth of thousands must not make every
    // path allocate (and map) that many vertices of ~300 bytes; the rare longer path grows as
    // before.
    constexpr int kReservedVertices = 16;
    path.vertices.reserve(static_cast<std::size_t>(
        settings.max_depth > 0 ? std::min(settings.max_depth, kReservedVertices)
                               : kReservedVertices));
    path.film_position = film_position;
    path.lens_sample = draw_lens_sample(scene.camera(), stream);
    Ray ray = scene.camera().generate_ray(film_position, path.lens_sample);
    path.camera_position = ray.origin;
    path.camera_direction = ray.direction;
    ++counters.paths;
    ++counters.camera_rays;

    for (int depth = 0;; ++depth) {
        if (depth > 0) ++counters.bounce_rays;
        const SurfaceInteraction si = scene.intersect(ray);
        const float u_emitter_choice = stream.next_1d();
        const Vec2f u_emitter = stream.next_2d();
        const float u_lobe = stream.next_1d();
        const Vec2f u_bsdf = stream.next_2d();
        (void)stream.next_1d();  // Russian roulette's dimension: kept for the common layout
        if (!si.valid()) {
            path.escaped = true;
            path.escape_direction = ray.direction;
            break;
        }
        PathVertex v;
        v.si = si;
        const Bsdf& bsdf = scene.bsdf_of(si);
        v.roughness = bsdf.roughness_class();
        const bool last = settings.max_depth >= 0 && depth + 1 >= settings.max_depth;
        if (last) {
            path.vertices.push_back(v);
            break;
        }
        const Vec3f wo = si.shading.to_local(-ray.direction);
        if (!bsdf.is_delta()) {
            v.light = scene.sample_emitter(si.p, u_emitter_choice, u_emitter);
            // A black sample (outside a spot's cone) is kept for the offsets but casts no ray.
            if (v.light.valid() && !is_black(v.light.radiance)) {
                const Ray shadow =
                    std::isinf(v.light.distance)
                        ? spawn_ray(si.p, si.n_geometric, v.light.wi)
                        : spawn_ray_to(si.p, si.n_geometric, v.light.p, v.light.n_geometric);
                ++counters.shadow_rays;
                v.light_visible = !scene.occluded(shadow);
            }
        }
        const BsdfSample bs = bsdf.sample(si.texture_point(), wo, u_lobe, u_bsdf);
        v.u_lobe = u_lobe;
        v.u_direction = u_bsdf;
        if (bs.valid()) {
            const Vec3f wi_world = si.shading.to_world(bs.wi);
            const float side = si.n_geometric.dot(wi_world) * si.n_geometric.dot(-ray.direction);
            if (bs.transmission ? side <= 0.f : side >= 0.f) {
                v.continued = true;
                v.wi_world = wi_world;
                v.pdf = bs.pdf_solid_angle;
                v.f = bs.weight * bs.pdf_solid_angle;
                v.delta = bs.delta;
                v.transmission = bs.transmission;
            }
        }
        path.vertices.push_back(v);
        if (!v.continued) break;
        ray = spawn_ray(si.p, si.n_geometric, v.wi_world);
    }
}

}  // namespace gdmlt
