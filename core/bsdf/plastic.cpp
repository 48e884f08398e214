// SPDX-License-Identifier: GPL-3.0-or-later
// Mitsuba's `plastic` and `roughplastic`: a dielectric coat (smooth, or rough with a microfacet
// distribution) over a Lambertian base. Light that enters the coat bounces between base and
// coat; summing that series in closed form divides the base albedo by (1 - R_int), with R_int
// the coat's diffuse reflectance seen from inside (for `nonlinear`, by (1 - albedo R_int)). On
// the way in and out the light loses the coat's transmittance, and leaving the denser medium
// compresses radiance by 1 / eta^2. The values below follow Mitsuba 3's documented model so
// that its renders serve as references.
#include <cmath>
#include <numbers>
#include <vector>

#include "core/bsdf/bsdf_models.h"
#include "core/bsdf/fresnel.h"
#include "core/math/frame.h"
#include "core/sampling/warp.h"

namespace gdmlt {
namespace {

/// Nodes and weights of n-point Gauss-Legendre quadrature on [-1, 1] (Newton's method on the
/// Legendre recurrence, the textbook construction; Golub & Welsch would do as well).
void gauss_legendre(int n, std::vector<double>* nodes, std::vector<double>* weights) {
    nodes->assign(static_cast<std::size_t>(n), 0.0);
    weights->assign(static_cast<std::size_t>(n), 0.0);
    for (int i = 0; i < (n + 1) / 2; ++i) {
        double x = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));  // Tricomi's guess
        double dp = 1.0;
        for (int iter = 0; iter < 100; ++iter) {
            double p0 = 1.0, p1 = x;
            for (int k = 2; k <= n; ++k) {
                const double pk = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = pk;
            }
            dp = n * (x * p1 - p0) / (x * x - 1.0);
            const double dx = p1 / dp;
            x -= dx;
            if (std::abs(dx) < 1e-15) break;
        }
        const double w = 2.0 / ((1.0 - x * x) * dp * dp);
        (*nodes)[static_cast<std::size_t>(i)] = -x;
        (*nodes)[static_cast<std::size_t>(n - 1 - i)] = x;
        (*weights)[static_cast<std::size_t>(i)] = w;
        (*weights)[static_cast<std::size_t>(n - 1 - i)] = w;
    }
}

/// Energy that a rough dielectric interface with relative index `eta` reflects (reflect =
/// true) or transmits for light arriving along `w` (w.z > 0): the expectation over the visible
/// normals of F or (1 - F) times the masking of the scattered direction, integrated with an
/// n x n Gauss-Legendre rule over the visible-normal sampler's unit square.
double coat_energy(const MicrofacetDistribution& d, const Vec3f& w, float eta, bool reflect,
                   const std::vector<double>& nodes, const std::vector<double>& weights) {
    double sum = 0.0;
    for (std::size_t a = 0; a < nodes.size(); ++a)
        for (std::size_t c = 0; c < nodes.size(); ++c) {
            const Vec2f u(static_cast<float>(0.5 * nodes[a] + 0.5),
                          static_cast<float>(0.5 * nodes[c] + 0.5));
            const Vec3f m = d.sample_visible(w, u);
            const float w_m = w.dot(m);
            if (!(w_m > 0.f)) continue;
            const FresnelDielectric f = fresnel_dielectric(w_m, eta);
            float value;
            if (reflect) {
                value = f.reflectance * d.G1(detail::reflect_about(w, m), m);
            } else {
                if (f.reflectance >= 1.f) continue;
                const Vec3f t = -f.eta_ti * w + (f.eta_ti * w_m + f.cos_theta_t) * m;
                value = (1.f - f.reflectance) * d.G1(t, m);
            }
            sum += weights[a] * weights[c] * value;
        }
    return 0.25 * sum;  // the rule's weights sum to 4 over [-1, 1]^2
}

float specular_sampling_weight(const RgbTexture& diffuse, const RgbTexture& specular) {
    // Mitsuba steers lobe choice by the mean reflectances: s / (s + d).
    const float d_mean = diffuse.mean_value().mean(), s_mean = specular.mean_value().mean();
    return s_mean + d_mean > 0.f ? s_mean / (s_mean + d_mean) : 0.5f;
}

