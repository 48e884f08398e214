// SPDX-License-Identifier: GPL-3.0-or-later
// The cameras as endpoints for light paths (the pinhole, the thin lens, the orthographic):
// connect() inverts generate_ray, and its importance integrates to one per pixel, measured with
// directions that know nothing of the camera. Together they are the goodness-of-fit test of
// generate_ray's direction density (pdf_direction_solid_angle = importance / pixel count): a
// chi-square over sphere bins does not work here, since the window's sharp edges cut bins into
// slivers that numerical integration of the expected counts misses.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <vector>

#include "core/camera/camera.h"
#include "core/math/frame.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "tests/support/chi2.h"

namespace gdmlt {
namespace {

/// A 40 x 30 film rendering the 20 x 16 window at (5, 4), 70 degrees along x, near clip 0.5.
/// `stretched` adds a non-uniform scale to to_world (generate_ray normalises, so the mapping
/// from film to directions changes and the importance must follow it in world measure).
Camera test_camera(bool stretched) {
    Film film;
    film.width = 40;
    film.height = 30;
    film.crop_offset_x = 5;
    film.crop_offset_y = 4;
    film.crop_width = 20;
    film.crop_height = 16;
    Mat4d m = Mat4d::Identity();
    m.topLeftCorner<3, 3>() =
        Eigen::AngleAxisd(0.8, Vec3d(0.3, 1.0, -0.2).normalized()).toRotationMatrix();
    if (stretched) m.topLeftCorner<3, 3>() *= Vec3d(1.0, 1.6, 0.7).asDiagonal();
    m.topRightCorner<3, 1>() = Vec3d(0.5, -1.0, 2.0);
    return Camera(Transform(m), film, 70.f, "x", 0.5f);
}

Vec2f random_crop_position(const Film& film, Pcg32& rng) {
    return {static_cast<float>(film.crop_offset_x) + rng.next_float() * film.crop_width,
            static_cast<float>(film.crop_offset_y) + rng.next_float() * film.crop_height};
}

TEST(CameraImportance, ConnectInvertsGenerateRay) {
    for (const bool stretched : {false, true}) {
        const Camera camera = test_camera(stretched);
        Pcg32 rng(3, 1);
        for (int i = 0; i < 2000; ++i) {
            const Vec2f film_position = random_crop_position(camera.film(), rng);
            const Ray ray = camera.generate_ray(film_position);
            const Vec3f p = ray.origin + ray.direction * (0.1f + 20.f * rng.next_float());
            const CameraConnection c = camera.connect(p);
            ASSERT_TRUE(c.valid()) << i;
            EXPECT_NEAR(c.film_position.x(), film_position.x(), 2e-3f) << i;
            EXPECT_NEAR(c.film_position.y(), film_position.y(), 2e-3f) << i;
            EXPECT_NEAR((c.direction - ray.direction).norm(), 0.f, 1e-5f) << i;
            EXPECT_NEAR(c.distance, (p - camera.position()).norm(), 1e-4f * c.distance) << i;
        }
        // Outside the crop window (film position 2, on the film but left of it), behind the
        // camera, and nearer than the near clip plane: nothing.
        const Ray left = camera.generate_ray(Vec2f(2.f, 10.f));
        EXPECT_FALSE(camera.connect(left.origin + 3.f * left.direction).valid());
        const Ray centre = camera.generate_ray(Vec2f(15.f, 12.f));
        EXPECT_FALSE(camera.connect(camera.position() - 3.f * centre.direction).valid());
        const Vec3f too_near = camera.position() + 0.2f * (centre.origin - camera.position());
        EXPECT_FALSE(camera.connect(too_near).valid());
        EXPECT_TRUE(
            camera.connect(camera.position() + 2.f * (centre.origin - camera.position())).valid());
    }
}

/// Per-pixel Monte Carlo integrals (sums of n estimates and of their squares) that should
/// each be 1: every pixel within 5 standard errors, the window's total within 4, and every
/// pixel's standard error below 3% (else there were too few samples to tell).
void expect_one_per_pixel(const std::vector<double>& sum, const std::vector<double>& sum2, int n) {
    double total = 0.0, total_var = 0.0;
    for (std::size_t k = 0; k < sum.size(); ++k) {
        const double mean = sum[k] / n;
        const double var = (sum2[k] / n - mean * mean) / (n - 1);
        total += mean;
        total_var += var;
        EXPECT_NEAR(mean, 1.0, 5.0 * std::sqrt(var)) << "pixel " << k;
        ASSERT_LT(std::sqrt(var), 0.03) << "too few samples to tell";
    }
    EXPECT_NEAR(total, static_cast<double>(sum.size()), 4.0 * std::sqrt(total_var));
}

/// W = dA_film / dw at the camera point `origin` (the pinhole, or a thin lens's point), so its
/// integral over the directions that land in a pixel is the pixel's area, 1. Directions
/// uniform in a cone about the window centre's direction (Pcg32 seed 5, 8M of them: at least
/// 2000 per pixel with this cone) know nothing of the projection; each pixel's Monte Carlo
/// integral has a relative standard error ~1.5%. Every pixel must lie within 5 standard
/// errors (320 pixels: a false alarm has probability 2e-4), and the whole window's integral
/// (SE 0.1%) within 4. `connect(p)` is the camera's view of world point p through that point.
template <typename Connect>
void expect_importance_one_per_pixel(const Camera& camera, const Vec3f& origin, const Vec3f& axis,
                                     const Connect& connect) {
    const Film& film = camera.film();
    const float cos_max = 0.5f;  // 60 degrees: wider than the window's farthest corner
    const Frame frame = Frame::from_normal(axis);
    const double pdf = warp::square_to_uniform_cone_pdf_solid_angle(cos_max);
    const int pixels = film.crop_width * film.crop_height;
    std::vector<double> sum(static_cast<std::size_t>(pixels), 0.0),
        sum2(static_cast<std::size_t>(pixels), 0.0);
    Pcg32 rng(5, 1);
    const int n = 8000000;
    for (int i = 0; i < n; ++i) {
        const Vec3f w = frame.to_world(
            warp::square_to_uniform_cone({rng.next_float(), rng.next_float()}, cos_max));
        const Vec3f p = origin + 10.f * w;
        const CameraConnection c = connect(p);
        if (!c.valid()) continue;
        const int x = static_cast<int>(std::floor(c.film_position.x())) - film.crop_offset_x;
        const int y = static_cast<int>(std::floor(c.film_position.y())) - film.crop_offset_y;
        ASSERT_TRUE(x >= 0 && x < film.crop_width && y >= 0 && y < film.crop_height);
        // BDPT's density of the first vertex: W / pixels in solid angle, to area at p.
        const Vec3f n_p = Vec3f(0.3f, -0.8f, 0.5f).normalized();
        ASSERT_NEAR(camera.pdf_area(c.position, p, n_p),
                    c.importance / static_cast<float>(pixels) * std::abs(n_p.dot(w)) / 100.f,
                    1e-5f * c.importance / static_cast<float>(pixels));
        ASSERT_NEAR(c.weight, c.importance / (c.distance * c.distance), 1e-5f * c.weight);
        ASSERT_NEAR((c.position - origin).norm(), 0.f, 1e-5f);
        const double v = c.importance / pdf;
        sum[static_cast<std::size_t>(y * film.crop_width + x)] += v;
        sum2[static_cast<std::size_t>(y * film.crop_width + x)] += v * v;
        // The cone must contain the whole window, or the integral would be short.
        ASSERT_GT(w.dot(axis), cos_max + 0.05f);
    }
    expect_one_per_pixel(sum, sum2, n);
}

TEST(CameraImportance, IntegratesToOnePerPixel) {
    // A cos^2 instead of the cos^3 of a rigid camera is 9% off at this window's corners: 6
    // standard errors (expect_importance_one_per_pixel).
    for (const bool stretched : {false, true}) {
        const Camera camera = test_camera(stretched);
        const Vec3f axis =
            (camera.generate_ray(Vec2f(15.f, 12.f)).direction).normalized();  // window centre
        expect_importance_one_per_pixel(camera, camera.position(), axis, [&](const Vec3f& p) {
            const CameraConnection c = camera.connect(p);
            if (c.valid()) {
                EXPECT_NEAR(camera.pdf_direction_solid_angle(c.direction), c.importance / 320.f,
                            1e-5f * c.importance);
            }
            return c;
        });
    }
}

/// test_camera's film and rigid pose as a thin lens: aperture radius 0.3, focused at 4.
Camera test_thin_lens() {
    const Camera pinhole = test_camera(false);
    return Camera::thin_lens(pinhole.world_from_camera(), pinhole.film(), 70.f, "x", 0.5f, 0.3f,
                             4.f);
}

/// test_camera's film and stretched pose (a non-uniform scale and a rotation) as an
/// orthographic camera.
Camera test_orthographic() {
    const Camera pinhole = test_camera(true);
    return Camera::orthographic(pinhole.world_from_camera(), pinhole.film(), 0.5f);
}

TEST(ThinLens, ConnectInvertsGenerateRayThroughTheSameLensPoint) {
    const Camera camera = test_thin_lens();
    ASSERT_TRUE(camera.needs_lens_sample());
    Pcg32 rng(3, 2);
    for (int i = 0; i < 2000; ++i) {
        const Vec2f film_position = random_crop_position(camera.film(), rng);
        const Vec2f u_lens(rng.next_float(), rng.next_float());
        const Ray ray = camera.generate_ray(film_position, u_lens);
        const Vec3f p = ray.origin + ray.direction * (0.1f + 20.f * rng.next_float());
        const CameraConnection c = camera.connect(p, u_lens);
        ASSERT_TRUE(c.valid()) << i;
        EXPECT_NEAR(c.film_position.x(), film_position.x(), 2e-3f) << i;
        EXPECT_NEAR(c.film_position.y(), film_position.y(), 2e-3f) << i;
        EXPECT_NEAR((c.direction - ray.direction).norm(), 0.f, 1e-5f) << i;
        // The ray leaves the lens point and starts on the near clip plane.
        EXPECT_NEAR((c.position - camera.lens_position(u_lens)).norm(), 0.f, 1e-5f) << i;
        EXPECT_NEAR((ray.origin - c.position).cross(ray.direction).norm(), 0.f, 1e-5f) << i;
        const Vec3f local = camera.world_from_camera().apply_inverse_point(ray.origin);
        EXPECT_NEAR(local.z(), 0.5f, 1e-5f) << i;
    }
    // Points in the focus plane are sharp: every lens point sees them at the same film position.
    const Ray centre = camera.generate_ray(Vec2f(12.f, 9.f));
    const Vec3f local_dir = camera.world_from_camera().apply_inverse_vector(centre.direction);
    const Vec3f focused =
        camera.lens_position(Vec2f(0.5f, 0.5f)) + centre.direction * (4.f / local_dir.z());
    for (const Vec2f& u : {Vec2f(0.1f, 0.2f), Vec2f(0.9f, 0.5f), Vec2f(0.4f, 0.95f)}) {
        const CameraConnection c = camera.connect(focused, u);
        ASSERT_TRUE(c.valid());
        EXPECT_NEAR(c.film_position.x(), 12.f, 2e-3f);
        EXPECT_NEAR(c.film_position.y(), 9.f, 2e-3f);
    }
    // Nearer than the near clip plane, or outside the window: nothing.
    EXPECT_FALSE(camera.connect(camera.position() + 0.2f * centre.direction).valid());
    const Ray left = camera.generate_ray(Vec2f(2.f, 10.f), Vec2f(0.5f, 0.5f));
    EXPECT_FALSE(camera.connect(left.origin + 3.f * left.direction).valid());
}

TEST(ThinLens, ImportanceIntegratesToOnePerPixelFromEveryLensPoint) {
    // As the pinhole's (expect_importance_one_per_pixel), from the lens centre, a point near
    // its rim and one between: W at a lens point is the pinhole's formula there (the film
    // maps onto the focus plane); measuring it from the lens centre's formula, or forgetting
    // the focus plane, puts the far lens points' pixels off by the shift of the window.
    const Camera camera = test_thin_lens();
    for (const Vec2f& u_lens : {Vec2f(0.5f, 0.5f), Vec2f(0.98f, 0.5f), Vec2f(0.2f, 0.7f)}) {
        SCOPED_TRACE(testing::Message() << "lens sample " << u_lens.transpose());
        const Vec3f origin = camera.lens_position(u_lens);
        const Vec3f axis = camera.generate_ray(Vec2f(15.f, 12.f), u_lens).direction;
        expect_importance_one_per_pixel(camera, origin, axis,
                                        [&](const Vec3f& p) { return camera.connect(p, u_lens); });
    }
}

TEST(ThinLens, LensPointsOfItsRaysAreUniformOnTheDiskChiSquare) {
    // Where generate_ray's rays cross the lens plane (camera z = 0), found from the rays
    // themselves: uniform on the disk of radius 0.3, whatever the film position. Binned in
    // (r^2 / R^2, phi), 10 x 16 equal-area bins, so every bin expects N / 160 exactly (no
    // numerical integration at the disk's edge). Pcg32 seed 8, 160k rays at random film
    // positions; alpha 1%. A lens sampled uniformly in radius (points crowd the centre), or
    // the square's corners kept, fails.
    const Camera camera = test_thin_lens();
    const Transform& world_from_camera = camera.world_from_camera();
    Pcg32 rng(8, 1);
    const int n = 160000, radial = 10, angular = 16;
    std::vector<double> observed(static_cast<std::size_t>(radial * angular + 1), 0.0);
    for (int i = 0; i < n; ++i) {
        const Vec2f film_position = random_crop_position(camera.film(), rng);
        const Ray ray =
            camera.generate_ray(film_position, Vec2f(rng.next_float(), rng.next_float()));
        const Vec3f o = world_from_camera.apply_inverse_point(ray.origin);
        const Vec3f d = world_from_camera.apply_inverse_vector(ray.direction);
        const Vec3f l = o - d * (o.z() / d.z());
        const double r2 = l.head<2>().squaredNorm() / 0.09;
        if (!(r2 < 1.0)) {
            observed.back() += 1.0;  // off the disk: expected never
            continue;
        }
        const double phi = std::atan2(l.y(), l.x()) + kPi;
        const int a = std::min(static_cast<int>(r2 * radial), radial - 1);
        const int b = std::min(static_cast<int>(phi / (2.0 * kPi) * angular), angular - 1);
        observed[static_cast<std::size_t>(a * angular + b)] += 1.0;
    }
    std::vector<double> expected(observed.size(), static_cast<double>(n) / (radial * angular));
    expected.back() = 0.0;
    const test::Chi2Result result = test::chi2_histogram_test(observed, expected);
    EXPECT_GT(result.p_value, 0.01) << result.summary;
}

TEST(Orthographic, ConnectInvertsGenerateRayAlongParallelRays) {
    const Camera camera = test_orthographic();
    EXPECT_FALSE(camera.needs_lens_sample());
    Pcg32 rng(3, 4);
    Vec3f first_direction = Vec3f::Zero();
    for (int i = 0; i < 2000; ++i) {
        const Vec2f film_position = random_crop_position(camera.film(), rng);
        const Ray ray = camera.generate_ray(film_position);
        if (i == 0) first_direction = ray.direction;
        EXPECT_NEAR((ray.direction - first_direction).norm(), 0.f, 1e-6f) << i;
        const Vec3f p = ray.origin + ray.direction * (0.1f + 20.f * rng.next_float());
        const CameraConnection c = camera.connect(p);
        ASSERT_TRUE(c.valid()) << i;
        EXPECT_NEAR(c.film_position.x(), film_position.x(), 2e-3f) << i;
        EXPECT_NEAR(c.film_position.y(), film_position.y(), 2e-3f) << i;
        EXPECT_NEAR((c.direction - ray.direction).norm(), 0.f, 1e-5f) << i;
        EXPECT_NEAR((c.position - ray.origin).norm(), 0.f, 1e-4f) << i;
        EXPECT_NEAR(c.distance, (p - ray.origin).norm(), 1e-4f * c.distance) << i;
    }
    // Behind the near plane, or outside the window: nothing.
    const Ray centre = camera.generate_ray(Vec2f(15.f, 12.f));
    EXPECT_FALSE(camera.connect(centre.origin - 0.1f * centre.direction).valid());
    const Ray left = camera.generate_ray(Vec2f(2.f, 10.f));
    EXPECT_FALSE(camera.connect(left.origin + 3.f * left.direction).valid());
}

TEST(Orthographic, ImportanceIntegratesToOnePerPixelOverTheAreaAcrossTheRays) {
    // The parallel rays' W = dA_film / dA_across: its integral over the area across the rays
    // that lands in a pixel is 1. Points uniform on a tilted world rectangle that covers the
    // window (Pcg32 seed 6, 4M) measure it as W |cos| / (1 / area) per point; and pdf_area
    // (BDPT's first-vertex density) must be W |cos| / pixels there. Per-pixel relative
    // standard error ~2.5% with ~1600 points per pixel; bounds as the pinhole's. A pixel area
    // taken in the film plane without the stretch (or without the projection across the rays)
    // is 37% off.
    const Camera camera = test_orthographic();
    const Film& film = camera.film();
    const Vec3f d = camera.generate_ray(Vec2f(15.f, 12.f)).direction;
    const Vec3f centre = camera.generate_ray(Vec2f(15.f, 12.f)).origin + 5.f * d;
    const Vec3f n = (d + Vec3f(0.4f, 0.3f, -0.2f)).normalized();  // tilted off the rays
    const Frame frame = Frame::from_normal(n);
    const float half = 1.5f;  // the rectangle's half side: the window's shadow fits
    const double area = 4.0 * half * half;
    const int pixels = film.crop_width * film.crop_height;
    std::vector<double> sum(static_cast<std::size_t>(pixels), 0.0),
        sum2(static_cast<std::size_t>(pixels), 0.0);
    Pcg32 rng(6, 1);
    const int samples = 4000000;
    int outside_rectangle_edge = 0;
    for (int i = 0; i < samples; ++i) {
        const Vec3f p = centre + frame.to_world(Vec3f((2.f * rng.next_float() - 1.f) * half,
                                                      (2.f * rng.next_float() - 1.f) * half, 0.f));
        const CameraConnection c = camera.connect(p);
        if (!c.valid()) continue;
        const Vec3f local = frame.to_local(p - centre);
        if (std::abs(local.x()) > 0.95f * half || std::abs(local.y()) > 0.95f * half)
            ++outside_rectangle_edge;
        const int x = static_cast<int>(std::floor(c.film_position.x())) - film.crop_offset_x;
        const int y = static_cast<int>(std::floor(c.film_position.y())) - film.crop_offset_y;
        ASSERT_TRUE(x >= 0 && x < film.crop_width && y >= 0 && y < film.crop_height);
        const double cos_p = std::abs(n.dot(d));
        ASSERT_NEAR(camera.pdf_area(c.position, p, n), c.weight * cos_p / pixels,
                    1e-5 * c.weight / pixels);
        const double v = c.weight * cos_p * area;
        sum[static_cast<std::size_t>(y * film.crop_width + x)] += v;
        sum2[static_cast<std::size_t>(y * film.crop_width + x)] += v * v;
    }
    ASSERT_EQ(outside_rectangle_edge, 0) << "the rectangle does not cover the window";
    expect_one_per_pixel(sum, sum2, samples);
}

TEST(CameraRays, LanesAreGenerateRayBitForBit) {
    // generate_rays on every instruction set against generate_ray, all seven floats of every
    // ray compared as bits: both test cameras (the stretched one makes the normalisation do
    // something), without and with a far clip plane, 203 positions (not a multiple of any vector
    // width) over the whole film and beyond it (Pcg32 stream seed 11), its corners and centre, a
    // huge one, and a NaN (which must come out as the scalar code's NaN ray, lane by lane).
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (const float far_clip : {kInfinity, 7.5f})
        for (const bool stretched : {false, true}) {
            Camera camera = test_camera(stretched);
            camera.set_far_clip(far_clip);
            const Film& film = camera.film();
            Pcg32 rng(11, 12);
            std::vector<float> film_x, film_y;
            const auto add = [&](float x, float y) {
                film_x.push_back(x);
                film_y.push_back(y);
            };
            const auto w = static_cast<float>(film.width), h = static_cast<float>(film.height);
            add(0.f, 0.f);
            add(w, h);
            add(w, 0.f);
            add(0.5f * w, 0.5f * h);
            add(1e30f, -1e30f);
            add(nan, 3.f);
            while (film_x.size() < 203)
                add((rng.next_float() * 1.5f - 0.25f) * w, (rng.next_float() * 1.5f - 0.25f) * h);
            for (const SimdIsa isa : available_simd_isas()) {
                SCOPED_TRACE(testing::Message() << "instruction set " << static_cast<int>(isa)
                                                << " stretched " << stretched);
                std::vector<Ray> rays(film_x.size());
                camera.generate_rays(film_x, film_y, rays, isa);
                for (std::size_t i = 0; i < rays.size(); ++i) {
                    const Ray expected = camera.generate_ray(Vec2f(film_x[i], film_y[i]));
                    for (int c = 0; c < 3; ++c) {
                        ASSERT_EQ(std::bit_cast<std::uint32_t>(rays[i].origin[c]),
                                  std::bit_cast<std::uint32_t>(expected.origin[c]))
                            << "ray " << i << " origin " << c;
                        ASSERT_EQ(std::bit_cast<std::uint32_t>(rays[i].direction[c]),
                                  std::bit_cast<std::uint32_t>(expected.direction[c]))
                            << "ray " << i << " direction " << c;
                    }
                    ASSERT_EQ(std::bit_cast<std::uint32_t>(rays[i].t_max),
                              std::bit_cast<std::uint32_t>(expected.t_max))
                        << "ray " << i << " far clip " << far_clip;
                }
            }
        }
}

TEST(FarClip, CameraRaysEndOnTheFarPlaneAndNothingBeyondIsSeen) {
    // Mitsuba's far_clip as a camera-space depth, for the rigid pinhole, the thin lens and the
    // orthographic camera (far clip 7.5): each ray (300 film positions and lens points, Pcg32
    // stream seed 5) ends where its camera-space depth is 7.5; a point on it 1% short of that
    // connects back to the camera with a nonzero density, one 1% beyond does not (connect and
    // pdf_area, which light tracing and BDPT use).
    const Camera rigid = test_camera(false);
    std::vector<Camera> cameras = {
        rigid, test_thin_lens(),
        Camera::orthographic(rigid.world_from_camera(), rigid.film(), 0.5f)};
    for (Camera& camera : cameras) {
        camera.set_far_clip(7.5f);
        SCOPED_TRACE(projection_name(camera.projection()));
        Pcg32 rng(5, 6);
        for (int i = 0; i < 300; ++i) {
            const Vec2f film_position = random_crop_position(camera.film(), rng);
            const Vec2f u_lens(rng.next_float(), rng.next_float());
            const Ray ray = camera.generate_ray(film_position, u_lens);
            const auto depth = [&](float t) {
                return camera.world_from_camera()
                    .apply_inverse_point(Vec3f(ray.origin + t * ray.direction))
                    .z();
            };
            ASSERT_NEAR(depth(ray.t_max), 7.5f, 1e-4f * 7.5f) << i;
            // The points 1% short of the far plane and 1% beyond it, on this ray.
            const float t_near_side = ray.t_max - 0.075f / (depth(1.f) - depth(0.f));
            const float t_far_side = ray.t_max + 0.075f / (depth(1.f) - depth(0.f));
            const Vec3f inside = ray.origin + t_near_side * ray.direction;
            const Vec3f beyond = ray.origin + t_far_side * ray.direction;
            EXPECT_GT(camera.connect(inside, u_lens).importance, 0.f) << i;
            EXPECT_EQ(camera.connect(beyond, u_lens).importance, 0.f) << i;
            const Vec3f camera_end = camera.camera_end(ray.origin, u_lens);
            const Vec3f n = -ray.direction;
            EXPECT_GT(camera.pdf_area(camera_end, inside, n), 0.f) << i;
            EXPECT_EQ(camera.pdf_area(camera_end, beyond, n), 0.f) << i;
        }
    }
}

}  // namespace
}  // namespace gdmlt
