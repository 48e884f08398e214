// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// BSDFs as a closed set of value types (std::variant), evaluated in the local shading frame
// (normal = +z).
//
// Conventions (pbrt-style names, Mitsuba-style values):
//  - `wo` points towards the previous vertex (camera side), `wi` towards the next (light side);
//    both unit, local frame.
//  - eval() returns f(wo, wi) * |cos theta_i|, the integrand in solid angle, so that a sample's
//    weight is eval / pdf_solid_angle. Delta lobes return 0 from eval() and pdf().
//  - TransportMode::Radiance for camera paths: refraction scales by 1/eta^2 (Veach 1997, 5.2).
#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <variant>

#include "core/bsdf/microfacet.h"
#include "core/bsdf/roughness_class.h"
#include "core/math/types.h"
#include "core/texture/texture.h"

namespace gdmlt {

enum class TransportMode { Radiance, Importance };

/// A sampled direction. Functions returning one keep a single named return object (an invalid
/// sample is `s = BsdfSample{}; return s;`, not `return BsdfSample{};`) so that it is built in
/// the caller's storage (NRVO); a second return object costs a copy per call, and the path
/// tracer samples a BSDF at every vertex.
struct BsdfSample {
    Vec3f wi = Vec3f::UnitZ();
    Rgb weight = Rgb::Zero();  // eval / pdf, or the delta lobe's weight
    float pdf_solid_angle = 0.f;
    float eta = 1.f;  // relative index eta_t / eta_i crossed by this sample (1 for reflection)
    bool delta = false;
    bool transmission = false;
    /// Class of the lobe that produced this sample (plastic: Delta for the coat's mirror
    /// reflection, Diffuse for the base), so that shifts can decide per vertex.
    RoughnessClass sampled_class = RoughnessClass::Diffuse;
    bool valid() const { return pdf_solid_angle > 0.f; }
};

/// Which kinds of lobes a BSDF has (a plastic has a diffuse and a delta or glossy lobe).
struct BsdfLobes {
    bool diffuse_reflection = false;
    bool glossy_reflection = false;
    bool glossy_transmission = false;
    bool delta_reflection = false;
    bool delta_transmission = false;
    /// The least connectable class among the lobes (a plastic's mirror coat: Delta; a rough
    /// lobe: its alpha's class), for deciding whether specular chains can occur.
    RoughnessClass sharpest_class = RoughnessClass::Diffuse;
    BsdfLobes& operator|=(const BsdfLobes& o) {
        sharpest_class = std::max(sharpest_class, o.sharpest_class);
        diffuse_reflection |= o.diffuse_reflection;
        glossy_reflection |= o.glossy_reflection;
        glossy_transmission |= o.glossy_transmission;
        delta_reflection |= o.delta_reflection;
        delta_transmission |= o.delta_transmission;
        return *this;
    }
};

struct DiffuseBsdf {
    RgbTexture reflectance{Rgb::Constant(0.5f)};
};

/// Smooth dielectric interface; eta = int_ior / ext_ior.
struct DielectricBsdf {
    float eta = 1.5046f / 1.000277f;
    RgbTexture specular_reflectance{Rgb::Ones()};
    RgbTexture specular_transmittance{Rgb::Ones()};
};

/// Thin slab (both interfaces parallel): reflection includes internal bounces, transmission
/// passes straight through.
struct ThinDielectricBsdf {
    float eta = 1.5046f / 1.000277f;
    RgbTexture specular_reflectance{Rgb::Ones()};
    RgbTexture specular_transmittance{Rgb::Ones()};
};

/// Smooth conductor with complex index eta + i k (per RGB channel). `perfect_mirror` (Mitsuba's
/// material "none") skips the Fresnel term.
struct ConductorBsdf {
    Rgb eta = Rgb::Zero();
    Rgb k = Rgb::Ones();
    bool perfect_mirror = true;
    RgbTexture specular_reflectance{Rgb::Ones()};
};

/// Microfacet roughness: distribution type and (possibly textured, possibly anisotropic)
/// alphas; `sample_visible` chooses visible-normal sampling (the default, as in Mitsuba).
struct MicrofacetRoughness {
    MicrofacetType type = MicrofacetType::Beckmann;
    FloatTexture alpha_u{0.1f};
    FloatTexture alpha_v{0.1f};
    bool sample_visible = true;

