// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/camera/camera.h"

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

}  // namespace gdmlt
