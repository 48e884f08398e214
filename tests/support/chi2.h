// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Chi-square goodness-of-fit test of a direction sampler against its claimed pdf, over the unit
// sphere binned in (z = cos theta, phi): equal z steps give equal-solid-angle bins. Expected
// counts come from integrating the pdf numerically over each bin; bins expecting fewer than 5
// samples are pooled (the usual validity rule of the chi-square approximation); failed samples
// form one more bin whose expected count is N * (1 - integral of the pdf).
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/math/types.h"
#include "core/sampling/rng.h"

namespace gdmlt::test {

struct Chi2Result {
    double statistic = 0.0;
    int degrees_of_freedom = 0;
    double p_value = 0.0;
    double pdf_integral = 0.0;  // numerical integral of the pdf over the sphere
    std::string summary;        // for failure messages
};

struct Chi2Settings {
    int samples = 200000;
    int z_bins = 20;
    int phi_bins = 40;
    int sub_samples = 12;  // per bin and axis, for integrating the pdf
    std::uint64_t seed = 1;
};

/// `sample` draws one direction from the generator (nullopt = the sampler failed), `pdf`
/// returns the solid-angle density of a direction.
Chi2Result chi2_sphere_test(const std::function<std::optional<Vec3f>(Pcg32&)>& sample,
                            const std::function<double(const Vec3f&)>& pdf,
                            const Chi2Settings& settings = {});

/// Pearson's chi-square of observed against expected counts per bin (same length). Bins
/// expecting fewer than 5 are pooled, smallest first; a count in a bin expecting none fails
/// outright (statistic infinite, p = 0).
Chi2Result chi2_histogram_test(const std::vector<double>& observed,
                               const std::vector<double>& expected);

/// Significance level for one of `test_count` tests run together: the Sidak correction of
/// alpha = 0.01, so the whole suite has a 1% chance of a false alarm.
double sidak_alpha(int test_count, double alpha = 0.01);

/// Relative MSE of the references' README: mean over pixels and channels of
/// (x - ref)^2 / (ref^2 + 0.01).
double relative_mse(const std::vector<float>& image, const std::vector<float>& reference);

}  // namespace gdmlt::test
