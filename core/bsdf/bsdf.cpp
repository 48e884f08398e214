// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/bsdf/bsdf.h"

#include <map>
#include <string>

#include "core/bsdf/bsdf_models.h"
#include "core/bsdf/fresnel.h"
#include "core/geometry/interaction.h"
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

Rgb eval_model(const DiffuseBsdf& m, const TexturePoint& at, const Vec3f& wo, const Vec3f& wi,
               TransportMode) {
    if (cos_theta(wo) <= 0.f || cos_theta(wi) <= 0.f) return Rgb::Zero();
    return m.reflectance.eval(at) * (kInvPi * cos_theta(wi));
}
float pdf_model(const DiffuseBsdf&, const TexturePoint&, const Vec3f& wo, const Vec3f& wi) {
    if (cos_theta(wo) <= 0.f || cos_theta(wi) <= 0.f) return 0.f;
    return warp::square_to_cosine_hemisphere_pdf_solid_angle(wi);
}
BsdfSample sample_model(const DiffuseBsdf& m, const TexturePoint& at, const Vec3f& wo, float,
                        const Vec2f& u, TransportMode) {
    BsdfSample s;
    if (cos_theta(wo) <= 0.f) return s;
    s.wi = warp::square_to_cosine_hemisphere(u);
    s.pdf_solid_angle = warp::square_to_cosine_hemisphere_pdf_solid_angle(s.wi);
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    s.weight = m.reflectance.eval(at);  // (R/pi * cos) / (cos/pi)
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
RoughnessClass model_class_at(const DiffuseBsdf&, const TexturePoint&) {
    return RoughnessClass::Diffuse;
}

BsdfSample sample_model(const DielectricBsdf& m, const TexturePoint& at, const Vec3f& wo,
                        float u_lobe, const Vec2f&, TransportMode mode) {
    BsdfSample s;
    const FresnelDielectric f = fresnel_dielectric(cos_theta(wo), m.eta);
    s.delta = true;
    s.sampled_class = RoughnessClass::Delta;
    // Choose reflection with probability F: the weight is then R or T without the Fresnel
    // factor (it cancels against the selection probability).
    if (u_lobe < f.reflectance) {
        s.wi = reflect_local(wo);
        s.pdf_solid_angle = f.reflectance;
        s.weight = m.specular_reflectance.eval(at);
        s.eta = 1.f;
    } else {
        s.wi = refract_local(wo, f.cos_theta_t, f.eta_ti);
        s.pdf_solid_angle = 1.f - f.reflectance;
        s.transmission = true;
        s.eta = f.eta_it;
        const float scale = mode == TransportMode::Radiance ? f.eta_ti * f.eta_ti : 1.f;
        s.weight = m.specular_transmittance.eval(at) * scale;
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

BsdfSample sample_model(const ThinDielectricBsdf& m, const TexturePoint& at, const Vec3f& wo,
                        float u_lobe, const Vec2f&, TransportMode) {
    BsdfSample s;
    s.delta = true;
    s.sampled_class = RoughnessClass::Delta;
    float r = fresnel_dielectric(std::abs(cos_theta(wo)), m.eta).reflectance;
    // Sum of the geometric series of internal reflections in the slab: R + T^2 R / (1 - R^2).
    if (r < 1.f) r += (1.f - r) * (1.f - r) * r / (1.f - r * r);
    if (u_lobe < r) {
        s.wi = reflect_local(wo);
        s.pdf_solid_angle = r;
        s.weight = m.specular_reflectance.eval(at);
    } else {
        s.wi = -wo;
        s.pdf_solid_angle = 1.f - r;
        s.transmission = true;
        s.weight = m.specular_transmittance.eval(at);
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

BsdfSample sample_model(const ConductorBsdf& m, const TexturePoint& at, const Vec3f& wo, float,
                        const Vec2f&, TransportMode) {
    BsdfSample s;
    if (cos_theta(wo) <= 0.f) return s;
    s.delta = true;
    s.sampled_class = RoughnessClass::Delta;
    s.wi = reflect_local(wo);
    s.pdf_solid_angle = 1.f;
    s.weight = m.specular_reflectance.eval(at);
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
#define GDMLT_DELTA_MODEL(M)                                                                   \
    Rgb eval_model(const M&, const TexturePoint&, const Vec3f&, const Vec3f&, TransportMode) { \
        return Rgb::Zero();                                                                    \
    }                                                                                          \
    float pdf_model(const M&, const TexturePoint&, const Vec3f&, const Vec3f&) {               \
        return 0.f;                                                                            \
    }                                                                                          \
    RoughnessClass model_class(const M&) {                                                     \
        return RoughnessClass::Delta;                                                          \
    }                                                                                          \
    RoughnessClass model_class_at(const M&, const TexturePoint&) {                             \
        return RoughnessClass::Delta;                                                          \
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

struct Bsdf::Composite {
    enum class Kind { Mask, Blend, NormalMap, BumpMap };
    Kind kind = Kind::Mask;
    /// Mask: the opacity (probability of the nested BSDF); blend: the second's probability.
    /// Clamped to [0, 1] where evaluated, as Mitsuba 3's mask and blendbsdf do.
    FloatTexture weight;
    Bsdf first;   // mask, normal map: the nested BSDF
    Bsdf second;  // blend only
    // Normal map: the normals; bump map: the height (its scalar value's gradient) and scale.
    RgbTexture normals;
    float bump_scale = 1.f;
    bool flip_invalid_normals = true;
    bool use_shadowing_function = true;

    float weight_at(const TexturePoint& at) const { return std::clamp(weight.eval(at), 0.f, 1.f); }
    bool mask() const { return kind == Kind::Mask; }
    /// The normal and bump maps: the nested BSDF in a perturbed frame.
    bool normal_map() const { return kind == Kind::NormalMap || kind == Kind::BumpMap; }

    /// The perturbed frame in local shading coordinates (Mitsuba 3.9's normalmap: tangent
    /// (1, 0, 0) projected), given the direction towards the camera side.
    Frame perturbed_frame(const TexturePoint& at, const Vec3f& w_camera) const {
        if (kind == Kind::BumpMap) return bumped_frame(at, w_camera);
        Vec3f n = (2.f * normals.eval(at) - 1.f).matrix();
        // Flip about the shading normal when the perturbed normal faces away from the side
        // the camera-side direction is on.
        if (flip_invalid_normals && cos_theta(w_camera) * w_camera.dot(n) <= 0.f)
            n = Vec3f(-n.x(), -n.y(), n.z());
        const float length = n.norm();
        n = length > 0.f && std::isfinite(length) ? Vec3f(n / length) : Vec3f::UnitZ();
        return Frame::from_normal_and_tangent(n, Vec3f::UnitX());
    }
    /// Mitsuba 3's bumpmap frame (src/bsdfs/bumpmap.cpp): dp/du and dp/dv with their
    /// components along the shading normal replaced by the scaled height's gradient, their
    /// cross product oriented with the geometric normal, flipped as the normal map's; the
    /// tangent is dp/du projected (Mitsuba projects it against the local normal in world
    /// components; the same for isotropic BSDFs, and this one is a frame of the surface).
    Frame bumped_frame(const TexturePoint& at, const Vec3f& w_camera) const {
        if (!at.surface) return Frame{};
        const SurfaceInteraction& si = *at.surface;
        // dp/du, dp/dv in texture uv (Mitsuba's si.dp_du): the surface's derivatives in its
        // own parameters times the inverse of d uv / d parameters.
        const float det = si.duv_du.x() * si.duv_dv.y() - si.duv_dv.x() * si.duv_du.y();
        if (!(det != 0.f) || !std::isfinite(det)) return Frame{};
        const Vec3f dp_du_tex = (si.duv_dv.y() * si.dp_du - si.duv_du.y() * si.dp_dv) / det;
        const Vec3f dp_dv_tex = (si.duv_du.x() * si.dp_dv - si.duv_dv.x() * si.dp_du) / det;
        const Vec2f grad = bump_scale * normals.gradient(at);
        const Vec3f& n_s = si.shading.n;
        const Vec3f dp_du = dp_du_tex + n_s * (grad.x() - n_s.dot(dp_du_tex));
        const Vec3f dp_dv = dp_dv_tex + n_s * (grad.y() - n_s.dot(dp_dv_tex));
        Vec3f n_world = dp_du.cross(dp_dv);
        const float length = n_world.norm();
        if (!(length > 0.f) || !std::isfinite(length)) return Frame{};
        n_world /= length;
        if (si.n_geometric.dot(n_world) < 0.f) n_world = -n_world;
        Vec3f n = si.shading.to_local(n_world);
        if (flip_invalid_normals && cos_theta(w_camera) * w_camera.dot(n) <= 0.f)
            n = Vec3f(-n.x(), -n.y(), n.z());
        const Vec3f tangent = si.shading.to_local(dp_du_tex);
        return Frame::from_normal_and_tangent(n, tangent);
    }
    /// Conty Estevez et al. 2019, "A microfacet-based shadowing function to solve the bump
    /// terminator problem" (Ray Tracing Gems, ch. 12): G1 of a GGX-like distribution whose
    /// alpha^2 is 1/8 of tan^2 of the perturbed normal, towards the light-side direction.
    float shadowing(const Vec3f& n_perturbed, const Vec3f& w_light) const {
        if (!use_shadowing_function) return 1.f;
        const auto tan2 = [](const Vec3f& w) {
            const float c2 = w.z() * w.z();
            return std::max(0.f, 1.f - c2) / c2;
        };
        const float alpha2 = std::min(0.125f * tan2(n_perturbed), 1.f);
        const float g = 2.f / (1.f + std::sqrt(1.f + alpha2 * tan2(w_light)));
        return std::isfinite(g) ? g : 0.f;
    }
};

Bsdf Bsdf::mask(FloatTexture opacity, Bsdf nested) {
    Composite c;
    c.kind = Composite::Kind::Mask;
    c.weight = std::move(opacity);
    c.first = std::move(nested);
    Bsdf b;
    b.composite_ = std::make_shared<const Composite>(std::move(c));
    return b;
}

Bsdf Bsdf::null() {
    return mask(FloatTexture(0.f), Bsdf{});
}

Bsdf Bsdf::normal_map(RgbTexture normals, Bsdf nested, bool flip_invalid_normals,
                      bool use_shadowing_function) {
    return perturbed(false, std::move(normals), 1.f, std::move(nested), flip_invalid_normals,
                     use_shadowing_function);
}

Bsdf Bsdf::bump_map(RgbTexture height, float scale, Bsdf nested, bool flip_invalid_normals,
                    bool use_shadowing_function) {
    return perturbed(true, std::move(height), scale, std::move(nested), flip_invalid_normals,
                     use_shadowing_function);
}

Bsdf Bsdf::perturbed(bool bump, RgbTexture texture, float scale, Bsdf nested,
                     bool flip_invalid_normals, bool use_shadowing_function) {
    Composite c;
    c.kind = bump ? Composite::Kind::BumpMap : Composite::Kind::NormalMap;
    c.first = std::move(nested);
    c.normals = std::move(texture);
    c.bump_scale = scale;
    c.flip_invalid_normals = flip_invalid_normals;
    c.use_shadowing_function = use_shadowing_function;
    Bsdf b;
    b.composite_ = std::make_shared<const Composite>(std::move(c));
    return b;
}

namespace {

/// The factor that turns the nested BSDF's adjoint in the perturbed frame into the adjoint of
/// the normal-mapped BSDF in the shading frame: with the camera-side direction w_c and the
/// light-side w_l, eval_radiance(w_c, w_l) = f_p(w_c, w_l) |cos_p w_l| S(w_l), the true BSDF is
/// that over |cos w_l|, and its adjoint times |cos w_c| is f_p(w_c, w_l) |cos_p w_l|
/// |cos w_c| S(w_l) / |cos w_l|; the nested Importance eval gives f_p(w_c, w_l) |cos_p w_c|.
float normal_map_adjoint_factor(const Vec3f& w_light, const Vec3f& w_light_perturbed,
                                const Vec3f& w_camera, const Vec3f& w_camera_perturbed) {
    const float denominator = abs_cos_theta(w_camera_perturbed) * abs_cos_theta(w_light);
    const float f = abs_cos_theta(w_light_perturbed) * abs_cos_theta(w_camera) / denominator;
    return denominator > 0.f && std::isfinite(f) ? f : 0.f;
}

}  // namespace

// Sampling draws in the frame of the direction it starts from (wo), so that pdf(wo, wi), which
// knows no transport mode, is the density of either mode's sample. eval uses the frame of the
// camera-side direction, which decides the flip (wo in Radiance mode, wi in Importance mode):
// where the two frames differ (a flip seen from one side only, at grazing angles on steep
// normals) an Importance sample is weighed by eval / pdf, and a delta one is dropped.
BsdfSample Bsdf::sample_normal_mapped(const TexturePoint& at, const Vec3f& wo, float u_lobe,
                                      const Vec2f& u, TransportMode mode) const {
    const Composite& c = *composite_;
    const Frame frame = c.perturbed_frame(at, wo);
    BsdfSample s = c.first.sample(at, frame.to_local(wo), u_lobe, u, mode);
    if (!s.valid()) return s;
    const Vec3f wi_perturbed = s.wi;
    s.wi = frame.to_world(wi_perturbed);
    if (cos_theta(s.wi) * cos_theta(wi_perturbed) <= 0.f) {
        s = BsdfSample{};
        return s;
    }
    if (mode == TransportMode::Radiance) {
        s.weight *= c.shadowing(frame.n, s.wi);
        return s;
    }
    if (s.delta) {
        const Frame camera_frame = c.perturbed_frame(at, s.wi);
        const Vec3f wo_perturbed = frame.to_local(wo);
        if (camera_frame.n != frame.n || cos_theta(wo) * cos_theta(wo_perturbed) <= 0.f) {
            s = BsdfSample{};
            return s;
        }
        s.weight *= normal_map_adjoint_factor(wo, wo_perturbed, s.wi, wi_perturbed) *
                    c.shadowing(frame.n, wo);
        return s;
    }
    s.pdf_solid_angle = pdf(at, wo, s.wi);
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    s.weight = eval(at, wo, s.wi, mode) / s.pdf_solid_angle;
    return s;
}

Bsdf Bsdf::blend(FloatTexture weight, Bsdf first, Bsdf second) {
    Composite c;
    c.kind = Composite::Kind::Blend;
    c.weight = std::move(weight);
    c.first = std::move(first);
    c.second = std::move(second);
    Bsdf b;
    b.composite_ = std::make_shared<const Composite>(std::move(c));
    return b;
}

BsdfSample Bsdf::sample_composite(const TexturePoint& at, const Vec3f& wo, float u_lobe,
                                  const Vec2f& u, TransportMode mode) const {
    const Composite& c = *composite_;
    if (c.normal_map()) return sample_normal_mapped(at, wo, u_lobe, u, mode);
    const float w = c.weight_at(at);
    BsdfSample s;
    if (c.mask()) {
        if (u_lobe >= w) {
            // The null lobe: straight through, no change of medium, the selection probability
            // 1 - opacity as the delta lobe's probability (weight (1 - opacity) / (1 - opacity)).
            s.wi = -wo;
            s.pdf_solid_angle = 1.f - w;
            s.weight = Rgb::Ones();
            s.delta = true;
            s.transmission = true;
            s.sampled_class = RoughnessClass::Delta;
            return s;
        }
        // The random number is reused for the nested BSDF's own lobe choice (Mitsuba 3 does the
        // same), rescaled to [0, 1).
        s = c.first.sample(at, wo, u_lobe / w, u, mode);
        // f and pdf both carry the opacity: the weight f / pdf is the nested one.
        s.pdf_solid_angle *= w;
        if (!s.valid()) s = BsdfSample{};
        return s;
    }
    // Blend: u_lobe < w picks the second component (Mitsuba 3's blendbsdf convention).
    const bool second = u_lobe < w;
    const float probability = second ? w : 1.f - w;
    const float u_rescaled = second ? u_lobe / w : (u_lobe - w) / (1.f - w);
    s = (second ? c.second : c.first).sample(at, wo, std::min(u_rescaled, 0x1.fffffep-1f), u, mode);
    if (!s.valid()) return s;
    if (s.delta) {
        s.pdf_solid_angle *= probability;
        return s;
    }
    // The density of the direction is the mixture's whichever component drew it.
    s.pdf_solid_angle = pdf(at, wo, s.wi);
    const Rgb f = eval(at, wo, s.wi, mode);
    if (!(s.pdf_solid_angle > 0.f)) {
        s = BsdfSample{};
        return s;
    }
    s.weight = f / s.pdf_solid_angle;
    return s;
}

const BsdfModel& Bsdf::model_for(const Vec3f& wo, Vec3f* wo_query, bool* flipped) const {
    *flipped = two_sided_ && cos_theta(wo) < 0.f;
    *wo_query = *flipped ? flip_z(wo) : wo;
    if (*flipped && back_) return *back_;
    return front_;
}

Rgb Bsdf::eval(const TexturePoint& at, const Vec3f& wo, const Vec3f& wi, TransportMode mode) const {
    if (composite_) {
        const Composite& c = *composite_;
        if (c.normal_map()) {
            const bool radiance = mode == TransportMode::Radiance;
            const Vec3f& w_camera = radiance ? wo : wi;
            const Vec3f& w_light = radiance ? wi : wo;
            const Frame frame = c.perturbed_frame(at, w_camera);
            const Vec3f wo_p = frame.to_local(wo), wi_p = frame.to_local(wi);
            const Vec3f& w_light_p = radiance ? wi_p : wo_p;
            if (cos_theta(w_light) * cos_theta(w_light_p) <= 0.f) return Rgb::Zero();
            Rgb f = c.first.eval(at, wo_p, wi_p, mode) * c.shadowing(frame.n, w_light);
            if (!radiance) f *= normal_map_adjoint_factor(wo, wo_p, wi, wi_p);
            return f;
        }
        const float w = c.weight_at(at);
        if (c.mask()) return w > 0.f ? Rgb(w * c.first.eval(at, wo, wi, mode)) : Rgb::Zero();
        Rgb f = Rgb::Zero();
        if (w < 1.f) f += (1.f - w) * c.first.eval(at, wo, wi, mode);
        if (w > 0.f) f += w * c.second.eval(at, wo, wi, mode);
        return f;
    }
    Vec3f wo_q;
    bool flipped;
    const BsdfModel& m = model_for(wo, &wo_q, &flipped);
    const Vec3f wi_q = flipped ? flip_z(wi) : wi;
    const Rgb f = std::visit(
        [&](const auto& model) { return detail::eval_model(model, at, wo_q, wi_q, mode); }, m);
    return is_finite(f) ? f : Rgb::Zero();
}

float Bsdf::pdf(const TexturePoint& at, const Vec3f& wo, const Vec3f& wi) const {
    if (composite_) {
        const Composite& c = *composite_;
        if (c.normal_map()) {
            const Frame frame = c.perturbed_frame(at, wo);
            const Vec3f wi_p = frame.to_local(wi);
            if (cos_theta(wi) * cos_theta(wi_p) <= 0.f) return 0.f;
            return c.first.pdf(at, frame.to_local(wo), wi_p);
        }
        const float w = c.weight_at(at);
        if (c.mask()) return w > 0.f ? w * c.first.pdf(at, wo, wi) : 0.f;
        float p = 0.f;
        if (w < 1.f) p += (1.f - w) * c.first.pdf(at, wo, wi);
        if (w > 0.f) p += w * c.second.pdf(at, wo, wi);
        return p;
    }
    Vec3f wo_q;
    bool flipped;
    const BsdfModel& m = model_for(wo, &wo_q, &flipped);
    const Vec3f wi_q = flipped ? flip_z(wi) : wi;
    const float p =
        std::visit([&](const auto& model) { return detail::pdf_model(model, at, wo_q, wi_q); }, m);
    return std::isfinite(p) ? p : 0.f;
}

BsdfSample Bsdf::sample(const TexturePoint& at, const Vec3f& wo, float u_lobe, const Vec2f& u,
                        TransportMode mode) const {
    if (composite_) return sample_composite(at, wo, u_lobe, u, mode);
    Vec3f wo_q;
    bool flipped;
    const BsdfModel& m = model_for(wo, &wo_q, &flipped);
    BsdfSample s = std::visit(
        [&](const auto& model) { return detail::sample_model(model, at, wo_q, u_lobe, u, mode); },
        m);
    if (flipped) s.wi = flip_z(s.wi);
    if (!s.valid() || !std::isfinite(s.pdf_solid_angle) || !is_finite(s.weight) ||
        !s.wi.allFinite())
        s = BsdfSample{};
    return s;
}

bool Bsdf::is_delta() const {
    if (composite_) {
        const Composite& c = *composite_;
        if (c.normal_map()) return c.first.is_delta();
        if (c.mask()) return c.weight.max_value() <= 0.f || c.first.is_delta();
        return c.first.is_delta() && c.second.is_delta();
    }
    return model_is_delta(front_) && (!back_ || model_is_delta(*back_));
}
bool Bsdf::has_transmission() const {
    if (composite_ && composite_->normal_map()) return composite_->first.has_transmission();
    if (composite_)
        return composite_->mask() || composite_->first.has_transmission() ||
               composite_->second.has_transmission();
    return model_transmits(front_) || (back_ && model_transmits(*back_));
}
RoughnessClass Bsdf::roughness_class() const {
    if (composite_) {
        const Composite& c = *composite_;
        if (c.normal_map()) return c.first.roughness_class();
        if (c.mask())
            return c.weight.max_value() <= 0.f ? RoughnessClass::Delta : c.first.roughness_class();
        if (c.weight.max_value() <= 0.f) return c.first.roughness_class();
        if (c.weight.min_value() >= 1.f) return c.second.roughness_class();
        return std::min(c.first.roughness_class(), c.second.roughness_class());
    }
    const auto cls = [](const BsdfModel& m) {
        return std::visit([](const auto& model) { return detail::model_class(model); }, m);
    };
    RoughnessClass c = cls(front_);
    if (back_) c = std::min(c, cls(*back_));  // enum order: most connectable first
    return c;
}
RoughnessClass Bsdf::roughness_class_at(const TexturePoint& at) const {
    if (composite_) {
        const Composite& c = *composite_;
        if (c.normal_map()) return c.first.roughness_class_at(at);
        const float w = c.weight_at(at);
        if (c.mask()) return w <= 0.f ? RoughnessClass::Delta : c.first.roughness_class_at(at);
        if (w <= 0.f) return c.first.roughness_class_at(at);
        if (w >= 1.f) return c.second.roughness_class_at(at);
        return std::min(c.first.roughness_class_at(at), c.second.roughness_class_at(at));
    }
    const auto cls = [&](const BsdfModel& m) {
        return std::visit([&](const auto& model) { return detail::model_class_at(model, at); }, m);
    };
    RoughnessClass c = cls(front_);
    if (back_) c = std::min(c, cls(*back_));
    return c;
}
BsdfLobes Bsdf::lobes() const {
    if (composite_) {
        const Composite& c = *composite_;
        if (c.normal_map()) return c.first.lobes();
        if (c.mask()) {
            BsdfLobes l = c.weight.max_value() > 0.f ? c.first.lobes() : BsdfLobes{};
            BsdfLobes null_lobe;
            null_lobe.delta_transmission = true;
            null_lobe.sharpest_class = RoughnessClass::Delta;
            l |= null_lobe;
            return l;
        }
        BsdfLobes l = c.first.lobes();
        l |= c.second.lobes();
        return l;
    }
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

namespace {

const std::map<std::string, ConductorIor>& conductor_table() {
    // Mitsuba 3's named conductors (its `material` list: measured spectral complex IORs, most
    // from Palik's handbook), as its RGB variants reduce them to RGB (Mitsuba 3.9.1, read from
    // the conductor plugin's eta and k after loading). Where Mitsuba clamps an out-of-gamut
    // reduction (AlSb's eta, several k of transparent crystals), its clamped value is kept.
    static const std::map<std::string, ConductorIor> table = {
        {"a-C", {Rgb(2.94405f, 2.22714f, 1.96816f), Rgb(0.887465f, 0.799299f, 0.81529f)}},
        {"Ag", {Rgb(0.155276f, 0.116728f, 0.138388f), Rgb(4.82835f, 3.12222f, 2.1469f)}},
        {"Al", {Rgb(1.6575f, 0.880405f, 0.521244f), Rgb(9.22381f, 6.2695f, 4.837f)}},
        {"AlAs", {Rgb(3.6053f, 3.23294f, 2.21632f), Rgb(0.000679437f, 0.f, 0.00751271f)}},
        {"AlAs_palik", {Rgb(3.6053f, 3.23294f, 2.21632f), Rgb(0.000679437f, 0.f, 0.00751271f)}},
        {"AlSb", {Rgb(0.f, 4.13937f, 4.66925f), Rgb(0.f, 0.0940091f, 1.30057f)}},
        {"AlSb_palik", {Rgb(0.f, 4.13937f, 4.66925f), Rgb(0.f, 0.0940091f, 1.30057f)}},
        {"Au", {Rgb(0.143036f, 0.375307f, 1.44205f), Rgb(3.983f, 2.38556f, 1.60336f)}},
        {"Be", {Rgb(4.18501f, 3.18503f, 2.78406f), Rgb(3.83547f, 3.01012f, 2.86899f)}},
        {"Be_palik", {Rgb(4.18501f, 3.18503f, 2.78406f), Rgb(3.83547f, 3.01012f, 2.86899f)}},
        {"Cr", {Rgb(4.36967f, 2.91651f, 1.6549f), Rgb(5.20655f, 4.23131f, 3.7547f)}},
        {"CsI", {Rgb(2.1449f, 1.70232f, 1.66243f), Rgb(0.f, 0.f, 0.f)}},
        {"CsI_palik", {Rgb(2.1449f, 1.70232f, 1.66243f), Rgb(0.f, 0.f, 0.f)}},
        {"Cu", {Rgb(0.201005f, 0.92375f, 1.10222f), Rgb(3.91326f, 2.45305f, 2.14209f)}},
        {"Cu2O", {Rgb(3.55177f, 2.94987f, 2.75188f), Rgb(0.114207f, 0.193897f, 0.606134f)}},
        {"Cu2O_palik", {Rgb(3.55177f, 2.94987f, 2.75188f), Rgb(0.114207f, 0.193897f, 0.606134f)}},
        {"Cu_palik", {Rgb(0.213229f, 0.919715f, 1.10241f), Rgb(3.92187f, 2.45733f, 2.13658f)}},
        {"CuO", {Rgb(3.24754f, 2.44781f, 2.21022f), Rgb(0.52109f, 0.570031f, 0.722179f)}},
        {"CuO_palik", {Rgb(3.24754f, 2.44781f, 2.21022f), Rgb(0.52109f, 0.570031f, 0.722179f)}},
        {"d-C", {Rgb(2.70872f, 2.31883f, 2.2289f), Rgb(0.f, 0.f, 0.f)}},
        {"d-C_palik", {Rgb(2.70872f, 2.31883f, 2.2289f), Rgb(0.f, 0.f, 0.f)}},
        {"Hg", {Rgb(2.39894f, 1.44003f, 0.90957f), Rgb(6.32759f, 4.37192f, 3.42176f)}},
        {"Hg_palik", {Rgb(2.39894f, 1.44003f, 0.90957f), Rgb(6.32759f, 4.37192f, 3.42176f)}},
        {"HgTe", {Rgb(4.77904f, 3.2312f, 2.6599f), Rgb(1.63161f, 1.58081f, 1.72929f)}},
        {"HgTe_palik", {Rgb(4.77904f, 3.2312f, 2.6599f), Rgb(1.63161f, 1.58081f, 1.72929f)}},
        {"Ir", {Rgb(3.0863f, 2.08219f, 1.61791f), Rgb(5.59215f, 4.06709f, 3.26731f)}},
        {"Ir_palik", {Rgb(3.0863f, 2.08219f, 1.61791f), Rgb(5.59215f, 4.06709f, 3.26731f)}},
        {"K", {Rgb(0.0640432f, 0.0464098f, 0.0381849f), Rgb(2.1042f, 1.34894f, 0.913126f)}},
        {"K_palik", {Rgb(0.0640432f, 0.0464098f, 0.0381849f), Rgb(2.1042f, 1.34894f, 0.913126f)}},
        {"Li", {Rgb(0.265791f, 0.195618f, 0.220949f), Rgb(3.54015f, 2.31112f, 1.66861f)}},
        {"Li_palik", {Rgb(0.265791f, 0.195618f, 0.220949f), Rgb(3.54015f, 2.31112f, 1.66861f)}},
        {"MgO", {Rgb(2.08958f, 1.65072f, 1.59488f), Rgb(4.3327e-12f, 0.f, 2.49865e-11f)}},
        {"MgO_palik", {Rgb(2.08958f, 1.65072f, 1.59488f), Rgb(4.3327e-12f, 0.f, 2.49865e-11f)}},
        {"Mo", {Rgb(4.48397f, 3.52513f, 2.77631f), Rgb(4.11144f, 3.42083f, 3.15061f)}},
        {"Mo_palik", {Rgb(4.48397f, 3.52513f, 2.77631f), Rgb(4.11144f, 3.42083f, 3.15061f)}},
        {"Na_palik", {Rgb(0.0602694f, 0.0561409f, 0.0619884f), Rgb(3.17927f, 2.11249f, 1.57904f)}},
        {"Nb", {Rgb(3.42007f, 2.79009f, 2.39563f), Rgb(3.44139f, 2.73767f, 2.57975f)}},
        {"Nb_palik", {Rgb(3.42007f, 2.79009f, 2.39563f), Rgb(3.44139f, 2.73767f, 2.57975f)}},
        {"Ni_palik", {Rgb(2.3673f, 1.66337f, 1.46708f), Rgb(4.49881f, 3.05015f, 2.34544f)}},
        {"Rh", {Rgb(2.58579f, 1.86022f, 1.55426f), Rgb(6.78226f, 4.70299f, 3.97607f)}},
        {"Rh_palik", {Rgb(2.58579f, 1.86022f, 1.55426f), Rgb(6.78226f, 4.70299f, 3.97607f)}},
        {"Se", {Rgb(4.05831f, 2.84294f, 2.82085f), Rgb(0.75405f, 0.638444f, 0.521808f)}},
        {"Se-e", {Rgb(5.72285f, 4.16574f, 4.08134f), Rgb(0.871136f, 1.10516f, 1.56532f)}},
        {"Se-e_palik", {Rgb(5.72285f, 4.16574f, 4.08134f), Rgb(0.871136f, 1.10516f, 1.56532f)}},
        {"Se_palik", {Rgb(4.05831f, 2.84294f, 2.82085f), Rgb(0.75405f, 0.638444f, 0.521808f)}},
        {"SiC", {Rgb(3.17234f, 2.52597f, 2.47937f), Rgb(7.53766e-07f, 0.f, 1.01925e-05f)}},
        {"SiC_palik", {Rgb(3.17234f, 2.52597f, 2.47937f), Rgb(7.53766e-07f, 0.f, 1.01925e-05f)}},
        {"SnTe", {Rgb(4.52425f, 1.98164f, 1.28159f), Rgb(0.f, 0.f, 0.f)}},
        {"SnTe_palik", {Rgb(4.52425f, 1.98164f, 1.28159f), Rgb(0.f, 0.f, 0.f)}},
        {"Ta", {Rgb(2.06272f, 2.39294f, 2.62793f), Rgb(2.40836f, 1.74149f, 1.94703f)}},
        {"Ta_palik", {Rgb(2.06272f, 2.39294f, 2.62793f), Rgb(2.40836f, 1.74149f, 1.94703f)}},
        {"Te", {Rgb(7.39023f, 4.4821f, 2.63711f), Rgb(3.25602f, 3.52706f, 3.29205f)}},
        {"Te-e", {Rgb(7.50891f, 4.29643f, 2.36999f), Rgb(5.58393f, 4.94721f, 3.99759f)}},
        {"Te-e_palik", {Rgb(7.50891f, 4.29643f, 2.36999f), Rgb(5.58393f, 4.94721f, 3.99759f)}},
        {"Te_palik", {Rgb(7.39023f, 4.4821f, 2.63711f), Rgb(3.25602f, 3.52706f, 3.29205f)}},
        {"ThF4", {Rgb(1.83071f, 1.44223f, 1.38765f), Rgb(0.f, 0.f, 0.f)}},
        {"ThF4_palik", {Rgb(1.83071f, 1.44223f, 1.38765f), Rgb(0.f, 0.f, 0.f)}},
        {"TiC", {Rgb(3.70053f, 2.83742f, 2.58229f), Rgb(3.26564f, 2.35159f, 2.17279f)}},
        {"TiC_palik", {Rgb(3.70053f, 2.83742f, 2.58229f), Rgb(3.26564f, 2.35159f, 2.17279f)}},
        {"TiN", {Rgb(1.64845f, 1.15052f, 1.37982f), Rgb(3.36833f, 1.9435f, 1.10207f)}},
        {"TiN_palik", {Rgb(1.64845f, 1.15052f, 1.37982f), Rgb(3.36833f, 1.9435f, 1.10207f)}},
        {"TiO2", {Rgb(3.45661f, 2.80174f, 2.90517f), Rgb(0.000105265f, 0.f, 0.000652887f)}},
        {"TiO2-e", {Rgb(3.10656f, 2.51317f, 2.58244f), Rgb(2.97516e-05f, 0.f, 0.000182698f)}},
        {"TiO2-e_palik", {Rgb(3.10656f, 2.51317f, 2.58244f), Rgb(2.97516e-05f, 0.f, 0.000182698f)}},
        {"TiO2_palik", {Rgb(3.45661f, 2.80174f, 2.90517f), Rgb(0.000105265f, 0.f, 0.000652887f)}},
        {"V_palik", {Rgb(4.27758f, 3.51295f, 2.76107f), Rgb(3.4913f, 2.88945f, 3.11152f)}},
        {"VC", {Rgb(3.65757f, 2.75274f, 2.53267f), Rgb(3.0683f, 2.19869f, 1.96319f)}},
        {"VC_palik", {Rgb(3.65757f, 2.75274f, 2.53267f), Rgb(3.0683f, 2.19869f, 1.96319f)}},
        {"VN", {Rgb(2.8656f, 2.11919f, 1.94009f), Rgb(3.03224f, 2.05612f, 1.61631f)}},
        {"VN_palik", {Rgb(2.8656f, 2.11919f, 1.94009f), Rgb(3.03224f, 2.05612f, 1.61631f)}},
        {"W", {Rgb(4.37082f, 3.30025f, 2.99841f), Rgb(3.50064f, 2.60487f, 2.27323f)}},
    };
    return table;
}

}  // namespace

std::optional<ConductorIor> lookup_conductor(const std::string& name) {
    const auto& table = conductor_table();
    const auto it = table.find(name);
    if (it == table.end()) return std::nullopt;
    return it->second;
}

std::string conductor_names() {
    std::string names;
    for (const auto& [name, ior] : conductor_table()) names += (names.empty() ? "" : ", ") + name;
    return names;
}

}  // namespace gdmlt
