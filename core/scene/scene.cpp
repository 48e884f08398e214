// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/scene/scene.h"

#include "core/sampling/warp.h"

namespace gdmlt {

const char* emitter_kind_name(const Emitter& e) {
    if (std::holds_alternative<AreaEmitter>(e)) return "area";
    if (std::holds_alternative<PointEmitter>(e)) return "point";
    return "constant";
}

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
    // lights get more shadow rays (pbrt-v4's PowerLightSampler does the same).
    std::vector<float> power(emitters_.size(), 0.f);
    for (std::size_t i = 0; i < emitters_.size(); ++i) {
        const Emitter& e = emitters_[i];
        if (const auto* area = std::get_if<AreaEmitter>(&e)) {
            power[i] = kPi * shapes_[static_cast<std::size_t>(area->shape)].surface_area() *
                       luminance(area->radiance.max_value());
        } else if (const auto* point = std::get_if<PointEmitter>(&e)) {
            power[i] = 4.f * kPi * luminance(point->intensity);
        } else if (const auto* constant = std::get_if<ConstantEmitter>(&e)) {
            power[i] = 4.f * kPi * kPi * bounds_radius_ * bounds_radius_ *
                       luminance(constant->radiance);
            infinite_emitters_.push_back(static_cast<int>(i));
        }
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
        const ShapeSample ps = shape.sample_area(u, u_remapped);
        const Vec3f d = ps.p - ref_p;
        const float dist2 = d.squaredNorm();
        if (!(dist2 > 0.f) || !(ps.pdf_area > 0.f)) return EmitterSample{};
        s.distance = std::sqrt(dist2);
        s.wi = d / s.distance;
        s.p = ps.p;
        s.n_geometric = ps.n_geometric;
        const float cos_light = -ps.n_geometric.dot(s.wi);
        if (cos_light <= 0.f) return EmitterSample{};  // back of a one-sided emitter
        // Area to solid angle: p_omega = p_A * d^2 / |cos theta_light|.
        s.pdf_solid_angle = pmf * ps.pdf_area * dist2 / cos_light;
        s.radiance = area->radiance.eval(Vec2f::Zero());
    } else if (const auto* point = std::get_if<PointEmitter>(&e)) {
        const Vec3f d = point->position - ref_p;
        const float dist2 = d.squaredNorm();
        if (!(dist2 > 0.f)) return EmitterSample{};
        s.distance = std::sqrt(dist2);
        s.wi = d / s.distance;
        s.p = point->position;
        s.radiance = point->intensity / dist2;
        s.pdf_solid_angle = pmf;
        s.delta = true;
    } else {
        const auto& constant = std::get<ConstantEmitter>(e);
        s.wi = warp::square_to_uniform_sphere(u);
        s.pdf_solid_angle = pmf * warp::square_to_uniform_sphere_pdf_solid_angle();
        s.radiance = constant.radiance;
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

Rgb Scene::environment(const Vec3f&) const {
    Rgb sum = Rgb::Zero();
    for (int index : infinite_emitters_)
        sum += std::get<ConstantEmitter>(emitters_[static_cast<std::size_t>(index)]).radiance;
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

float Scene::pdf_environment_solid_angle(const Vec3f&) const {
    float pdf = 0.f;
    for (int index : infinite_emitters_)
        pdf += emitter_selection_.pmf(static_cast<std::size_t>(index)) *
               warp::square_to_uniform_sphere_pdf_solid_angle();
    return pdf;
}

}  // namespace gdmlt
