// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/poisson_l1.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "core/math/stopwatch.h"
#include "reconstruct/graph_system.h"

namespace gdmlt::reconstruct {
namespace {

inline double norm3(double a, double b, double c) {
    return std::sqrt(a * a + b * b + c * c);
}

/// The L1 objective J(x) = alpha sum_i |x_i - p_i| + sum_e w_e |x_to - x_from - g_e| (RGB
/// 2-norms; Kettunen 2015 eq. 11 on a general graph), and, in the same pass, the IRLS weights
/// for the next solve:  screen_i = alpha^2 / (alpha |x_i - p_i| + rho)  (the NVIDIA solver's
/// weight of the data row alpha (x - p)), edge weight w_e / (|r_e| + rho).
///
/// The NVIDIA solver also rescales all weights to mean 1. Scaling every weight by one constant
/// changes neither the minimiser nor the Jacobi-preconditioned CG iterates nor the relative
/// residual; it only guards float range there, which double does not need, so we skip it.
double objective_and_weights(const detail::CompiledGraph& g, double alpha,
                             const std::vector<double>& xs, double rho, double huber_k,
                             detail::SystemWeights& w, std::size_t block) {
    const std::size_t n = g.pixels;
    // Huber's threshold of a row with per-channel variance v (reconstruct_config.h): the RGB
    // norm of its noise is about sqrt(3 v). 0 (pure L1) when off or unknown; the objective
    // reported stays the L1 one (it only decides when to stop).
    const auto delta = [huber_k](const std::vector<float>& variance, std::size_t k) {
        if (huber_k <= 0.0 || variance.empty()) return 0.0;
        const double v = variance[k];
        return std::isfinite(v) && v > 0.0 ? huber_k * std::sqrt(3.0 * v) : 0.0;
    };
    const auto width = static_cast<std::size_t>(g.width);
    const double* x = xs.data();
    const auto pixel_part = detail::reduce_blocks<1>(n, block, [&](std::size_t b, std::size_t e) {
        double sum = 0.0;
        for (std::size_t i = b; i < e; ++i) {
            const double* xi = x + 3 * i;
            if (g.has_primal[i]) {
                const double* pi = &g.primal[3 * i];
                const double r = alpha * norm3(xi[0] - pi[0], xi[1] - pi[1], xi[2] - pi[2]);
                sum += r;
                w.screen[i] = alpha * alpha / (r + rho);
            }
            const auto lattice = [&](float w0, std::size_t j, const float* d, float& out,
                                     double delta_e) {
                if (w0 == 0.f) return;
                const double* xj = x + 3 * j;
                const double r =
                    norm3(xj[0] - xi[0] - d[0], xj[1] - xi[1] - d[1], xj[2] - xi[2] - d[2]);
                sum += w0 * r;
                out = static_cast<float>(w0 / (std::max(r, delta_e) + rho));
            };
            if (i + 1 < n)
                lattice(g.right_weight[i], i + 1, &g.right_difference[3 * i], w.right[i],
                        delta(g.right_variance, i));
            if (i + width < n)
                lattice(g.down_weight[i], i + width, &g.down_difference[3 * i], w.down[i],
                        delta(g.down_variance, i));
        }
        return std::array<double, 1>{sum};
    });
    double total = pixel_part[0];
    const std::size_t m = g.irregular_from.size();
    if (m > 0) {
        const auto edge_part =
            detail::reduce_blocks<1>(m, block, [&](std::size_t b, std::size_t e) {
                double sum = 0.0;
                for (std::size_t k = b; k < e; ++k) {
                    const double* xa = x + 3 * static_cast<std::size_t>(g.irregular_from[k]);
                    const double* xb = x + 3 * static_cast<std::size_t>(g.irregular_to[k]);
                    const float* d = &g.irregular_difference[3 * k];
                    const double r =
                        norm3(xb[0] - xa[0] - d[0], xb[1] - xa[1] - d[1], xb[2] - xa[2] - d[2]);
                    const double w0 = g.irregular_weight[k];
                    sum += w0 * r;
                    w.irregular[k] = static_cast<float>(
                        w0 / (std::max(r, delta(g.irregular_variance, k)) + rho));
                }
                return std::array<double, 1>{sum};
            });
        total += edge_part[0];
    }
    return total;
}

}  // namespace

ReconstructResult solve_l1(const ReconstructInput& input, const ReconstructConfig& config) {
    if (!std::isfinite(config.alpha) || config.alpha < 0.0)
        throw std::invalid_argument("reconstruct: alpha must be finite and >= 0");
    if (config.block_size <= 0) throw std::invalid_argument("reconstruct: block_size <= 0");
    if (!(config.huber_k >= 0.0 && std::isfinite(config.huber_k)))
        throw std::invalid_argument("reconstruct: huber_k must be finite and >= 0");
    if (!(config.irls_rho_min > 0.0))
        throw std::invalid_argument("reconstruct: irls_rho_min must be > 0");
    const auto block = static_cast<std::size_t>(config.block_size);
    const auto t0 = Clock::now();
    ReconstructResult result;
    ReconstructStats& stats = result.stats;
    const detail::CompiledGraph graph = detail::compile_graph(input, stats);
    detail::SystemWeights weights = detail::l2_weights(graph, config.alpha);
    std::vector<double> x = detail::initial_guess(graph, config.warm_start);
    stats.seconds_setup = seconds_since(t0);

    const auto t1 = Clock::now();
    detail::CgWorkspace work;
    const int outer = std::max(1, config.irls_iterations);
    for (int k = 0; k < outer; ++k) {
        // Iteration 0 is the plain L2 solve (unit IRLS weights); each later one solves with
        // the weights computed from the previous solution, warm-started from it.
        const detail::CgOutcome cg = detail::solve_pcg(graph, weights, x, config.irls_cg_iterations,
                                                       config.irls_cg_tolerance, block, work);
        stats.cg_iterations += cg.iterations;
        stats.cg_iterations_per_outer.push_back(cg.iterations);
        stats.final_relative_residual = cg.relative_residual;
        stats.converged = cg.converged;
        stats.iterations = k + 1;
        // rho_{k+1} = rho0 gamma^k (NVIDIA L1D schedule), never below the floor.
        const double rho =
            std::max(config.irls_rho_min, config.irls_rho0 * std::pow(config.irls_gamma, k));
        const double objective =
            objective_and_weights(graph, config.alpha, x, rho, config.huber_k, weights, block);
        stats.l1_objective.push_back(objective);
        if (k >= 1 && config.l1_objective_tolerance > 0.0) {
            const double previous = stats.l1_objective[static_cast<std::size_t>(k - 1)];
            if (std::abs(objective - previous) <= config.l1_objective_tolerance * previous) break;
        }
    }
    stats.seconds_solve = seconds_since(t1);
    result.image = detail::to_image(graph, x);
    stats.seconds_total = seconds_since(t0);
    return result;
}

}  // namespace gdmlt::reconstruct
