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
    const RenderOutput wavefront = render_path(scene, settings);

    const Film& film = scene.camera().film();
    FilmBuffer one_at_a_time(film.crop_width, film.crop_height);
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
    // The wavefront counts what the one-path loop counts.
    EXPECT_EQ(wavefront.stats.counters.paths, counters.paths);
    EXPECT_EQ(wavefront.stats.counters.camera_rays, counters.camera_rays);
    EXPECT_EQ(wavefront.stats.counters.bounce_rays, counters.bounce_rays);
    EXPECT_EQ(wavefront.stats.counters.shadow_rays, counters.shadow_rays);
}

}  // namespace
}  // namespace gdmlt
