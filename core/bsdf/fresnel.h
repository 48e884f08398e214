// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Fresnel equations for unpolarised light.
#include <complex>

#include "core/math/types.h"

namespace gdmlt {

/// Dielectric Fresnel reflectance at an interface with relative index `eta` = eta_inside /
/// eta_outside. `cos_theta_i` is signed: positive when the incident direction is on the outside
/// (the normal's side). Outputs the signed cosine of the refracted direction (opposite side,
/// zero under total internal reflection) and the relative indices eta_it = eta_t / eta_i and
/// eta_ti = 1 / eta_it for the actual crossing direction.
struct FresnelDielectric {
    float reflectance = 1.f;
    float cos_theta_t = 0.f;
    float eta_it = 1.f;
    float eta_ti = 1.f;
};

inline FresnelDielectric fresnel_dielectric(float cos_theta_i, float eta) {
    FresnelDielectric f;
    const bool outside = cos_theta_i >= 0.f;
    f.eta_it = outside ? eta : 1.f / eta;
    f.eta_ti = outside ? 1.f / eta : eta;
    if (eta == 1.f) {
        f.reflectance = 0.f;
        f.cos_theta_t = -cos_theta_i;
        return f;
    }
    const float cos_i = std::abs(cos_theta_i);
    // Snell: sin_t^2 = sin_i^2 / eta_it^2
    const float sin2_t = (1.f - cos_i * cos_i) * f.eta_ti * f.eta_ti;
    if (sin2_t >= 1.f) {  // total internal reflection
        f.reflectance = 1.f;
        f.cos_theta_t = 0.f;
        return f;
    }
    const float cos_t = safe_sqrt(1.f - sin2_t);
    // Amplitude coefficients for s- and p-polarised light, indices relative to the incident side.
    const float r_s = (cos_i - f.eta_it * cos_t) / (cos_i + f.eta_it * cos_t);
    const float r_p = (f.eta_it * cos_i - cos_t) / (f.eta_it * cos_i + cos_t);
    f.reflectance = 0.5f * (r_s * r_s + r_p * r_p);
    f.cos_theta_t = outside ? -cos_t : cos_t;
    return f;
}

/// Conductor Fresnel reflectance with complex index eta + i k (per channel), cos_theta_i >= 0.
inline float fresnel_conductor(float cos_theta_i, float eta, float k) {
    using C = std::complex<float>;
    const float cos_i = std::clamp(cos_theta_i, 0.f, 1.f);
    const C eta_c(eta, k);
    const C sin2_t = C(1.f - cos_i * cos_i) / (eta_c * eta_c);
    const C cos_t = std::sqrt(C(1.f) - sin2_t);
    const C r_p = (eta_c * cos_i - cos_t) / (eta_c * cos_i + cos_t);
    const C r_s = (C(cos_i) - eta_c * cos_t) / (C(cos_i) + eta_c * cos_t);
    const float f = 0.5f * (std::norm(r_s) + std::norm(r_p));
    return std::isfinite(f) ? std::clamp(f, 0.f, 1.f) : 1.f;
}

inline Rgb fresnel_conductor(float cos_theta_i, const Rgb& eta, const Rgb& k) {
    return {fresnel_conductor(cos_theta_i, eta[0], k[0]),
            fresnel_conductor(cos_theta_i, eta[1], k[1]),
            fresnel_conductor(cos_theta_i, eta[2], k[2])};
}

/// Mirror reflection about +z (local frame).
inline Vec3f reflect_local(const Vec3f& w) {
    return {-w.x(), -w.y(), w.z()};
}

/// Refraction about +z (local frame) given the outputs of fresnel_dielectric.
inline Vec3f refract_local(const Vec3f& w, float cos_theta_t, float eta_ti) {
    return {-eta_ti * w.x(), -eta_ti * w.y(), cos_theta_t};
}

}  // namespace gdmlt
