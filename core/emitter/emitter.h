// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Emitters as a closed set of value types, with Mitsuba 3's plugin meanings:
//  area (textured radiance), point, spot, directional, constant and envmap.
#include <memory>
#include <variant>

#include "core/math/types.h"
#include "core/sampling/distribution_2d.h"
#include "core/texture/texture.h"

namespace gdmlt {

/// Diffuse emission from the front side (normal side) of a shape; the radiance may be textured
/// (looked up at the surface's uv).
struct AreaEmitter {
    RgbTexture radiance;
    int shape = -1;
};

/// Isotropic point light; intensity in W/sr.
struct PointEmitter {
    Vec3f position = Vec3f::Zero();
    Rgb intensity = Rgb::Ones();
};

/// Mitsuba's `spot`: a point light shining along its local +z, full intensity inside
/// `beam_width`, falling off linearly in angle to zero at `cutoff_angle`. Build with
/// make_spot(), which precomputes the cosines.
struct SpotEmitter {
    Vec3f position = Vec3f::Zero();
    Mat3f local_from_world = Mat3f::Identity();  // rotation; local +z is the beam axis
    Rgb intensity = Rgb::Ones();
    float cutoff_rad = 0.f;
    float beam_width_rad = 0.f;
    float cos_cutoff = 1.f;
    float cos_beam_width = 1.f;

    /// Intensity (W/sr) emitted along the unit world direction `w` (from the light outwards).
    Rgb intensity_towards(const Vec3f& w) const {
        const float cos_theta = (local_from_world * w).z();
        if (!(cos_theta > cos_cutoff)) return Rgb::Zero();
        if (cos_theta >= cos_beam_width) return intensity;
        const float falloff = (cutoff_rad - safe_acos(cos_theta)) / (cutoff_rad - beam_width_rad);
        return intensity * std::clamp(falloff, 0.f, 1.f);
    }
};
/// Angles in degrees, Mitsuba's defaults: cutoff 20, beam width 3/4 of the cutoff.
SpotEmitter make_spot(const Vec3f& position, const Mat3f& world_from_local, const Rgb& intensity,
                      float cutoff_deg, float beam_width_deg);

/// Mitsuba's `directional`: parallel light travelling along `direction` with the given
/// irradiance (W/m^2 on a surface facing it).
struct DirectionalEmitter {
    Vec3f direction = Vec3f(0.f, 0.f, 1.f);  // unit, the direction light travels
    Rgb irradiance = Rgb::Ones();
};

/// Uniform radiance arriving from every direction at infinity.
struct ConstantEmitter {
    Rgb radiance = Rgb::Ones();
};

/// A latitude-longitude environment image in Mitsuba's convention: in the emitter's local frame
/// (y up) the direction d is seen at u = atan2(d.x, -d.z) / (2 pi) (wrapped to [0, 1)),
/// v = acos(d.y) / pi; pixel column i is centred at u = (i + 0.5) / width, and row j sits at
/// v = j / (height - 1), so that the first and last rows are the poles. Radiance is bilinear
/// between those samples.
struct EnvmapData {
    int width = 0;
    int height = 0;
    std::vector<Rgb> texels;  // row-major, linear RGB
    /// The texels again for lookup(): four floats each (SIMD arithmetic on whole texels), each
    /// row followed by a copy of its first texel, so that a bilinear lookup's right-hand column
    /// is always the next entry, across the wrap too.
    std::vector<Eigen::Array4f> padded_rows;
    /// Importance sampling over (u, v) in [0, 1)^2: piecewise constant on a width x height grid,
    /// proportional to (largest radiance in the cell) x (mean sin(theta) over the cell).
    Distribution2D distribution;
    /// Integral of the luminance over the sphere (for emitter selection by power).
    float luminance_integral = 0.f;

    Rgb lookup(const Vec2f& uv) const;  // radiance at (u, v) before `scale`
};

/// Builds EnvmapData from linear texels. Throws std::invalid_argument when smaller than 2 x 3
/// (Mitsuba's limit).
EnvmapData make_envmap_data(int width, int height, std::vector<Rgb> texels);

struct EnvmapEmitter {
    std::shared_ptr<const EnvmapData> data;
    Mat3f world_from_local = Mat3f::Identity();  // rotation
    Mat3f local_from_world = Mat3f::Identity();
    float scale = 1.f;

    /// Radiance arriving from the unit world direction `d` (pointing away from the scene).
    Rgb eval(const Vec3f& d) const;
    struct Sample {
        Vec3f direction = Vec3f::UnitZ();  // world, towards the environment
        float pdf_solid_angle = 0.f;
        Rgb radiance = Rgb::Zero();
        Vec2f uv = Vec2f::Zero();  // where in the map
    };
    Sample sample(const Vec2f& u) const;
    /// sample() without the radiance (left zero): for callers that evaluate the direction
    /// themselves (Scene sums every infinite emitter along it).
    Sample sample_direction(const Vec2f& u) const;
    /// Radiance at a point (u, v) of the map, `scale` applied.
    Rgb radiance_at(const Vec2f& uv) const { return data->lookup(uv) * scale; }
    float pdf_solid_angle(const Vec3f& d) const;
    /// eval() and pdf_solid_angle() from one direction -> (u, v) map: what an escaping ray
    /// needs, at half the trigonometry of the two calls.
    struct Value {
        Rgb radiance = Rgb::Zero();
        float pdf_solid_angle = 0.f;
    };
    Value eval_with_pdf(const Vec3f& d) const;
};

using Emitter = std::variant<AreaEmitter, PointEmitter, SpotEmitter, DirectionalEmitter,
                             ConstantEmitter, EnvmapEmitter>;

/// Emitters with a Dirac delta in position (shadow rays to one point).
inline bool is_delta_position(const Emitter& e) {
    return std::holds_alternative<PointEmitter>(e) || std::holds_alternative<SpotEmitter>(e);
}
/// Emitters with a Dirac delta in direction.
inline bool is_delta_direction(const Emitter& e) {
    return std::holds_alternative<DirectionalEmitter>(e);
}
/// Emitters that a ray escaping the scene can hit (they answer Scene::environment()).
inline bool is_infinite(const Emitter& e) {
    return std::holds_alternative<ConstantEmitter>(e) || std::holds_alternative<EnvmapEmitter>(e);
}
const char* emitter_kind_name(const Emitter& e);

}  // namespace gdmlt
