// SPDX-License-Identifier: GPL-3.0-or-later
// The chain runner on a toy gradient target: its chains' final states follow the target, and
// its splats, normalised by the bootstrap's b, integrate what they should.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>
#include <cmath>
#include <limits>

#include "mlt/chain_runner.h"
#include "tests/support/chi2.h"

namespace gdmlt::mlt {
namespace {

constexpr int kPixels = 16;

/// A 1D "image" with a step edge and a ramp, and the GDMLT-style target of each pixel:
/// T(p) = |I(p+1) - I(p)| + |I(p) - I(p-1)| + w I(p), w = 0.25 (mlt/gdmlt.h).
std::array<double, kPixels> toy_target_per_pixel() {
    std::array<double, kPixels> intensity{};
    for (int p = 0; p < kPixels; ++p) intensity[p] = p < 6 ? 0.05 : p < 11 ? 1.0 + 0.2 * p : 0.3;
    std::array<double, kPixels> target{};
    for (int p = 0; p < kPixels; ++p) {
        double t = 0.25 * intensity[p];
        if (p + 1 < kPixels) t += std::abs(intensity[p + 1] - intensity[p]);
        if (p > 0) t += std::abs(intensity[p] - intensity[p - 1]);
        target[p] = t;
    }
    return target;
}

/// f(u) = T(pixel of u0) * (0.5 + u1) * (u1 > 0.5 ? 0.5 + u2 : 1): the chain must mutate more
/// than the pixel coordinate, and states read 2 or 3 coordinates. The factors after T
/// integrate to 0.375 + 0.625 * 1 = 1 over (u1, u2), so pixel p holds the fraction
/// T(p) / sum T of the target's mass. Splats: 1 into slot p (its integral
/// over primary sample space is 1/kPixels).
class ToyGradientTarget final : public ChainTarget {
  public:
    std::size_t slot_count() const override { return kPixels; }
    std::size_t density_slot_count() const override { return kPixels; }
    void evaluate(SampleStream& stream, ChainState& state, ChainCounters&) const override {
        const Vec2f u = stream.next_2d();
        const int p = std::min(static_cast<int>(u.x() * kPixels), kPixels - 1);
        // x3 keeps b = E[f] (about 2.8) away from 1, so a lost b could not go unnoticed.
        double f = 3.0 * target_[static_cast<std::size_t>(p)] * (0.5 + u.y());
        if (u.y() > 0.5f) f *= 0.5 + stream.next_1d();
        state.target = f;
        state.density_slot = p;
        state.splats.push_back({static_cast<std::uint32_t>(p), Rgb::Ones()});
    }

