// SPDX-License-Identifier: GPL-3.0-or-later
#include "tests/support/chi2.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>
#include <sstream>
#include <vector>

namespace gdmlt::test {

Chi2Result chi2_sphere_test(const std::function<std::optional<Vec3f>(Pcg32&)>& sample,
                            const std::function<double(const Vec3f&)>& pdf,
                            const Chi2Settings& settings) {
    const int nz = settings.z_bins, nphi = settings.phi_bins;
    const auto bin_count = static_cast<std::size_t>(nz * nphi);
    std::vector<double> observed(bin_count + 1, 0.0), expected(bin_count + 1, 0.0);

    Pcg32 rng(settings.seed, 7);
    for (int i = 0; i < settings.samples; ++i) {
        const std::optional<Vec3f> w = sample(rng);
        if (!w || !w->allFinite()) {
            observed[bin_count] += 1.0;
            continue;
        }
        const double z = std::clamp(static_cast<double>(w->z()), -1.0, 1.0);
        double phi = std::atan2(static_cast<double>(w->y()), static_cast<double>(w->x()));
        if (phi < 0.0) phi += 2.0 * M_PI;
        const int iz = std::min(static_cast<int>((z + 1.0) * 0.5 * nz), nz - 1);
        const int iphi = std::min(static_cast<int>(phi / (2.0 * M_PI) * nphi), nphi - 1);
        observed[static_cast<std::size_t>(iz * nphi + iphi)] += 1.0;
    }

    // Midpoint rule on a sub-grid; dz dphi is the solid-angle element.
    const int m = settings.sub_samples;
    const double dz = 2.0 / nz / m, dphi = 2.0 * M_PI / nphi / m;
    double integral = 0.0;
    for (int iz = 0; iz < nz; ++iz) {
        for (int iphi = 0; iphi < nphi; ++iphi) {
            double mass = 0.0;
            for (int a = 0; a < m; ++a) {
                const double z = -1.0 + (iz * m + a + 0.5) * dz;
                const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
                for (int b = 0; b < m; ++b) {
                    const double phi = (iphi * m + b + 0.5) * dphi;
                    const Vec3f w(static_cast<float>(r * std::cos(phi)),
                                  static_cast<float>(r * std::sin(phi)), static_cast<float>(z));
                    mass += pdf(w) * dz * dphi;
                }
            }
            expected[static_cast<std::size_t>(iz * nphi + iphi)] = mass * settings.samples;
            integral += mass;
        }
    }
    expected[bin_count] = std::max(0.0, 1.0 - integral) * settings.samples;

    Chi2Result result = chi2_histogram_test(observed, expected);
    result.pdf_integral = integral;
    result.summary += "; pdf integral = " + std::to_string(integral) +
                      ", failed samples = " + std::to_string(observed[bin_count]) + " (expected " +
                      std::to_string(expected[bin_count]) + ")";
    return result;
}

Chi2Result chi2_histogram_test(const std::vector<double>& observed,
                               const std::vector<double>& expected) {
    const std::size_t bin_count = observed.size();
    // Pool small bins (sorted by expected count) until each pooled group expects >= 5.
    std::vector<std::size_t> order(bin_count);
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return expected[a] < expected[b]; });
    Chi2Result result;
    double pooled_observed = 0.0, pooled_expected = 0.0;
    int cells = 0;
    double statistic = 0.0;
    std::ostringstream notes;
    for (std::size_t i : order) {
        if (expected[i] == 0.0) {
            if (observed[i] > 0.0) {
                // Samples where the pdf claims there can be none: a certain failure.
                notes << "bin " << i << " observed " << observed[i] << " with zero expected; ";
                statistic = std::numeric_limits<double>::infinity();
            }
            continue;
        }
        if (expected[i] < 5.0) {
            pooled_observed += observed[i];
            pooled_expected += expected[i];
            if (pooled_expected >= 5.0) {
                statistic += sqr(pooled_observed - pooled_expected) / pooled_expected;
                ++cells;
                pooled_observed = pooled_expected = 0.0;
            }
            continue;
        }
        statistic += sqr(observed[i] - expected[i]) / expected[i];
        ++cells;
    }
    if (pooled_expected > 0.0) {
        statistic += sqr(pooled_observed - pooled_expected) / pooled_expected;
        ++cells;
    }
    result.statistic = statistic;
    result.degrees_of_freedom = std::max(cells - 1, 1);
    if (std::isinf(statistic)) {
        result.p_value = 0.0;
    } else {
        boost::math::chi_squared dist(result.degrees_of_freedom);
        result.p_value = boost::math::cdf(boost::math::complement(dist, statistic));
    }
    std::ostringstream summary;
    summary << "chi2 = " << statistic << ", dof = " << result.degrees_of_freedom
            << ", p = " << result.p_value << " " << notes.str();
    result.summary = summary.str();
    return result;
}

double sidak_alpha(int test_count, double alpha) {
    return 1.0 - std::pow(1.0 - alpha, 1.0 / static_cast<double>(test_count));
}

double relative_mse(const std::vector<float>& image, const std::vector<float>& reference) {
    double sum = 0.0;
    for (std::size_t i = 0; i < image.size(); ++i) {
        const double r = reference[i];
        sum += sqr(static_cast<double>(image[i]) - r) / (r * r + 0.01);
    }
    return image.empty() ? 0.0 : sum / static_cast<double>(image.size());
}

}  // namespace gdmlt::test
