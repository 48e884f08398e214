// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Emitters as a closed set of value types, with Mitsuba 3's plugin meanings:
//  area (textured radiance), point, spot, directional, constant, envmap and projector.
#include <memory>
#include <optional>
#include <variant>

#include "core/camera/camera.h"
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
/// `beam_width`, falling off linearly in angle to zero at `cutoff_angle`, optionally modulated by
/// a texture projected over the cutoff cone (Mitsuba 3's `texture` parameter: u, v = 1/2 +
/// x / (2 z tan(cutoff)), 1/2 + y / (2 z tan(cutoff)) in the local frame). Build with
/// make_spot(), which precomputes the cosines.
struct SpotEmitter {
    Vec3f position = Vec3f::Zero();
    Mat3f local_from_world = Mat3f::Identity();  // rotation; local +z is the beam axis
    Rgb intensity = Rgb::Ones();
    float cutoff_rad = 0.f;
    float beam_width_rad = 0.f;
    float cos_cutoff = 1.f;
    float cos_beam_width = 1.f;
    float tan_cutoff = 0.f;
    bool textured = false;
    RgbTexture texture{Rgb::Ones()};

    /// Intensity (W/sr) emitted along the unit world direction `w` (from the light outwards).
    Rgb intensity_towards(const Vec3f& w) const {
        const Vec3f local = local_from_world * w;
        const float cos_theta = local.z();
        if (!(cos_theta > cos_cutoff)) return Rgb::Zero();
        const Rgb base = textured ? Rgb(intensity * texture.eval(texture_uv(local))) : intensity;
        if (cos_theta >= cos_beam_width) return base;
        const float falloff = (cutoff_rad - safe_acos(cos_theta)) / (cutoff_rad - beam_width_rad);
        return base * std::clamp(falloff, 0.f, 1.f);
    }
    /// Where the local direction `local` (z > 0) falls on the projected texture.
    Vec2f texture_uv(const Vec3f& local) const {
        const float scale = 0.5f / (local.z() * tan_cutoff);
        return {0.5f + local.x() * scale, 0.5f + local.y() * scale};
    }
};
/// Mitsuba's `projector`: a pinhole that projects the `irradiance` texture as a perspective
/// camera with the same parameters would see it (the texture's pixels are the film's), so that
/// the irradiance on a plane facing it at distance 1 is the texture times `scale`. Intensity
/// towards a direction at angle theta from the axis is pi scale E(uv) / cos^3(theta) (Mitsuba
/// 3's projector.cpp: its radiance pi E / (z^2 cos) at a point of camera depth z).
struct ProjectorEmitter {
    Camera camera;  // the projection: film = the texture's pixels, crop = all of it
    RgbTexture irradiance{Rgb::Ones()};
    float scale = 1.f;
    Vec3f axis = Vec3f::UnitZ();  // unit world direction of the optical axis

    /// Intensity (W/sr) along the unit world direction `w` from the pinhole; zero outside the
    /// projected image.
    Rgb intensity_towards(const Vec3f& w) const {
        const CameraConnection c = camera.connect(camera.position() + w);
        const float cos_theta = w.dot(axis);
        if (!c.valid() || !(cos_theta > 0.f)) return Rgb::Zero();
        const Film& film = camera.film();
        const Vec2f uv(c.film_position.x() / static_cast<float>(film.width),
                       c.film_position.y() / static_cast<float>(film.height));
        return irradiance.eval(uv) * (kPi * scale / (cos_theta * cos_theta * cos_theta));
    }
    /// Area of the projected image on the plane at distance 1 (for its total power).
    float image_area() const { return 4.f * camera.tan_half_fov_x() * camera.tan_half_fov_y(); }
};

/// Angles in degrees, Mitsuba's defaults: cutoff 20, beam width 3/4 of the cutoff.
SpotEmitter make_spot(const Vec3f& position, const Mat3f& world_from_local, const Rgb& intensity,
                      float cutoff_deg, float beam_width_deg,
                      std::optional<RgbTexture> texture = std::nullopt);

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
    /// The texels (row-major, linear RGB, negatives and non-finite values zeroed) for lookup():
    /// four floats each (SIMD arithmetic on whole texels), each row followed by a copy of its
    /// first texel, so that a bilinear lookup's right-hand column is always the next entry,
    /// across the wrap too.
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
                             ConstantEmitter, EnvmapEmitter, ProjectorEmitter>;

/// Emitters with a Dirac delta in position (shadow rays to one point).
inline bool is_delta_position(const Emitter& e) {
    return std::holds_alternative<PointEmitter>(e) || std::holds_alternative<SpotEmitter>(e) ||
           std::holds_alternative<ProjectorEmitter>(e);
}
/// A delta-position emitter's position and its intensity (W/sr) along the unit world direction
/// `w` leaving it (point, spot, projector).
inline Vec3f delta_position_of(const Emitter& e) {
    if (const auto* spot = std::get_if<SpotEmitter>(&e)) return spot->position;
    if (const auto* projector = std::get_if<ProjectorEmitter>(&e))
        return projector->camera.position();
    return std::get<PointEmitter>(e).position;
}
inline Rgb delta_intensity_towards(const Emitter& e, const Vec3f& w) {
    if (const auto* spot = std::get_if<SpotEmitter>(&e)) return spot->intensity_towards(w);
    if (const auto* projector = std::get_if<ProjectorEmitter>(&e))
        return projector->intensity_towards(w);
    return std::get<PointEmitter>(e).intensity;
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