  private:
    std::array<double, kPixels> target_ = toy_target_per_pixel();
};

ChainRunnerSettings toy_settings(std::uint64_t seed, int chains, std::uint64_t mutations) {
    ChainRunnerSettings s;
    s.seed = seed;
    s.chains = chains;
    s.mutations = mutations;
    s.bootstrap_samples = 1;  // raised to 10 x chains
    s.image_width = kPixels;
    return s;
}

TEST(ChainRunner, FinalStatesOfIndependentChainsFollowTheToyGradientTarget) {
    // 4000 independent chains of 100 mutations each (seed 3): their final states are 4000
    // independent draws from the chain's distribution, which must be the target's (T(p) / sum
    // T per pixel). Chi-square over the 16 pixels at alpha = 1%. Checked to fail when the
    // acceptance ignores the target (a = 1), which drifts the chains towards uniform.
    const ToyGradientTarget target;
    const ChainRunnerOutput out = run_chains(target, toy_settings(3, 4000, 4000 * 100));
    ASSERT_EQ(out.final_density_slots.size(), 4000u);
    std::vector<double> observed(kPixels, 0.0), expected(kPixels, 0.0);
    for (std::int32_t p : out.final_density_slots) {
        ASSERT_GE(p, 0);
        observed[static_cast<std::size_t>(p)] += 1.0;
    }
    const std::array<double, kPixels> t = toy_target_per_pixel();
    double total = 0.0;
    for (double v : t) total += v;
    for (int p = 0; p < kPixels; ++p) expected[p] = 4000.0 * t[p] / total;
    const test::Chi2Result chi2 = test::chi2_histogram_test(observed, expected);
    EXPECT_GT(chi2.p_value, 0.01) << chi2.summary;
    // Every chain did its share, and both kinds of step were accepted sometimes.
    EXPECT_EQ(out.stats.mutations, 4000u * 100u);
    EXPECT_GT(out.stats.small_accepted, 0u);
    EXPECT_GT(out.stats.large_accepted, 0u);
    EXPECT_LT(out.stats.small_accepted, out.stats.small_proposed);
}

TEST(ChainRunner, SplatsIntegrateTheirContributionOverPrimarySampleSpace) {
    // Each slot's estimate is the integral of the indicator of its pixel: 1/16. Eight
    // independent runs (seeds 10..17, 64 chains x 20000 mutations) give a mean and a standard
    // error per pixel; the mean must lie within 4 standard errors of 1/16, for Kelemen's and
    // for Veach's weights. Checked to fail when the splat weight forgets b (then every slot
    // is off by the factor b = mean of f, here about 2.8).
    const ToyGradientTarget target;
    for (bool kelemen : {true, false}) {
        std::array<double, kPixels> sum{}, sum2{};
        constexpr int kRuns = 8;
        for (int run = 0; run < kRuns; ++run) {
            ChainRunnerSettings s =
                toy_settings(10 + static_cast<std::uint64_t>(run), 64, 64 * 20000);
            s.kelemen_weights = kelemen;
            const ChainRunnerOutput out = run_chains(target, s);
            for (int p = 0; p < kPixels; ++p) {
                const double v = out.estimate[static_cast<std::size_t>(p)][0];
                sum[p] += v;
                sum2[p] += v * v;
            }
        }
        for (int p = 0; p < kPixels; ++p) {
            const double mean = sum[p] / kRuns;
            const double se = std::sqrt(std::max(0.0, sum2[p] / kRuns - mean * mean) / (kRuns - 1));
            EXPECT_NEAR(mean, 1.0 / kPixels, 4.0 * se + 1e-12)
                << "pixel " << p << (kelemen ? " (Kelemen weights)" : " (expected values)");
            // The test could not fail if the runs were as noisy as the quantity itself.
            EXPECT_LT(se, 0.1 / kPixels);
        }
    }
}

TEST(ChainRunner, LargeStepsRefineBAndTheEstimateFollowsTheFinalB) {
    // The toy's b is known: E[f] = 3 mean_p T(p), the other factors integrating to 1. With a
    // bootstrap of only 640 samples (about 4% error), the final b also counts the ~384k large
    // steps of 64 chains x 20000 mutations (p_large 0.3), so its standard error must be far
    // smaller (sqrt(640 / 385k) = 0.04 of the bootstrap's; asked: below 0.2 of it), the true b
    // must lie within 4 of them (seeds 20..27), and the image, whose total is 1 (each state
    // splats 1 into its pixel), must follow the final b rather than the bootstrap's.
    const ToyGradientTarget target;
    const std::array<double, kPixels> t = toy_target_per_pixel();
    double b_true = 0.0;
    for (double v : t) b_true += 3.0 * v / kPixels;
    double squared_error_final = 0.0, squared_error_bootstrap = 0.0;
    for (std::uint64_t seed = 20; seed < 28; ++seed) {
        const ChainRunnerOutput out = run_chains(target, toy_settings(seed, 64, 64 * 20000));
        const ChainStats& s = out.stats;
        EXPECT_EQ(s.b_samples, s.bootstrap_samples + s.large_proposed);
        EXPECT_LT(s.b_standard_error, 0.2 * s.b_bootstrap_standard_error);
        EXPECT_NEAR(s.b, b_true, 4.0 * s.b_standard_error) << "seed " << seed;
        double total = 0.0;
        for (const RgbD& v : out.estimate) total += v[0];
        squared_error_final += (total - 1.0) * (total - 1.0);
        squared_error_bootstrap += (s.b_bootstrap / b_true - 1.0) * (s.b_bootstrap / b_true - 1.0);
    }
    // Measured: the total's RMS error over the 8 seeds 0.0017, the bootstrap b's 0.065 (what
    // the total's would be without the rescale). 0.01 sits between them; the second check
    // keeps the test able to fail (a bootstrap that was already precise would prove nothing).
    EXPECT_LT(std::sqrt(squared_error_final / 8.0), 0.01);
    EXPECT_GT(std::sqrt(squared_error_bootstrap / 8.0), 0.02);
}

/// The toy target, except that every state in pixel `broken_pixel` evaluates to NaN (as a path
/// whose contribution overflowed would): the runner must drop and count those states.
class ToyTargetWithNan final : public ChainTarget {
  public:
    static constexpr int broken_pixel = 3;
    std::size_t slot_count() const override { return toy_.slot_count(); }
    void evaluate(SampleStream& stream, ChainState& state, ChainCounters& counters) const override {
        toy_.evaluate(stream, state, counters);
        if (state.density_slot == broken_pixel) {
            state.target = std::numeric_limits<double>::quiet_NaN();
            state.splats.front().value = Rgb::Constant(std::numeric_limits<float>::quiet_NaN());
        }
    }