Rgb base_albedo(const RgbTexture& diffuse, const TexturePoint& at, bool nonlinear,
                float r_internal) {
    const Rgb albedo = diffuse.eval(at);
    if (nonlinear) return albedo / (1.f - albedo * r_internal);
    return albedo / (1.f - r_internal);
}

}  // namespace

float fresnel_diffuse_reflectance(float eta) {
    // 2 int_0^1 F(mu) mu dmu by the midpoint rule; 8192 panels resolve the kink at the critical
    // angle (eta < 1) to ~1e-6. Done once per material at load time.
    constexpr int kPanels = 8192;
    double sum = 0.0;
    for (int i = 0; i < kPanels; ++i) {
        const double mu = (i + 0.5) / kPanels;
        sum += fresnel_dielectric(static_cast<float>(mu), eta).reflectance * mu;
    }
    return static_cast<float>(2.0 * sum / kPanels);
}

PlasticBsdf make_plastic(float eta, RgbTexture diffuse_reflectance, RgbTexture specular_reflectance,
                         bool nonlinear) {
    PlasticBsdf p;
    p.eta = eta;
    p.specular_sampling_weight =
        specular_sampling_weight(diffuse_reflectance, specular_reflectance);
    p.diffuse_reflectance = std::move(diffuse_reflectance);
    p.specular_reflectance = std::move(specular_reflectance);
    p.nonlinear = nonlinear;
    p.fdr_internal = fresnel_diffuse_reflectance(1.f / eta);
    return p;
}

float RoughCoatTable::transmittance(float cos_theta) const {
    // Linear interpolation over cos(theta) in [0, 1] at kResolution equally spaced nodes.
    const float x = std::clamp(cos_theta, 0.f, 1.f) * static_cast<float>(kResolution - 1);
    const int i = std::min(static_cast<int>(x), kResolution - 2);
    const float t = x - static_cast<float>(i);
    return (1.f - t) * external_transmittance[i] + t * external_transmittance[i + 1];
}

RoughPlasticBsdf make_rough_plastic(MicrofacetType type, float alpha, bool sample_visible,
                                    float eta, RgbTexture diffuse_reflectance,
                                    RgbTexture specular_reflectance, bool nonlinear) {
    RoughPlasticBsdf p;
    p.type = type;
    p.alpha = std::max(alpha, kMinMicrofacetAlpha);
    p.sample_visible = sample_visible;
    p.eta = eta;
    p.specular_sampling_weight =
        specular_sampling_weight(diffuse_reflectance, specular_reflectance);
    p.diffuse_reflectance = std::move(diffuse_reflectance);
    p.specular_reflectance = std::move(specular_reflectance);
    p.nonlinear = nonlinear;

    // The coat's transmittance from outside per angle, and its mean reflectance from inside,
    // by quadrature over the visible normals (always visible: the quadrature needs that map,
    // whatever the sampling choice). Gauss-Legendre 32^2 resolves the smooth outside case;
    // the inside case has total internal reflection and gets 48^2.
    auto table = std::make_shared<RoughCoatTable>();
    const MicrofacetDistribution d(type, p.alpha, p.alpha);
    std::vector<double> nodes_out, weights_out, nodes_in, weights_in;
    gauss_legendre(32, &nodes_out, &weights_out);
    gauss_legendre(48, &nodes_in, &weights_in);
    double internal = 0.0;
    for (int i = 0; i < RoughCoatTable::kResolution; ++i) {
        const float mu = std::max(1e-6f, static_cast<float>(i) / (RoughCoatTable::kResolution - 1));
        const Vec3f w(std::sqrt(1.f - mu * mu), 0.f, mu);
        table->external_transmittance[i] =
            static_cast<float>(coat_energy(d, w, eta, false, nodes_out, weights_out));
        internal += coat_energy(d, w, 1.f / eta, true, nodes_in, weights_in) * mu;
    }
    // 2 int R(mu) mu dmu as the mean over the table's nodes, the same rule as Mitsuba 3 (it
    // reads about 1.5% low against the exact integral; matching it keeps the base albedo of
    // our renders equal to the reference's).
    table->internal_reflectance = static_cast<float>(2.0 * internal / RoughCoatTable::kResolution);
    p.table = std::move(table);
    return p;
}