    MicrofacetDistribution at(const TexturePoint& at) const {
        return {type, alpha_u.eval(at), alpha_v.eval(at)};
    }
    /// The class of the sharpest place and direction: a lobe narrow along one axis cannot be
    /// reconnected to, whatever its width along the other.
    RoughnessClass roughness_class() const {
        return classify_alpha(std::min(alpha_u.min_value(), alpha_v.min_value()));
    }
    RoughnessClass roughness_class_at(const TexturePoint& at) const {
        return classify_alpha(std::min(alpha_u.eval(at), alpha_v.eval(at)));
    }
};

/// Rough conductor (Walter et al. 2007 microfacet reflection, conductor Fresnel; Mitsuba's
/// `roughconductor`). Front side only.
struct RoughConductorBsdf {
    MicrofacetRoughness roughness;
    Rgb eta = Rgb::Zero();
    Rgb k = Rgb::Ones();
    bool perfect_mirror = true;
    RgbTexture specular_reflectance{Rgb::Ones()};
};

/// Rough dielectric interface (Walter et al. 2007, reflection and refraction; Mitsuba's
/// `roughdielectric`); eta = int_ior / ext_ior. Both sides.
struct RoughDielectricBsdf {
    MicrofacetRoughness roughness;
    float eta = 1.5046f / 1.000277f;
    RgbTexture specular_reflectance{Rgb::Ones()};
    RgbTexture specular_transmittance{Rgb::Ones()};
};

/// Mitsuba's `plastic`: a smooth dielectric coat over a diffuse base, with the internal
/// scattering between them in closed form (Weidlich & Wilkie 2007 style layering: the base's
/// albedo is divided by 1 - F_dr, the diffuse Fresnel reflectance of the inside of the coat).
/// Build with make_plastic(), which fills the derived members.
struct PlasticBsdf {
    float eta = 1.49f / 1.000277f;
    RgbTexture diffuse_reflectance{Rgb::Constant(0.5f)};
    RgbTexture specular_reflectance{Rgb::Ones()};
    bool nonlinear = false;
    // Derived:
    float fdr_internal = 0.f;               // diffuse Fresnel reflectance seen from inside
    float specular_sampling_weight = 0.5f;  // s_mean / (s_mean + d_mean), as Mitsuba
};
PlasticBsdf make_plastic(float eta, RgbTexture diffuse_reflectance, RgbTexture specular_reflectance,
                         bool nonlinear);

/// Per-angle energy of a rough dielectric coat (roughplastic's precomputation).
struct RoughCoatTable {
    static constexpr int kResolution = 64;  // over cos(theta) in [0, 1], as Mitsuba 3
    float external_transmittance[kResolution] = {};
    float internal_reflectance = 0.f;
    float transmittance(float cos_theta) const;
};

/// Mitsuba's `roughplastic`: a rough dielectric coat (isotropic microfacet reflection) over a
/// diffuse base; the coat's angular transmittance and internal reflectance are precomputed
/// by quadrature over the visible normals. Build with make_rough_plastic().
struct RoughPlasticBsdf {
    MicrofacetType type = MicrofacetType::Beckmann;
    float alpha = 0.1f;
    bool sample_visible = true;
    float eta = 1.49f / 1.000277f;
    RgbTexture diffuse_reflectance{Rgb::Constant(0.5f)};
    RgbTexture specular_reflectance{Rgb::Ones()};
    bool nonlinear = false;
    // Derived:
    std::shared_ptr<const RoughCoatTable> table;
    float specular_sampling_weight = 0.5f;
};
RoughPlasticBsdf make_rough_plastic(MicrofacetType type, float alpha, bool sample_visible,
                                    float eta, RgbTexture diffuse_reflectance,
                                    RgbTexture specular_reflectance, bool nonlinear);

/// Diffuse Fresnel reflectance 2 int_0^1 F(mu, eta) mu dmu of a smooth interface with relative
/// index eta (eta < 1: seen from the denser side, including total internal reflection).
float fresnel_diffuse_reflectance(float eta);

using BsdfModel =
    std::variant<DiffuseBsdf, DielectricBsdf, ThinDielectricBsdf, ConductorBsdf, RoughConductorBsdf,
                 RoughDielectricBsdf, PlasticBsdf, RoughPlasticBsdf>;

/// A surface's scattering: one model on the front (normal side); `two_sided` mirrors the
/// directions of back-side queries onto the front and uses `back` (or the front model when
/// `back` is empty), as Mitsuba's `twosided` does. One-sided non-transmissive models are black
/// from behind.
///
/// A Bsdf can also be a stochastic mixture of other Bsdfs (is_composite()):
///  - Mitsuba's `mask`: with probability 1 - opacity(at) the ray passes straight through (a
///    null lobe: delta transmission, wi = -wo, eta 1, weight 1), otherwise the nested BSDF
///    scatters; f = opacity f_nested. `null` is a mask of opacity 0.
///  - Mitsuba's `blendbsdf`: f = (1 - w(at)) f_first + w(at) f_second, sampled by choosing a
///    component with those probabilities; a non-delta sample is weighed by the mixture's
///    f / pdf (one-sample MIS over the components, Veach 1997 sec. 9.2.4), a delta one by its
///    component's weight, its pdf being the lobe probability times the selection probability.
///  - Mitsuba 3's `normalmap`: the nested BSDF in a frame whose normal is 2 rgb(at) - 1 in the
///    local shading frame, flipped about the normal towards the camera side when it faces away
///    from it (`flip_invalid_normals`, Schuessler et al. 2017), attenuated by the microfacet
///    terminator term of Conty Estevez et al. 2019 (`use_shadowing_function`), both on by
///    default as in Mitsuba 3.9. In Importance mode it is the adjoint of that BSDF (Veach 1997,
///    sec. 3.7.6), so that light tracing and BDPT converge to the path tracer's image.
///  - Mitsuba 3's `bumpmap`: as the normal map, with the normal of the surface displaced along
///    its shading normal by scale times the texture (Blinn 1978): dp/du and dp/dv get the
///    height's gradient as their normal components, n = dp/du x dp/dv oriented with the
///    geometric normal. It reads the surface's differential geometry (TexturePoint::surface);
///    a lookup without it sees the surface unperturbed.
/// front(), back() and is_two_sided() describe a leaf only; callers that look inside the model
/// (the path tracer's lanes, the manifold walk) treat composites as opaque.
class Bsdf {
  public:
    Bsdf() = default;
    explicit Bsdf(BsdfModel front) : front_(std::move(front)) {}
    static Bsdf two_sided(BsdfModel front, std::optional<BsdfModel> back);
    static Bsdf mask(FloatTexture opacity, Bsdf nested);
    static Bsdf null();
    static Bsdf blend(FloatTexture weight, Bsdf first, Bsdf second);
    static Bsdf normal_map(RgbTexture normals, Bsdf nested, bool flip_invalid_normals = true,
                           bool use_shadowing_function = true);
    static Bsdf bump_map(RgbTexture height, float scale, Bsdf nested,
                         bool flip_invalid_normals = true, bool use_shadowing_function = true);
    bool is_composite() const { return composite_ != nullptr; }

