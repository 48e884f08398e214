// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/path/bidirectional.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace gdmlt {

float adjoint_shading_correction(const SurfaceInteraction& si, const Vec3f& wo, const Vec3f& wi) {
    const float wo_ns = std::abs(wo.dot(si.shading.n)), wo_ng = std::abs(wo.dot(si.n_geometric));
    const float wi_ns = std::abs(wi.dot(si.shading.n)), wi_ng = std::abs(wi.dot(si.n_geometric));
    if (!(wo_ng > 0.f) || !(wi_ns > 0.f)) return 0.f;
    return wo_ns * wi_ng / (wo_ng * wi_ns);
}

namespace {

float cos_at(const Vec3f& n_geometric, const Vec3f& w) {
    return n_geometric.isZero() ? 1.f : std::abs(n_geometric.dot(w));
}

/// A solid-angle density at `from` of the direction towards `to`, as a density in the area
/// measure at `to` (Veach 1997, eq. 8.10: p_A = p_w |cos theta_to| / d^2); unchanged for a
/// vertex at infinity, whose measure is solid angle.
float to_area(float pdf_solid_angle, const BdptVertex& from, const BdptVertex& to) {
    if (to.at_infinity) return pdf_solid_angle;
    const Vec3f d = to.p - from.p;
    const float distance2 = d.squaredNorm();
    if (!(distance2 > 0.f)) return 0.f;
    return pdf_solid_angle * cos_at(to.n_geometric, d / std::sqrt(distance2)) / distance2;
}

Vec3f direction(const BdptVertex& from, const BdptVertex& to) {
    if (to.at_infinity) return -to.travel;
    if (from.at_infinity) return from.travel;
    return (to.p - from.p).normalized();
}

/// Density of `v` as the origin of a light subpath (emitter choice included): per area for
/// area lights, the choice's probability for point, spot and directional lights, per solid
/// angle for the environment (a direction).
float light_origin_pdf(const Scene& scene, const BdptVertex& v) {
    if (v.at_infinity && v.emitter < 0)  // the environment, reached or chosen as one light
        return scene.pdf_environment_solid_angle(-v.travel);
    if (v.emitter < 0) return 0.f;
    const Emitter& e = scene.emitters()[static_cast<std::size_t>(v.emitter)];
    const float pmf = scene.emitter_selection_pmf(v.emitter);
    if (const auto* area = std::get_if<AreaEmitter>(&e)) {
        const float a = scene.shapes()[static_cast<std::size_t>(area->shape)].surface_area();
        return a > 0.f ? pmf / a : 0.f;
    }
    if (is_infinite(e)) return scene.pdf_environment_solid_angle(-v.travel);
    return pmf;  // point, spot, directional
}

/// Density of `next` generated from light vertex `v` (or from a camera subpath's vertex on an
/// emitter, for s = 0) by an emitted ray: the emission's direction
/// density in area measure; for lights at infinity the disk's area density projected onto
/// `next` (parallel rays: no 1 / d^2).
float light_next_pdf(const Scene& scene, const BdptVertex& v, const BdptVertex& next) {
    if (v.at_infinity) {
        const float r = scene.bounds_radius();
        return cos_at(next.n_geometric, v.travel) / (kPi * r * r);
    }
    if (v.emitter < 0) return 0.f;
    const Vec3f w = direction(v, next);
    const EmissionPdf pdf = scene.pdf_emitted_ray(v.emitter, v.n_geometric, w);
    return to_area(pdf.direction, v, next);
}

/// BSDF value f |cos| at surface vertex `v` from its `wo` towards unit `wi`, with the
/// geometric sides required to agree with the shading frame's idea of reflection or
/// transmission (as the path tracer does), and the adjoint correction on light subpaths.
Rgb vertex_f(const Scene& scene, const BdptVertex& v, const Vec3f& wi, TransportMode mode) {
    const SurfaceInteraction& si = v.si;
    const Vec3f wo_local = si.shading.to_local(v.wo), wi_local = si.shading.to_local(wi);
    const bool shading_reflects = wo_local.z() * wi_local.z() > 0.f;
    const bool geometric_reflects = si.n_geometric.dot(v.wo) * si.n_geometric.dot(wi) > 0.f;
    if (shading_reflects != geometric_reflects) return Rgb::Zero();
    Rgb f = scene.bsdf_of(si).eval(si.texture_point(), wo_local, wi_local, mode);
    if (mode == TransportMode::Importance) f *= adjoint_shading_correction(si, v.wo, wi);
    return f;
}

/// Density of `next` as the camera vertex `v` (its end of the ray: Camera::pdf_area) samples
/// it, area measure (solid angle for a vertex at infinity).
float camera_vertex_pdf(const Scene& scene, const BdptVertex& v, const BdptVertex& next) {
    const Camera& camera = scene.camera();
    if (camera.projection() == Projection::Pinhole)
        return to_area(camera.pdf_direction_solid_angle(direction(v, next)), v, next);
    // The other cameras know their own measure (the orthographic camera's parallel rays have
    // no solid angle).
    return next.at_infinity ? camera.pdf_area(v.p, v.p, -next.travel, true)
                            : camera.pdf_area(v.p, next.p, next.n_geometric);
}

/// Density of `next` sampled from `v`, which its subpath reached from `prev` (area measure at
/// `next`). `prev` is unused for the pinhole and for light origins.
float vertex_pdf(const Scene& scene, const BdptVertex& v, const BdptVertex* prev,
                 const BdptVertex& next) {
    const Vec3f w = direction(v, next);
    switch (v.kind) {
        case BdptVertex::Kind::Camera:
            return camera_vertex_pdf(scene, v, next);
        case BdptVertex::Kind::Light:
            return light_next_pdf(scene, v, next);
        case BdptVertex::Kind::Surface: {
            if (!prev) return 0.f;
            const Vec3f wo = direction(v, *prev);
            const float pdf = scene.bsdf_of(v.si).pdf(
                v.si.texture_point(), v.si.shading.to_local(wo), v.si.shading.to_local(w));
            return to_area(pdf, v, next);
        }
    }
    return 0.f;
}

bool connectible(const Scene& scene, const BdptVertex& v) {
    if (v.kind == BdptVertex::Kind::Surface) return !scene.bsdf_of(v.si).is_delta();
    return true;
}

/// Extends `path` (holding its endpoint vertex) by a random walk from `ray`: Veach 1997,
/// sec. 10.2, with the forward density of each new vertex and the reverse density of the one
/// before it. Reads 4 numbers per vertex (lobe, direction, roulette) whether used or not, and
/// on camera subpaths 3 more for next-event estimation; returns how many it read.
std::size_t random_walk(const Scene& scene, Ray ray, Rgb beta, float pdf_direction,
                        TransportMode mode, SampleStream& stream, int max_vertices, int rr_depth,
                        std::vector<BdptVertex>& path, PathCounters& counters) {
    float pdf_fwd = pdf_direction;
    const bool camera = mode == TransportMode::Radiance;
    const std::size_t per_vertex = camera ? kBdptCameraDimensions : kBdptLightDimensions;
    std::size_t read = 0;
    while (static_cast<int>(path.size()) < max_vertices) {
        const float u_lobe = stream.next_1d();
        const Vec2f u = stream.next_2d();
        const float u_rr = stream.next_1d();
        float u_light_select = 0.f;
        Vec2f u_light = Vec2f::Zero();
        if (camera) {
            u_light_select = stream.next_1d();
            u_light = stream.next_2d();
        }
        read += per_vertex;
        const SurfaceInteraction si = scene.intersect(ray);
        ++counters.bounce_rays;
        if (!si.valid()) {
            // A camera subpath that escapes reaches the environment: a light vertex at
            // infinity (strategy s = 0), its density the direction's.
            if (mode == TransportMode::Radiance && scene.has_environment()) {
                BdptVertex v;
                v.kind = BdptVertex::Kind::Light;
                v.at_infinity = true;
                v.travel = -ray.direction;
                v.beta = beta;
                v.pdf_fwd = pdf_fwd;
                path.push_back(v);
            }
            return read;
        }
        BdptVertex v;
        v.kind = BdptVertex::Kind::Surface;
        v.si = si;
        v.p = si.p;
        v.n_geometric = si.n_geometric;
        v.wo = -ray.direction;
        v.beta = beta;
        v.emitter = scene.shapes()[static_cast<std::size_t>(si.shape)].emitter();
        v.pdf_fwd = to_area(pdf_fwd, path.back(), v);
        v.u_light_select = u_light_select;
        v.u_light = u_light;
        path.push_back(v);
        if (static_cast<int>(path.size()) >= max_vertices) return read;

        const Bsdf& bsdf = scene.bsdf_of(si);
        const Vec3f wo_local = si.shading.to_local(v.wo);
        const BsdfSample bs = bsdf.sample(si.texture_point(), wo_local, u_lobe, u, mode);
        if (!bs.valid()) return read;
        const Vec3f wi = si.shading.to_world(bs.wi);
        const float side = si.n_geometric.dot(wi) * si.n_geometric.dot(v.wo);
        if (bs.transmission ? side > 0.f : side < 0.f) return read;
        float pdf_rev = 0.f;
        if (bs.delta) {
            // A delta lobe has no density: zero marks it (the MIS sums skip such vertices).
            path.back().delta = true;
            pdf_fwd = 0.f;
        } else {
            pdf_fwd = bs.pdf_solid_angle;
            pdf_rev = bsdf.pdf(si.texture_point(), bs.wi, wo_local);
        }
        beta *= bs.weight;
        if (mode == TransportMode::Importance) beta *= adjoint_shading_correction(si, v.wo, wi);
        if (!(beta.maxCoeff() > 0.f) || !is_finite(beta)) return read;
        // The vertex before, generated from this one by the reverse walk.
        BdptVertex& prev = path[path.size() - 2];
        prev.pdf_rev = to_area(pdf_rev, path.back(), prev);
        if (static_cast<int>(path.size()) >= rr_depth) {
            const float q = std::min(beta.maxCoeff(), 0.95f);
            if (!(u_rr < q)) return read;
            beta /= q;
        }
        ray = spawn_ray(si.p, si.n_geometric, wi);
    }
    return read;
}

/// `block_vertices`: the largest camera subpath of the settings, which sizes the stream block
/// (a single-strategy sample stops at `max_vertices` but keeps the layout).
void camera_subpath(const Scene& scene, const Vec2f& film_position, const Vec2f& u_lens,
                    SampleStream& stream, int max_vertices, int block_vertices, int rr_depth,
                    std::vector<BdptVertex>& path, PathCounters& counters) {
    path.clear();
    const Camera& camera = scene.camera();
    const Ray ray = camera.generate_ray(film_position, u_lens);
    BdptVertex c;
    c.kind = BdptVertex::Kind::Camera;
    // The camera's end of the ray: the pinhole, the lens point, or the orthographic ray's
    // origin (Camera::pdf_area reads any point of its ray).
    c.p = camera.camera_end(ray.origin, u_lens);
    c.beta = Rgb::Ones();  // W / p of the film position: 1 with the per-pixel density W
    path.push_back(c);
    ++counters.camera_rays;
    --counters.bounce_rays;  // the walk counts its first ray as a bounce
    const std::size_t read =
        random_walk(scene, ray, Rgb::Ones(), camera.pdf_direction_solid_angle(ray.direction),
                    TransportMode::Radiance, stream, max_vertices, rr_depth, path, counters);
    // The first vertex's density as the camera has it (the walk converted the pinhole's).
    if (camera.projection() != Projection::Pinhole && path.size() > 1)
        path[1].pdf_fwd = camera_vertex_pdf(scene, path[0], path[1]);
    // The camera's block has a fixed size: the light subpath's numbers keep their coordinates.
    stream.skip(static_cast<std::size_t>(kBdptCameraDimensions) *
                    static_cast<std::size_t>(std::max(block_vertices - 1, 0)) -
                read);
}

void light_subpath(const Scene& scene, SampleStream& stream, int max_vertices, int rr_depth,
                   std::vector<BdptVertex>& path, PathCounters& counters) {
    path.clear();
    const float u_select = stream.next_1d();
    const Vec2f u_position = stream.next_2d();
    const Vec2f u_direction = stream.next_2d();
    if (max_vertices < 1) return;
    const EmittedRay e = scene.sample_emitted_ray(u_select, u_position, u_direction);
    if (!e.valid()) return;
    BdptVertex l;
    l.kind = BdptVertex::Kind::Light;
    l.p = e.origin;
    l.n_geometric = e.n_geometric;
    l.emitter = is_infinite(scene.emitters()[static_cast<std::size_t>(e.emitter)]) ? -1 : e.emitter;
    l.at_infinity = e.at_infinity;
    l.travel = e.direction;
    l.delta_light = e.delta_position || e.delta_direction;
    l.pdf_fwd = light_origin_pdf(scene, l);
    if (!(l.pdf_fwd > 0.f)) return;
    l.beta = e.radiance / l.pdf_fwd;
    path.push_back(l);
    const Ray ray = e.n_geometric.isZero() ? Ray{e.origin, e.direction, kInfinity}
                                           : spawn_ray(e.origin, e.n_geometric, e.direction);
    random_walk(scene, ray, e.weight, e.pdf_direction, TransportMode::Importance, stream,
                max_vertices, rr_depth, path, counters);
    // From a light at infinity the first surface's density is the disk's, projected (the
    // walk converted a solid angle from the disk point, which is not the vertex's measure).
    if (e.at_infinity && path.size() > 1) path[1].pdf_fwd = light_next_pdf(scene, l, path[1]);
}

/// The MIS weight of strategy (s, t) for the path it made (Veach 1997, sec. 10.3.4): the
/// densities of all other strategies relative to this one, as products of reverse over forward
/// densities walking the connection along the path. `sampled_light` replaces light vertex 0
/// (s = 1: next-event estimation) and `sampled_camera` camera vertex 0 (t = 1) when that
/// vertex was sampled for the connection.
float mis_weight(const Scene& scene, const std::vector<BdptVertex>& light,
                 const std::vector<BdptVertex>& camera, const BdptVertex* sampled_light,
                 const BdptVertex* sampled_camera, int s, int t, bool power,
                 double light_tracing_scale, std::vector<BdptMisEntry>& light_mis,
                 std::vector<BdptMisEntry>& camera_mis) {
    const auto light_at = [&](int i) {
        return (sampled_light && i == 0) ? sampled_light : &light[static_cast<std::size_t>(i)];
    };
    const auto camera_at = [&](int i) {
        return (sampled_camera && i == 0) ? sampled_camera : &camera[static_cast<std::size_t>(i)];
    };
    const BdptVertex* qs = s > 0 ? light_at(s - 1) : nullptr;
    const BdptVertex* pt = camera_at(t - 1);
    const BdptVertex* qs_minus = s > 1 ? &light[static_cast<std::size_t>(s - 2)] : nullptr;
    const BdptVertex* pt_minus = t > 1 ? &camera[static_cast<std::size_t>(t - 2)] : nullptr;

    light_mis.resize(static_cast<std::size_t>(s));
    camera_mis.resize(static_cast<std::size_t>(t));
    for (int i = 0; i < s; ++i) {
        const BdptVertex* v = light_at(i);
        light_mis[static_cast<std::size_t>(i)] = {v->pdf_fwd, v->pdf_rev, v->delta};
    }
    for (int i = 0; i < t; ++i) {
        const BdptVertex* v = camera_at(i);
        camera_mis[static_cast<std::size_t>(i)] = {v->pdf_fwd, v->pdf_rev, v->delta};
    }
    // The connection's ends are connected, not scattered: not delta; and their reverse
    // densities are those of the other subpath continuing through them.
    BdptMisEntry& pt_e = camera_mis[static_cast<std::size_t>(t - 1)];
    pt_e.delta = false;
    pt_e.pdf_rev = s > 0 ? vertex_pdf(scene, *qs, qs_minus, *pt) : light_origin_pdf(scene, *pt);
    if (pt_minus) {
        // With s = 0, pt is the light origin the reverse walk would have started from.
        camera_mis[static_cast<std::size_t>(t - 2)].pdf_rev =
            s > 0 ? vertex_pdf(scene, *pt, qs, *pt_minus) : light_next_pdf(scene, *pt, *pt_minus);
    }
    if (qs) {
        BdptMisEntry& qs_e = light_mis[static_cast<std::size_t>(s - 1)];
        qs_e.delta = false;
        qs_e.pdf_rev = vertex_pdf(scene, *pt, pt_minus, *qs);
    }
    if (qs_minus)
        light_mis[static_cast<std::size_t>(s - 2)].pdf_rev = vertex_pdf(scene, *qs, pt, *qs_minus);

    const auto remap = [](float pdf) { return pdf != 0.f ? pdf : 1.f; };
    const auto h = [&](double r) { return power ? r * r : r; };
    // Light tracing's density counts light_tracing_scale times (Veach 1997, sec. 9.2: any
    // weights that sum to one over the strategies of a path are unbiased, so c_i p_i in place of
    // p_i is). The gradient-domain samplers use c < 1 because light tracing's image is not
    // shifted and keeps its noise, while the other strategies' noise is reduced by the solve.
    const double c = light_tracing_scale;
    double sum = 0.0, ratio = 1.0;
    // Moving the connection towards the camera: strategies (s + k, t - k). The pinhole
    // (camera vertex 0) cannot be hit; i = 1 is light tracing.
    for (int i = t - 1; i > 0; --i) {
        const BdptMisEntry& e = camera_mis[static_cast<std::size_t>(i)];
        ratio *= static_cast<double>(remap(e.pdf_rev)) / remap(e.pdf_fwd);
        if (!e.delta && !camera_mis[static_cast<std::size_t>(i - 1)].delta)
            sum += h(i == 1 ? ratio * c : ratio);
    }
    // This strategy is light tracing: the others relative to its scaled density.
    const double own = t == 1 ? 1.0 / c : 1.0;
    // Towards the light: strategies (s - k, t + k); a light with a delta in position or
    // direction cannot be hit (k = s).
    ratio = 1.0;
    for (int i = s - 1; i >= 0; --i) {
        const BdptMisEntry& e = light_mis[static_cast<std::size_t>(i)];
        ratio *= static_cast<double>(remap(e.pdf_rev)) / remap(e.pdf_fwd);
        const bool delta_before =
            i > 0 ? light_mis[static_cast<std::size_t>(i - 1)].delta : light_at(0)->delta_light;
        if (!e.delta && !delta_before) sum += h(ratio * own);
    }
    return static_cast<float>(1.0 / (1.0 + sum));
}

}  // namespace

