// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/camera/camera.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/sampling/warp.h"

namespace gdmlt {
namespace {

/// What generate_rays' kernel needs of the camera.
struct CameraRayConstants {
    float width = 0.f, height = 0.f;  // full film, pixels
    float tan_x = 0.f, tan_y = 0.f;   // tangents of the half fields of view
    float near_clip = 0.f, far_clip = 0.f;
    double m[3][3] = {};  // world_from_camera's linear part, row by row
    float position[3] = {};
};

// The kernel, compiled for each instruction set of core/math/simd.h (simd_targets.inc).
#define GDMLT_SIMD_KERNEL "core/camera/camera_lanes_kernel.inc"
#include "core/math/simd_targets.inc"
#undef GDMLT_SIMD_KERNEL

}  // namespace

Camera::Camera(const Transform& world_from_camera, const Film& film, float fov_deg,
               const std::string& fov_axis, float near_clip)
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

Ray Camera::generate_ray(const Vec2f& film_position, const Vec2f& u_lens) const {
    if (projection_ == Projection::ThinLens) {
        // Mitsuba 3's thinlens.cpp sample_ray: from the lens point towards the point the
        // pinhole ray of this film position meets on the focus plane (camera z =
        // focus_distance), starting on the near clip plane.
        const Vec2f plane = plane_from_film(film_position);
        const Vec3f focus(plane.x() * focus_distance_, plane.y() * focus_distance_,
                          focus_distance_);
        const Vec3f lens = lens_point(u_lens);
        const Vec3f d_camera = (focus - lens).normalized();
        Ray ray;
        ray.direction = world_from_camera_.apply_vector(d_camera).normalized();
        const float t_near = near_clip_ / d_camera.z();
        ray.origin = world_from_camera_.apply_point(lens) + ray.direction * t_near;
        ray.t_max = far_clip_ / d_camera.z() - t_near;
        return ray;
    }
    if (projection_ == Projection::Orthographic) {
        // Mitsuba 3's orthographic.cpp: film [0, width] x [0, height] onto camera x in [1, -1],
        // y in [1, -1] / aspect, on the plane z = near_clip.
        const float aspect = static_cast<float>(film_.width) / static_cast<float>(film_.height);
        const Vec3f local(
            1.f - 2.f * film_position.x() / static_cast<float>(film_.width),
            (1.f - 2.f * film_position.y() / static_cast<float>(film_.height)) / aspect,
            near_clip_);
        Ray ray;
        ray.origin = world_from_camera_.apply_point(local);
        ray.direction = orthographic_direction_;
        ray.t_max = far_clip_ - near_clip_;
        return ray;
    }
    // Written out operation by operation (not with Eigen's product and normalized()), so that
    // generate_rays' SIMD lanes can repeat it in the same order and round alike. The
    // camera-space direction is (dx, dy, 1).
    const Vec2f plane = plane_from_film(film_position);
    const float dx = plane.x(), dy = plane.y();
    // Rotated by world_from_camera's linear part in double, as Transform::apply_vector does,
    // then rounded to float; the z term is m(r, 2) * 1 = m(r, 2).
    const Eigen::Matrix4d& m = world_from_camera_.matrix;
    const auto row = [&](int r) {
        return static_cast<float>(
            (m(r, 0) * static_cast<double>(dx) + m(r, 1) * static_cast<double>(dy)) + m(r, 2));
    };
    Vec3f d_world(row(0), row(1), row(2));
    // Normalised; a zero vector stays as it is (Eigen's normalized() does the same).
    const float squared =
        d_world.x() * d_world.x() + (d_world.y() * d_world.y() + d_world.z() * d_world.z());
    if (squared > 0.f) {
        const float length = std::sqrt(squared);
        d_world = Vec3f(d_world.x() / length, d_world.y() / length, d_world.z() / length);
    }
    // near_clip and far_clip are depths along the optical axis (z = 1 in camera space), as in
    // Mitsuba: the ray runs between the two planes.
    const float length_per_depth = std::sqrt(dx * dx + (dy * dy + 1.f));
    const float t_near = near_clip_ * length_per_depth;
    Ray ray;
    ray.origin = Vec3f(position_.x() + d_world.x() * t_near, position_.y() + d_world.y() * t_near,
                       position_.z() + d_world.z() * t_near);
    ray.direction = d_world;
    ray.t_max = far_clip_ * length_per_depth - t_near;
    return ray;
}

void Camera::generate_rays(std::span<const float> film_x, std::span<const float> film_y,
                           std::span<Ray> rays, SimdIsa isa) const {
    if (film_y.size() != film_x.size() || rays.size() < film_x.size())
        throw std::invalid_argument("generate_rays: film_x, film_y and rays differ in size");
    if (projection_ != Projection::Pinhole)
        throw std::logic_error("generate_rays: the lanes know the pinhole only");
    CameraRayConstants c;
    c.width = static_cast<float>(film_.width);
    c.height = static_cast<float>(film_.height);
    c.tan_x = tan_half_fov_x_;
    c.tan_y = tan_half_fov_y_;
    c.near_clip = near_clip_;
    c.far_clip = far_clip_;
    for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) c.m[r][k] = world_from_camera_.matrix(r, k);
        c.position[r] = position_[r];
    }
    const std::size_t count = film_x.size();
    switch (isa) {
        case SimdIsa::Avx512:
            avx512::generate_rays(c, count, film_x.data(), film_y.data(), rays.data());
            break;
        case SimdIsa::Avx2:
            avx2::generate_rays(c, count, film_x.data(), film_y.data(), rays.data());
            break;
        case SimdIsa::Baseline:
            baseline::generate_rays(c, count, film_x.data(), film_y.data(), rays.data());
            break;
    }
}

