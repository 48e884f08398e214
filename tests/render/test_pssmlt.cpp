// SPDX-License-Identifier: GPL-3.0-or-later
// PSSMLT converges to the path tracer's image; chains run through zero-contribution states
// without NaN, and a black scene ends after the bootstrap, saying so.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <atomic>
#include <cmath>

#include "core/render/render_path.h"
#include "mlt/pssmlt.h"
#include "tests/support/chi2.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

TEST(Pssmlt, ConvergesToThePathTracersImageOnASmallCornellBox) {
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(24));
    // Reference: the path tracer at 4096 spp (seed 1). Its own relMSE is about 0.0030 * 64 / 4096
    // ~ 5e-5 (cbox's measured error at 64 spp), negligible below.
    const RenderOutput reference = test::reference_render(scene);

    mlt::PssmltSettings settings;
    settings.seed = 7;
    settings.mutations_per_pixel = 1024;
    settings.bootstrap_samples = 200000;
    settings.chains = 64;
    settings.path.max_depth = 8;
    const mlt::PssmltOutput out = mlt::render_pssmlt(scene, settings);
    const mlt::PssmltStats& s = out.stats;
    EXPECT_EQ(s.nonfinite_dropped, 0u);
    EXPECT_EQ(s.replay_mismatches, 0u);
    EXPECT_EQ(s.mutations, static_cast<std::uint64_t>(1024 * 24 * 24));

    // The image mean is b up to the chain's noise; b is a mean of 200k independent samples,
    // so it must agree with the path tracer's image mean within 4 of its standard errors.
    const double pt_mean = test::mean_luminance(reference.image);
    EXPECT_NEAR(s.b, pt_mean, 4.0 * s.b_standard_error);
    EXPECT_NEAR(s.b_independent, pt_mean, 4.0 * s.b_independent_standard_error);
    EXPECT_NEAR(test::mean_luminance(out.image), pt_mean,
                4.0 * s.b_standard_error + 0.01 * pt_mean);

    // Per-pixel agreement. Measured with these seeds: relMSE 0.0025 (PSSMLT's error at 1024
    // mutations per pixel on this scene, dominated by correlated chain noise); the bound of
    // 0.01 leaves 4x for the heavy-tailed spread of MLT error over seeds and still fails for a
    // systematic per-pixel error above ~10%, e.g. a wrong splat weight or normalisation.
    const double rel_mse = test::relative_mse(out.image.pixels, reference.image.pixels);
    EXPECT_LT(rel_mse, 0.01);
    RecordProperty("relMSE", std::to_string(rel_mse));
}

TEST(Pssmlt, ABlackSceneEndsAfterTheBootstrapWithAZeroImageAndSaysSo) {
    // A light that faces away from everything: every path has zero contribution (those that
    // reach the light see its black back). No chain can start (there is no state with f > 0 to
    // start from): the render must end after the bootstrap with a finite black image, and say
    // why rather than leave a black image unexplained.
    const Scene scene = test::scene_from_xml(test::sensor_xml(8, 40.f, "0, 0, 4") + R"(
        <shape type="rectangle"><transform name="to_world"><translate z="-1"/></transform></shape>
        <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="180"/><translate z="-2"/></transform>
            <emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>)");
    mlt::PssmltSettings settings;
    settings.mutations_per_pixel = 16;
    settings.bootstrap_samples = 1000;
    ::testing::internal::CaptureStderr();
    const mlt::PssmltOutput out = mlt::render_pssmlt(scene, settings);
    const std::string said = ::testing::internal::GetCapturedStderr();
    EXPECT_NE(said.find("every bootstrap sample was black"), std::string::npos) << said;
    EXPECT_GE(out.stats.bootstrap_samples, 1000u);
    EXPECT_EQ(out.stats.bootstrap_nonzero, 0u);
    EXPECT_EQ(out.stats.b, 0.0);
    EXPECT_EQ(out.stats.mutations, 0u);
    EXPECT_EQ(out.stats.nonfinite_dropped, 0u);
    ASSERT_EQ(out.image.pixels.size(), 8u * 8u * 3u);
    for (float v : out.image.pixels) EXPECT_EQ(v, 0.f);  // also false for NaN
}

