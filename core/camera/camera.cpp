// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/camera/camera.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace gdmlt {

PerspectiveCamera::PerspectiveCamera(const Transform& world_from_camera, const Film& film,
                                     float fov_deg, const std::string& fov_axis, float near_clip)
    : world_from_camera_(world_from_camera), film_(film), near_clip_(near_clip) {
    position_ = world_from_camera_.apply_point(Vec3f(Vec3f::Zero()));
    const float aspect = static_cast<float>(film.width) / static_cast<float>(film.height);
    const float tan_half = std::tan(degrees_to_radians(fov_deg) * 0.5f);
    // Mitsuba 3's fov_axis: which film extent the field of view refers to.
    std::string axis = fov_axis;
    if (axis == "smaller") axis = aspect > 1.f ? "y" : "x";
    if (axis == "larger") axis = aspect > 1.f ? "x" : "y";
    if (axis == "x") {
        tan_half_fov_x_ = tan_half;
        tan_half_fov_y_ = tan_half / aspect;
    } else if (axis == "y") {
        tan_half_fov_y_ = tan_half;
        tan_half_fov_x_ = tan_half * aspect;
    } else if (axis == "diagonal") {
        const float diagonal = std::sqrt(1.f + aspect * aspect);
        tan_half_fov_x_ = tan_half * aspect / diagonal;
        tan_half_fov_y_ = tan_half / diagonal;
    } else {
        throw std::invalid_argument("unknown fov_axis '" + fov_axis + "'");
    }
    axis_x_ = world_from_camera_.apply_vector(Vec3f(Vec3f::UnitX()));
    axis_y_ = world_from_camera_.apply_vector(Vec3f(Vec3f::UnitY()));
    axis_z_ = world_from_camera_.apply_vector(Vec3f(Vec3f::UnitZ()));
    camera_from_world_linear_ = world_from_camera_.inverse.topLeftCorner<3, 3>().cast<float>();
    const Vec3f plane_cross = axis_x_.cross(axis_y_);
    plane_normal_ = plane_cross.normalized();
    // generate_ray: camera-space plane point (X, Y) = (-ndc_x tan_x, -ndc_y tan_y) with
    // ndc = 2 film / size - 1, so one pixel spans 2 tan_x / width by 2 tan_y / height there,
    // and |axis_x x axis_y| world area per unit of camera-plane area.
    pixel_area_on_plane_ = plane_cross.norm() *
                           (2.f * tan_half_fov_x_ / static_cast<float>(film.width)) *
                           (2.f * tan_half_fov_y_ / static_cast<float>(film.height));
}

Ray PerspectiveCamera::generate_ray(const Vec2f& film_position) const {
    const float ndc_x = 2.f * film_position.x() / static_cast<float>(film_.width) - 1.f;
    const float ndc_y = 2.f * film_position.y() / static_cast<float>(film_.height) - 1.f;
    const Vec3f d_camera(-ndc_x * tan_half_fov_x_, -ndc_y * tan_half_fov_y_, 1.f);
    const Vec3f d_world = world_from_camera_.apply_vector(d_camera).normalized();
    // near_clip is a distance along the optical axis (z = 1 in d_camera), as in Mitsuba.
    const float t_near = near_clip_ * d_camera.norm();
    Ray ray;
    ray.origin = position_ + d_world * t_near;
    ray.direction = d_world;
    ray.t_max = kInfinity;
    return ray;
}

CameraConnection PerspectiveCamera::project(const Vec3f& d, float* camera_z) const {
    CameraConnection c;
    const Vec3f local = camera_from_world_linear_ * d;
    if (camera_z) *camera_z = local.z();
    if (!(local.z() > 0.f)) return c;
    const float x = local.x() / local.z(), y = local.y() / local.z();
    // generate_ray inverted: ndc = -X / tan_half_fov, film = (ndc + 1) size / 2.
    const float film_x = 0.5f * (1.f - x / tan_half_fov_x_) * static_cast<float>(film_.width);
    const float film_y = 0.5f * (1.f - y / tan_half_fov_y_) * static_cast<float>(film_.height);
    const float x0 = static_cast<float>(film_.crop_offset_x),
                y0 = static_cast<float>(film_.crop_offset_y);
    if (!(film_x >= x0 && film_x < x0 + static_cast<float>(film_.crop_width) && film_y >= y0 &&
          film_y < y0 + static_cast<float>(film_.crop_height)))
        return c;
    // dw = dA_plane |cos| / |q|^2 for the plane point q in direction w (Veach 1997, eq. 4.4
    // with the plane as the surface), so W = dA_pixel / dw = |q|^2 / (A_pixel |cos|); for a
    // rigid to_world that is 1 / (A_pixel cos^3 theta).
    const Vec3f q = axis_z_ + x * axis_x_ + y * axis_y_;
    const float q_length = q.norm();
    const float cos_plane = std::abs(q.dot(plane_normal_)) / q_length;
    c.film_position = Vec2f(film_x, film_y);
    c.direction = q / q_length;
    c.importance = q_length * q_length / (pixel_area_on_plane_ * cos_plane);
    if (!std::isfinite(c.importance)) c.importance = 0.f;
    return c;
}

CameraConnection PerspectiveCamera::connect(const Vec3f& p) const {
    const Vec3f d = p - position_;
    float camera_z = 0.f;
    CameraConnection c = project(d, &camera_z);
    // Camera rays start on the plane z = near_clip in camera space (generate_ray): nothing
    // nearer is seen.
    if (!(camera_z > near_clip_)) return CameraConnection{};
    c.distance = d.norm();
    return c;
}

float PerspectiveCamera::pdf_direction_solid_angle(const Vec3f& w) const {
    const CameraConnection c = project(w, nullptr);
    return c.importance /
           (static_cast<float>(film_.crop_width) * static_cast<float>(film_.crop_height));
}

}  // namespace gdmlt
