// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Affine transforms as 4x4 double matrices (composition is done once at load time, in double;
// application to float geometry converts at the end).
#include "core/math/types.h"

namespace gdmlt {

struct Transform {
    Mat4d matrix = Mat4d::Identity();
    Mat4d inverse = Mat4d::Identity();

    Transform() = default;
    explicit Transform(const Mat4d& m) : matrix(m), inverse(m.inverse()) {}

    Vec3d apply_point(const Vec3d& p) const {
        return matrix.topLeftCorner<3, 3>() * p + matrix.topRightCorner<3, 1>();
    }
    Vec3d apply_vector(const Vec3d& v) const { return matrix.topLeftCorner<3, 3>() * v; }
    /// Normals transform by the inverse transpose.
    Vec3d apply_normal(const Vec3d& n) const {
        return inverse.topLeftCorner<3, 3>().transpose() * n;
    }
    Vec3f apply_point(const Vec3f& p) const {
        return apply_point(Vec3d(p.cast<double>())).cast<float>();
    }
    Vec3f apply_vector(const Vec3f& v) const {
        return apply_vector(Vec3d(v.cast<double>())).cast<float>();
    }
    /// The inverse map, from world to this transform's space (cameras project through it).
    Vec3f apply_inverse_point(const Vec3f& p) const {
        const Vec3d q = p.cast<double>();
        return (inverse.topLeftCorner<3, 3>() * q + inverse.topRightCorner<3, 1>()).cast<float>();
    }
    Vec3f apply_inverse_vector(const Vec3f& v) const {
        return (inverse.topLeftCorner<3, 3>() * v.cast<double>()).cast<float>();
    }
    Vec3f apply_normal(const Vec3f& n) const {
        return apply_normal(Vec3d(n.cast<double>())).normalized().cast<float>();
    }
    /// True when the linear part flips orientation (mirror); triangle winding then flips too.
    bool flips_handedness() const { return matrix.topLeftCorner<3, 3>().determinant() < 0.0; }
    bool is_finite() const { return matrix.allFinite() && inverse.allFinite(); }
};

}  // namespace gdmlt
