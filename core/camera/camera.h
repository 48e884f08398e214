// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The camera: Mitsuba's perspective (a pinhole), thin-lens and orthographic sensors, with
// Mitsuba's conventions: in camera space the camera looks along +z, +y is up and +x is to the
// left, so raster x grows towards -x.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>

#include "core/camera/pixel_filter.h"
#include "core/geometry/ray.h"
#include "core/math/simd.h"
#include "core/math/transform.h"
#include "core/math/types.h"

namespace gdmlt {

struct Film {
    int width = 768;  // full film size in pixels
    int height = 576;
    int crop_offset_x = 0;  // rendered window inside the film
    int crop_offset_y = 0;
    int crop_width = 768;
    int crop_height = 576;
    PixelFilter filter;  // box unless the scene says otherwise (core/camera/pixel_filter.h)
};

/// Row-major index in the crop window of the pixel containing `film_position` (full-film
/// pixels), clamped to the window (a position on its far edge rounds into it).
inline std::uint32_t crop_pixel_index(const Film& film, const Vec2f& film_position) {
    const int x = std::clamp(static_cast<int>(std::floor(film_position.x())) - film.crop_offset_x,
                             0, film.crop_width - 1);
    const int y = std::clamp(static_cast<int>(std::floor(film_position.y())) - film.crop_offset_y,
                             0, film.crop_height - 1);
    return static_cast<std::uint32_t>(y * film.crop_width + x);
}

/// Calls `add(pixel, weight)` for every crop-window pixel p whose filter reaches
/// `film_position`, with weight h_p(film_position) (core/camera/pixel_filter.h): how a value
/// found at that position (a light path's, a Markov chain's) is spread over the pixels. With
/// the box filter, the one pixel crop_pixel_index gives, weight 1.
template <typename Add>
void for_each_filtered_pixel(const Film& film, const Vec2f& film_position, Add&& add) {
    const PixelFilter& f = film.filter;
    if (f.is_box()) {
        add(crop_pixel_index(film, film_position), 1.f);
        return;
    }
    // Pixel centres within the radius, in crop coordinates.
    const float px = film_position.x() - static_cast<float>(film.crop_offset_x);
    const float py = film_position.y() - static_cast<float>(film.crop_offset_y);
    const float r = f.radius();
    const int x0 = std::max(static_cast<int>(std::ceil(px - 0.5f - r)), 0);
    const int x1 = std::min(static_cast<int>(std::floor(px - 0.5f + r)), film.crop_width - 1);
    const int y0 = std::max(static_cast<int>(std::ceil(py - 0.5f - r)), 0);
    const int y1 = std::min(static_cast<int>(std::floor(py - 0.5f + r)), film.crop_height - 1);
    for (int y = y0; y <= y1; ++y) {
        const float cy = static_cast<float>(y) + 0.5f;
        const float wy = f.eval(py - cy);
        if (!(wy > 0.f)) continue;
        const double norm_y = f.integral(-cy, static_cast<float>(film.crop_height) - cy);
        for (int x = x0; x <= x1; ++x) {
            const float cx = static_cast<float>(x) + 0.5f;
            const float wx = f.eval(px - cx);
            if (!(wx > 0.f)) continue;
            const double norm = norm_y * f.integral(-cx, static_cast<float>(film.crop_width) - cx);
            add(static_cast<std::uint32_t>(y * film.crop_width + x),
                static_cast<float>(static_cast<double>(wx) * wy / norm));
        }
    }
}

/// A world point as the camera sees it: where on the film it lands and the importance there
/// (light tracing and BDPT connect light-subpath vertices to the camera through this).
struct CameraConnection {
    Vec2f film_position = Vec2f::Zero();  // full-film pixels ((0,0) = top-left corner)
    Vec3f position = Vec3f::Zero();       // the camera's end: pinhole, lens point, or ray origin
    Vec3f direction = Vec3f::UnitZ();     // unit, world, from `position` to the point
    float distance = 0.f;                 // from `position` to the point
    /// W(w) = dA_film / dw: film area in pixels per steradian of directions at the pinhole.
    /// With the box pixel filter a pixel's value is the mean radiance over its unit film area,
    /// I_j = integral over pixel j of L dA = integral of W_j(w) L(w) dw (Veach 1997, eq. 4.19
    /// with the pinhole's delta in position), so a light subpath that reaches the pinhole along
    /// w adds W(w) times its radiance-like weight to the pixel it lands in.
    /// The thin lens: W at the lens point (the film maps to the focus plane as seen from it,
    /// so the pinhole's formula holds there: Mitsuba 3's thinlens.cpp importance()). The
    /// orthographic camera has no solid angle: 1 / (pixel area across the rays), as `weight`.
    float importance = 0.f;
    /// What a light-subpath vertex's throughput times f |cos| at the point (or an area light's
    /// L_e |cos|) is multiplied by to give the pixel's value: W / distance^2 for the pinhole,
    /// and for the thin lens, whose lens point was chosen with density 1 / (lens area) and
    /// whose pixel value averages over the lens (Mitsuba's normalisation), the same; for the
    /// orthographic camera, whose rays are parallel, 1 / (world area of a pixel across them)
    /// with no fall-off.
    float weight = 0.f;
    bool valid() const { return weight > 0.f; }
};

/// Mitsuba's `perspective`, `thinlens` and `orthographic` sensors.
enum class Projection : std::uint8_t { Pinhole, ThinLens, Orthographic };

/// The Mitsuba plugin name of a projection ("perspective" for the pinhole).
inline const char* projection_name(Projection p) {
    switch (p) {
        case Projection::Pinhole:
            return "perspective";
        case Projection::ThinLens:
            return "thinlens";
        case Projection::Orthographic:
            return "orthographic";
    }
    return "?";
}

class Camera {
  public:
    Camera() = default;
    /// The pinhole (Mitsuba's `perspective`): `fov_deg` along `fov_axis` ("x", "y",
    /// "diagonal", "smaller", "larger").
    Camera(const Transform& world_from_camera, const Film& film, float fov_deg,
           const std::string& fov_axis, float near_clip);
    /// Mitsuba's `thinlens`: a disk of `aperture_radius` at the pinhole's place, focused on the
    /// plane at camera depth `focus_distance`. world_from_camera must not scale (as Mitsuba
    /// 3 requires): lens radius and distances are world lengths.
    static Camera thin_lens(const Transform& world_from_camera, const Film& film, float fov_deg,
                            const std::string& fov_axis, float near_clip, float aperture_radius,
                            float focus_distance);
    /// Mitsuba's `orthographic`: parallel rays along camera +z from the plane z = near_clip;
    /// the film spans camera x in [-1, 1] and y in [-1, 1] / aspect (to_world scales it).
    static Camera orthographic(const Transform& world_from_camera, const Film& film,
                               float near_clip);

