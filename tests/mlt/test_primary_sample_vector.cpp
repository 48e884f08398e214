// SPDX-License-Identifier: GPL-3.0-or-later
// The chain core: lazy primary samples, backup/restore, symmetric small steps, and a
// Metropolis chain on a toy target whose histogram must match the target.
#include <gtest/gtest.h>

#include <boost/math/distributions/chi_squared.hpp>

#include "mlt/mutation.h"
#include "mlt/primary_sample_vector.h"

namespace gdmlt::mlt {
namespace {

TEST(PrimarySampleVector, FirstLargeStepReplaysItsGenerator) {
    // A chain starts from a bootstrap sample by replaying the same generator.
    PrimarySampleVector a(MutationSettings{}, Pcg32(5, 9)), b(MutationSettings{}, Pcg32(5, 9));
    a.start_iteration(true);
    b.start_iteration(true);
    for (int i = 0; i < 20; ++i) EXPECT_EQ(a.next_double(), b.next_double());
}

TEST(PrimarySampleVector, RejectRestoresExactlyTheRejectedStatesSamples) {
    PrimarySampleVector psv(MutationSettings{}, Pcg32(1, 2));
    psv.start_iteration(true);
    for (int i = 0; i < 10; ++i) psv.next_1d();
    psv.accept();
    const std::vector<double> before = psv.values();
    for (bool large : {false, true}) {
        psv.start_iteration(large);
        for (int i = 0; i < 14; ++i) psv.next_1d();  // also creates 4 new coordinates
        EXPECT_NE(psv.values()[3], before[3]);
        psv.reject();
        const std::vector<double> after = psv.values();
        for (std::size_t i = 0; i < before.size(); ++i)
            EXPECT_EQ(after[i], before[i]) << "coordinate " << i;
    }
    // Coordinates only read by rejected proposals are drawn afresh when next read, as if the
    // rejected iterations never happened: values stay in [0, 1).
    psv.start_iteration(false);
    for (int i = 0; i < 14; ++i) {
        const float v = psv.next_1d();
        EXPECT_GE(v, 0.f);
        EXPECT_LT(v, 1.f);
    }
}

TEST(PrimarySampleVector, AcceptedSmallStepMovesEachReadCoordinateByAtMostS2) {
    MutationSettings settings;
    PrimarySampleVector psv(settings, Pcg32(3, 4));
    psv.start_iteration(true);
    for (int i = 0; i < 6; ++i) psv.next_1d();
    psv.accept();
    const std::vector<double> before = psv.values();
    psv.start_iteration(false);
    for (int i = 0; i < 6; ++i) psv.next_1d();
    psv.accept();
    const std::vector<double> after = psv.values();
    for (std::size_t i = 0; i < before.size(); ++i) {
        double d = std::abs(after[i] - before[i]);
        d = std::min(d, 1.0 - d);  // distance on the torus
        EXPECT_LE(d, settings.s2 + 1e-12);
        EXPECT_GE(d, settings.s1 - 1e-12);
    }
}

TEST(KelemenSmallStep, ProposalIsSymmetric) {
    // T(x -> y) = T(y -> x) for a translation-invariant kernel on the torus means the signed
    // offset d = y - x has a symmetric distribution. Histogram d into 16 bins on each side
    // (log-spaced, the natural scale of the kernel) and compare mirrored bins: each pair's
    // counts differ by binomial noise only (chi-square with 16 dof, 0.1% level: 39.25).
    const double s1 = 1.0 / 1024.0, s2 = 1.0 / 64.0, log_ratio = std::log(s2 / s1);
    Pcg32 rng(42, 1);
    constexpr int kBins = 16, kSamples = 400000;
    std::vector<double> positive(kBins, 0.0), negative(kBins, 0.0);
    for (int i = 0; i < kSamples; ++i) {
        const double x = rng.next_double();
        const double y = kelemen_small_step(x, s2, log_ratio, rng.next_double(), rng.next_double());
        ASSERT_GE(y, 0.0);
        ASSERT_LT(y, 1.0);
        double d = y - x;
        if (d > 0.5) d -= 1.0;
        if (d < -0.5) d += 1.0;
        const int bin = std::clamp(static_cast<int>(std::log(std::abs(d) / s1) / log_ratio * kBins),
                                   0, kBins - 1);
        (d > 0 ? positive : negative)[static_cast<std::size_t>(bin)] += 1.0;
    }
    double chi2 = 0.0;
    for (int b = 0; b < kBins; ++b) {
        const double p = positive[static_cast<std::size_t>(b)],
                     n = negative[static_cast<std::size_t>(b)];
        chi2 += (p - n) * (p - n) / (p + n);
        // Log-uniform magnitude: every log-spaced bin expects the same count.
        EXPECT_NEAR(p + n, kSamples / kBins, 5.0 * std::sqrt(kSamples / kBins));
    }
    EXPECT_LT(chi2, 39.25);
}

TEST(MetropolisChain, HistogramMatchesAToyTargetThatReadsAVariableNumberOfCoordinates) {
    // Target on primary sample space: f(u) = g(u0) h(v) with v = u1 when u0 < 0.5 and v = u2
    // otherwise, so which coordinates a state reads depends on the state (as with paths of
    // different lengths). Its (u0, v) marginal is proportional to g(u0) h(v).
    auto g = [](double x) { return 0.2 + x * x; };
    auto h = [](double x) { return x < 0.25 ? 3.0 : 0.5 + x; };
    auto target = [&](PrimarySampleVector& psv, double* u0_out, double* v_out) {
        const double u0 = psv.next_double();
        const double u1 = psv.next_double();
        double v = u1;
        if (u0 >= 0.5) v = psv.next_double();
        *u0_out = u0;
        *v_out = v;
        return g(u0) * h(v);
    };
    // Many independent chains, each started exactly from the target (rejection sampling with
    // a replayed generator, so the start state is a proper chain state) and run for 40
    // mutations: if the kernel keeps the target invariant, the final states are independent
    // draws from it, and a chi-square test of their histogram is valid. Seeds fixed.
    constexpr int kChains = 20000, kMutations = 40, kBins = 8;
    const double f_max = g(1.0) * 3.0;
    std::vector<double> counts(kBins * kBins, 0.0);
    MutationSettings settings;
    settings.s2 = 1.0 / 16.0;  // larger steps: more movement in 40 mutations
    for (int c = 0; c < kChains; ++c) {
        Pcg32 control(100 + static_cast<std::uint64_t>(c), 7);
        std::uint64_t key = 0;
        for (;; ++key) {  // rejection-sample the start state
            PrimarySampleVector probe(settings, Pcg32(static_cast<std::uint64_t>(c), key));
            probe.start_iteration(true);
            double u0, v;
            if (control.next_double() * f_max < target(probe, &u0, &v)) break;
        }
        PrimarySampleVector psv(settings, Pcg32(static_cast<std::uint64_t>(c), key));
        psv.start_iteration(true);
        double u0, v;
        double f_current = target(psv, &u0, &v);
        psv.accept();
        double cur_u0 = u0, cur_v = v;
        for (int m = 0; m < kMutations; ++m) {
            psv.start_iteration(control.next_double() < 0.3);
            const double f_proposal = target(psv, &u0, &v);
            if (control.next_double() < std::min(1.0, f_proposal / f_current)) {
                psv.accept();
                f_current = f_proposal;
                cur_u0 = u0;
                cur_v = v;
            } else {
                psv.reject();
            }
        }
        const int i = std::min(static_cast<int>(cur_u0 * kBins), kBins - 1);
        const int j = std::min(static_cast<int>(cur_v * kBins), kBins - 1);
        counts[static_cast<std::size_t>(i * kBins + j)] += 1.0;
    }
    // Expected counts from the marginal density, integrated by a fine midpoint rule.
    std::vector<double> expected(kBins * kBins, 0.0);
    double total = 0.0;
    constexpr int kFine = 64;
    for (int i = 0; i < kBins * kFine; ++i)
        for (int j = 0; j < kBins * kFine; ++j) {
            const double w = g((i + 0.5) / (kBins * kFine)) * h((j + 0.5) / (kBins * kFine));
            expected[static_cast<std::size_t>((i / kFine) * kBins + j / kFine)] += w;
            total += w;
        }
    double chi2 = 0.0;
    for (std::size_t k = 0; k < counts.size(); ++k) {
        const double e = expected[k] / total * kChains;
        chi2 += (counts[k] - e) * (counts[k] - e) / e;
    }
    boost::math::chi_squared distribution(kBins * kBins - 1);
    const double p_value = boost::math::cdf(boost::math::complement(distribution, chi2));
    EXPECT_GT(p_value, 0.001) << "chi2 = " << chi2;
}

}  // namespace
}  // namespace gdmlt::mlt
