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
#include <optional>
#include <variant>

#include "core/bsdf/roughness_class.h"
#include "core/math/types.h"
#include "core/texture/texture.h"

namespace gdmlt {

enum class TransportMode { Radiance, Importance };

struct BsdfSample {
    Vec3f wi = Vec3f::UnitZ();
    Rgb weight = Rgb::Zero();  // eval / pdf, or the delta lobe's weight
    float pdf_solid_angle = 0.f;
    float eta = 1.f;  // relative index eta_t / eta_i crossed by this sample (1 for reflection)
    bool delta = false;
    bool transmission = false;
    bool valid() const { return pdf_solid_angle > 0.f; }
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

using BsdfModel = std::variant<DiffuseBsdf, DielectricBsdf, ThinDielectricBsdf, ConductorBsdf>;

/// A surface's scattering: one model on the front (normal side); `two_sided` mirrors the
/// directions of back-side queries onto the front and uses `back` (or the front model when
/// `back` is empty), as Mitsuba's `twosided` does. One-sided non-transmissive models are black
/// from behind.
class Bsdf {
public:
    Bsdf() = default;
    explicit Bsdf(BsdfModel front) : front_(std::move(front)) {}
    static Bsdf two_sided(BsdfModel front, std::optional<BsdfModel> back);

    Rgb eval(const Vec2f& uv, const Vec3f& wo, const Vec3f& wi,
             TransportMode mode = TransportMode::Radiance) const;
    float pdf(const Vec2f& uv, const Vec3f& wo, const Vec3f& wi) const;
    /// `u_lobe` chooses among lobes, `u` the direction.
    BsdfSample sample(const Vec2f& uv, const Vec3f& wo, float u_lobe, const Vec2f& u,
                      TransportMode mode = TransportMode::Radiance) const;

    /// True when every lobe is a Dirac delta (no point in light sampling or MIS).
    bool is_delta() const;
    /// True when some lobe transmits.
    bool has_transmission() const;
    /// The roughness class of the surface, the most connectable lobe first
    /// (diffuse > glossy > delta) as shifts need it; see roughness_class.h.
    RoughnessClass roughness_class() const;
    const BsdfModel& front() const { return front_; }
    bool is_two_sided() const { return two_sided_; }

private:
    const BsdfModel& model_for(const Vec3f& wo, Vec3f* wo_flip, bool* flipped) const;

    BsdfModel front_;
    std::optional<BsdfModel> back_;
    bool two_sided_ = false;
};

/// Mitsuba's named IORs ("bk7", "water", "air", ...); nullopt for unknown names.
std::optional<float> lookup_ior(const std::string& name);
/// RGB complex IOR of Mitsuba's named conductors ("Au", "Ag", "Cu", "Al", "Cr", ...).
struct ConductorIor {
    Rgb eta, k;
};
std::optional<ConductorIor> lookup_conductor(const std::string& name);

}  // namespace gdmlt