BdptConnection connect_bdpt(const Scene& scene, const BdptConnectionInput& in, BdptScratch& scratch,
                            PathCounters& counters) {
    const std::vector<BdptVertex>& camera = *in.camera;
    const std::vector<BdptVertex>& light = *in.light;
    const int s = in.s, t = in.t;
    const Camera& cam = scene.camera();
    BdptConnection out;
    Rgb contribution = Rgb::Zero();
    BdptVertex sampled;
    bool use_sampled = false;
    if (s == 0) {
        // The camera subpath reached a light by itself.
        const BdptVertex& pt = camera[static_cast<std::size_t>(t - 1)];
        if (pt.at_infinity)
            contribution = pt.beta * scene.environment(-pt.travel);
        else if (pt.is_surface() && pt.emitter >= 0)
            contribution = pt.beta * scene.emitted(pt.si, pt.wo);
    } else if (t == 1) {
        // Light tracing: a light vertex seen by the pinhole, splatted where it lands.
        const BdptVertex& qs = light[static_cast<std::size_t>(s - 1)];
        if (qs.at_infinity || qs.delta_light || !connectible(scene, qs)) return out;
        const CameraConnection c = cam.connect(qs.p, in.u_lens);
        if (!c.valid()) return out;
        const Vec3f to_camera = -c.direction;
        if (qs.is_surface()) {
            contribution =
                qs.beta * vertex_f(scene, qs, to_camera, TransportMode::Importance) * c.weight;
        } else {
            // An area light's point (diffuse emission, front side only).
            const float cos_light = qs.n_geometric.dot(to_camera);
            if (!(cos_light > 0.f)) return out;
            contribution = qs.beta * (cos_light * c.weight);
        }
        if (is_black(contribution)) return out;
        ++counters.shadow_rays;
        if (scene.occluded(spawn_ray_to(qs.p, qs.n_geometric, c.position, Vec3f::Zero())))
            return out;
        sampled.kind = BdptVertex::Kind::Camera;
        sampled.p = c.position;
        use_sampled = true;
        out.film_position = c.film_position;
        out.camera_position = c.position;
    } else if (s == 1) {
        // Next-event estimation: a point on a light, chosen as the light subpath chooses its
        // origin (same emitter choice, uniform by area), or the one given.
        const BdptVertex& pt = camera[static_cast<std::size_t>(t - 1)];
        if (!pt.is_surface() || !connectible(scene, pt)) return out;
        const EmitterSample es = in.light_sample
                                     ? *in.light_sample
                                     : scene.sample_emitter(pt.p, pt.u_light_select, pt.u_light);
        if (!es.valid()) return out;
        const Rgb f = vertex_f(scene, pt, es.wi, TransportMode::Radiance);
        if (is_black(f)) return out;
        contribution = pt.beta * f * es.radiance / es.pdf_solid_angle;
        if (is_black(contribution)) return out;
        if (in.light_sample) {
            if (!in.light_sample_visible) return out;
        } else {
            const Ray shadow = std::isinf(es.distance)
                                   ? spawn_ray(pt.p, pt.n_geometric, es.wi)
                                   : spawn_ray_to(pt.p, pt.n_geometric, es.p, es.n_geometric);
            ++counters.shadow_rays;
            if (scene.occluded(shadow)) return out;
        }
        sampled.kind = BdptVertex::Kind::Light;
        sampled.at_infinity = std::isinf(es.distance);
        sampled.travel = -es.wi;
        sampled.p = es.p;
        sampled.n_geometric = es.n_geometric;
        const Emitter& e = scene.emitters()[static_cast<std::size_t>(es.emitter)];
        sampled.emitter = is_infinite(e) ? -1 : es.emitter;
        sampled.delta_light = es.delta;
        sampled.pdf_fwd = light_origin_pdf(scene, sampled);
        use_sampled = true;
    } else {
        const BdptVertex& qs = light[static_cast<std::size_t>(s - 1)];
        const BdptVertex& pt = camera[static_cast<std::size_t>(t - 1)];
        if (!qs.is_surface() || !pt.is_surface() || !connectible(scene, qs) ||
            !connectible(scene, pt))
            return out;
        const Vec3f d = qs.p - pt.p;
        const float distance2 = d.squaredNorm();
        if (!(distance2 > 0.f)) return out;
        const Vec3f w = d / std::sqrt(distance2);
        const Rgb f_camera = vertex_f(scene, pt, w, TransportMode::Radiance);
        if (is_black(f_camera)) return out;
        const Rgb f_light = vertex_f(scene, qs, -w, TransportMode::Importance);
        // Both cosines are inside the f's (eval includes |cos| of its second direction).
        contribution = qs.beta * f_light * f_camera * pt.beta / distance2;
        if (is_black(contribution)) return out;
        ++counters.shadow_rays;
        if (scene.occluded(spawn_ray_to(pt.p, pt.n_geometric, qs.p, qs.n_geometric))) return out;
    }
    if (is_black(contribution)) return out;
    out.contribution = contribution;
    out.weight =
        in.mis ? mis_weight(scene, light, camera, use_sampled && t > 1 ? &sampled : nullptr,
                            use_sampled && t == 1 ? &sampled : nullptr, s, t, in.power_heuristic,
                            in.light_tracing_scale, scratch.light_mis, scratch.camera_mis)
               : 1.f;
    return out;
}

