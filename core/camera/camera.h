// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Pinhole perspective camera with Mitsuba's conventions: in camera space the camera looks
// along +z, +y is up and +x is to the left, so raster x grows towards -x.
#include "core/geometry/ray.h"
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
};

class PerspectiveCamera {
  public:
    PerspectiveCamera() = default;
    /// `fov_deg` along `fov_axis` ("x", "y", "diagonal", "smaller", "larger").
    PerspectiveCamera(const Transform& world_from_camera, const Film& film, float fov_deg,
                      const std::string& fov_axis, float near_clip);

    /// Ray through a position on the full film, in pixels ((0,0) = top-left corner).
    Ray generate_ray(const Vec2f& film_position) const;

    const Film& film() const { return film_; }
    const Transform& world_from_camera() const { return world_from_camera_; }
    Vec3f position() const { return position_; }
    float tan_half_fov_x() const { return tan_half_fov_x_; }
    float tan_half_fov_y() const { return tan_half_fov_y_; }

  private:
    Transform world_from_camera_;
    Film film_;
    Vec3f position_ = Vec3f::Zero();
    float tan_half_fov_x_ = 1.f, tan_half_fov_y_ = 1.f;
    float near_clip_ = 0.01f;
};

}  // namespace gdmlt
