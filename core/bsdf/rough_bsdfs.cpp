// SPDX-License-Identifier: GPL-3.0-or-later
// Rough conductor and rough dielectric (Walter et al. 2007, "Microfacet models for refraction
// through rough surfaces"), sampled by visible normals (Heitz & d'Eon 2014) by default.
//
// Notation: wo is the camera-side direction, wi the light-side one (bsdf.h). For refraction,
// eta_rel = eta(wi's side) / eta(wo's side), and the generalised half vector is
// h ~ wo + eta_rel wi (Walter eq. 16, up to sign), turned towards +z.
#include "core/bsdf/bsdf_models.h"
#include "core/bsdf/fresnel.h"
#include "core/math/frame.h"

namespace gdmlt::detail {
namespace {

/// Walter eq. 17 rewritten for our directions: the Jacobian d omega_h / d omega_wi of the
/// refraction half vector, eta_rel^2 |wi.h| / (wo.h + eta_rel wi.h)^2.
float refraction_jacobian(float wo_h, float wi_h, float eta_rel) {
    const float denom = wo_h + eta_rel * wi_h;
    if (denom == 0.f) return 0.f;
    return eta_rel * eta_rel * std::abs(wi_h) / (denom * denom);
}

/// Density of the microfacet normal `m` as the sampler draws it for `wo` (either side).
float microfacet_pdf(const MicrofacetDistribution& d, bool sample_visible, const Vec3f& wo,
                     const Vec3f& m) {
    if (!sample_visible) return d.pdf_all(m);
    // Seen from below the surface, the visible normals are those of the mirrored direction.
    return d.pdf_visible(wo.z() >= 0.f ? wo : Vec3f(-wo), m);
}

Vec3f sample_microfacet(const MicrofacetDistribution& d, bool sample_visible, const Vec3f& wo,
                        const Vec2f& u) {
    if (!sample_visible) return d.sample_all(u);
    return d.sample_visible(wo.z() >= 0.f ? wo : Vec3f(-wo), u);
}

}  // namespace

// --- Rough conductor -------------------------------------------------------------------------

Rgb eval_model(const RoughConductorBsdf& b, const TexturePoint& at, const Vec3f& wo,
               const Vec3f& wi, TransportMode) {
    if (!(cos_theta(wo) > 0.f) || !(cos_theta(wi) > 0.f)) return Rgb::Zero();
    Vec3f h = wo + wi;
    const float len = h.norm();
    if (!(len > 0.f)) return Rgb::Zero();
    h /= len;
    const MicrofacetDistribution d = b.roughness.at(at);
    const float D = d.D(h);
    if (D == 0.f) return Rgb::Zero();
    // f cos(theta_i) = F D G / (4 cos_o cos_i) * cos_i (Walter eq. 20).
    const float value = D * d.G(wo, wi, h) / (4.f * cos_theta(wo));
    Rgb f = b.specular_reflectance.eval(at) * value;
    if (!b.perfect_mirror) f *= fresnel_conductor(wo.dot(h), b.eta, b.k);
    return f;
}

float pdf_model(const RoughConductorBsdf& b, const TexturePoint& at, const Vec3f& wo,
                const Vec3f& wi) {
    if (!(cos_theta(wo) > 0.f) || !(cos_theta(wi) > 0.f)) return 0.f;
    Vec3f h = wo + wi;
    const float len = h.norm();
    if (!(len > 0.f)) return 0.f;
    h /= len;
    const MicrofacetDistribution d = b.roughness.at(at);
    // Reflection Jacobian d omega_h / d omega_i = 1 / (4 |wi.h|) (Walter eq. 14).
    return microfacet_pdf(d, b.roughness.sample_visible, wo, h) / (4.f * wi.dot(h));
}

BsdfSample sample_model(const RoughConductorBsdf& b, const TexturePoint& at, const Vec3f& wo, float,
                        const Vec2f& u, TransportMode) {
    BsdfSample s;
    if (!(cos_theta(wo) > 0.f)) return s;
    const MicrofacetDistribution d = b.roughness.at(at);
    const Vec3f m = sample_microfacet(d, b.roughness.sample_visible, wo, u);
    const float wo_m = wo.dot(m);
    if (!(wo_m > 0.f) || !(m.z() > 0.f)) return s;
    s.wi = reflect_about(wo, m);
    if (!(cos_theta(s.wi) > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    s.pdf_solid_angle = microfacet_pdf(d, b.roughness.sample_visible, wo, m) / (4.f * wo_m);
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    // eval / pdf in closed form: with visible normals D and G1(wo) cancel, leaving G1(wi)
    // (Heitz & d'Eon 2014, eq. 14); otherwise G (wo.m) / (cos_o cos_m).
    const float g = b.roughness.sample_visible ? d.G1(s.wi, m)
                                               : d.G(wo, s.wi, m) * wo_m / (cos_theta(wo) * m.z());
    s.weight = b.specular_reflectance.eval(at) * g;
    if (!b.perfect_mirror) s.weight *= fresnel_conductor(wo_m, b.eta, b.k);
    s.sampled_class = b.roughness.roughness_class_at(at);
    return s;
}

BsdfLobes model_lobes(const RoughConductorBsdf& b) {
    BsdfLobes l;
    l.sharpest_class = b.roughness.roughness_class();
    // The lobe has a density whatever its alpha: glossy by kind; how delta-like or broad it
    // is, is the class's business (roughness_class.h).
    l.glossy_reflection = true;
    return l;
}
RoughnessClass model_class(const RoughConductorBsdf& b) {
    return b.roughness.roughness_class();
}
RoughnessClass model_class_at(const RoughConductorBsdf& b, const TexturePoint& at) {
    return b.roughness.roughness_class_at(at);
}

// --- Rough dielectric ------------------------------------------------------------------------

namespace {

/// The half vector of a (wo, wi) pair and the checks shared by eval and pdf. Returns false when
/// the pair cannot come from any microfacet (grazing, back-facing facet, degenerate h).
struct DielectricPair {
    Vec3f h;
    bool reflection;
    float eta_rel;  // eta(wi side) / eta(wo side), for refraction
};
bool dielectric_pair(const RoughDielectricBsdf& b, const Vec3f& wo, const Vec3f& wi,
                     DielectricPair* out) {
    const float cos_o = cos_theta(wo), cos_i = cos_theta(wi);
    if (cos_o == 0.f || cos_i == 0.f || !std::isfinite(cos_o) || !std::isfinite(cos_i))
        return false;
    out->reflection = cos_o * cos_i > 0.f;
    out->eta_rel = cos_o > 0.f ? b.eta : 1.f / b.eta;
    Vec3f h = out->reflection ? Vec3f(wo + wi) : Vec3f(wo + out->eta_rel * wi);
    const float len = h.norm();
    if (!(len > 0.f)) return false;
    h /= len;
    if (h.z() < 0.f) h = -h;
    // Both directions must see the front of the facet from their own side (Walter eq. 7's chi+
    // for each direction): otherwise the configuration is unreachable.
    if (!(wo.dot(h) * cos_o > 0.f) || !(wi.dot(h) * cos_i > 0.f)) return false;
    out->h = h;
    return true;
}

/// Fresnel reflectance of the pair's microfacet. For refraction both cosines are known from
/// the pair itself, so the Fresnel amplitudes are evaluated from them directly instead of
/// deriving one from the other through Snell's law, which cancels catastrophically near the
/// critical angle (25% errors in 1 - F at 1e-3 from grazing) and would make eval(wo, wi) and
/// eval(wi, wo) disagree. The expression is symmetric in the two sides, as F is.
float pair_fresnel(const RoughDielectricBsdf& b, const DielectricPair& p, float wo_h, float wi_h,
                   bool wo_outside) {
    if (p.reflection) return fresnel_dielectric(wo_h, b.eta).reflectance;
    const float n_o = wo_outside ? 1.f : b.eta, n_i = wo_outside ? b.eta : 1.f;
    const float c_o = std::abs(wo_h), c_i = std::abs(wi_h);
    const float r_s = (n_o * c_o - n_i * c_i) / (n_o * c_o + n_i * c_i);
    const float r_p = (n_i * c_o - n_o * c_i) / (n_i * c_o + n_o * c_i);
    return std::clamp(0.5f * (r_s * r_s + r_p * r_p), 0.f, 1.f);
}

}  // namespace

Rgb eval_model(const RoughDielectricBsdf& b, const TexturePoint& at, const Vec3f& wo,
               const Vec3f& wi, TransportMode mode) {
    DielectricPair p;
    if (!dielectric_pair(b, wo, wi, &p)) return Rgb::Zero();
    const MicrofacetDistribution d = b.roughness.at(at);
    const float D = d.D(p.h);
    if (D == 0.f) return Rgb::Zero();
    const float G = d.G(wo, wi, p.h);
    const float wo_h = wo.dot(p.h), wi_h = wi.dot(p.h);
    const float F = pair_fresnel(b, p, wo_h, wi_h, cos_theta(wo) > 0.f);
    const float abs_cos_o = std::abs(cos_theta(wo));
    if (p.reflection) return b.specular_reflectance.eval(at) * (F * D * G / (4.f * abs_cos_o));
    // Walter eq. 21 times |cos_i|, written with eta_rel = eta_i / eta_o (their i, o = our wi,
    // wo): |wi.h| |wo.h| (1 - F) D G / (|cos_o| (wo.h + eta_rel wi.h)^2). This is the radiance
    // BSDF; the adjoint (importance) BSDF carries eta_rel^2 more (Veach 1997, eq. 5.13).
    const float denom = wo_h + p.eta_rel * wi_h;
    if (denom == 0.f) return Rgb::Zero();
    float value = std::abs(wo_h * wi_h) * (1.f - F) * D * G / (abs_cos_o * denom * denom);
    if (mode == TransportMode::Importance) value *= p.eta_rel * p.eta_rel;
    return b.specular_transmittance.eval(at) * value;
}

float pdf_model(const RoughDielectricBsdf& b, const TexturePoint& at, const Vec3f& wo,
                const Vec3f& wi) {
    DielectricPair p;
    if (!dielectric_pair(b, wo, wi, &p)) return 0.f;
    const MicrofacetDistribution d = b.roughness.at(at);
    const float pdf_m = microfacet_pdf(d, b.roughness.sample_visible, wo, p.h);
    const float wo_h = wo.dot(p.h), wi_h = wi.dot(p.h);
    const float F = pair_fresnel(b, p, wo_h, wi_h, cos_theta(wo) > 0.f);
    if (p.reflection) return pdf_m * F / (4.f * std::abs(wi_h));
    return pdf_m * (1.f - F) * refraction_jacobian(wo_h, wi_h, p.eta_rel);
}

BsdfSample sample_model(const RoughDielectricBsdf& b, const TexturePoint& at, const Vec3f& wo,
                        float u_lobe, const Vec2f& u, TransportMode mode) {
    BsdfSample s;
    const float cos_o = cos_theta(wo);
    if (cos_o == 0.f || !std::isfinite(cos_o)) return s;
    const MicrofacetDistribution d = b.roughness.at(at);
    const Vec3f m = sample_microfacet(d, b.roughness.sample_visible, wo, u);
    const float wo_m = wo.dot(m);
    if (!(m.z() > 0.f) || !(wo_m * cos_o > 0.f)) return s;
    const float pdf_m = microfacet_pdf(d, b.roughness.sample_visible, wo, m);
    if (!(pdf_m > 0.f)) return s;
    const FresnelDielectric f = fresnel_dielectric(wo_m, b.eta);
    s.sampled_class = b.roughness.roughness_class_at(at);
    const bool visible = b.roughness.sample_visible;
    // Reflection with probability F(wo.m), so that F cancels from the weight (Walter Sec. 5.3).
    if (u_lobe < f.reflectance) {
        s.wi = reflect_about(wo, m);
        if (!(cos_theta(s.wi) * cos_o > 0.f)) {
            s = BsdfSample{};
            return s;
        }
        const float wi_m = std::abs(s.wi.dot(m));
        s.pdf_solid_angle = pdf_m * f.reflectance / (4.f * wi_m);
        const float g =
            visible ? d.G1(s.wi, m) : d.G(wo, s.wi, m) * wi_m / (std::abs(cos_o) * m.z());
        s.weight = b.specular_reflectance.eval(at) * g;
        return s;
    }
    // Refraction about m (Walter eq. 40); f.cos_theta_t is signed along m.
    s.wi = (-f.eta_ti * wo + (f.eta_ti * wo_m + f.cos_theta_t) * m).normalized();
    if (!(cos_theta(s.wi) * cos_o < 0.f)) {
        s = BsdfSample{};
        return s;
    }
    const float eta_rel = f.eta_it;
    const float wi_m = s.wi.dot(m);
    s.pdf_solid_angle = pdf_m * (1.f - f.reflectance) * refraction_jacobian(wo_m, wi_m, eta_rel);
    s.transmission = true;
    s.eta = eta_rel;
    // eval / pdf: G1(wi) with visible normals, G |wo.m| / (|cos_o| cos_m) otherwise; the
    // radiance BSDF carries 1 / eta_rel^2 relative to the importance one.
    float g =
        visible ? d.G1(s.wi, m) : d.G(wo, s.wi, m) * std::abs(wo_m) / (std::abs(cos_o) * m.z());
    if (mode == TransportMode::Radiance) g /= eta_rel * eta_rel;
    s.weight = b.specular_transmittance.eval(at) * g;
    return s;
}

BsdfLobes model_lobes(const RoughDielectricBsdf& b) {
    BsdfLobes l;
    l.sharpest_class = b.roughness.roughness_class();
    l.glossy_reflection = l.glossy_transmission = true;
    return l;
}
RoughnessClass model_class(const RoughDielectricBsdf& b) {
    return b.roughness.roughness_class();
}
RoughnessClass model_class_at(const RoughDielectricBsdf& b, const TexturePoint& at) {
    return b.roughness.roughness_class_at(at);
}

}  // namespace gdmlt::detail