    Rgb eval(const TexturePoint& at, const Vec3f& wo, const Vec3f& wi,
             TransportMode mode = TransportMode::Radiance) const;
    float pdf(const TexturePoint& at, const Vec3f& wo, const Vec3f& wi) const;
    /// `u_lobe` chooses among lobes, `u` the direction.
    BsdfSample sample(const TexturePoint& at, const Vec3f& wo, float u_lobe, const Vec2f& u,
                      TransportMode mode = TransportMode::Radiance) const;

    /// True when every lobe is a Dirac delta (no point in light sampling or MIS).
    bool is_delta() const;
    /// True when some lobe transmits.
    bool has_transmission() const;
    /// The roughness class of the surface, the most connectable lobe first
    /// (diffuse > glossy > delta) as shifts need it; see roughness_class.h. With textured
    /// roughness this is the class of the sharpest place on the surface (a summary for
    /// SceneFeatures); per vertex use roughness_class_at(at).
    RoughnessClass roughness_class() const;
    RoughnessClass roughness_class_at(const TexturePoint& at) const;
    /// Every kind of lobe that occurs on either side.
    BsdfLobes lobes() const;
    const BsdfModel& front() const { return front_; }
    bool is_two_sided() const { return two_sided_; }
    /// The model seen from behind when it differs from the front one (two-sided only).
    const BsdfModel* back() const { return back_ ? &*back_ : nullptr; }

  private:
    struct Composite;
    /// A normal map, or a bump map (`bump`, with its height texture and scale).
    static Bsdf perturbed(bool bump, RgbTexture texture, float scale, Bsdf nested,
                          bool flip_invalid_normals, bool use_shadowing_function);
    const BsdfModel& model_for(const Vec3f& wo, Vec3f* wo_flip, bool* flipped) const;
    BsdfSample sample_composite(const TexturePoint& at, const Vec3f& wo, float u_lobe,
                                const Vec2f& u, TransportMode mode) const;
    BsdfSample sample_normal_mapped(const TexturePoint& at, const Vec3f& wo, float u_lobe,
                                    const Vec2f& u, TransportMode mode) const;

    BsdfModel front_;
    std::optional<BsdfModel> back_;
    bool two_sided_ = false;
    std::shared_ptr<const Composite> composite_;  // immutable, shared by copies
};

/// Mitsuba's named IORs ("bk7", "water", "air", ...); nullopt for unknown names.
std::optional<float> lookup_ior(const std::string& name);
/// RGB complex IOR of Mitsuba's named conductors ("Au", "Ag", "Cu", "Al", "Cr", ...).
struct ConductorIor {
    Rgb eta, k;
};
std::optional<ConductorIor> lookup_conductor(const std::string& name);
/// The names lookup_conductor knows, comma-separated (for error messages).
std::string conductor_names();

}  // namespace gdmlt
