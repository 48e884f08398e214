// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Emitters as a closed set of value types.
#include <variant>

#include "core/math/types.h"
#include "core/texture/texture.h"

namespace gdmlt {

/// Diffuse emission from the front side (normal side) of a shape.
struct AreaEmitter {
    RgbTexture radiance;
    int shape = -1;
};

/// Isotropic point light; intensity in W/sr.
struct PointEmitter {
    Vec3f position = Vec3f::Zero();
    Rgb intensity = Rgb::Ones();
};

/// Uniform radiance arriving from every direction at infinity.
struct ConstantEmitter {
    Rgb radiance = Rgb::Ones();
};

using Emitter = std::variant<AreaEmitter, PointEmitter, ConstantEmitter>;

inline bool is_delta_position(const Emitter& e) { return std::holds_alternative<PointEmitter>(e); }
inline bool is_infinite(const Emitter& e) { return std::holds_alternative<ConstantEmitter>(e); }
const char* emitter_kind_name(const Emitter& e);

}  // namespace gdmlt
