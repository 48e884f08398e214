// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/scene/scene.h"

#include "core/sampling/warp.h"

namespace gdmlt {

Scene::Scene(std::vector<Shape> shapes, std::vector<Bsdf> bsdfs, std::vector<Emitter> emitters,
             Camera camera, IntegratorSettings integrator, SamplerSettings sampler,
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
            power[i] = 2.f * kPi * (1.f - std::cos(half)) * luminance(spot->intensity) *
                       (spot->textured ? luminance(spot->texture.mean_value()) : 1.f);
        } else if (const auto* projector = std::get_if<ProjectorEmitter>(&e)) {
            // The integral of pi scale E / cos^3 over the solid angle of the image, which is
            // cos^3 dA on the plane at distance 1: pi scale E A.
            power[i] = kPi * projector->scale * luminance(projector->irradiance.mean_value()) *
                       projector->image_area();
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
    emitter_selection_ = AliasTable(power);

    first_emitter_triangle_.assign(emitters_.size(), -1);
    for (std::size_t i = 0; i < emitters_.size(); ++i) {
        const auto* area = std::get_if<AreaEmitter>(&emitters_[i]);
        if (!area || !area->radiance.is_constant()) continue;
        const Shape& shape = shapes_[static_cast<std::size_t>(area->shape)];
        const auto* mesh = std::get_if<TriangleMesh>(&shape.geometry());
        // The same condition as Shape::area_triangle's: a mesh with some area.
        if (!mesh || !shape.area_triangle(0.f).a) continue;
        first_emitter_triangle_[i] = static_cast<std::int64_t>(emitter_triangles_.size());
        for (std::uint32_t t = 0; t < mesh->triangle_count(); ++t) {
            const std::uint32_t* corner = &mesh->indices[3 * static_cast<std::size_t>(t)];
            emitter_triangles_.push_back(EmitterTriangle{
                mesh->positions[corner[0]], mesh->positions[corner[1]], mesh->positions[corner[2]],
                shape.triangle_normal(t), area->radiance.eval(TexturePoint()),
                emitter_selection_.pmf(i), shape.surface_area()});
        }
    }
}

SurfaceInteraction Scene::intersect(const Ray& ray) const {
    return interaction(ray, accelerator_->intersect(ray));
}

SurfaceInteraction Scene::interaction(const Ray& ray, const RayHit& hit) const {
    // One return object, built in the caller's (NRVO): an early `return SurfaceInteraction{}`
    // beside `return si` made GCC build `si` on the stack and copy its 136 bytes out per hit.
    SurfaceInteraction si =
        hit.valid() ? shapes_[static_cast<std::size_t>(hit.shape)].interaction(
                          hit.primitive, hit.barycentric, ray.origin, ray.direction, hit.t)
                    : SurfaceInteraction{};
    if (hit.valid()) si.shape = hit.shape;
    return si;
}

Scene::EmitterChoice Scene::choose_emitter(float u_select) const {
    EmitterChoice c;
    c.index = emitter_selection_.sample(u_select, &c.u_remapped);
    c.pmf = emitter_selection_.pmf(c.index);
    return c;
}

EmitterSample Scene::sample_emitter(const Vec3f& ref_p, float u_select, const Vec2f& u) const {
    EmitterSample s;
    if (!emitter_selection_.valid()) return s;
    const auto [index, pmf, u_remapped] = choose_emitter(u_select);
    const Emitter& e = emitters_[index];
    s.emitter = static_cast<int>(index);

    if (const auto* area = std::get_if<AreaEmitter>(&e)) {
        const Shape& shape = shapes_[static_cast<std::size_t>(area->shape)];
        const AreaPoint point = sample_area_emitter_point(index, u_remapped, u);
        const Vec3f p = point.p, n = point.n;
        const float area_total = shape.surface_area();
        const Vec3f d = p - ref_p;
        const float dist2 = d.squaredNorm();
        if (!(dist2 > 0.f) || !(area_total > 0.f)) {
            s = EmitterSample{};
            return s;
        }
        s.distance = std::sqrt(dist2);
        s.wi = d / s.distance;
        s.p = p;
        s.n_geometric = n;
        const float cos_light = -n.dot(s.wi);
        if (cos_light <= 0.f) {  // back of a one-sided emitter
            s = EmitterSample{};
            return s;
        }
        // Area to solid angle: p_omega = p_A * d^2 / |cos theta_light|.
        s.pdf_solid_angle = pmf * dist2 / (cos_light * area_total);
        s.radiance = area->radiance.eval(point.texture);
    } else if (is_delta_position(e)) {
        const Vec3f position = delta_position_of(e);
        const Vec3f d = position - ref_p;
        const float dist2 = d.squaredNorm();
        if (!(dist2 > 0.f)) {
            s = EmitterSample{};
            return s;
        }
        s.distance = std::sqrt(dist2);
        s.wi = d / s.distance;
        s.p = position;
        // Valid even where the light sends nothing this way (outside a spot's cone, a black
        // texel): a gradient-domain shift reuses the light's position for offset vertices the
        // light does reach, and an invalid base sample would drop their light (GDPT's
        // differences around a spot's cone were biased). Callers skip black samples' rays.
        s.radiance = delta_position_radiance(static_cast<int>(index), -s.wi, dist2);
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
        EnvironmentValue env;
        if (const auto* envmap = std::get_if<EnvmapEmitter>(&e)) {
            const EnvmapEmitter::Sample es = envmap->sample_direction(u);
            if (!(es.pdf_solid_angle > 0.f)) {
                s = EmitterSample{};
                return s;
            }
            s.wi = es.direction;
            env = environment_of_sample(*envmap, es, pmf);
        } else {
            s.wi = warp::square_to_uniform_sphere(u);
            env = environment_with_pdf(s.wi);
        }
        s.pdf_solid_angle = env.pdf_solid_angle;
        s.radiance = env.radiance;
        s.distance = kInfinity;
    }
    if (!std::isfinite(s.pdf_solid_angle) || !is_finite(s.radiance)) {
        s = EmitterSample{};
        return s;
    }
    return s;
}

std::int64_t Scene::emitter_triangle(float u_select) const {
    if (!emitter_selection_.valid()) return -1;
    const auto [index, pmf, u_remapped] = choose_emitter(u_select);
    const std::int64_t first = first_emitter_triangle_[index];
    if (first < 0) return -1;
    const Shape& shape =
        shapes_[static_cast<std::size_t>(std::get<AreaEmitter>(emitters_[index]).shape)];
    return first + shape.area_triangle_index(u_remapped);
}

Scene::AreaPoint Scene::sample_area_emitter_point(std::size_t index, float u_primitive,
                                                  const Vec2f& u) const {
    const auto& area = std::get<AreaEmitter>(emitters_[index]);
    const Shape& shape = shapes_[static_cast<std::size_t>(area.shape)];
    AreaPoint out;
    if (area.radiance.is_constant()) {
        const ShapeSample ps = shape.sample_area(u, u_primitive);
        out.p = ps.p;
        out.n = ps.n_geometric;
        return out;
    }
    // Textured radiance needs the uv of the point: sample uniformly by area through the
    // shape's own parametrisation (same density 1 / area as sample_area).
    SurfaceInteraction at;
    const Distribution1D& triangles = textured_emitter_triangles_[index];
    if (triangles.valid()) {
        const auto t = static_cast<std::uint32_t>(triangles.sample(u_primitive));
        at = shape.interaction_at(t, warp::square_to_uniform_triangle(u));
    } else {
        const Vec3f dir = warp::square_to_uniform_sphere(u);
        float phi = std::atan2(dir.y(), dir.x());
        if (phi < 0.f) phi += 2.f * kPi;
        at = shape.interaction_at(0, Vec2f(phi * (0.5f * kInvPi), safe_acos(dir.z()) * kInvPi));
    }
    out.p = at.p;
    out.n = at.n_geometric;
    out.texture = at.texture_point();
    out.texture.shape = area.shape;  // interaction_at knows the geometry, not its index
    out.texture.surface = nullptr;   // `at` ends here
    return out;
}

EmittedRay Scene::sample_emitted_ray(float u_select, const Vec2f& u_position,
                                     const Vec2f& u_direction) const {
    EmittedRay r;
    if (!emitter_selection_.valid()) return r;
    const auto [index, pmf, u_remapped] = choose_emitter(u_select);
    const Emitter& e = emitters_[index];
    r.emitter = static_cast<int>(index);
    // A point on the disk of the bounding sphere's radius perpendicular to `towards_light`,
    // one radius out from the centre on the light's side (lights at infinity).
    const auto disk_origin = [&](const Vec3f& towards_light) {
        const Vec2f d = warp::square_to_uniform_disk_concentric(u_position) * bounds_radius_;
        const Frame frame = Frame::from_normal(towards_light);
        return Vec3f(bounds_center_ + bounds_radius_ * towards_light + d.x() * frame.s +
                     d.y() * frame.t);
    };
    const float disk_pdf = 1.f / (kPi * bounds_radius_ * bounds_radius_);

    if (std::holds_alternative<AreaEmitter>(e)) {
        const auto& area = std::get<AreaEmitter>(e);
        const Shape& shape = shapes_[static_cast<std::size_t>(area.shape)];
        const AreaPoint point = sample_area_emitter_point(index, u_remapped, u_position);
        const float area_total = shape.surface_area();
        if (!(area_total > 0.f)) return EmittedRay{};
        // Emission leaves the front side only: cosine-weighted about the normal, so that the
        // weight Le cos / pdf is Le pi area / pmf whatever the direction.
        const Vec3f local = warp::square_to_cosine_hemisphere(u_direction);
        r.origin = point.p;
        r.n_geometric = point.n;
        r.direction = Frame::from_normal(point.n).to_world(local);
        r.radiance = area.radiance.eval(point.texture);
        r.pdf_position = pmf / area_total;
        r.pdf_direction = warp::square_to_cosine_hemisphere_pdf_solid_angle(local);
        if (!(r.pdf_direction > 0.f)) return EmittedRay{};
        r.weight = r.radiance * (local.z() / (r.pdf_position * r.pdf_direction));
    } else if (const auto* point = std::get_if<PointEmitter>(&e)) {
        r.origin = point->position;
        r.direction = warp::square_to_uniform_sphere(u_direction);
        r.radiance = point->intensity;
        r.pdf_position = pmf;
        r.pdf_direction = warp::square_to_uniform_sphere_pdf_solid_angle();
        r.delta_position = true;
        r.weight = r.radiance / (r.pdf_position * r.pdf_direction);
    } else if (const auto* spot = std::get_if<SpotEmitter>(&e)) {
        // Uniform over the cutoff cone: the falloff is not worth inverting (Mitsuba 3 does
        // the same).
        r.origin = spot->position;
        r.direction = spot->local_from_world.transpose() *
                      warp::square_to_uniform_cone(u_direction, spot->cos_cutoff);
        r.radiance = spot->intensity_towards(r.direction);
        r.pdf_position = pmf;
        r.pdf_direction = warp::square_to_uniform_cone_pdf_solid_angle(spot->cos_cutoff);
        r.delta_position = true;
        r.weight = r.radiance / (r.pdf_position * r.pdf_direction);
    } else if (const auto* projector = std::get_if<ProjectorEmitter>(&e)) {
        // Uniform over the projected image (film positions uniform over the texture's pixels;
        // Mitsuba 3 samples them by the texture, which only changes the noise).
        const Film& film = projector->camera.film();
        const Ray ray =
            projector->camera.generate_ray({u_direction.x() * static_cast<float>(film.width),
                                            u_direction.y() * static_cast<float>(film.height)});
        r.origin = projector->camera.position();
        r.direction = ray.direction;
        r.radiance = projector->intensity_towards(r.direction);
        r.pdf_position = pmf;
        r.pdf_direction = projector->camera.pdf_direction_solid_angle(r.direction);
        r.delta_position = true;
        if (!(r.pdf_direction > 0.f)) return EmittedRay{};
        r.weight = r.radiance / (r.pdf_position * r.pdf_direction);
    } else if (const auto* directional = std::get_if<DirectionalEmitter>(&e)) {
        r.direction = directional->direction;
        r.origin = disk_origin(-directional->direction);
        r.radiance = directional->irradiance;
        r.pdf_position = pmf * disk_pdf;
        r.pdf_direction = 1.f;
        r.delta_direction = true;
        r.at_infinity = true;
        r.weight = r.radiance / r.pdf_position;
    } else {
        // The environment as one light (sample_emitter): a direction towards it from the chosen
        // emitter's sampler, with the radiance and density of all of them; the ray comes back.
        Vec3f towards = Vec3f::Zero();
        EnvironmentValue env;
        if (const auto* envmap = std::get_if<EnvmapEmitter>(&e)) {
            const EnvmapEmitter::Sample es = envmap->sample_direction(u_direction);
            if (!(es.pdf_solid_angle > 0.f)) return EmittedRay{};
            towards = es.direction;
            env = environment_of_sample(*envmap, es, pmf);
        } else {
            towards = warp::square_to_uniform_sphere(u_direction);
            env = environment_with_pdf(towards);
        }
        r.direction = -towards;
        r.origin = disk_origin(towards);
        r.radiance = env.radiance;
        r.pdf_position = disk_pdf;
        r.pdf_direction = env.pdf_solid_angle;
        r.at_infinity = true;
        if (!(r.pdf_direction > 0.f)) return EmittedRay{};
        r.weight = r.radiance / (r.pdf_position * r.pdf_direction);
    }
    if (!r.valid() || !is_finite(r.weight) || !r.origin.allFinite()) return EmittedRay{};
    return r;
}

EmissionPdf Scene::pdf_emitted_ray(int emitter, const Vec3f& n_geometric,
                                   const Vec3f& direction) const {
    EmissionPdf pdf;
    if (emitter < 0 || static_cast<std::size_t>(emitter) >= emitters_.size()) return pdf;
    const auto index = static_cast<std::size_t>(emitter);
    const float pmf = emitter_selection_.pmf(index);
    const Emitter& e = emitters_[index];
    if (const auto* area = std::get_if<AreaEmitter>(&e)) {
        const float area_total = shapes_[static_cast<std::size_t>(area->shape)].surface_area();
        const float cos_theta = n_geometric.dot(direction);
        if (!(area_total > 0.f) || !(cos_theta > 0.f)) return pdf;
        pdf.position = pmf / area_total;
        pdf.direction = cos_theta * kInvPi;
    } else if (std::holds_alternative<PointEmitter>(e)) {
        pdf.position = pmf;
        pdf.direction = warp::square_to_uniform_sphere_pdf_solid_angle();
    } else if (const auto* spot = std::get_if<SpotEmitter>(&e)) {
        if (!((spot->local_from_world * direction).z() > spot->cos_cutoff)) return pdf;
        pdf.position = pmf;
        pdf.direction = warp::square_to_uniform_cone_pdf_solid_angle(spot->cos_cutoff);
    } else if (const auto* projector = std::get_if<ProjectorEmitter>(&e)) {
        pdf.direction = projector->camera.pdf_direction_solid_angle(direction);
        if (!(pdf.direction > 0.f)) return EmissionPdf{};
        pdf.position = pmf;
    } else if (std::holds_alternative<DirectionalEmitter>(e)) {
        pdf.position = pmf / (kPi * bounds_radius_ * bounds_radius_);
        pdf.direction = 1.f;
    } else {
        return pdf_environment_ray(direction);
    }
    return pdf;
}

EmissionPdf Scene::pdf_environment_ray(const Vec3f& direction) const {
    EmissionPdf pdf;
    if (infinite_emitters_.empty()) return pdf;
    pdf.direction = pdf_environment_solid_angle(-direction);
    if (pdf.direction > 0.f) pdf.position = 1.f / (kPi * bounds_radius_ * bounds_radius_);
    return pdf;
}

Rgb Scene::emitted(const SurfaceInteraction& si, const Vec3f& w) const {
    const int emitter = shapes_[static_cast<std::size_t>(si.shape)].emitter();
    if (emitter < 0) return Rgb::Zero();
    const auto& area = std::get<AreaEmitter>(emitters_[static_cast<std::size_t>(emitter)]);
    if (si.n_geometric.dot(w) <= 0.f) return Rgb::Zero();  // emits from the front side only
    return area.radiance.eval(si.texture_point());
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

Scene::EnvironmentValue Scene::environment_with_pdf(const Vec3f& direction) const {
    EnvironmentValue v;
    for (int index : infinite_emitters_) {
        const Emitter& e = emitters_[static_cast<std::size_t>(index)];
        const float pmf = emitter_selection_.pmf(static_cast<std::size_t>(index));
        if (const auto* envmap = std::get_if<EnvmapEmitter>(&e)) {
            const EnvmapEmitter::Value ev = envmap->eval_with_pdf(direction);
            v.radiance += ev.radiance;
            v.pdf_solid_angle += pmf * ev.pdf_solid_angle;
        } else {
            v.radiance += std::get<ConstantEmitter>(e).radiance;
            v.pdf_solid_angle += pmf * warp::square_to_uniform_sphere_pdf_solid_angle();
        }
    }
    return v;
}

Scene::EnvironmentValue Scene::environment_of_sample(const EnvmapEmitter& envmap,
                                                     const EnvmapEmitter::Sample& sample,
                                                     float pmf) const {
    // The only infinite emitter: its radiance and density at the sample's own (u, v), without
    // mapping the direction back to (u, v) (two atan2 and a square root, and the texel and
    // density lookups again: a tenth of the path tracer's time on an image-lit scene, perf).
    // The density is the one environment_with_pdf() gives for the direction except where the
    // float round trip (within 2e-7 rad) crosses a sampling cell's edge: a strip along the
    // edges of about 1e-5 of the directions of a 32 x 16 map (tests/core/test_emitter.cpp).
    if (infinite_emitters_.size() != 1) return environment_with_pdf(sample.direction);
    EnvironmentValue v;
    v.radiance = envmap.radiance_at(sample.uv);
    v.pdf_solid_angle = pmf * sample.pdf_solid_angle;
    return v;
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
