// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Basic value types. Geometry is float (Embree is single precision); solvers, Jacobians and
// accumulation use double (the project's precision policy).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <numbers>

namespace gdmlt {

using Vec2f = Eigen::Vector2f;
using Vec3f = Eigen::Vector3f;
using Vec2d = Eigen::Vector2d;
using Vec3d = Eigen::Vector3d;
using Vec2i = Eigen::Vector2i;
using Mat3f = Eigen::Matrix3f;
using Mat4d = Eigen::Matrix4d;

/// Linear RGB radiance, reflectance or throughput; component-wise arithmetic.
using Rgb = Eigen::Array3f;
using RgbD = Eigen::Array3d;

inline constexpr float kPi = std::numbers::pi_v<float>;
inline constexpr float kInvPi = std::numbers::inv_pi_v<float>;
inline constexpr float kInfinity = std::numeric_limits<float>::infinity();

/// Rec. 709 luminance, used for Russian roulette and light power.
inline float luminance(const Rgb& c) {
    return 0.212671f * c[0] + 0.715160f * c[1] + 0.072169f * c[2];
}

inline bool is_finite(const Rgb& c) {
    return std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]);
}
inline bool is_black(const Rgb& c) {
    return c[0] == 0.f && c[1] == 0.f && c[2] == 0.f;
}

inline float safe_sqrt(float x) {
    return std::sqrt(std::max(x, 0.f));
}
inline double safe_sqrt(double x) {
    return std::sqrt(std::max(x, 0.0));
}
inline float safe_acos(float x) {
    return std::acos(std::clamp(x, -1.f, 1.f));
}
inline float sqr(float x) {
    return x * x;
}
inline double sqr(double x) {
    return x * x;
}

inline float degrees_to_radians(float deg) {
    return deg * (kPi / 180.f);
}

}  // namespace gdmlt