    Projection projection() const { return projection_; }
    /// Whether generate_ray and connect read their lens sample (the thin lens): integrators
    /// draw two numbers for it after the film position only then, so that the pinhole's and
    /// the orthographic camera's random-number layouts are unchanged.
    bool needs_lens_sample() const { return projection_ == Projection::ThinLens; }

    /// Ray through a position on the full film, in pixels ((0,0) = top-left corner); `u_lens`
    /// (uniform on the unit square) picks the point on a thin lens (concentric map, as
    /// Mitsuba), unread by the other projections.
    Ray generate_ray(const Vec2f& film_position, const Vec2f& u_lens = Vec2f(0.5f, 0.5f)) const;
    /// generate_ray for many film positions at once, in SIMD lanes (the path tracer's camera
    /// rays, a wavefront at a time): rays[i] is generate_ray({film_x[i], film_y[i]}) bit for
    /// bit, on every instruction set. Pinhole only (the others take the scalar generate_ray).
    /// film_x and film_y have the same size; rays at least it.
    void generate_rays(std::span<const float> film_x, std::span<const float> film_y,
                       std::span<Ray> rays, SimdIsa isa = best_simd_isa()) const;

    /// The camera's view of world point `p`, through the lens point `u_lens` chooses (thin
    /// lens): invalid when `p` lies nearer than the near clip plane (camera rays start there),
    /// beyond the far clip plane (they end there) or outside the crop window.
    CameraConnection connect(const Vec3f& p, const Vec2f& u_lens = Vec2f(0.5f, 0.5f)) const;

    /// Solid-angle density with which generate_ray from the pinhole, at film positions
    /// uniform over the crop window, produces world direction `w` (unit): W(w) / (crop pixel
    /// count); 0 outside. Pinhole only (the projector's).
    float pdf_direction_solid_angle(const Vec3f& w) const;

    /// Mitsuba's far_clip: camera rays end at this camera-space depth (what lies beyond is not
    /// seen; a ray that meets nothing before it sees the environment, as in Mitsuba). Infinite
    /// unless set; scene files default to Mitsuba's 1e4.
    void set_far_clip(float far_clip) { far_clip_ = far_clip; }
    float far_clip() const { return far_clip_; }
    /// Area density at `p` (geometric normal `n`) of a camera ray that starts at the camera
    /// end `camera_p` (the pinhole, the ray's lens point, or for the orthographic camera any
    /// point of the ray), for film positions uniform over the crop window: the first vertex's
    /// density in BDPT's MIS. For an environment direction (`at_infinity`, `p` unused, the unit
    /// direction in `n`): the solid-angle density, 0 for the orthographic camera.
    float pdf_area(const Vec3f& camera_p, const Vec3f& p, const Vec3f& n,
                   bool at_infinity = false) const;

