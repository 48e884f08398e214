// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Microfacet normal distributions (Beckmann and GGX, anisotropic) with Smith masking, and the
// sampling of either the full distribution D(m) cos(theta_m) or of the normals visible from a
// direction.
//
// Local frame (normal = +z). Both distributions are written in terms of the *stretched*
// components (m.x / alpha_u, m.y / alpha_v, m.z): an anisotropic distribution is the isotropic
// one with alpha = 1 stretched along x and y (Heitz 2014, "Understanding the masking-shadowing
// function in microfacet-based BRDFs", Sec. 5.3), which is what makes visible-normal sampling
// of anisotropic lobes no harder than isotropic ones.
//
// References: Walter et al. 2007, "Microfacet models for refraction through rough surfaces"
// (D, G, eqs. 25-34); Heitz & d'Eon 2014, "Importance sampling microfacet-based BSDFs using
// the distribution of visible normals" (Beckmann visible slopes); Heitz 2018, "Sampling the
// GGX distribution of visible normals" (JCGT 7(4), the GGX algorithm).
#include "core/math/types.h"

namespace gdmlt {

enum class MicrofacetType { Beckmann, Ggx };

/// Alphas below this are raised to it: the peak of D grows like 1 / alpha^2 and would overflow
/// float at alpha ~ 1e-20; 1e-4 keeps every quantity finite and is far below the delta-like
/// threshold of roughness_class.h. (Mitsuba 3 clamps at the same value.)
inline constexpr float kMinMicrofacetAlpha = 1e-4f;

struct MicrofacetDistribution {
    MicrofacetType type = MicrofacetType::Beckmann;
    float alpha_u = 0.1f;
    float alpha_v = 0.1f;

    MicrofacetDistribution() = default;
    MicrofacetDistribution(MicrofacetType type_, float alpha_u_, float alpha_v_)
        : type(type_),
          alpha_u(std::max(alpha_u_, kMinMicrofacetAlpha)),
          alpha_v(std::max(alpha_v_, kMinMicrofacetAlpha)) {}

    /// Normal distribution D(m), normalised so that the projected area integrates to one:
    /// int D(m) cos(theta_m) dm = 1 (Walter et al. 2007, eq. 4). Zero for m.z <= 0.
    float D(const Vec3f& m) const {
        if (!(m.z() > 0.f)) return 0.f;
        const float x = m.x() / alpha_u, y = m.y() / alpha_v, z2 = m.z() * m.z();
        float result;
        if (type == MicrofacetType::Beckmann) {
            // exp(-tan^2 theta (cos^2 phi / au^2 + sin^2 phi / av^2)) / (pi au av cos^4 theta)
            result = std::exp(-(x * x + y * y) / z2) / (kPi * alpha_u * alpha_v * z2 * z2);
        } else {
            // 1 / (pi au av cos^4 theta (1 + tan^2 theta (...))^2) = 1 / (pi au av (x^2+y^2+z^2)^2)
            const float s = x * x + y * y + z2;
            result = 1.f / (kPi * alpha_u * alpha_v * s * s);
        }
        return std::isfinite(result) ? result : 0.f;
    }

    /// Smith's Lambda(w) for the direction w (either hemisphere; it depends on tan^2 theta).
    float lambda(const Vec3f& w) const;

    /// Smith's masking G1(w, m): the fraction of microfacets with normal m visible from w.
    /// Zero when w sees the back of m relative to the macro surface (Walter et al. eq. 7's chi+).
    float G1(const Vec3f& w, const Vec3f& m) const {
        if (!(w.dot(m) * w.z() > 0.f)) return 0.f;
        return 1.f / (1.f + lambda(w));
    }

    /// Separable shadowing-masking G(wo, wi, m) = G1(wo, m) G1(wi, m) (Walter et al. eq. 23);
    /// Mitsuba 3 uses the same form, which matters when its renders are the reference.
    float G(const Vec3f& wo, const Vec3f& wi, const Vec3f& m) const {
        return G1(wo, m) * G1(wi, m);
    }

    /// Density of the visible normals from `wo` (wo.z > 0): D_wo(m) = G1(wo, m) max(0, wo.m)
    /// D(m) / cos(theta_o) (Heitz & d'Eon 2014, eq. 2), in solid angle of m.
    float pdf_visible(const Vec3f& wo, const Vec3f& m) const {
        if (!(wo.z() > 0.f)) return 0.f;
        const float wo_m = wo.dot(m);
        if (!(wo_m > 0.f)) return 0.f;
        return G1(wo, m) * wo_m * D(m) / wo.z();
    }
    /// Density of D(m) cos(theta_m), in solid angle of m.
    float pdf_all(const Vec3f& m) const { return D(m) * std::max(m.z(), 0.f); }

    /// A microfacet normal distributed as the normals visible from `wo` (wo.z > 0).
    Vec3f sample_visible(const Vec3f& wo, const Vec2f& u) const;
    /// A microfacet normal distributed as D(m) cos(theta_m).
    Vec3f sample_all(const Vec2f& u) const;
};

/// Inverse error function on (-1, 1), accurate to float precision (Giles 2010's polynomial
/// approximation, evaluated in double).
float erfinv(float x);

/// The x slope of a visible normal of the alpha = 1 Beckmann surface seen from polar angle
/// theta (azimuth 0), for one uniform number u: the inverse of its CDF (microfacet.cpp).
/// MicrofacetDistribution::sample_visible's first step; public for its test.
float sample_beckmann_visible_slope_x(float cos_theta, float sin_theta, float u);

}  // namespace gdmlt