TEST(Pssmlt, ChainsRunThroughMostlyZeroContributionStatesAndStayFinite) {
    // Only a small bright light seen directly, over black surroundings: about 1 state in 1000
    // has light, so nearly every proposal has zero contribution and is rejected against a
    // bright state (a = 0, Kelemen weight of a zero-target proposal). The chains must really
    // run their whole budget through such states, and nothing may be NaN.
    const Scene scene = test::scene_from_xml(test::sensor_xml(8, 40.f, "0, 0, 4") + R"(
        <shape type="disk"><transform name="to_world"><scale value="0.05"/></transform>
            <emitter type="area"><rgb name="radiance" value="100"/></emitter></shape>)");
    mlt::PssmltSettings settings;
    settings.mutations_per_pixel = 64;
    settings.bootstrap_samples = 20000;
    const mlt::PssmltOutput out = mlt::render_pssmlt(scene, settings);
    const mlt::PssmltStats& s = out.stats;
    EXPECT_EQ(s.mutations, 64u * 8u * 8u);
    EXPECT_GT(s.bootstrap_nonzero, 0u);
    EXPECT_LT(s.bootstrap_nonzero, s.bootstrap_samples / 10) << "most states must be black";
    EXPECT_GT(s.small_proposed + s.large_proposed - s.small_accepted - s.large_accepted,
              s.mutations / 2)
        << "most proposals (zero contribution) must be rejected";
    EXPECT_EQ(s.nonfinite_dropped, 0u);
    double sum = 0.0;
    for (float v : out.image.pixels) {
        ASSERT_TRUE(std::isfinite(v));
        sum += v;
    }
    EXPECT_GT(sum, 0.0);
}

TEST(Pssmlt, CancelledDuringTheBootstrapTheImageIsTheBootstrapsUnbiasedMean) {
    // Ctrl-C while the bootstrap ran used to leave a black image: no chain had run yet. The
    // bootstrap's samples are independent and uniform over primary sample space, so their mean
    // is itself an unbiased whole image. The progress callback, called after every bootstrap
    // batch of 8192 samples, sets the cancel flag after the fourth: a deterministic cancel.
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(16));
    mlt::PssmltSettings settings;
    settings.seed = 4;
    settings.bootstrap_samples = 100000;
    settings.chains = 64;
    settings.path.max_depth = 8;
    std::atomic<bool> cancel{false};
    int calls = 0;
    const mlt::PssmltOutput out = mlt::render_pssmlt(scene, settings, &cancel, [&](double, double) {
        if (++calls == 4) cancel = true;
    });
    const mlt::PssmltStats& s = out.stats;
    EXPECT_EQ(calls, 4);
    EXPECT_TRUE(s.interrupted);
    EXPECT_TRUE(s.bootstrap_estimate);
    EXPECT_EQ(s.mutations, 0u);
    EXPECT_EQ(s.bootstrap_samples, 4u * 8192u);
    // Whole: 128 samples per pixel, and every pixel of the box sees lit surfaces.
    int lit = 0;
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            if (out.image(x, y, 0) + out.image(x, y, 1) + out.image(x, y, 2) > 0.f) ++lit;
    EXPECT_GE(lit, 243) << "at least 95% of the 256 pixels";
    // Right: the image mean is the mean luminance of the 32768 samples (b_bootstrap, with its
    // standard error). The reference, the path tracer at 1024 spp (262144 samples, seed 1), has
    // 8x as many samples of the same paths (stratified by pixel, which only lowers its
    // variance): its error variance is at most 1/8 of the bootstrap's. 4 combined standard
    // errors. The light seen directly spreads the samples widely (one standard error is about
    // 4% of the mean), so the bound, about 16%, must stay below 20% of the mean: it catches a
    // black or mis-scaled image, not a bias of a few percent.
    RenderSettings pt;
    pt.spp = 1024;
    pt.seed = 1;
    pt.path.max_depth = 8;
    const double reference_mean = test::mean_luminance(render_path(scene, pt).image);
    const double tolerance = 4.0 * s.b_bootstrap_standard_error * std::sqrt(1.0 + 1.0 / 8.0);
    EXPECT_NEAR(test::mean_luminance(out.image), reference_mean, tolerance);
    EXPECT_LT(tolerance, 0.2 * reference_mean);
    RecordProperty("relative_tolerance", std::to_string(tolerance / reference_mean));
}

TEST(Pssmlt, SameSeedGivesTheSameImageAtOneAndTwoThreads) {
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(12, true));
    mlt::PssmltSettings settings;
    settings.mutations_per_pixel = 32;
    settings.bootstrap_samples = 5000;
    settings.chains = 40;
    const auto [one, two] =
        test::at_one_and_two_threads([&] { return mlt::render_pssmlt(scene, settings); });
    EXPECT_TRUE(one.image == two.image);
}

}  // namespace
}  // namespace gdmlt
