// SPDX-License-Identifier: GPL-3.0-or-later
// Weighted image-space control variates (Rousselle, Jarosz, Novak 2016).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>

#include "reconstruct/control_variates.h"

namespace gdmlt::reconstruct {
namespace {

Image smooth_image(int w, int h) {
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double u = static_cast<double>(x) / w, v = static_cast<double>(y) / h;
            img(x, y, 0) = static_cast<float>(0.5 + 0.4 * std::sin(5.0 * u) * std::cos(3.0 * v));
            img(x, y, 1) = static_cast<float>(0.3 + 0.6 * u * v);
            img(x, y, 2) = static_cast<float>(x > w / 3 ? 0.8 : 0.1);
        }
    return img;
}

Image add_noise(const Image& img, double sigma, std::uint32_t seed) {
    std::mt19937 rng(seed);
    Image out = img;
    for (float& v : out.pixels) {
        const double a = (rng() + 0.5) / 4294967296.0, b = (rng() + 0.5) / 4294967296.0;
        v += static_cast<float>(sigma * std::sqrt(-2.0 * std::log(a)) *
                                std::cos(6.283185307179586 * b));
    }
    return out;
}

double rmse(const Image& a, const Image& b) {
    double s = 0.0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i) {
        const double d = static_cast<double>(a.pixels[i]) - b.pixels[i];
        s += d * d;
    }
    return std::sqrt(s / static_cast<double>(a.pixels.size()));
}

TEST(ControlVariates, ExactDataIsAFixedPoint) {
    const Image img = smooth_image(64, 64);
    ReconstructInput in{make_lattice_graph(64, 64), img, Image(64, 64, 1, 0.01f)};
    set_differences_from_image(in.graph, img);
    for (bool weighted : {false, true}) {
        ReconstructConfig c;
        c.cv_use_variance = weighted;
        const ReconstructResult r = solve_cv(in, c);
        EXPECT_EQ(r.stats.iterations, c.cv_iterations);
        // Every estimate equals the pixel, so each average does too, up to double rounding.
        for (std::size_t i = 0; i < img.pixels.size(); ++i)
            ASSERT_NEAR(r.image.pixels[i], img.pixels[i], 1e-6);
    }
}

TEST(ControlVariates, NoisyPrimalWithGoodGradientsIsDenoised) {
    // sigma 0.1 primal noise, sigma 0.01 gradient noise: 50 iterations average the primal over
    // a wide neighbourhood through the gradients. Measured RMSE ~0.02 vs 0.1; asserted < 0.05.
    const Image img = smooth_image(64, 64);
    const Image primal = add_noise(img, 0.1, 1);
    ReconstructInput in{make_lattice_graph(64, 64), primal, {}};
    set_differences_from_image(in.graph, add_noise(img, 0.01, 2));
    const ReconstructResult r = solve_cv(in, ReconstructConfig{});
    const double before = rmse(primal, img), after = rmse(r.image, img);
    EXPECT_NEAR(before, 0.1, 0.01);
    EXPECT_LT(after, 0.5 * before) << after;
}

TEST(ControlVariates, AnUntrustedPixelIsReplacedByItsNeighboursEstimates) {
    // One pixel's primal is off by +100 but its variance says so (infinite): the weighted
    // scheme gives it weight 0, so exact differences from exact neighbours restore it. The
    // uniform scheme keeps averaging it in and leaks the error.
    const int w = 32, h = 32;
    const Image img = smooth_image(w, h);
    Image primal = img;
    primal(10, 12, 0) += 100.f;
    Image variance(w, h, 1, 1e-3f);
    variance(10, 12) = std::numeric_limits<float>::infinity();
    ReconstructInput in{make_lattice_graph(w, h), primal, variance};
    set_differences_from_image(in.graph, img);
    ReconstructConfig c;
    c.cv_use_variance = true;
    const ReconstructResult weighted = solve_cv(in, c);
    EXPECT_NEAR(weighted.image(10, 12, 0), img(10, 12, 0), 1e-4);
    EXPECT_LT(rmse(weighted.image, img), 1e-5);
    c.cv_use_variance = false;
    const ReconstructResult uniform = solve_cv(in, c);
    EXPECT_GT(rmse(uniform.image, img), 0.01);
}

TEST(ControlVariates, LowVarianceNeighboursOutweighHighVarianceOnes) {
    // Left half: accurate primal (variance 1e-4), right half: noisy (variance 0.25, sigma 0.5).
    // Uniform weights leak the right half's noise into the left half; inverse-variance weights
    // keep the accurate half accurate and do at least as well overall. Measured (48x32):
    // left-half RMSE weighted 0.0049 vs uniform 0.012 (what remains is the 0.005 gradient noise
    // integrated over the iterations); asserted: weighted < 0.6 x uniform.
    const int w = 48, h = 32;
    const Image img = smooth_image(w, h);
    Image primal = img;
    Image variance(w, h, 1, 1e-4f);
    const Image noisy = add_noise(img, 0.5, 5);
    for (int y = 0; y < h; ++y)
        for (int x = w / 2; x < w; ++x) {
            variance(x, y) = 0.25f;
            for (int c = 0; c < 3; ++c) primal(x, y, c) = noisy(x, y, c);
        }
    ReconstructInput in{make_lattice_graph(w, h), primal, variance};
    set_differences_from_image(in.graph, add_noise(img, 0.005, 6));
    const auto left_rmse = [&](const Image& r) {
        double s = 0.0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w / 2; ++x)
                for (int c = 0; c < 3; ++c) {
                    const double d = static_cast<double>(r(x, y, c)) - img(x, y, c);
                    s += d * d;
                }
        return std::sqrt(s / (3.0 * (w / 2) * h));
    };
    ReconstructConfig c;
    const Image weighted = solve_cv(in, c).image;
    c.cv_use_variance = false;
    const Image uniform = solve_cv(in, c).image;
    EXPECT_LT(left_rmse(weighted), 0.6 * left_rmse(uniform));
    EXPECT_LE(rmse(weighted, img), rmse(uniform, img));
}

}  // namespace
}  // namespace gdmlt::reconstruct