    /// The world point camera rays through lens sample `u_lens` leave from (before they move
    /// forward to the near clip plane): the pinhole, or the thin lens's point. The
    /// orthographic camera's rays each have their own (their origins).
    Vec3f lens_position(const Vec2f& u_lens) const {
        return projection_ == Projection::ThinLens
                   ? world_from_camera_.apply_point(lens_point(u_lens))
                   : position_;
    }

    /// The camera's end of a camera ray that starts at `ray_origin` through lens sample
    /// `u_lens` (Camera::pdf_area's camera_p, BDPT's camera vertex): lens_position, or the
    /// orthographic ray's own origin.
    Vec3f camera_end(const Vec3f& ray_origin, const Vec2f& u_lens) const {
        return projection_ == Projection::Orthographic ? ray_origin : lens_position(u_lens);
    }

    const Film& film() const { return film_; }
    /// Changes only how samples are weighed into pixels, not the rays.
    void set_film_filter(const PixelFilter& filter) { film_.filter = filter; }
    const Transform& world_from_camera() const { return world_from_camera_; }
    /// The pinhole, the lens centre, or the orthographic camera's origin.
    Vec3f position() const { return position_; }
    float tan_half_fov_x() const { return tan_half_fov_x_; }
    float tan_half_fov_y() const { return tan_half_fov_y_; }

  private:
    Projection projection_ = Projection::Pinhole;
    Transform world_from_camera_;
    Film film_;
    Vec3f position_ = Vec3f::Zero();
    float tan_half_fov_x_ = 1.f, tan_half_fov_y_ = 1.f;
    float near_clip_ = 0.01f;
    float far_clip_ = kInfinity;  // Mitsuba's far_clip (scene files default to its 1e4)
    // For the inverse map (world point -> film): the camera-space axes in world space (the
    // image plane z = 1 is axis_z_ + X axis_x_ + Y axis_y_), the inverse of their matrix, the
    // plane's unit normal and the world area one pixel covers on it. to_world may scale: all
    // of this is in world measure.
    Vec3f axis_x_ = Vec3f::UnitX(), axis_y_ = Vec3f::UnitY(), axis_z_ = Vec3f::UnitZ();
    Mat3f camera_from_world_linear_ = Mat3f::Identity();
    Vec3f plane_normal_ = Vec3f::UnitZ();
    float pixel_area_on_plane_ = 1.f;
    float aperture_radius_ = 0.f, focus_distance_ = 1.f;  // thin lens
    float orthographic_pixel_area_ = 1.f;  // world area of a pixel across the parallel rays
    Vec3f orthographic_direction_ = Vec3f::UnitZ();  // unit, world

    /// Film position and importance of the world direction `d` (any length) from the
    /// pinhole, or importance 0 when it misses the crop window; `camera_z` (optional) gets the
    /// camera-space depth of position_ + d.
    CameraConnection project(const Vec3f& d, float* camera_z) const;
    /// Film position and W of the camera-space direction `d` from the camera-space lens
    /// point `lens` (thin lens), or W = 0 when it misses the crop window.
    CameraConnection project_from_lens(const Vec3f& lens, const Vec3f& d) const;
    /// The orthographic camera's film position of camera-space point `local`, and whether it
    /// lies in the crop window.
    bool orthographic_film_position(const Vec3f& local, Vec2f& film_position) const;
    /// Camera-space lens point of `u_lens` (thin lens).
    Vec3f lens_point(const Vec2f& u_lens) const;
    /// The point (X, Y) of the perspective plane z = 1 a film position maps to: (-ndc_x tan_x,
    /// -ndc_y tan_y) with ndc = 2 film / size - 1 (Mitsuba 3's perspective and thin lens).
    Vec2f plane_from_film(const Vec2f& film_position) const {
        const float ndc_x = 2.f * film_position.x() / static_cast<float>(film_.width) - 1.f;
        const float ndc_y = 2.f * film_position.y() / static_cast<float>(film_.height) - 1.f;
        return {-ndc_x * tan_half_fov_x_, -ndc_y * tan_half_fov_y_};
    }
    /// Its inverse: film = (1 - X / tan) size / 2.
    Vec2f film_from_plane(float x, float y) const {
        return {0.5f * (1.f - x / tan_half_fov_x_) * static_cast<float>(film_.width),
                0.5f * (1.f - y / tan_half_fov_y_) * static_cast<float>(film_.height)};
    }
    bool in_crop_window(float film_x, float film_y) const;
    /// Whether a camera-space depth lies between the clip planes, where camera rays see.
    bool in_depth_range(float camera_z) const {
        return camera_z > near_clip_ && camera_z <= far_clip_;
    }
};

/// The lens sample a camera ray needs: the stream's next two numbers for a thin lens, the
/// lens centre (no numbers drawn) otherwise.
template <typename Stream>
Vec2f draw_lens_sample(const Camera& camera, Stream& stream) {
    return camera.needs_lens_sample() ? Vec2f(stream.next_2d()) : Vec2f(0.5f, 0.5f);
}

}  // namespace gdmlt
