// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Ray-sphere intersection, the one the accelerator's sphere geometry runs.
#include <algorithm>
#include <cmath>
#include <limits>

namespace gdmlt {

/// The nearest distance t with t_min < t < t_max at which origin + t direction meets the sphere
/// |x - center| = radius, or +infinity. `direction` need not be unit length (t is in its units).
///
/// The quadratic a t^2 + 2 b t + c = 0 (f = origin - center, a = |d|^2, b = f.d,
/// c = |f|^2 - r^2) is set up in double, as Mitsuba 3's sphere does for its CPU variants: the
/// products of floats are exact there, so c keeps its digits for an origin on the surface
/// (a spawned ray, where |f|^2 and r^2 agree to 1e-4) and b^2 - a c keeps its digits for a ray
/// that passes close to tangent (where both sides are tiny) and for one from far away (where
/// both are huge: relative error ~1e-16 (|f| / r)^2 of r^2). In float, either form of the
/// discriminant (the textbook one or Haines et al.'s a (r^2 - |f - (b/a) d|^2), Ray Tracing
/// Gems ch. 7) loses a few ulps of r^2 to cancellation in one of these cases, which near
/// tangency grows into dozens of ulps of t. The square root and the divisions are then done in
/// float on numbers already exact to float: q = -(b + sign(b) sqrt(disc)) adds like signs, and
/// the roots are c / q and q / a (Press et al., Numerical Recipes, Sec. 5.6), so neither root
/// cancels and a small root keeps its relative precision.
inline float intersect_sphere(float center_x, float center_y, float center_z, float radius,
                              float origin_x, float origin_y, float origin_z, float direction_x,
                              float direction_y, float direction_z, float t_min, float t_max) {
    // Differences of floats are exact in double unless their exponents differ by more than 29.
    const double fx = double(origin_x) - center_x, fy = double(origin_y) - center_y,
                 fz = double(origin_z) - center_z;
    const double dx = direction_x, dy = direction_y, dz = direction_z;
    const double a = dx * dx + dy * dy + dz * dz;
    const double b = fx * dx + fy * dy + fz * dz;
    const double c = (fx * fx + fy * fy + fz * fz) - double(radius) * radius;
    const auto disc = static_cast<float>(b * b - a * c);
    const auto b_f = static_cast<float>(b), a_f = static_cast<float>(a);
    // Selects rather than branches: the two roots are as random as the rays.
    const float q = -(b_f + std::copysign(std::sqrt(std::max(disc, 0.f)), b_f));
    const float t0 = static_cast<float>(c) / q, t1 = q / a_f;  // NaN only for q = c = 0: t1 = 0
    const float t_near = t0 < t1 ? t0 : t1, t_far = t0 < t1 ? t1 : t0;
    constexpr float kMiss = std::numeric_limits<float>::infinity();
    const float t = (t_near > t_min && t_near < t_max) ? t_near
                    : (t_far > t_min && t_far < t_max) ? t_far
                                                       : kMiss;
    return (disc >= 0.f && a_f > 0.f) ? t : kMiss;
}

}  // namespace gdmlt
