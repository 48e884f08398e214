// SPDX-License-Identifier: GPL-3.0-or-later
// The pinhole camera as an endpoint for light paths: connect() inverts generate_ray, and its
// importance integrates to one per pixel, measured with directions that know nothing of the
// camera. Together they are the goodness-of-fit test of generate_ray's direction density
// (pdf_direction_solid_angle = importance / pixel count): a chi-square over sphere bins does
// not work here, since the window's sharp edges cut bins into slivers that numerical
// integration of the expected counts misses.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <vector>

#include "core/camera/camera.h"
#include "core/math/frame.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"

namespace gdmlt {
namespace {

/// A 40 x 30 film rendering the 20 x 16 window at (5, 4), 70 degrees along x, near clip 0.5.
/// `stretched` adds a non-uniform scale to to_world (generate_ray normalises, so the mapping
/// from film to directions changes and the importance must follow it in world measure).
PerspectiveCamera test_camera(bool stretched) {
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
    return PerspectiveCamera(Transform(m), film, 70.f, "x", 0.5f);
}

Vec2f random_crop_position(const Film& film, Pcg32& rng) {
    return {static_cast<float>(film.crop_offset_x) + rng.next_float() * film.crop_width,
            static_cast<float>(film.crop_offset_y) + rng.next_float() * film.crop_height};
}

TEST(CameraImportance, ConnectInvertsGenerateRay) {
    for (const bool stretched : {false, true}) {
        const PerspectiveCamera camera = test_camera(stretched);
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

TEST(CameraImportance, IntegratesToOnePerPixel) {
    // W = dA_film / dw, so its integral over the directions that land in a pixel is the
    // pixel's area, 1. Directions uniform in a cone about the camera's mean view direction
    // (Pcg32 seed 5, 8M of them: at least 2000 per pixel with this cone) know nothing of the
    // projection; each pixel's Monte Carlo integral has a relative standard error ~1.5%.
    // Every pixel must lie within 5 standard errors (320 pixels: a false alarm has
    // probability 2e-4), and the whole window's integral (SE 0.1%) within 4. A cos^2 instead
    // of the cos^3 of a rigid camera is 9% off at this window's corners: 6 standard errors.
    for (const bool stretched : {false, true}) {
        const PerspectiveCamera camera = test_camera(stretched);
        const Film& film = camera.film();
        const Vec3f axis =
            (camera.generate_ray(Vec2f(15.f, 12.f)).direction).normalized();  // window centre
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
            const CameraConnection c = camera.connect(camera.position() + 10.f * w);
            if (!c.valid()) continue;
            const int x = static_cast<int>(std::floor(c.film_position.x())) - film.crop_offset_x;
            const int y = static_cast<int>(std::floor(c.film_position.y())) - film.crop_offset_y;
            ASSERT_TRUE(x >= 0 && x < film.crop_width && y >= 0 && y < film.crop_height);
            ASSERT_NEAR(camera.pdf_direction_solid_angle(w),
                        c.importance / static_cast<float>(pixels), 1e-5f * c.importance);
            const double v = c.importance / pdf;
            sum[static_cast<std::size_t>(y * film.crop_width + x)] += v;
            sum2[static_cast<std::size_t>(y * film.crop_width + x)] += v * v;
            // The cone must contain the whole window, or the integral would be short.
            ASSERT_GT(w.dot(axis), cos_max + 0.05f);
        }
        double total = 0.0, total_var = 0.0;
        for (int j = 0; j < pixels; ++j) {
            const auto k = static_cast<std::size_t>(j);
            const double mean = sum[k] / n;
            const double var = (sum2[k] / n - mean * mean) / (n - 1);
            total += mean;
            total_var += var;
            EXPECT_NEAR(mean, 1.0, 5.0 * std::sqrt(var)) << "pixel " << j;
            ASSERT_LT(std::sqrt(var), 0.03) << "too few samples to tell";
        }
        EXPECT_NEAR(total, pixels, 4.0 * std::sqrt(total_var));
    }
}

TEST(CameraRays, LanesAreGenerateRayBitForBit) {
    // generate_rays on every instruction set against generate_ray, all seven floats of every
    // ray compared as bits: both test cameras (the stretched one makes the normalisation do
    // something), 203 positions (not a multiple of any vector width) over the whole film and
    // beyond it (Pcg32 stream seed 11), its corners and centre, a huge one, and a NaN (which
    // must come out as the scalar code's NaN ray, lane by lane).
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (const bool stretched : {false, true}) {
        const PerspectiveCamera camera = test_camera(stretched);
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
                ASSERT_EQ(rays[i].t_max, expected.t_max);
            }
        }
    }
}

}  // namespace
}  // namespace gdmlt
