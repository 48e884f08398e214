// SPDX-License-Identifier: GPL-3.0-or-later
// The path tracer's render loop: its wavefront driver against the one-path estimator. A unit
// test (milliseconds), so that it also runs under AddressSanitizer and UBSan.
#include <gtest/gtest.h>

#include <cmath>

#include "core/render/film_buffer.h"
#include "core/render/pixel_passes.h"
#include "core/render/render_path.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

TEST(FilmBuffer, SecondMomentsAreTheMeanSquaredXyzOfTheSamples) {
    // Two samples in pixel (1, 0): pure red and pure green. XYZ by Mitsuba 3's srgb_to_xyz
    // columns; the second moment per channel is the mean of the two squares; pixel (0, 0) saw
    // none (zero), and without tracking there is no layer.
    FilmBuffer buffer(2, 1);
    EXPECT_TRUE(buffer.second_moment().pixels.empty());
    buffer.track_second_moment();
    buffer.add(1, 0, Rgb(1.f, 0.f, 0.f));
    buffer.add(1, 0, Rgb(0.f, 1.f, 0.f));
    const Image m2 = buffer.second_moment();
    const float red[3] = {0.412453f, 0.212671f, 0.019334f};
    const float green[3] = {0.357580f, 0.715160f, 0.119193f};
    for (int c = 0; c < 3; ++c) {
        EXPECT_FLOAT_EQ(m2(1, 0, c), 0.5f * (red[c] * red[c] + green[c] * green[c]));
        EXPECT_EQ(m2(0, 0, c), 0.f);
    }
}

TEST(Wavefront, PathTracerGivesTheImageOfOnePathAtATime) {
    // render_path advances 256 paths a vertex at a time and traces their rays in packets of 16;
    // sample_path_radiance traces one path at a time with one-ray queries. Both run the same
    // per-vertex code on the same streams (pixel_sample), so each sample is the same path:
    // only Embree's packet and one-ray kernels may round a hit distance or barycentric
    // differently in the last bits (on the shared scenes: at most 1.2e-4 absolute per pixel).
    // A driver bug (a shadow ray's contribution added to another lane or after the next vertex,
    // a lane dropped or counted twice, samples filed under the wrong pixel) changes pixels by
    // whole sample values, orders of magnitude above the relative 1e-4 allowed here. 40x40 at
    // 7 spp: 11,200 paths, so batches of 256 end mid-pixel and a tile (16x16) does not fill
    // its last batch. The box with a glass sphere: diffuse and delta vertices, next-event
    // estimation blocked and unblocked.
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(40, true));
    constexpr int kSpp = 7;
    constexpr std::uint64_t kSeed = 5;
    RenderSettings settings;
    settings.spp = kSpp;
    settings.seed = kSeed;
    settings.path.max_depth = 12;
    settings.second_moment = true;  // Mitsuba's moment layers: the same paths, squared
    const RenderOutput wavefront = render_path(scene, settings);

    const Film& film = scene.camera().film();
    FilmBuffer one_at_a_time(film.crop_width, film.crop_height);
    one_at_a_time.track_second_moment();
    PathCounters counters;
    for (int y = 0; y < film.crop_height; ++y)
        for (int x = 0; x < film.crop_width; ++x)
            for (int s = 0; s < kSpp; ++s) {
                PixelSample ps = pixel_sample(film, kSeed, x, y, s);
                one_at_a_time.add(
                    x, y,
                    sample_path_radiance(scene, scene.camera().generate_ray(ps.film_position),
                                         ps.stream, settings.path, counters));
            }
    const Image expected = one_at_a_time.mean();
    ASSERT_EQ(wavefront.image.pixels.size(), expected.pixels.size());
    double sum = 0.0;
    int different = 0;
    for (std::size_t i = 0; i < expected.pixels.size(); ++i) {
        sum += expected.pixels[i];
        const float tolerance = 1e-4f * std::abs(expected.pixels[i]) + 1e-7f;
        if (std::abs(wavefront.image.pixels[i] - expected.pixels[i]) > tolerance) ++different;
    }
    EXPECT_GT(sum, 0.0);  // the scene is lit: a black image would compare equal too
    EXPECT_EQ(different, 0);
    const Image expected_m2 = one_at_a_time.second_moment();
    ASSERT_EQ(wavefront.second_moment.pixels.size(), expected_m2.pixels.size());
    int different_m2 = 0;
    for (std::size_t i = 0; i < expected_m2.pixels.size(); ++i) {
        const float tolerance = 2e-4f * std::abs(expected_m2.pixels[i]) + 1e-7f;
        if (std::abs(wavefront.second_moment.pixels[i] - expected_m2.pixels[i]) > tolerance)
            ++different_m2;
    }
    EXPECT_EQ(different_m2, 0);
    // The wavefront counts what the one-path loop counts.
    EXPECT_EQ(wavefront.stats.counters.paths, counters.paths);
    EXPECT_EQ(wavefront.stats.counters.camera_rays, counters.camera_rays);
    EXPECT_EQ(wavefront.stats.counters.bounce_rays, counters.bounce_rays);
    EXPECT_EQ(wavefront.stats.counters.shadow_rays, counters.shadow_rays);
}

}  // namespace
}  // namespace gdmlt
