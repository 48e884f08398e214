// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Mitsuba 3's `aov` integrator: arbitrary output variables of the first surface a camera ray
// meets, written as EXR layers beside the beauty (core/render/aov_pass.h renders them).
// `<string name="aovs" value="nn:sh_normal, depth.y:depth"/>` names each layer and its type;
// channel suffixes are Mitsuba's (".X/.Y/.Z" for vectors, ".U/.V" for uv, ".T" for depth,
// ".I" for indices).
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace gdmlt {

enum class AovType { Depth, Position, Uv, GeometricNormal, ShadingNormal, PrimIndex, ShapeIndex };

struct AovRequest {
    std::string name;  // the layer's name (Mitsuba's channel prefix)
    AovType type = AovType::Depth;
};

/// Mitsuba 3's name of an AOV type, or nullopt for one gdmlt does not write.
inline std::optional<AovType> parse_aov_type(std::string_view name) {
    if (name == "depth") return AovType::Depth;
    if (name == "position") return AovType::Position;
    if (name == "uv") return AovType::Uv;
    if (name == "geo_normal") return AovType::GeometricNormal;
    if (name == "sh_normal") return AovType::ShadingNormal;
    if (name == "prim_index") return AovType::PrimIndex;
    if (name == "shape_index") return AovType::ShapeIndex;
    return std::nullopt;
}

inline constexpr const char* kAovTypeNames =
    "depth, position, uv, geo_normal, sh_normal, prim_index, shape_index";

/// The channel suffixes Mitsuba 3 gives the type's layer.
inline std::vector<std::string> aov_channels(AovType type) {
    switch (type) {
        case AovType::Depth:
            return {"T"};
        case AovType::Uv:
            return {"U", "V"};
        case AovType::PrimIndex:
        case AovType::ShapeIndex:
            return {"I"};
        case AovType::Position:
        case AovType::GeometricNormal:
        case AovType::ShadingNormal:
            return {"X", "Y", "Z"};
    }
    return {};
}

}  // namespace gdmlt
