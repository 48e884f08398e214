// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Orthonormal frame (s, t, n). Local shading coordinates have the normal along +z, so that
// cos(theta) = v.z(); BSDFs work only in this frame.
#include "core/math/types.h"

namespace gdmlt {

struct Frame {
    Vec3f s = Vec3f::UnitX();
    Vec3f t = Vec3f::UnitY();
    Vec3f n = Vec3f::UnitZ();

    /// A frame around `n` with an arbitrary but continuous-almost-everywhere tangent
    /// (Duff et al. 2017, "Building an orthonormal basis, revisited", JCGT 6(1)).
    static Frame from_normal(const Vec3f& n);

    /// A frame around `n` whose first tangent follows `dpdu` projected onto the tangent plane
    /// (anisotropic BSDFs need the surface's u direction); falls back to from_normal when
    /// `dpdu` is (nearly) parallel to `n` or zero.
    static Frame from_normal_and_tangent(const Vec3f& n, const Vec3f& dpdu);

    Vec3f to_local(const Vec3f& world) const { return {world.dot(s), world.dot(t), world.dot(n)}; }
    Vec3f to_world(const Vec3f& local) const {
        return s * local.x() + t * local.y() + n * local.z();
    }
};

inline Frame Frame::from_normal(const Vec3f& n) {
    const float sign = std::copysign(1.f, n.z());
    const float a = -1.f / (sign + n.z());
    const float b = n.x() * n.y() * a;
    Frame f;
    f.n = n;
    f.s = Vec3f(1.f + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
    f.t = Vec3f(b, sign + n.y() * n.y() * a, -n.y());
    return f;
}

inline Frame Frame::from_normal_and_tangent(const Vec3f& n, const Vec3f& dpdu) {
    const Vec3f s = dpdu - n * n.dot(dpdu);
    const float len2 = s.squaredNorm();
    if (!(len2 > 1e-12f * std::max(dpdu.squaredNorm(), 1e-30f))) return from_normal(n);
    Frame f;
    f.n = n;
    // One division instead of three: this runs once per ray hit.
    f.s = s * (1.f / std::sqrt(len2));
    f.t = n.cross(f.s);
    return f;
}

// Helpers on local directions (normal = +z).
inline float cos_theta(const Vec3f& w) {
    return w.z();
}
inline float abs_cos_theta(const Vec3f& w) {
    return std::abs(w.z());
}
inline bool same_hemisphere(const Vec3f& a, const Vec3f& b) {
    return a.z() * b.z() > 0.f;
}

}  // namespace gdmlt
