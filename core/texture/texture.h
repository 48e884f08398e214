// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Spatially varying parameters (reflectance, radiance, roughness). A closed set of value types.
#include <variant>

#include "core/math/types.h"

namespace gdmlt {

struct ConstantTexture {
    Rgb value = Rgb::Zero();
};

class RgbTexture {
public:
    RgbTexture() = default;
    /// A constant; implicit so that `DiffuseBsdf{Rgb(0.5f, 0.5f, 0.5f)}` reads naturally.
    template <typename Derived>
    RgbTexture(const Eigen::ArrayBase<Derived>& constant)  // NOLINT: implicit on purpose
        : texture_(ConstantTexture{Rgb(constant)}) {}
    explicit RgbTexture(std::variant<ConstantTexture> texture) : texture_(std::move(texture)) {}

    Rgb eval(const Vec2f& uv) const {
        (void)uv;
        return std::get<ConstantTexture>(texture_).value;
    }
    bool is_constant() const { return std::holds_alternative<ConstantTexture>(texture_); }
    /// Largest value over the surface (for light power and bounds).
    Rgb max_value() const { return std::get<ConstantTexture>(texture_).value; }

private:
    std::variant<ConstantTexture> texture_;
};

}  // namespace gdmlt