CameraConnection Camera::project(const Vec3f& d, float* camera_z) const {
    CameraConnection c;
    const Vec3f local = camera_from_world_linear_ * d;
    if (camera_z) *camera_z = local.z();
    if (!(local.z() > 0.f)) return c;
    const float x = local.x() / local.z(), y = local.y() / local.z();
    const Vec2f film = film_from_plane(x, y);  // generate_ray inverted
    if (!in_crop_window(film.x(), film.y())) return c;
    // dw = dA_plane |cos| / |q|^2 for the plane point q in direction w (Veach 1997, eq. 4.4
    // with the plane as the surface), so W = dA_pixel / dw = |q|^2 / (A_pixel |cos|); for a
    // rigid to_world that is 1 / (A_pixel cos^3 theta).
    const Vec3f q = axis_z_ + x * axis_x_ + y * axis_y_;
    const float q_length = q.norm();
    const float cos_plane = std::abs(q.dot(plane_normal_)) / q_length;
    c.film_position = film;
    c.direction = q / q_length;
    c.importance = q_length * q_length / (pixel_area_on_plane_ * cos_plane);
    if (!std::isfinite(c.importance)) c.importance = 0.f;
    return c;
}

CameraConnection Camera::connect(const Vec3f& p, const Vec2f& u_lens) const {
    if (projection_ == Projection::ThinLens) {
        const Vec3f local = world_from_camera_.apply_inverse_point(p);
        if (!in_depth_range(local.z())) return CameraConnection{};
        const Vec3f lens = lens_point(u_lens);
        CameraConnection c = project_from_lens(lens, local - lens);
        if (!(c.importance > 0.f)) return CameraConnection{};
        c.position = world_from_camera_.apply_point(lens);
        const Vec3f d = p - c.position;
        c.distance = d.norm();
        if (!(c.distance > 0.f)) return CameraConnection{};
        c.direction = d / c.distance;
        c.weight = c.importance / (c.distance * c.distance);
        if (!std::isfinite(c.weight)) return CameraConnection{};
        return c;
    }
    if (projection_ == Projection::Orthographic) {
        // The one ray through `p`: it starts where p's camera-space (x, y) meet the near plane.
        const Vec3f local = world_from_camera_.apply_inverse_point(p);
        CameraConnection c;
        if (!in_depth_range(local.z()) || !orthographic_film_position(local, c.film_position))
            return c;
        c.position = world_from_camera_.apply_point(Vec3f(local.x(), local.y(), near_clip_));
        c.direction = orthographic_direction_;
        c.distance = (p - c.position).norm();
        c.importance = c.weight = 1.f / orthographic_pixel_area_;
        return c;
    }
    const Vec3f d = p - position_;
    float camera_z = 0.f;
    CameraConnection c = project(d, &camera_z);
    // Camera rays run from the plane z = near_clip to z = far_clip in camera space
    // (generate_ray): nothing nearer or farther is seen.
    if (!in_depth_range(camera_z)) return CameraConnection{};
    c.position = position_;
    c.distance = d.norm();
    c.weight = c.importance / (c.distance * c.distance);
    if (!std::isfinite(c.weight)) return CameraConnection{};
    return c;
}

float Camera::pdf_direction_solid_angle(const Vec3f& w) const {
    const CameraConnection c = project(w, nullptr);
    return c.importance /
           (static_cast<float>(film_.crop_width) * static_cast<float>(film_.crop_height));
}