void sample_light_subpath(const Scene& scene, SampleStream& stream, int max_vertices, int rr_depth,
                          std::vector<BdptVertex>& path, PathCounters& counters) {
    light_subpath(scene, stream, max_vertices, rr_depth, path, counters);
}

void camera_subpath_from_path(const Scene& scene, const Path& path, int vertex_count,
                              std::vector<BdptVertex>& out) {
    out.clear();
    const auto n = static_cast<std::size_t>(
        std::clamp(vertex_count, 0, static_cast<int>(path.vertices.size())));
    const Camera& camera = scene.camera();
    BdptVertex c;
    c.kind = BdptVertex::Kind::Camera;
    // As camera_subpath's: the lens point, not the ray's origin on the near clip plane.
    c.p = camera.camera_end(path.camera_position, path.lens_sample);
    c.beta = Rgb::Ones();
    out.push_back(c);
    // The direction leaving the previous vertex: its f / pdf for the throughput, its density
    // (0 after a delta lobe) for the next vertex's pdf_fwd. The pinhole's direction has the
    // camera's density and throughput 1 (W / p of the film position).
    Rgb beta = Rgb::Ones();
    float pdf_direction = scene.camera().pdf_direction_solid_angle(path.camera_direction);
    for (std::size_t k = 0; k < n; ++k) {
        const PathVertex& pv = path.vertices[k];
        BdptVertex v;
        v.kind = BdptVertex::Kind::Surface;
        v.si = pv.si;
        v.p = pv.si.p;
        v.n_geometric = pv.si.n_geometric;
        v.wo = (out.back().p - pv.si.p).normalized();
        v.beta = beta;
        v.emitter = scene.shapes()[static_cast<std::size_t>(pv.si.shape)].emitter();
        v.pdf_fwd = k == 0 && camera.projection() != Projection::Pinhole
                        ? camera_vertex_pdf(scene, out.back(), v)
                        : to_area(pdf_direction, out.back(), v);
        v.delta = pv.continued && pv.delta;
        out.push_back(v);
        if (!pv.continued) break;
        // The vertex before, as the reverse walk from this one would generate it.
        if (!pv.delta) {
            const BdptVertex& here = out.back();
            const float pdf_rev =
                scene.bsdf_of(pv.si).pdf(pv.si.texture_point(), pv.si.shading.to_local(pv.wi_world),
                                         pv.si.shading.to_local(here.wo));
            BdptVertex& prev = out[out.size() - 2];
            prev.pdf_rev = to_area(pdf_rev, here, prev);
        }
        beta *= pv.f / pv.pdf;
        pdf_direction = pv.delta ? 0.f : pv.pdf;
    }
    const bool all_continued = n == 0 || path.vertices[n - 1].continued;
    if (n == path.vertices.size() && path.escaped && scene.has_environment() && all_continued) {
        BdptVertex v;
        v.kind = BdptVertex::Kind::Light;
        v.at_infinity = true;
        v.travel = -(n == 0 ? path.camera_direction : path.escape_direction);
        v.beta = beta;
        v.pdf_fwd = pdf_direction;
        out.push_back(v);
    }
}

