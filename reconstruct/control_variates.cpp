// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/control_variates.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "core/math/stopwatch.h"
#include "reconstruct/graph_system.h"

namespace gdmlt::reconstruct {

ReconstructResult solve_cv(const ReconstructInput& input, const ReconstructConfig& config) {
    if (config.block_size <= 0) throw std::invalid_argument("reconstruct: block_size <= 0");
    if (!(config.cv_epsilon > 0.0)) throw std::invalid_argument("reconstruct: cv_epsilon <= 0");
    const auto t0 = Clock::now();
    ReconstructResult result;
    ReconstructStats& stats = result.stats;
    const detail::CompiledGraph g = detail::compile_graph(input, stats);
    const std::size_t n = g.pixels;
    const auto width = static_cast<std::size_t>(g.width);
    const bool weighted = config.cv_use_variance && !g.primal_variance.empty();
    const bool edge_var_lattice = !g.right_variance.empty();
    const bool edge_var_irregular = !g.irregular_variance.empty();
    // Starting point x^0 = p (Rousselle et al. 2016 start from the primal image; missing = 0).
    std::vector<double> x = g.primal;
    std::vector<double> next(3 * n, 0.0);
    stats.seconds_setup = seconds_since(t0);

    const auto t1 = Clock::now();
    const double eps = config.cv_epsilon;
    // v scales Var(p) into the variance of the current iterate x^k. x^0 = p, so v_0 = 1; each
    // iteration averages the pixel with about 4 neighbour estimates, dividing the variance by
    // ~5 at first and by less as the estimates become correlated: the course code's model
    // v_k = 1 / prod_{m<k} (1.01 + 4 * 0.5^m) (Rousselle et al. 2016's public course code; there
    // the product starts one step earlier, which would discount even the untouched primal).
    double v = 1.0;
    for (int k = 0; k < config.cv_iterations; ++k) {
        const double* xo = x.data();
        double* xn = next.data();
        detail::for_blocks(
            n, static_cast<std::size_t>(config.block_size), [&](std::size_t b, std::size_t e) {
                for (std::size_t i = b; i < e; ++i) {
                    double num[3] = {0.0, 0.0, 0.0};
                    double den = 0.0;
                    if (g.has_primal[i]) {
                        const double wi = weighted ? 1.0 / (eps + g.primal_variance[i] * v) : 1.0;
                        for (int c = 0; c < 3; ++c) num[c] += wi * xo[3 * i + c];
                        den += wi;
                    }
                    // Estimate of x_i from neighbour j: x_j + sign * d, with edge weight w0 and
                    // difference variance var_e; weight w0 / (eps + Var(x_j) + var_e).
                    const auto estimate = [&](float w0, std::size_t j, const float* d, double sign,
                                              double var_e) {
                        if (w0 == 0.f) return;
                        double wij = w0;
                        if (weighted) {
                            // A neighbour without primal has no own variance; its iterate is only
                            // known through others, so treat it as the pixel's own variance.
                            const double vj =
                                g.has_primal[j] ? g.primal_variance[j] : g.primal_variance[i];
                            wij = w0 / (eps + vj * v + var_e);
                        }
                        for (int c = 0; c < 3; ++c) num[c] += wij * (xo[3 * j + c] + sign * d[c]);
                        den += wij;
                    };
                    if (i + 1 < n)
                        estimate(g.right_weight[i], i + 1, &g.right_difference[3 * i], -1.0,
                                 edge_var_lattice ? g.right_variance[i] : 0.0);
                    if (i >= 1)
                        estimate(g.right_weight[i - 1], i - 1, &g.right_difference[3 * (i - 1)],
                                 1.0, edge_var_lattice ? g.right_variance[i - 1] : 0.0);
                    if (i + width < n)
                        estimate(g.down_weight[i], i + width, &g.down_difference[3 * i], -1.0,
                                 edge_var_lattice ? g.down_variance[i] : 0.0);
                    if (i >= width)
                        estimate(g.down_weight[i - width], i - width,
                                 &g.down_difference[3 * (i - width)], 1.0,
                                 edge_var_lattice ? g.down_variance[i - width] : 0.0);
                    if (!g.csr_offset.empty()) {
                        for (auto k2 = static_cast<std::size_t>(g.csr_offset[i]);
                             k2 < static_cast<std::size_t>(g.csr_offset[i + 1]); ++k2) {
                            const auto ed = static_cast<std::size_t>(g.csr_edge[k2]);
                            const bool is_to = g.irregular_to[ed] == static_cast<std::int32_t>(i);
                            const auto j = static_cast<std::size_t>(is_to ? g.irregular_from[ed]
                                                                          : g.irregular_to[ed]);
                            estimate(g.irregular_weight[ed], j, &g.irregular_difference[3 * ed],
                                     is_to ? 1.0 : -1.0,
                                     edge_var_irregular ? g.irregular_variance[ed] : 0.0);
                        }
                    }
                    // Infinite variances give weight 0; a pixel with nothing to average keeps its
                    // value (a missing primal with no usable neighbour stays 0).
                    if (den > 0.0 && std::isfinite(den)) {
                        for (int c = 0; c < 3; ++c) xn[3 * i + c] = num[c] / den;
                    } else {
                        for (int c = 0; c < 3; ++c) xn[3 * i + c] = xo[3 * i + c];
                    }
                }
            });
        x.swap(next);
        v /= 1.01 + 4.0 * std::pow(0.5, k);
        stats.iterations = k + 1;
    }
    stats.converged = true;
    stats.seconds_solve = seconds_since(t1);
    result.image = detail::to_image(g, x);
    stats.seconds_total = seconds_since(t0);
    return result;
}

}  // namespace gdmlt::reconstruct