  private:
    ToyGradientTarget toy_;
};

TEST(ChainRunner, NonFiniteStatesAreDroppedCountedAndTheRestStaysUnbiased) {
    // Pixel 3's states are NaN: they must be counted (bootstrap and chains), never splatted,
    // and the other pixels' estimates must still be 1/16 (they do not depend on pixel 3), within
    // 4 standard errors of 8 runs (seeds 40..47, 64 chains x 20000 mutations), Kelemen weights.
    // Checked to fail with the runner's non-finite guard removed: NaN targets then poison the
    // acceptance and the splats.
    const ToyTargetWithNan target;
    std::array<double, kPixels> sum{}, sum2{};
    constexpr int kRuns = 8;
    for (int run = 0; run < kRuns; ++run) {
        const ChainRunnerOutput out =
            run_chains(target, toy_settings(40 + static_cast<std::uint64_t>(run), 64, 64 * 20000));
        EXPECT_GT(out.stats.nonfinite_dropped, 0u);
        EXPECT_TRUE(std::isfinite(out.stats.b));
        for (int p = 0; p < kPixels; ++p) {
            const double v = out.estimate[static_cast<std::size_t>(p)][0];
            ASSERT_TRUE(std::isfinite(v)) << "pixel " << p;
            sum[p] += v;
            sum2[p] += v * v;
        }
        EXPECT_EQ(out.estimate[ToyTargetWithNan::broken_pixel][0], 0.0);
    }
    for (int p = 0; p < kPixels; ++p) {
        if (p == ToyTargetWithNan::broken_pixel) continue;
        const double mean = sum[p] / kRuns;
        const double se = std::sqrt(std::max(0.0, sum2[p] / kRuns - mean * mean) / (kRuns - 1));
        EXPECT_NEAR(mean, 1.0 / kPixels, 4.0 * se + 1e-12) << "pixel " << p;
        EXPECT_LT(se, 0.1 / kPixels);
    }
}

TEST(ChainRunner, SameSeedGivesTheSameResultAtOneAndTwoThreads) {
    const ToyGradientTarget target;
    const ChainRunnerSettings s = toy_settings(5, 37, 37 * 300);
    ChainRunnerOutput one, two;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        one = run_chains(target, s);
    }
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
        two = run_chains(target, s);
    }
    ASSERT_EQ(one.estimate.size(), two.estimate.size());
    for (std::size_t i = 0; i < one.estimate.size(); ++i)
        EXPECT_TRUE((one.estimate[i] == two.estimate[i]).all());
    EXPECT_EQ(one.final_density_slots, two.final_density_slots);
    EXPECT_EQ(one.stats.b, two.stats.b);
}

TEST(ChainRunner, BootstrapGrowsUntilBIsAsPreciseAsAsked) {
    // With 1% asked, the bootstrap must grow beyond its initial 10 x chains samples (the toy's
    // f has a relative standard deviation near 1, so 640 samples give about 4%), and stop once
    // the standard error is below 1% of b (or at 16x its start).
    const ToyGradientTarget target;
    ChainRunnerSettings s = toy_settings(2, 64, 64 * 10);
    s.bootstrap_relative_error = 0.01;
    const ChainRunnerOutput out = run_chains(target, s);
    EXPECT_GT(out.stats.bootstrap_samples, 640u);
    EXPECT_TRUE(out.stats.b_bootstrap_standard_error <= 0.01 * out.stats.b_bootstrap ||
                out.stats.bootstrap_samples == 16u * 640u)
        << out.stats.b_bootstrap_standard_error / out.stats.b_bootstrap << " after "
        << out.stats.bootstrap_samples;
}

}  // namespace
}  // namespace gdmlt::mlt