void light_subpath_from_path(const Scene& scene, const BdptVertex& origin, const Path& path,
                             std::vector<BdptVertex>& out) {
    out.clear();
    out.push_back(origin);
    const auto n = static_cast<int>(path.vertices.size());
    // Path vertices n-2 .. 0 become light vertices 1 .. n-1 (vertex n-1 is the origin).
    for (int k = n - 2; k >= 0; --k) {
        const PathVertex& pv = path.vertices[static_cast<std::size_t>(k)];
        BdptVertex v;
        v.kind = BdptVertex::Kind::Surface;
        v.si = pv.si;
        v.p = pv.si.p;
        v.n_geometric = pv.si.n_geometric;
        v.wo = (out.back().p - v.p).normalized();
        v.emitter = scene.shapes()[static_cast<std::size_t>(pv.si.shape)].emitter();
        // The pair of directions at a vertex is scattered through the same lobe either way.
        v.delta = k > 0 && pv.delta;
        const BdptVertex* before = out.size() >= 2 ? &out[out.size() - 2] : nullptr;
        const BdptVertex& prev = out.back();
        v.pdf_fwd = prev.delta ? 0.f : vertex_pdf(scene, prev, before, v);
        out.push_back(v);
    }
    // Reverse densities: light vertex i generated from i + 1 (reached from i + 2).
    for (std::size_t i = 0; i + 2 < out.size(); ++i) {
        const BdptVertex& from = out[i + 1];
        out[i].pdf_rev = from.delta ? 0.f : vertex_pdf(scene, from, &out[i + 2], out[i]);
    }
}

