// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/path/diffuse_lanes.h"

#include <immintrin.h>

#include <cfloat>
#include <cstdint>

namespace gdmlt {
namespace {

// The kernel, compiled for each instruction set of core/math/simd.h (simd_targets.inc).
using Lane = DiffuseLanes::Arrays::Lane;
using Lane3 = DiffuseLanes::Arrays::Lane3;
#define GDMLT_SIMD_KERNEL "core/path/diffuse_lanes_kernel.inc"
#include "core/math/simd_targets.inc"
#undef GDMLT_SIMD_KERNEL

Vec3f column(const DiffuseLanes::Arrays::Lane3& v, std::size_t i) {
    return {v[0][i], v[1][i], v[2][i]};
}
void set(DiffuseLanes::Arrays::Lane3& v, std::size_t i, const Vec3f& x) {
    v[0][i] = x.x();
    v[1][i] = x.y();
    v[2][i] = x.z();
}
void set(DiffuseLanes::Arrays::Lane3& v, std::size_t i, const Rgb& x) {
    v[0][i] = x[0];
    v[1][i] = x[1];
    v[2][i] = x[2];
}

}  // namespace

DiffuseLanes::DiffuseLanes(const Scene& scene) : scene_(&scene), arrays_(1) {
    const auto constant_diffuse = [](const BsdfModel& m, Rgb& albedo) {
        const auto* d = std::get_if<DiffuseBsdf>(&m);
        if (!d || !d->reflectance.is_constant()) return false;
        albedo = d->reflectance.eval(TexturePoint());
        return is_finite(albedo);
    };
    for (const Bsdf& bsdf : scene.bsdfs()) {
        Diffuse d;
        d.two_sided = bsdf.is_two_sided();
        // A mask or blend is not a leaf model: its front() says nothing about it.
        d.handled = !bsdf.is_composite() && constant_diffuse(bsdf.front(), d.front);
        d.back = d.front;
        if (bsdf.back()) d.handled = d.handled && constant_diffuse(*bsdf.back(), d.back);
        diffuse_.push_back(d);
    }
    const auto append = [](std::array<std::vector<float>, 3>& column, const auto& value) {
        for (int c = 0; c < 3; ++c) column[static_cast<std::size_t>(c)].push_back(value[c]);
    };
    for (const Diffuse& d : diffuse_) {
        tables_.two_sided.push_back(d.two_sided ? 1.f : 0.f);
        append(tables_.albedo, d.front);
        append(tables_.albedo_back, d.back);
    }
    std::vector<Scene::EmitterTriangle> triangles = scene.emitter_triangles();
    if (triangles.empty()) triangles.emplace_back();  // index 0 is read by lanes without one
    for (const Scene::EmitterTriangle& triangle : triangles) {
        append(tables_.light_a, triangle.a);
        append(tables_.light_b, triangle.b);
        append(tables_.light_c, triangle.c);
        append(tables_.light_n, triangle.n_geometric);
        append(tables_.light_radiance, triangle.radiance);
        tables_.light_pmf.push_back(triangle.pmf);
        tables_.light_area.push_back(triangle.area);
    }
    for (const Shape& shape : scene.shapes()) {
        const auto* mesh = std::get_if<TriangleMesh>(&shape.geometry());
        from_hit_.push_back(mesh && mesh->normals.empty() && shape.emitter() < 0 &&
                                    diffuse_[static_cast<std::size_t>(shape.bsdf())].handled
                                ? 1
                                : 0);
    }
}

template <class Interaction>
void DiffuseLanes::push_path(std::size_t i, std::int32_t shape, const VertexNumbers& u,
                             const PathState& state, const PathSamplerSettings& settings,
                             const Interaction& interaction) {
    Arrays& a = arrays_.front();
    a.bsdf[i] = scene_->shapes()[static_cast<std::size_t>(shape)].bsdf();
    set(a.wo_world, i, Vec3f(-state.ray.direction));
    set(a.throughput, i, state.throughput);
    a.eta_product[i] = state.eta_product;
    a.u_bsdf_x[i] = u.bsdf.x();
    a.u_bsdf_y[i] = u.bsdf.y();
    a.u_roulette[i] = u.roulette;
    a.roulette[i] = state.depth + 1 >= settings.rr_depth ? 1.f : 0.f;

    a.nee_mode[i] = 0.f;
    a.light[i] = 0;
    if (state.depth + 2 < settings.min_depth) return;
    if (const std::int64_t triangle = scene_->emitter_triangle(u.emitter_choice); triangle >= 0) {
        a.nee_mode[i] = 1.f;
        a.light[i] = static_cast<std::int32_t>(triangle);
        a.u_light_x[i] = u.emitter.x();
        a.u_light_y[i] = u.emitter.y();
        return;
    }
    // Any other emitter: finish_vertex's own code, here, once per lane.
    const SurfaceInteraction& si = interaction();
    if (sample_next_event(*scene_, si, si.shading.to_local(-state.ray.direction), u,
                          state.throughput, given_[i]))
        a.nee_mode[i] = 2.f;
}

void DiffuseLanes::push(std::uint32_t id, const SurfaceInteraction& si, const VertexNumbers& u,
                        const PathState& state, const PathSamplerSettings& settings) {
    Arrays& a = arrays_.front();
    const std::size_t i = count_++;
    ids_[i] = id;
    a.from_hit[i] = 0.f;
    set(a.p, i, si.p);
    set(a.n_geometric, i, si.n_geometric);
    set(a.frame_s, i, si.shading.s);
    set(a.frame_t, i, si.shading.t);
    set(a.frame_n, i, si.shading.n);
    push_path(i, si.shape, u, state, settings, [&]() -> const SurfaceInteraction& { return si; });
}

void DiffuseLanes::push_hit(std::uint32_t id, const RayHit& hit, const VertexNumbers& u,
                            const PathState& state, const PathSamplerSettings& settings) {
    Arrays& a = arrays_.front();
    const std::size_t i = count_++;
    ids_[i] = id;
    const Shape& shape = scene_->shapes()[static_cast<std::size_t>(hit.shape)];
    const auto& mesh = std::get<TriangleMesh>(shape.geometry());
    const std::uint32_t* index = &mesh.indices[3 * static_cast<std::size_t>(hit.primitive)];
    a.from_hit[i] = 1.f;
    set(a.corner0, i, mesh.positions[index[0]]);
    set(a.corner1, i, mesh.positions[index[1]]);
    set(a.corner2, i, mesh.positions[index[2]]);
    set(a.n_geometric, i, shape.triangle_normal(hit.primitive));
    set(a.frame_tangent, i, shape.triangle_frame_tangent(hit.primitive));
    a.bary_u[i] = hit.barycentric.x();
    a.bary_v[i] = hit.barycentric.y();
    push_path(i, hit.shape, u, state, settings,
              [&] { return scene_->interaction(state.ray, hit); });
}

void DiffuseLanes::run(SimdIsa isa) {
    switch (isa) {
        case SimdIsa::Avx512:
            avx512::diffuse_vertices(arrays_.front(), tables_, count_);
            break;
        case SimdIsa::Avx2:
            avx2::diffuse_vertices(arrays_.front(), tables_, count_);
            break;
        case SimdIsa::Baseline:
            baseline::diffuse_vertices(arrays_.front(), tables_, count_);
            break;
    }
}

void DiffuseLanes::finish(std::size_t i, PathState& state, NextEventRay& next_event,
                          PathCounters& counters) const {
    const Arrays& a = arrays_.front();
    // Every field is copied whether it is used or not: whether a vertex has a shadow ray, and
    // whether its path goes on, are as random as the paths, and branches on them mispredict.
    if (a.nee_mode[i] == 2.f) {
        next_event = given_[i];
    } else {
        next_event.requested = a.nee_requested[i] != 0.f;
        next_event.shadow =
            Ray{column(a.shadow_origin, i), column(a.shadow_direction, i), a.shadow_t_max[i]};
        next_event.contribution =
            Rgb(a.contribution[0][i], a.contribution[1][i], a.contribution[2][i]);
    }
    counters.shadow_rays += next_event.requested ? 1 : 0;
    state.active = a.active[i] != 0.f;
    state.throughput = Rgb(a.throughput[0][i], a.throughput[1][i], a.throughput[2][i]);
    state.prev_pdf_bsdf = a.pdf_bsdf[i];
    state.prev_delta = false;
    state.prev_p = column(a.p, i);
    state.ray = Ray{column(a.ray_origin, i), column(a.ray_direction, i), kInfinity};
    const int went_on = state.active ? 1 : 0;
    state.depth += went_on;
    counters.bounce_rays += static_cast<std::uint64_t>(went_on);
}

}  // namespace gdmlt
