// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/bsdf/bsdf.h"

#include <map>
#include <string>

#include "core/bsdf/bsdf_models.h"
#include "core/bsdf/fresnel.h"
#include "core/math/frame.h"
#include "core/sampling/warp.h"

namespace gdmlt {

const char* to_string(RoughnessClass c) {
    switch (c) {
        case RoughnessClass::Diffuse:
            return "diffuse";
        case RoughnessClass::Glossy:
            return "glossy";
        case RoughnessClass::Delta:
            return "delta";
    }
    return "?";
}

namespace detail {

// Smooth models and the diffuse base. Delta lobes have no density: eval and pdf are zero.

Rgb eval_model(const DiffuseBsdf& m, const Vec2f& uv, const Vec3f& wo, const Vec3f& wi,
               TransportMode) {
    if (cos_theta(wo) <= 0.f || cos_theta(wi) <= 0.f) return Rgb::Zero();
    return m.reflectance.eval(uv) * (kInvPi * cos_theta(wi));
}
float pdf_model(const DiffuseBsdf&, const Vec2f&, const Vec3f& wo, const Vec3f& wi) {
    if (cos_theta(wo) <= 0.f || cos_theta(wi) <= 0.f) return 0.f;
    return warp::square_to_cosine_hemisphere_pdf_solid_angle(wi);
}
BsdfSample sample_model(const DiffuseBsdf& m, const Vec2f& uv, const Vec3f& wo, float,
                        const Vec2f& u, TransportMode) {
    BsdfSample s;
    if (cos_theta(wo) <= 0.f) return s;
    s.wi = warp::square_to_cosine_hemisphere(u);
    s.pdf_solid_angle = warp::square_to_cosine_hemisphere_pdf_solid_angle(s.wi);
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    s.weight = m.reflectance.eval(uv);  // (R/pi * cos) / (cos/pi)
    s.sampled_class = RoughnessClass::Diffuse;
    return s;
}
BsdfLobes model_lobes(const DiffuseBsdf&) {
    BsdfLobes l;
    l.diffuse_reflection = true;
    return l;
}
RoughnessClass model_class(const DiffuseBsdf&) {
    return RoughnessClass::Diffuse;
}
RoughnessClass model_class_at(const DiffuseBsdf&, const Vec2f&) {
    return RoughnessClass::Diffuse;
}

BsdfSample sample_model(const DielectricBsdf& m, const Vec2f& uv, const Vec3f& wo, float u_lobe,
                        const Vec2f&, TransportMode mode) {
    BsdfSample s;
    const FresnelDielectric f = fresnel_dielectric(cos_theta(wo), m.eta);
    s.delta = true;
    s.sampled_class = RoughnessClass::Delta;
    // Choose reflection with probability F: the weight is then R or T without the Fresnel
    // factor (it cancels against the selection probability).
    if (u_lobe < f.reflectance) {
        s.wi = reflect_local(wo);
        s.pdf_solid_angle = f.reflectance;
        s.weight = m.specular_reflectance.eval(uv);
        s.eta = 1.f;
    } else {
        s.wi = refract_local(wo, f.cos_theta_t, f.eta_ti);
        s.pdf_solid_angle = 1.f - f.reflectance;
        s.transmission = true;
        s.eta = f.eta_it;
        const float scale = mode == TransportMode::Radiance ? f.eta_ti * f.eta_ti : 1.f;
        s.weight = m.specular_transmittance.eval(uv) * scale;
    }
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    return s;
}
BsdfLobes model_lobes(const DielectricBsdf&) {
    BsdfLobes l;
    l.sharpest_class = RoughnessClass::Delta;
    l.delta_reflection = l.delta_transmission = true;
    return l;
}

BsdfSample sample_model(const ThinDielectricBsdf& m, const Vec2f& uv, const Vec3f& wo, float u_lobe,
                        const Vec2f&, TransportMode) {
    BsdfSample s;
    s.delta = true;
    s.sampled_class = RoughnessClass::Delta;
    float r = fresnel_dielectric(std::abs(cos_theta(wo)), m.eta).reflectance;
    // Sum of the geometric series of internal reflections in the slab: R + T^2 R / (1 - R^2).
    if (r < 1.f) r += (1.f - r) * (1.f - r) * r / (1.f - r * r);
    if (u_lobe < r) {
        s.wi = reflect_local(wo);
        s.pdf_solid_angle = r;
        s.weight = m.specular_reflectance.eval(uv);
    } else {
        s.wi = -wo;
        s.pdf_solid_angle = 1.f - r;
        s.transmission = true;
        s.weight = m.specular_transmittance.eval(uv);
    }
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    return s;
}
BsdfLobes model_lobes(const ThinDielectricBsdf&) {
    BsdfLobes l;
    l.sharpest_class = RoughnessClass::Delta;
    l.delta_reflection = l.delta_transmission = true;
    return l;
}

BsdfSample sample_model(const ConductorBsdf& m, const Vec2f& uv, const Vec3f& wo, float,
                        const Vec2f&, TransportMode) {
    BsdfSample s;
    if (cos_theta(wo) <= 0.f) return s;
    s.delta = true;
    s.sampled_class = RoughnessClass::Delta;
    s.wi = reflect_local(wo);
    s.pdf_solid_angle = 1.f;
    s.weight = m.specular_reflectance.eval(uv);
    if (!m.perfect_mirror) s.weight *= fresnel_conductor(cos_theta(wo), m.eta, m.k);
    return s;
}
BsdfLobes model_lobes(const ConductorBsdf&) {
    BsdfLobes l;
    l.sharpest_class = RoughnessClass::Delta;
    l.delta_reflection = true;
    return l;
}

// The three purely delta models share eval, pdf and class.
#define GDMLT_DELTA_MODEL(M)                                                            \
    Rgb eval_model(const M&, const Vec2f&, const Vec3f&, const Vec3f&, TransportMode) { \
        return Rgb::Zero();                                                             \
    }                                                                                   \
    float pdf_model(const M&, const Vec2f&, const Vec3f&, const Vec3f&) {               \
        return 0.f;                                                                     \
    }                                                                                   \
    RoughnessClass model_class(const M&) {                                              \
        return RoughnessClass::Delta;                                                   \
    }                                                                                   \
    RoughnessClass model_class_at(const M&, const Vec2f&) {                             \
        return RoughnessClass::Delta;                                                   \
    }
GDMLT_DELTA_MODEL(DielectricBsdf)
GDMLT_DELTA_MODEL(ThinDielectricBsdf)
GDMLT_DELTA_MODEL(ConductorBsdf)
#undef GDMLT_DELTA_MODEL

}  // namespace detail

namespace {

bool model_is_delta(const BsdfModel& m) {
    return std::holds_alternative<DielectricBsdf>(m) ||
           std::holds_alternative<ThinDielectricBsdf>(m) ||
           std::holds_alternative<ConductorBsdf>(m);
}
BsdfLobes model_lobes(const BsdfModel& m) {
    return std::visit([](const auto& model) { return detail::model_lobes(model); }, m);
}
bool model_transmits(const BsdfModel& m) {
    const BsdfLobes l = model_lobes(m);
    return l.delta_transmission || l.glossy_transmission;
}

Vec3f flip_z(const Vec3f& w) {
    return {w.x(), w.y(), -w.z()};
}

}  // namespace

Bsdf Bsdf::two_sided(BsdfModel front, std::optional<BsdfModel> back) {
    Bsdf b(std::move(front));
    b.back_ = std::move(back);
    b.two_sided_ = true;
    return b;
}

const BsdfModel& Bsdf::model_for(const Vec3f& wo, Vec3f* wo_query, bool* flipped) const {
    *flipped = two_sided_ && cos_theta(wo) < 0.f;
    *wo_query = *flipped ? flip_z(wo) : wo;
    if (*flipped && back_) return *back_;
    return front_;
}

Rgb Bsdf::eval(const Vec2f& uv, const Vec3f& wo, const Vec3f& wi, TransportMode mode) const {
    Vec3f wo_q;
    bool flipped;
    const BsdfModel& m = model_for(wo, &wo_q, &flipped);
    const Vec3f wi_q = flipped ? flip_z(wi) : wi;
    const Rgb f = std::visit(
        [&](const auto& model) { return detail::eval_model(model, uv, wo_q, wi_q, mode); }, m);
    return is_finite(f) ? f : Rgb::Zero();
}

float Bsdf::pdf(const Vec2f& uv, const Vec3f& wo, const Vec3f& wi) const {
    Vec3f wo_q;
    bool flipped;
    const BsdfModel& m = model_for(wo, &wo_q, &flipped);
    const Vec3f wi_q = flipped ? flip_z(wi) : wi;
    const float p =
        std::visit([&](const auto& model) { return detail::pdf_model(model, uv, wo_q, wi_q); }, m);
    return std::isfinite(p) ? p : 0.f;
}

BsdfSample Bsdf::sample(const Vec2f& uv, const Vec3f& wo, float u_lobe, const Vec2f& u,
                        TransportMode mode) const {
    Vec3f wo_q;
    bool flipped;
    const BsdfModel& m = model_for(wo, &wo_q, &flipped);
    BsdfSample s = std::visit(
        [&](const auto& model) { return detail::sample_model(model, uv, wo_q, u_lobe, u, mode); },
        m);
    if (flipped) s.wi = flip_z(s.wi);
    if (!s.valid() || !std::isfinite(s.pdf_solid_angle) || !is_finite(s.weight) ||
        !s.wi.allFinite())
        s = BsdfSample{};
    return s;
}

bool Bsdf::is_delta() const {
    return model_is_delta(front_) && (!back_ || model_is_delta(*back_));
}
bool Bsdf::has_transmission() const {
    return model_transmits(front_) || (back_ && model_transmits(*back_));
}
RoughnessClass Bsdf::roughness_class() const {
    const auto cls = [](const BsdfModel& m) {
        return std::visit([](const auto& model) { return detail::model_class(model); }, m);
    };
    RoughnessClass c = cls(front_);
    if (back_) c = std::min(c, cls(*back_));  // enum order: most connectable first
    return c;
}
RoughnessClass Bsdf::roughness_class_at(const Vec2f& uv) const {
    const auto cls = [&](const BsdfModel& m) {
        return std::visit([&](const auto& model) { return detail::model_class_at(model, uv); }, m);
    };
    RoughnessClass c = cls(front_);
    if (back_) c = std::min(c, cls(*back_));
    return c;
}
BsdfLobes Bsdf::lobes() const {
    BsdfLobes l = model_lobes(front_);
    if (back_) l |= model_lobes(*back_);
    return l;
}

std::optional<float> lookup_ior(const std::string& name) {
    // Mitsuba's table of named indices of refraction (values at visible wavelengths).
    static const std::map<std::string, float> table = {
        {"vacuum", 1.0f},      {"helium", 1.000036f},        {"hydrogen", 1.000132f},
        {"air", 1.000277f},    {"carbon dioxide", 1.00045f}, {"water", 1.3330f},
        {"acetone", 1.36f},    {"ethanol", 1.361f},          {"carbon tetrachloride", 1.461f},
        {"glycerol", 1.4729f}, {"benzene", 1.501f},          {"silicone oil", 1.52045f},
        {"bromine", 1.661f},   {"water ice", 1.31f},         {"fused quartz", 1.458f},
        {"pyrex", 1.470f},     {"acrylic glass", 1.49f},     {"polypropylene", 1.49f},
        {"bk7", 1.5046f},      {"sodium chloride", 1.544f},  {"amber", 1.55f},
        {"pet", 1.5750f},      {"diamond", 2.419f}};
    const auto it = table.find(name);
    if (it == table.end()) return std::nullopt;
    return it->second;
}

std::optional<ConductorIor> lookup_conductor(const std::string& name) {
    // RGB reductions of measured spectral complex IORs (Palik), the values RGB renderers
    // commonly use for these metals.
    static const std::map<std::string, ConductorIor> table = {
        {"Ag", {Rgb(0.155265f, 0.116723f, 0.138342f), Rgb(4.82835f, 3.12225f, 2.14696f)}},
        {"Al", {Rgb(1.65746f, 0.880369f, 0.521229f), Rgb(9.22387f, 6.26952f, 4.837f)}},
        {"Au", {Rgb(0.143119f, 0.374957f, 1.44248f), Rgb(3.98316f, 2.38572f, 1.60322f)}},
        {"Cu", {Rgb(0.200438f, 0.924033f, 1.10221f), Rgb(3.91295f, 2.45285f, 2.14219f)}},
        {"Cr", {Rgb(4.36968f, 2.9167f, 1.6547f), Rgb(5.20643f, 4.23136f, 3.75495f)}},
    };
    const auto it = table.find(name);
    if (it == table.end()) return std::nullopt;
    return it->second;
}

}  // namespace gdmlt
