// SPDX-License-Identifier: GPL-3.0-or-later
// The alias table (core/sampling/alias_table.h): chosen bins follow pmf(), pmf() is weight /
// total, the handed-back number is uniform inside each bin and independent of the choice,
// empty bins are never chosen. Chi-square at alpha 1% Sidak-corrected over the two
// statistical tests of this file, fixed seeds.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/sampling/alias_table.h"
#include "core/sampling/rng.h"
#include "tests/support/chi2.h"

namespace gdmlt {
namespace {

constexpr int kStatisticalTests = 2;

/// Weight lists with the cases Vose's algorithm handles differently: equal weights (every
/// column its own), one heavy bin among light ones (one bin lends to all), empty bins between
/// others and at both ends, a single non-empty bin, and weights spanning eight decades.
std::vector<std::vector<float>> weight_lists() {
    std::vector<std::vector<float>> lists = {
        {1.f, 1.f},
        {3.f, 1.f},
        {0.f, 2.f, 0.f, 5.f, 1.f, 0.f},
        {0.f, 0.f, 7.f, 0.f},
        {100.f, 1.f, 1.f, 1.f, 1.f, 1.f, 1.f, 1.f, 1.f, 1.f},
    };
    std::vector<float> decades;
    for (int i = 0; i < 9; ++i) decades.push_back(std::pow(10.f, static_cast<float>(i - 4)));
    lists.push_back(decades);
    Pcg32 rng(21, 4);
    std::vector<float> random(300);
    for (float& w : random) w = rng.next_float() < 0.3f ? 0.f : rng.next_float();
    lists.push_back(random);
    return lists;
}

TEST(AliasTable, PmfIsWeightOverTotalAndEmptyBinsHaveNone) {
    // The table's own probabilities (summed from its float thresholds) against weight / total:
    // float thresholds are exact to 6e-8 of a column's 1 / n, so 1e-6 relative plus 1e-7 / n
    // absolute bounds a correct table; a column given to the wrong bin moves a whole 1 / n.
    for (const auto& weights : weight_lists()) {
        const AliasTable t(weights);
        ASSERT_TRUE(t.valid());
        ASSERT_EQ(t.size(), weights.size());
        double total = 0.0, pmf_sum = 0.0;
        for (const float w : weights) total += w;
        for (std::size_t i = 0; i < weights.size(); ++i) {
            const double want = weights[i] / total;
            if (weights[i] == 0.f) {
                EXPECT_EQ(t.pmf(i), 0.f) << "bin " << i << " of " << weights.size();
            } else {
                EXPECT_NEAR(t.pmf(i), want, 1e-6 * want + 1e-7 / weights.size())
                    << "bin " << i << " of " << weights.size();
            }
            pmf_sum += t.pmf(i);
        }
        EXPECT_NEAR(pmf_sum, 1.0, 1e-6);
    }
}

TEST(AliasTable, ChosenBinsFollowThePmf) {
    // 200k draws per list (seed 3): the histogram of bins against 200k x pmf.
    for (const auto& weights : weight_lists()) {
        const AliasTable t(weights);
        Pcg32 rng(3, 1);
        constexpr int kDraws = 200000;
        std::vector<double> observed(weights.size(), 0.0), expected(weights.size(), 0.0);
        for (int k = 0; k < kDraws; ++k) observed[t.sample(rng.next_float())] += 1.0;
        for (std::size_t i = 0; i < weights.size(); ++i) expected[i] = kDraws * t.pmf(i);
        const auto r = test::chi2_histogram_test(observed, expected);
        EXPECT_GT(r.p_value, test::sidak_alpha(kStatisticalTests)) << r.summary;
    }
}

TEST(AliasTable, HandedBackNumberIsUniformInsideEachBin) {
    // The remapped number, in 10 slices of [0, 1), jointly with the bin: expected 200k x pmf /
    // 10 per cell. A remap that is uniform overall but not within a bin (the alias part's
    // numbers offset, say) fails here.
    const std::vector<float> weights = {0.f, 2.f, 0.f, 5.f, 1.f, 0.f, 0.5f, 3.f};
    const AliasTable t(weights);
    Pcg32 rng(17, 5);
    constexpr int kDraws = 200000, kSlices = 10;
    std::vector<double> observed(weights.size() * kSlices, 0.0), expected(observed.size(), 0.0);
    for (int k = 0; k < kDraws; ++k) {
        float r = -1.f;
        const std::size_t bin = t.sample(rng.next_float(), &r);
        ASSERT_GE(r, 0.f);
        ASSERT_LT(r, 1.f);
        observed[bin * kSlices + static_cast<std::size_t>(r * kSlices)] += 1.0;
    }
    for (std::size_t i = 0; i < weights.size(); ++i)
        for (int s = 0; s < kSlices; ++s) expected[i * kSlices + s] = kDraws * t.pmf(i) / kSlices;
    const auto result = test::chi2_histogram_test(observed, expected);
    EXPECT_GT(result.p_value, test::sidak_alpha(kStatisticalTests)) << result.summary;
}

TEST(AliasTable, EdgeNumbersAndBadWeights) {
    // u = 0, the last float below 1, every column's edge and its neighbours, and NaN: a valid
    // bin with weight, a handed-back number in [0, 1) (NaN only for a NaN u). Negative and
    // non-finite weights count as empty; all-empty is invalid.
    const std::vector<float> weights = {0.f, 2.f, -1.f, 5.f, std::nanf(""), 1.f, INFINITY, 0.f};
    const AliasTable t(weights);
    ASSERT_TRUE(t.valid());
    std::vector<float> us = {0.f, 0x1.fffffep-1f};
    for (int c = 1; c < 8; ++c) {
        const float edge = static_cast<float>(c) / 8.f;
        us.insert(us.end(), {edge, std::nextafter(edge, 0.f), std::nextafter(edge, 1.f)});
    }
    for (const float u : us) {
        float r = -1.f;
        const std::size_t bin = t.sample(u, &r);
        ASSERT_LT(bin, weights.size());
        EXPECT_TRUE(bin == 1 || bin == 3 || bin == 5) << "u " << u << " bin " << bin;
        EXPECT_GE(r, 0.f);
        EXPECT_LT(r, 1.f);
    }
    const std::size_t nan_bin = t.sample(std::nanf(""));
    EXPECT_TRUE(nan_bin == 1 || nan_bin == 3 || nan_bin == 5) << nan_bin;
    EXPECT_FALSE(AliasTable({0.f, 0.f}).valid());
    EXPECT_FALSE(AliasTable({std::nanf(""), -1.f}).valid());
    EXPECT_FALSE(AliasTable(std::vector<float>{}).valid());
}

}  // namespace
}  // namespace gdmlt