float light_tracing_mis_weight(const Scene& scene, const std::vector<BdptVertex>& light, int s,
                               const Vec3f& camera_p, bool power_heuristic,
                               float light_tracing_scale, BdptScratch& scratch) {
    BdptVertex lens;
    lens.kind = BdptVertex::Kind::Camera;
    lens.p = camera_p;
    // With t = 1 the weight reads camera vertex 0 only, and that is `lens`: no camera
    // subpath (this runs per light tracing term and link, so no allocation either).
    static const std::vector<BdptVertex> kNoCameraSubpath;
    return mis_weight(scene, light, kNoCameraSubpath, nullptr, &lens, s, 1, power_heuristic,
                      light_tracing_scale, scratch.light_mis, scratch.camera_mis);
}

void sample_bdpt(const Scene& scene, const Vec2f& film_position, SampleStream& camera_stream,
                 SampleStream& light_stream, const BdptSettings& settings, BdptScratch& scratch,
                 BdptSample& out, PathCounters& counters) {
    out.pixel = Rgb::Zero();
    out.splats.clear();
    out.nonfinite = 0;
    const bool bounded = settings.max_depth >= 0;
    // A path of s + t vertices has s + t - 1 segments (Mitsuba's depth).
    const int camera_block = bounded ? settings.max_depth + 1 : kBdptUnboundedVertices;
    const bool only = settings.only_s >= 0;
    const int max_camera = only ? std::min(camera_block, settings.only_t) : camera_block;
    const int max_light = std::min(bounded ? settings.max_depth : kBdptUnboundedVertices,
                                   only ? settings.only_s : kBdptUnboundedVertices);
    // The camera subpath counts the pinhole as a vertex; rr_depth may be INT_MAX (no roulette,
    // as MMLT asks): no overflow.
    const int camera_rr_depth = settings.rr_depth < std::numeric_limits<int>::max()
                                    ? settings.rr_depth + 1
                                    : settings.rr_depth;
    // The thin lens's point comes first in the camera's stream (no numbers for other cameras);
    // light tracing (t = 1) connects to the same point.
    const Vec2f u_lens = draw_lens_sample(scene.camera(), camera_stream);
    camera_subpath(scene, film_position, u_lens, camera_stream, max_camera, camera_block,
                   camera_rr_depth, scratch.camera, counters);
    light_subpath(scene, light_stream, max_light, settings.rr_depth, scratch.light, counters);
    ++counters.paths;
    BdptConnectionInput in;
    in.camera = &scratch.camera;
    in.light = &scratch.light;
    in.mis = !only || settings.weight_only;
    in.power_heuristic = settings.power_heuristic;
    in.light_tracing_scale = settings.light_tracing_scale;
    in.u_lens = u_lens;
    const int n_camera = static_cast<int>(scratch.camera.size());
    const int n_light = static_cast<int>(scratch.light.size());
    for (int t = 1; t <= n_camera; ++t) {
        for (int s = 0; s <= n_light; ++s) {
            const int segments = s + t - 1;
            if (segments < 1 || (bounded && segments > settings.max_depth)) continue;
            if (s == 0 && t == 1) continue;
            if (only && (s != settings.only_s || t != settings.only_t)) continue;
            // Emitters seen directly: strategies (0, 2) and (1, 1).
            if (settings.hide_emitters && segments == 1) continue;
            in.s = s;
            in.t = t;
            const BdptConnection c = connect_bdpt(scene, in, scratch, counters);
            if (is_black(c.contribution)) continue;
            const Rgb value = c.contribution * c.weight;
            if (!is_finite(value)) {
                ++out.nonfinite;
                continue;
            }
            if (t == 1)
                out.splats.push_back({c.film_position, value});
            else
                out.pixel += value;
        }
    }
}

}  // namespace gdmlt
