// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Warps from the unit square to common domains, each beside its pdf in the measure it is named
// for. Every pair is chi-square tested in tests/core/test_warp.cpp.
#include "core/math/trig.h"
#include "core/math/types.h"

namespace gdmlt::warp {

/// In core/math/trig.h beside the other branch-free trigonometry; named here too, as the
/// concentric map's part.
using gdmlt::sincos_quarter_pi;

/// Shirley-Chiu concentric map (1997): low distortion, continuous, area-preserving up to pi.
/// Its angle is phi = pi/4 y/x, or phi = pi/2 - pi/4 x/y, whose cosine and sine are the sine
/// and cosine of pi/4 x/y: both cases need sine and cosine on [-pi/4, pi/4] only.
inline Vec2f square_to_uniform_disk_concentric(const Vec2f& u) {
    const float x = 2.f * u.x() - 1.f, y = 2.f * u.y() - 1.f;
    if (x == 0.f && y == 0.f) return {0.f, 0.f};
    float sin_a, cos_a;
    if (std::abs(x) > std::abs(y)) {
        sincos_quarter_pi((kPi / 4.f) * (y / x), sin_a, cos_a);
        return {x * cos_a, x * sin_a};
    }
    sincos_quarter_pi((kPi / 4.f) * (x / y), sin_a, cos_a);
    return {y * sin_a, y * cos_a};
}
inline float square_to_uniform_disk_pdf_area() {
    return kInvPi;
}

/// Cosine-weighted hemisphere around +z (Malley's method).
inline Vec3f square_to_cosine_hemisphere(const Vec2f& u) {
    const Vec2f d = square_to_uniform_disk_concentric(u);
    const float z = safe_sqrt(1.f - d.squaredNorm());
    return {d.x(), d.y(), z};
}
inline float square_to_cosine_hemisphere_pdf_solid_angle(const Vec3f& w) {
    return w.z() > 0.f ? w.z() * kInvPi : 0.f;
}

inline Vec3f square_to_uniform_sphere(const Vec2f& u) {
    const float z = 1.f - 2.f * u.y();
    const float r = safe_sqrt(1.f - z * z);
    const float phi = 2.f * kPi * u.x();
    return {r * std::cos(phi), r * std::sin(phi), z};
}
inline float square_to_uniform_sphere_pdf_solid_angle() {
    return 0.25f * kInvPi;
}

/// Uniform in the cone of directions around +z with cos(theta) >= cos_theta_max.
inline Vec3f square_to_uniform_cone(const Vec2f& u, float cos_theta_max) {
    const float cos_theta = 1.f - u.y() * (1.f - cos_theta_max);
    const float sin_theta = safe_sqrt(1.f - cos_theta * cos_theta);
    const float phi = 2.f * kPi * u.x();
    return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta};
}
inline float square_to_uniform_cone_pdf_solid_angle(float cos_theta_max) {
    return 1.f / (2.f * kPi * (1.f - cos_theta_max));
}

/// Barycentrics (b1, b2) uniform over a triangle (the square-root parametrisation, pdf 2 in
/// barycentric area, i.e. 1/area on the triangle).
inline Vec2f square_to_uniform_triangle(const Vec2f& u) {
    const float su = safe_sqrt(u.x());
    return {1.f - su, u.y() * su};
}

}  // namespace gdmlt::warp
