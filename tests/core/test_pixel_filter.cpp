// SPDX-License-Identifier: GPL-3.0-or-later
// The film's reconstruction filters (core/camera/pixel_filter.h): Mitsuba 3's shapes, sampling
// that draws offsets with density proportional to the weight (truncated ranges too), splat
// weights h_p that integrate to one over every pixel's support (at the borders too), and
// jittered_film_position drawing from the same h_p that the splats use.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/camera/camera.h"
#include "core/render/pixel_passes.h"
#include "core/sampling/rng.h"
#include "tests/support/chi2.h"

namespace gdmlt {
namespace {

TEST(PixelFilter, ShapesAreMitsubas) {
    const PixelFilter box;
    EXPECT_EQ(box.eval(0.49f), 1.f);
    EXPECT_EQ(box.eval(0.51f), 0.f);
    const PixelFilter tent = PixelFilter::tent(1.25f);
    EXPECT_FLOAT_EQ(tent.eval(0.5f), 0.6f);
    EXPECT_EQ(tent.eval(1.3f), 0.f);
    EXPECT_NEAR(tent.integral(-10.f, 10.f), 1.25, 1e-7);  // a triangle of height 1
    const PixelFilter gaussian = PixelFilter::gaussian(0.5f);
    EXPECT_FLOAT_EQ(gaussian.radius(), 2.f);
    EXPECT_FLOAT_EQ(gaussian.eval(0.5f), std::exp(-0.5f) - std::exp(-8.f));
    EXPECT_EQ(gaussian.eval(2.f), 0.f);
    // Integral of exp(-x^2 / (2 s^2)) over [-4s, 4s] minus the subtracted constant over it.
    const double expected =
        std::sqrt(2.0 * 3.14159265358979) * 0.5 * std::erf(4.0 / std::sqrt(2.0)) -
        4.0 * std::exp(-8.0);
    // Within float rounding of the weights the table integrates (6e-8 relative).
    EXPECT_NEAR(gaussian.integral(-2.f, 2.f), expected, 1e-7);
}

/// Offsets drawn in [lo, hi] against their density w / integral(lo, hi), in 24 bins.
void expect_samples_follow_the_weight(const PixelFilter& f, float lo, float hi) {
    // Pcg32 (5, 1), 120000 draws; Pearson's chi-square at the Sidak-corrected 1% level over
    // this file's 13 histogram tests (tests/support/chi2.h).
    constexpr int kBins = 24, kDraws = 120000;
    std::vector<double> observed(kBins, 0.0), expected(kBins, 0.0);
    Pcg32 rng(5, 1);
    const float a = std::max(lo, -f.radius()), b = std::min(hi, f.radius());
    for (int i = 0; i < kDraws; ++i) {
        const float x = f.sample(rng.next_float(), lo, hi);
        ASSERT_GE(x, a);
        ASSERT_LE(x, b);
        observed[static_cast<std::size_t>(
            std::min(kBins - 1, static_cast<int>((x - a) / (b - a) * kBins)))] += 1.0;
    }
    const double total = f.integral(a, b);
    for (int k = 0; k < kBins; ++k) {
        const float x0 = a + (b - a) * static_cast<float>(k) / kBins;
        const float x1 = a + (b - a) * static_cast<float>(k + 1) / kBins;
        expected[static_cast<std::size_t>(k)] = kDraws * f.integral(x0, x1) / total;
    }
    const test::Chi2Result r = test::chi2_histogram_test(observed, expected);
    EXPECT_GT(r.p_value, test::sidak_alpha(13))
        << f.name() << " on [" << lo << ", " << hi << "]: " << r.summary;
}

TEST(PixelFilter, SamplesFollowTheWeightOnWholeAndTruncatedRanges) {
    for (const PixelFilter& f : {PixelFilter::gaussian(0.5f), PixelFilter::tent(1.f),
                                 PixelFilter::gaussian(1.f), PixelFilter::tent(2.5f)}) {
        expect_samples_follow_the_weight(f, -100.f, 100.f);
        expect_samples_follow_the_weight(f, -0.5f, 100.f);  // a pixel on the left edge
        expect_samples_follow_the_weight(f, -1.5f, 0.7f);
    }
}

TEST(PixelFilter, SplatWeightsIntegrateToOneOverEveryPixelBordersIncluded) {
    // h_p integrates to one over the crop window for every pixel p, as the box's indicator
    // does: integrated by the midpoint rule on a 1/32-pixel grid over a 7 x 5 film with a crop
    // offset (so film and crop coordinates differ). The splatting integrators' estimate of a
    // pixel is then unbiased for the same I(p) as filter-sampled pixel passes.
    for (const PixelFilter& f : {PixelFilter(), PixelFilter::tent(1.f), PixelFilter::gaussian(0.5f),
                                 PixelFilter::gaussian(0.8f)}) {
        Film film;
        film.width = 10;
        film.height = 8;
        film.crop_offset_x = 2;
        film.crop_offset_y = 1;
        film.crop_width = 7;
        film.crop_height = 5;
        film.filter = f;
        std::vector<double> mass(35, 0.0);
        constexpr int kSub = 32;
        const double cell = 1.0 / (kSub * kSub);
        for (int j = 0; j < film.crop_height * kSub; ++j)
            for (int i = 0; i < film.crop_width * kSub; ++i) {
                const Vec2f position(film.crop_offset_x + (i + 0.5f) / kSub,
                                     film.crop_offset_y + (j + 0.5f) / kSub);
                for_each_filtered_pixel(film, position, [&](std::uint32_t pixel, float weight) {
                    mass[pixel] += weight * cell;
                });
            }
        for (std::size_t p = 0; p < mass.size(); ++p)
            EXPECT_NEAR(mass[p], 1.0, 2e-3) << f.name() << " pixel " << p;
    }
}

TEST(PixelFilter, FilmPositionsOfAPixelAreDrawnFromItsSplatWeights) {
    // jittered_film_position for pixel (0, 2) of a 6 x 5 crop (a border pixel: its h_p is
    // truncated) against h_p over a 1/4-pixel grid: chi-square at the level above, Pcg32
    // (9, 1), 200000 draws.
    Film film;
    film.width = film.crop_width = 6;
    film.height = film.crop_height = 5;
    film.filter = PixelFilter::gaussian(0.5f);
    const int px = 0, py = 2;
    constexpr int kSub = 4;
    const int cells_x = film.crop_width * kSub, cells_y = film.crop_height * kSub;
    std::vector<double> observed(static_cast<std::size_t>(cells_x * cells_y), 0.0);
    Pcg32 rng(9, 1);
    constexpr int kDraws = 200000;
    for (int i = 0; i < kDraws; ++i) {
        const float u = rng.next_float(), v = rng.next_float();
        const Vec2f position = jittered_film_position(film, px, py, u, v);
        const int cx = std::min(cells_x - 1, static_cast<int>(position.x() * kSub));
        const int cy = std::min(cells_y - 1, static_cast<int>(position.y() * kSub));
        ASSERT_GE(cx, 0);
        ASSERT_GE(cy, 0);
        observed[static_cast<std::size_t>(cy * cells_x + cx)] += 1.0;
    }
    // Expected: the splat weight to pixel (px, py), integrated over each cell (8 x 8 midpoints).
    std::vector<double> expected(observed.size(), 0.0);
    const std::uint32_t target = static_cast<std::uint32_t>(py * film.crop_width + px);
    constexpr int kMid = 8;
    for (int cy = 0; cy < cells_y; ++cy)
        for (int cx = 0; cx < cells_x; ++cx)
            for (int j = 0; j < kMid; ++j)
                for (int i = 0; i < kMid; ++i) {
                    const Vec2f position((cx + (i + 0.5f) / kMid) / kSub,
                                         (cy + (j + 0.5f) / kMid) / kSub);
                    for_each_filtered_pixel(film, position, [&](std::uint32_t pixel, float w) {
                        if (pixel == target)
                            expected[static_cast<std::size_t>(cy * cells_x + cx)] +=
                                kDraws * w / (kSub * kSub * kMid * kMid);
                    });
                }
    const test::Chi2Result r = test::chi2_histogram_test(observed, expected);
    EXPECT_GT(r.p_value, test::sidak_alpha(13)) << r.summary;
}

TEST(PixelFilter, ImageFilteringKeepsAConstantImageAndSpreadsAPoint) {
    const PixelFilter f = PixelFilter::gaussian(0.5f);
    Image constant(9, 7, 3, 2.5f);
    const Image filtered = filter_image(constant, f);
    for (float v : filtered.pixels) EXPECT_NEAR(v, 2.5f, 1e-6f);
    Image point(9, 7, 1, 0.f);
    point(4, 3) = 1.f;
    const Image spread = filter_image(point, f);
    const std::vector<double> k = f.pixel_kernel();
    double sum_k = 0.0;
    for (double v : k) sum_k += v;
    EXPECT_NEAR(spread(4, 3), (k[k.size() / 2] / sum_k) * (k[k.size() / 2] / sum_k), 1e-6);
    EXPECT_NEAR(spread(5, 3), (k[k.size() / 2 + 1] / sum_k) * (k[k.size() / 2] / sum_k), 1e-6);
    // The box filter leaves an image as it is.
    EXPECT_EQ(filter_image(point, PixelFilter()).pixels, point.pixels);
}

}  // namespace
}  // namespace gdmlt
