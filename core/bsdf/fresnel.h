// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Fresnel equations for unpolarised light.
#include <algorithm>
#include <cmath>

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
///
/// Real arithmetic only: with a^2 + b^2 = |eta_c^2 - sin^2 theta| (eta_c = eta + i k) and
/// a = Re sqrt(eta_c^2 - sin^2 theta), the s- and p-reflectances are (Pharr, Jakob & Humphreys,
/// "Physically Based Rendering", 3rd ed., Sec. 8.2.1, the conductor equations after eq. 8.3)
///   R_s = (a^2 + b^2 + cos^2 - 2 a cos) / (a^2 + b^2 + cos^2 + 2 a cos),
///   R_p = R_s ((a^2 + b^2) cos^2 + sin^4 - 2 a cos sin^2) / ((a^2 + b^2) cos^2 + sin^4 + 2 a cos
///   sin^2),
/// which is 0.5 (|r_s|^2 + |r_p|^2) of the complex amplitudes without std::complex's division
/// and square root (libgcc's __divsc3 and libm's csqrtf were 5% of the path tracer's time on
/// rough_metal_glass and cbox_glass_sphere). tests/core/test_bsdf.cpp holds it against the
/// complex formula in double.
inline float fresnel_conductor(float cos_theta_i, float eta, float k) {
    const float cos_i = std::clamp(cos_theta_i, 0.f, 1.f);
    const float cos2 = cos_i * cos_i;
    const float sin2 = 1.f - cos2;
    const float eta2 = eta * eta, k2 = k * k;
    // z = eta_c^2 - sin^2 = (eta^2 - k^2 - sin^2) + i (2 eta k); a2_plus_b2 is |z|. Re z cancels
    // where eta^2 - k^2 is close to sin^2, so it is summed in double from exact products (float
    // times float is exact in double): in float, sin^2 = 1 - cos^2 rounds to 1 at grazing
    // incidence and F on a matched index (eta = 1, k = 0) came out 1 instead of 0.
    const double cos_d = cos_i, eta_d = eta, k_d = k;
    const auto t0 = static_cast<float>((eta_d * eta_d - k_d * k_d - 1.0) + cos_d * cos_d);
    const float a2_plus_b2 = std::sqrt(t0 * t0 + 4.f * eta2 * k2);
    // a^2 = (|z| + Re z) / 2 loses every digit to cancellation when Re z < 0 (eta < sin theta,
    // the near-total-reflection side of a weak absorber); there a^2 = (Im z)^2 / (2 (|z| - Re z)).
    const float a2 = t0 >= 0.f ? 0.5f * (a2_plus_b2 + t0) : 2.f * eta2 * k2 / (a2_plus_b2 - t0);
    const float a = std::sqrt(a2);
    const float t1 = a2_plus_b2 + cos2;
    const float t2 = 2.f * a * cos_i;
    const float r_s = (t1 - t2) / (t1 + t2);
    const float t3 = a2_plus_b2 * cos2 + sin2 * sin2;
    const float t4 = t2 * sin2;
    const float r_p = r_s * (t3 - t4) / (t3 + t4);
    const float f = 0.5f * (r_s + r_p);
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
