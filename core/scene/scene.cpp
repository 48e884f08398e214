// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/scene/scene.h"

#include "core/sampling/warp.h"

namespace gdmlt {

Scene::Scene(std::vector<Shape> shapes, std::vector<Bsdf> bsdfs, std::vector<Emitter> emitters,
             PerspectiveCamera camera, IntegratorSettings integrator, SamplerSettings sampler,
             SceneFeatures features, std::map<std::string, std::size_t> counts)
    : shapes_(std::move(shapes)),
      bsdfs_(std::move(bsdfs)),
      emitters_(std::move(emitters)),
      camera_(std::move(camera)),
      integrator_(std::move(integrator)),
      sampler_(sampler),
      features_(std::move(features)),
      counts_(std::move(counts)) {
    accelerator_ = std::make_unique<Accelerator>(shapes_);
    Eigen::AlignedBox3f box = accelerator_->bounds();
    if (box.isEmpty()) box = Eigen::AlignedBox3f(Vec3f::Constant(-1.f), Vec3f::Constant(1.f));
    bounds_center_ = box.center();
    bounds_radius_ = std::max(0.5f * box.diagonal().norm(), 1e-6f);

    // Emitters are chosen proportionally to an estimate of their emitted power, so that bright
    // lights get more shadow rays (pbrt-v4's PowerLightSampler). Lights at infinity (constant,
    // envmap, directional) have a "power" only relative to an assumed receiver, the scene's
    // bounding disk (pi r^2); most of it lands on places no camera path visits (the outside of
    // walls, the underside of floors), and letting it compete with bounded lights starves them:
    // on scenes/rough_metal_glass.xml the dim sky would take 78% of the shadow rays and double
    // the error of the image. So, as pbrt-v4's BVHLightSampler does, the infinite lights as a
    // group get the share of one more light, n_inf / (n_inf + 1), and power decides within
    // each group.
    const float disk_area = kPi * bounds_radius_ * bounds_radius_;
    std::vector<float> power(emitters_.size(), 0.f);
    textured_emitter_triangles_.resize(emitters_.size());
    for (std::size_t i = 0; i < emitters_.size(); ++i) {
        const Emitter& e = emitters_[i];
        if (const auto* area = std::get_if<AreaEmitter>(&e)) {
            const Shape& shape = shapes_[static_cast<std::size_t>(area->shape)];
            power[i] = kPi * shape.surface_area() * luminance(area->radiance.mean_value());
            if (!area->radiance.is_constant())
                if (const auto* mesh = std::get_if<TriangleMesh>(&shape.geometry())) {
                    std::vector<float> areas(mesh->triangle_count());
                    for (std::size_t t = 0; t < areas.size(); ++t) {
                        const Vec3f& a = mesh->positions[mesh->indices[3 * t]];
                        const Vec3f& b = mesh->positions[mesh->indices[3 * t + 1]];
                        const Vec3f& c = mesh->positions[mesh->indices[3 * t + 2]];
                        areas[t] = 0.5f * (b - a).cross(c - a).norm();
                    }
                    textured_emitter_triangles_[i] = Distribution1D(areas);
                }
        } else if (const auto* point = std::get_if<PointEmitter>(&e)) {
            power[i] = 4.f * kPi * luminance(point->intensity);
        } else if (const auto* spot = std::get_if<SpotEmitter>(&e)) {
            // The cone out to the middle of the falloff (pbrt-v4's SpotLight::Phi estimate).
            const float half = 0.5f * (spot->cutoff_rad + spot->beam_width_rad);
            power[i] = 2.f * kPi * (1.f - std::cos(half)) * luminance(spot->intensity);
        } else if (const auto* directional = std::get_if<DirectionalEmitter>(&e)) {
            power[i] = disk_area * luminance(directional->irradiance);
        } else if (const auto* constant = std::get_if<ConstantEmitter>(&e)) {
            power[i] = disk_area * 4.f * kPi * luminance(constant->radiance);
            infinite_emitters_.push_back(static_cast<int>(i));
        } else if (const auto* envmap = std::get_if<EnvmapEmitter>(&e)) {
            power[i] = disk_area * envmap->data->luminance_integral * envmap->scale;
            infinite_emitters_.push_back(static_cast<int>(i));
        }
    }
    std::vector<bool> at_infinity(emitters_.size(), false);
    double finite_power = 0.0, infinite_power = 0.0;
    int infinite_count = 0;
    for (std::size_t i = 0; i < emitters_.size(); ++i) {
        at_infinity[i] = is_infinite(emitters_[i]) || is_delta_direction(emitters_[i]);
        (at_infinity[i] ? infinite_power : finite_power) += power[i];
        infinite_count += at_infinity[i] ? 1 : 0;
    }
    if (finite_power > 0.0 && infinite_power > 0.0) {
        const double infinite_share = infinite_count / (infinite_count + 1.0);
        for (std::size_t i = 0; i < emitters_.size(); ++i)
            power[i] = static_cast<float>(at_infinity[i]
                                              ? infinite_share * power[i] / infinite_power
                                              : (1.0 - infinite_share) * power[i] / finite_power);
    }
    emitter_selection_ = Distribution1D(power);
}

SurfaceInteraction Scene::intersect(const Ray& ray) const {
    const RayHit hit = accelerator_->intersect(ray);
    if (!hit.valid()) return SurfaceInteraction{};
    SurfaceInteraction si = shapes_[static_cast<std::size_t>(hit.shape)].interaction(
        hit.primitive, hit.barycentric, ray.origin, ray.direction, hit.t);
    si.shape = hit.shape;
    return si;
}

EmitterSample Scene::sample_emitter(const Vec3f& ref_p, float u_select, const Vec2f& u) const {
    EmitterSample s;
    if (!emitter_selection_.valid()) return s;
    float u_remapped = 0.f;
    const std::size_t index = emitter_selection_.sample(u_select, &u_remapped);
    const float pmf = emitter_selection_.pmf(index);
    const Emitter& e = emitters_[index];
    s.emitter = static_cast<int>(index);

    if (const auto* area = std::get_if<AreaEmitter>(&e)) {
        const Shape& shape = shapes_[static_cast<std::size_t>(area->shape)];
        Vec3f p, n;
        Vec2f uv = Vec2f::Zero();
        if (area->radiance.is_constant()) {
            const ShapeSample ps = shape.sample_area(u, u_remapped);
            p = ps.p;
            n = ps.n_geometric;
        } else {
            // Textured radiance needs the uv of the point: sample uniformly by area through
            // the shape's own parametrisation (same density 1 / area as sample_area).
            SurfaceInteraction at;
            const Distribution1D& triangles = textured_emitter_triangles_[index];
            if (triangles.valid()) {
                const auto t = static_cast<std::uint32_t>(triangles.sample(u_remapped));
                at = shape.interaction_at(t, warp::square_to_uniform_triangle(u));
            } else {
                const Vec3f dir = warp::square_to_uniform_sphere(u);
                float phi = std::atan2(dir.y(), dir.x());
                if (phi < 0.f) phi += 2.f * kPi;
                at = shape.interaction_at(
                    0, Vec2f(phi * (0.5f * kInvPi), safe_acos(dir.z()) * kInvPi));
            }
            p = at.p;
            n = at.n_geometric;
            uv = at.uv;
        }
        const float area_total = shape.surface_area();
        const Vec3f d = p - ref_p;
        const float dist2 = d.squaredNorm();
        if (!(dist2 > 0.f) || !(area_total > 0.f)) return EmitterSample{};
        s.distance = std::sqrt(dist2);
        s.wi = d / s.distance;
        s.p = p;
        s.n_geometric = n;
        const float cos_light = -n.dot(s.wi);
        if (cos_light <= 0.f) return EmitterSample{};  // back of a one-sided emitter
        // Area to solid angle: p_omega = p_A * d^2 / |cos theta_light|.
        s.pdf_solid_angle = pmf * dist2 / (cos_light * area_total);
        s.radiance = area->radiance.eval(uv);
    } else if (is_delta_position(e)) {
        const bool is_spot = std::holds_alternative<SpotEmitter>(e);
        const Vec3f position =
            is_spot ? std::get<SpotEmitter>(e).position : std::get<PointEmitter>(e).position;
        const Vec3f d = position - ref_p;
        const float dist2 = d.squaredNorm();
        if (!(dist2 > 0.f)) return EmitterSample{};
        s.distance = std::sqrt(dist2);
        s.wi = d / s.distance;
        s.p = position;
        const Rgb intensity = is_spot ? std::get<SpotEmitter>(e).intensity_towards(-s.wi)
                                      : std::get<PointEmitter>(e).intensity;
        if (is_black(intensity)) return EmitterSample{};
        s.radiance = intensity / dist2;
        s.pdf_solid_angle = pmf;
        s.delta = true;
    } else if (const auto* directional = std::get_if<DirectionalEmitter>(&e)) {
        s.wi = -directional->direction;
        s.radiance = directional->irradiance;
        s.pdf_solid_angle = pmf;
        s.distance = kInfinity;
        s.delta = true;
    } else {
        // An infinite emitter: a direction from its own sampler, then the radiance and density
        // of all infinite emitters together (see the header).
        if (const auto* envmap = std::get_if<EnvmapEmitter>(&e)) {
            const EnvmapEmitter::Sample es = envmap->sample(u);
            if (!(es.pdf_solid_angle > 0.f)) return EmitterSample{};
            s.wi = es.direction;
        } else {
            s.wi = warp::square_to_uniform_sphere(u);
        }
        s.pdf_solid_angle = pdf_environment_solid_angle(s.wi);
        s.radiance = environment(s.wi);
        s.distance = kInfinity;
    }
    if (!std::isfinite(s.pdf_solid_angle) || !is_finite(s.radiance)) return EmitterSample{};
    return s;
}

Rgb Scene::emitted(const SurfaceInteraction& si, const Vec3f& w) const {
    const int emitter = shapes_[static_cast<std::size_t>(si.shape)].emitter();
    if (emitter < 0) return Rgb::Zero();
    const auto& area = std::get<AreaEmitter>(emitters_[static_cast<std::size_t>(emitter)]);
    if (si.n_geometric.dot(w) <= 0.f) return Rgb::Zero();  // emits from the front side only
    return area.radiance.eval(si.uv);
}

Rgb Scene::environment(const Vec3f& direction) const {
    Rgb sum = Rgb::Zero();
    for (int index : infinite_emitters_) {
        const Emitter& e = emitters_[static_cast<std::size_t>(index)];
        if (const auto* envmap = std::get_if<EnvmapEmitter>(&e))
            sum += envmap->eval(direction);
        else
            sum += std::get<ConstantEmitter>(e).radiance;
    }
    return sum;
}

float Scene::pdf_emitter_solid_angle(const Vec3f& ref_p, const SurfaceInteraction& si) const {
    const int emitter = shapes_[static_cast<std::size_t>(si.shape)].emitter();
    if (emitter < 0) return 0.f;
    const Vec3f d = si.p - ref_p;
    const float dist2 = d.squaredNorm();
    const float cos_light = -si.n_geometric.dot(d) / std::sqrt(dist2);
    if (!(cos_light > 0.f)) return 0.f;
    const Shape& shape = shapes_[static_cast<std::size_t>(si.shape)];
    const float pmf = emitter_selection_.pmf(static_cast<std::size_t>(emitter));
    return pmf * dist2 / (cos_light * shape.surface_area());
}

float Scene::pdf_environment_solid_angle(const Vec3f& direction) const {
    float pdf = 0.f;
    for (int index : infinite_emitters_) {
        const Emitter& e = emitters_[static_cast<std::size_t>(index)];
        const float pmf = emitter_selection_.pmf(static_cast<std::size_t>(index));
        if (const auto* envmap = std::get_if<EnvmapEmitter>(&e))
            pdf += pmf * envmap->pdf_solid_angle(direction);
        else
            pdf += pmf * warp::square_to_uniform_sphere_pdf_solid_angle();
    }
    return pdf;
}

}  // namespace gdmlt