namespace detail {

// --- Smooth plastic --------------------------------------------------------------------------

namespace {
/// Probability of choosing the coat's mirror lobe for this wo (Mitsuba's rule: Fresnel
/// reflectance against the base's transmitted share, each weighted by its mean reflectance).
float plastic_specular_probability(float f_i, float weight) {
    const float s = f_i * weight, d = (1.f - f_i) * (1.f - weight);
    return s + d > 0.f ? s / (s + d) : weight;
}
}  // namespace

Rgb eval_model(const PlasticBsdf& b, const TexturePoint& at, const Vec3f& wo, const Vec3f& wi,
               TransportMode) {
    if (!(cos_theta(wo) > 0.f) || !(cos_theta(wi) > 0.f)) return Rgb::Zero();
    const float f_i = fresnel_dielectric(cos_theta(wo), b.eta).reflectance;
    const float f_o = fresnel_dielectric(cos_theta(wi), b.eta).reflectance;
    return base_albedo(b.diffuse_reflectance, at, b.nonlinear, b.fdr_internal) *
           (kInvPi * cos_theta(wi) * (1.f - f_i) * (1.f - f_o) / (b.eta * b.eta));
}

float pdf_model(const PlasticBsdf& b, const TexturePoint&, const Vec3f& wo, const Vec3f& wi) {
    if (!(cos_theta(wo) > 0.f) || !(cos_theta(wi) > 0.f)) return 0.f;
    const float f_i = fresnel_dielectric(cos_theta(wo), b.eta).reflectance;
    const float p_spec = plastic_specular_probability(f_i, b.specular_sampling_weight);
    return (1.f - p_spec) * warp::square_to_cosine_hemisphere_pdf_solid_angle(wi);
}

BsdfSample sample_model(const PlasticBsdf& b, const TexturePoint& at, const Vec3f& wo, float u_lobe,
                        const Vec2f& u, TransportMode mode) {
    BsdfSample s;
    if (!(cos_theta(wo) > 0.f)) return s;
    const float f_i = fresnel_dielectric(cos_theta(wo), b.eta).reflectance;
    const float p_spec = plastic_specular_probability(f_i, b.specular_sampling_weight);
    if (u_lobe < p_spec) {
        s.wi = reflect_local(wo);
        s.pdf_solid_angle = p_spec;
        s.delta = true;
        s.sampled_class = RoughnessClass::Delta;
        s.weight = b.specular_reflectance.eval(at) * (f_i / p_spec);
        return s;
    }
    s.wi = warp::square_to_cosine_hemisphere(u);
    s.pdf_solid_angle = (1.f - p_spec) * warp::square_to_cosine_hemisphere_pdf_solid_angle(s.wi);
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    s.weight = eval_model(b, at, wo, s.wi, mode) / s.pdf_solid_angle;
    s.sampled_class = RoughnessClass::Diffuse;
    return s;
}

BsdfLobes model_lobes(const PlasticBsdf&) {
    BsdfLobes l;
    l.sharpest_class = RoughnessClass::Delta;
    l.diffuse_reflection = l.delta_reflection = true;
    return l;
}
// The most connectable lobe: shifts may reconnect at the base even though the coat is a mirror.
RoughnessClass model_class(const PlasticBsdf&) {
    return RoughnessClass::Diffuse;
}
RoughnessClass model_class_at(const PlasticBsdf&, const TexturePoint&) {
    return RoughnessClass::Diffuse;
}

// --- Rough plastic ---------------------------------------------------------------------------

namespace {
float rough_plastic_specular_probability(const RoughPlasticBsdf& b, float t_i) {
    const float s = (1.f - t_i) * b.specular_sampling_weight,
                d = t_i * (1.f - b.specular_sampling_weight);
    return s + d > 0.f ? s / (s + d) : b.specular_sampling_weight;
}
MicrofacetDistribution coat_distribution(const RoughPlasticBsdf& b) {
    return {b.type, b.alpha, b.alpha};
}
}  // namespace

Rgb eval_model(const RoughPlasticBsdf& b, const TexturePoint& at, const Vec3f& wo, const Vec3f& wi,
               TransportMode) {
    if (!(cos_theta(wo) > 0.f) || !(cos_theta(wi) > 0.f)) return Rgb::Zero();
    Rgb value = Rgb::Zero();
    const Vec3f h = (wo + wi).normalized();
    const MicrofacetDistribution d = coat_distribution(b);
    const float D = d.D(h);
    if (D > 0.f) {
        const float F = fresnel_dielectric(wo.dot(h), b.eta).reflectance;
        value = b.specular_reflectance.eval(at) * (F * D * d.G(wo, wi, h) / (4.f * cos_theta(wo)));
    }
    const float t_i = b.table->transmittance(cos_theta(wo)),
                t_o = b.table->transmittance(cos_theta(wi));
    value += base_albedo(b.diffuse_reflectance, at, b.nonlinear, b.table->internal_reflectance) *
             (kInvPi * cos_theta(wi) * t_i * t_o / (b.eta * b.eta));
    return value;
}

float pdf_model(const RoughPlasticBsdf& b, const TexturePoint&, const Vec3f& wo, const Vec3f& wi) {
    if (!(cos_theta(wo) > 0.f) || !(cos_theta(wi) > 0.f)) return 0.f;
    const float p_spec =
        rough_plastic_specular_probability(b, b.table->transmittance(cos_theta(wo)));
    const Vec3f h = (wo + wi).normalized();
    const MicrofacetDistribution d = coat_distribution(b);
    const float pdf_m = b.sample_visible ? d.pdf_visible(wo, h) : d.pdf_all(h);
    const float wi_h = wi.dot(h);
    const float pdf_spec = wi_h > 0.f ? pdf_m / (4.f * wi_h) : 0.f;
    return p_spec * pdf_spec +
           (1.f - p_spec) * warp::square_to_cosine_hemisphere_pdf_solid_angle(wi);
}

BsdfSample sample_model(const RoughPlasticBsdf& b, const TexturePoint& at, const Vec3f& wo,
                        float u_lobe, const Vec2f& u, TransportMode mode) {
    BsdfSample s;
    if (!(cos_theta(wo) > 0.f)) return s;
    const float p_spec =
        rough_plastic_specular_probability(b, b.table->transmittance(cos_theta(wo)));
    if (u_lobe < p_spec) {
        const MicrofacetDistribution d = coat_distribution(b);
        const Vec3f m = b.sample_visible ? d.sample_visible(wo, u) : d.sample_all(u);
        s.wi = reflect_about(wo, m);
        s.sampled_class = classify_alpha(b.alpha);
    } else {
        s.wi = warp::square_to_cosine_hemisphere(u);
        s.sampled_class = RoughnessClass::Diffuse;
    }
    if (!(cos_theta(s.wi) > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    // A mixture: the weight is the whole BSDF over the whole density (one-sample MIS).
    s.pdf_solid_angle = pdf_model(b, at, wo, s.wi);
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    s.weight = eval_model(b, at, wo, s.wi, mode) / s.pdf_solid_angle;
    return s;
}

BsdfLobes model_lobes(const RoughPlasticBsdf& b) {
    BsdfLobes l;
    l.sharpest_class = classify_alpha(b.alpha);
    // Microfacet lobes have a density whatever their alpha: glossy by kind; how delta-like
    // they are is the class's business (roughness_class.h).
    l.diffuse_reflection = l.glossy_reflection = true;
    return l;
}
RoughnessClass model_class(const RoughPlasticBsdf&) {
    return RoughnessClass::Diffuse;
}
RoughnessClass model_class_at(const RoughPlasticBsdf&, const TexturePoint&) {
    return RoughnessClass::Diffuse;
}

}  // namespace detail
}  // namespace gdmlt