float Camera::pdf_area(const Vec3f& camera_p, const Vec3f& p, const Vec3f& n,
                       bool at_infinity) const {
    const float pixels =
        static_cast<float>(film_.crop_width) * static_cast<float>(film_.crop_height);
    // Camera rays never reach a point outside the clip planes.
    if (!at_infinity && !in_depth_range(world_from_camera_.apply_inverse_point(p).z())) return 0.f;
    if (projection_ == Projection::Orthographic) {
        if (at_infinity) return 0.f;  // parallel rays: a delta in direction
        Vec2f film_position;
        if (!orthographic_film_position(world_from_camera_.apply_inverse_point(p), film_position))
            return 0.f;
        // Ray origins uniform over the crop window's world area A = pixels * pixel area,
        // projected along the rays onto the surface: density |cos| / A.
        return std::abs(n.dot(orthographic_direction_)) / (orthographic_pixel_area_ * pixels);
    }
    const Vec3f d = at_infinity ? n : Vec3f(p - camera_p);
    float importance = 0.f;
    if (projection_ == Projection::ThinLens) {
        const Vec3f lens = world_from_camera_.apply_inverse_point(camera_p);
        importance = project_from_lens(lens, world_from_camera_.apply_inverse_vector(d)).importance;
    } else {
        importance = project(d, nullptr).importance;
    }
    const float pdf_solid_angle = importance / pixels;
    if (at_infinity) return pdf_solid_angle;
    const float distance2 = d.squaredNorm();
    if (!(distance2 > 0.f)) return 0.f;
    return pdf_solid_angle * std::abs(n.dot(d)) / (distance2 * std::sqrt(distance2));
}

Camera Camera::thin_lens(const Transform& world_from_camera, const Film& film, float fov_deg,
                         const std::string& fov_axis, float near_clip, float aperture_radius,
                         float focus_distance) {
    Camera camera(world_from_camera, film, fov_deg, fov_axis, near_clip);
    camera.projection_ = Projection::ThinLens;
    camera.aperture_radius_ = aperture_radius;
    camera.focus_distance_ = focus_distance;
    return camera;
}

Camera Camera::orthographic(const Transform& world_from_camera, const Film& film, float near_clip) {
    Camera camera(world_from_camera, film, 90.f, "x", near_clip);
    camera.projection_ = Projection::Orthographic;
    camera.position_ = world_from_camera.apply_point(Vec3f(0.f, 0.f, near_clip));
    camera.orthographic_direction_ = camera.axis_z_.normalized();
    // A pixel is 2 / width by 2 / (aspect height) in camera x and y; in world, the
    // parallelogram of axis_x and axis_y, seen across the rays.
    const float aspect = static_cast<float>(film.width) / static_cast<float>(film.height);
    const Vec3f cross = camera.axis_x_.cross(camera.axis_y_);
    camera.orthographic_pixel_area_ = std::abs(cross.dot(camera.orthographic_direction_)) *
                                      (2.f / static_cast<float>(film.width)) *
                                      (2.f / (aspect * static_cast<float>(film.height)));
    return camera;
}

bool Camera::in_crop_window(float film_x, float film_y) const {
    const float x0 = static_cast<float>(film_.crop_offset_x),
                y0 = static_cast<float>(film_.crop_offset_y);
    return film_x >= x0 && film_x < x0 + static_cast<float>(film_.crop_width) && film_y >= y0 &&
           film_y < y0 + static_cast<float>(film_.crop_height);
}

Vec3f Camera::lens_point(const Vec2f& u_lens) const {
    const Vec2f disk = warp::square_to_uniform_disk_concentric(u_lens) * aperture_radius_;
    return {disk.x(), disk.y(), 0.f};
}

CameraConnection Camera::project_from_lens(const Vec3f& lens, const Vec3f& d) const {
    CameraConnection c;
    if (!(d.z() > 0.f)) return c;
    // Where the ray meets the focus plane, as a point of the pinhole's plane z = 1.
    const float t = focus_distance_ / d.z();
    const float x = (lens.x() + t * d.x()) / focus_distance_;
    const float y = (lens.y() + t * d.y()) / focus_distance_;
    const Vec2f film = film_from_plane(x, y);
    if (!in_crop_window(film.x(), film.y())) return c;
    // W = dA_film / dw at the lens point: the focus plane's pixel (focus_distance^2 times the
    // plane z = 1's) seen at distance focus_distance / cos theta and angle theta, so
    // W = 1 / (A_pixel cos^3 theta) as for the pinhole (Mitsuba 3's thinlens importance).
    const float cos_theta = d.z() / d.norm();
    c.film_position = film;
    c.importance = 1.f / (pixel_area_on_plane_ * cos_theta * cos_theta * cos_theta);
    if (!std::isfinite(c.importance)) c.importance = 0.f;
    return c;
}

bool Camera::orthographic_film_position(const Vec3f& local, Vec2f& film_position) const {
    const float aspect = static_cast<float>(film_.width) / static_cast<float>(film_.height);
    const float film_x = 0.5f * (1.f - local.x()) * static_cast<float>(film_.width);
    const float film_y = 0.5f * (1.f - local.y() * aspect) * static_cast<float>(film_.height);
    film_position = Vec2f(film_x, film_y);
    return in_crop_window(film_x, film_y);
}

}  // namespace gdmlt
