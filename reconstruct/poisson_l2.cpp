// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/poisson_l2.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "core/math/stopwatch.h"
#include "reconstruct/graph_system.h"

namespace gdmlt::reconstruct {

ReconstructResult solve_l2(const ReconstructInput& input, const ReconstructConfig& config) {
    if (!std::isfinite(config.alpha) || config.alpha < 0.0)
        throw std::invalid_argument("reconstruct: alpha must be finite and >= 0");
    if (config.block_size <= 0) throw std::invalid_argument("reconstruct: block_size <= 0");
    const auto t0 = Clock::now();
    ReconstructResult result;
    const detail::CompiledGraph graph = detail::compile_graph(input, result.stats);
    const detail::SystemWeights weights = detail::l2_weights(graph, config.alpha);
    std::vector<double> x = detail::initial_guess(graph, config.warm_start);
    result.stats.seconds_setup = seconds_since(t0);

    const auto t1 = Clock::now();
    detail::CgWorkspace work;
    const detail::CgOutcome cg =
        detail::solve_pcg(graph, weights, x, config.cg_max_iterations, config.cg_tolerance,
                          static_cast<std::size_t>(config.block_size), work);
    result.stats.seconds_solve = seconds_since(t1);

    result.stats.iterations = cg.iterations;
    result.stats.cg_iterations = cg.iterations;
    result.stats.final_relative_residual = cg.relative_residual;
    result.stats.converged = cg.converged;
    result.image = detail::to_image(graph, x);
    result.stats.seconds_total = seconds_since(t0);
    return result;
}

}  // namespace gdmlt::reconstruct
