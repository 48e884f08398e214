// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Internal to reconstruct/: the compiled form of a PixelGraph shared by the L2, L1 and CV
// solvers, the matrix-free screened Poisson operator and the Jacobi-preconditioned CG.
//
// Layout (why): the 4-neighbour lattice is by far the common case, so lattice edges live in
// per-pixel arrays (weight and RGB difference of the edge to the right and the edge below); the
// operator then reads four contiguous weights per pixel and needs no index arrays. Every other
// edge (ADAP's diagonal or long-range neighbours, duplicates of a lattice pair) goes to an
// irregular edge list with a CSR incidence built once. Any graph works; the lattice is fast.
//
// Determinism: per-pixel updates are independent of the partition, and every reduction sums
// fixed blocks of `block_size` pixels, each block sequentially, then the block sums in order,
// so results are bit-identical at any thread count.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "reconstruct/reconstruct_input.h"
#include "reconstruct/reconstruct_result.h"

namespace gdmlt::reconstruct::detail {

struct CompiledGraph {
    int width = 0;
    int height = 0;
    std::size_t pixels = 0;

    // Lattice edges, per pixel; weight 0 means "no edge". Differences are oriented as
    // I(right) - I(i) and I(below) - I(i), 3 floats per pixel.
    std::vector<float> right_weight, down_weight;
    std::vector<float> right_difference, down_difference;
    std::vector<float> right_variance, down_variance;  // empty when unknown

    // Irregular edges (structure of arrays) and, per pixel, the irregular edges touching it.
    std::vector<std::int32_t> irregular_from, irregular_to;
    std::vector<float> irregular_difference;  // 3 per edge: I(to) - I(from)
    std::vector<float> irregular_weight;
    std::vector<float> irregular_variance;  // empty when unknown
    std::vector<std::int32_t> csr_offset;   // pixels + 1 entries; empty when no irregular edge
    std::vector<std::int32_t> csr_edge;

    // Primal, 3 per pixel, 0 where missing; has_primal marks the finite ones.
    std::vector<double> primal;
    std::vector<std::uint8_t> has_primal;
    // Per-pixel primal variance (+inf where unknown-but-present-elsewhere); empty when unknown.
    std::vector<float> primal_variance;

    bool has_irregular() const { return !irregular_from.empty(); }
};

/// Validates and compiles; fills the drop/missing counters of `stats`. Throws
/// std::invalid_argument on out-of-range indices or inconsistent sizes.
CompiledGraph compile_graph(const ReconstructInput& input, ReconstructStats& stats);

/// Current weights of the least-squares system
///   sum_e w_e |x_to - x_from - g_e|^2 + sum_i s_i |x_i - p_i|^2
/// (s_i = alpha^2 for L2; IRLS changes both). Same layout as CompiledGraph.
struct SystemWeights {
    std::vector<float> right, down, irregular;
    std::vector<double> screen;
};

/// L2 weights: the graph's edge weights and alpha^2 on every pixel with a primal.
SystemWeights l2_weights(const CompiledGraph& graph, double alpha);

/// Work vectors of CG, kept between IRLS iterations so large buffers are allocated once.
struct CgWorkspace {
    std::vector<double> r, p, q, inv_diag;
};

struct CgOutcome {
    int iterations = 0;
    double relative_residual = 0.0;
    bool converged = false;
};

/// Jacobi-preconditioned CG on the normal equations, all three channels at once with their own
/// step lengths (three independent CGs sharing every matrix pass). `x` (3 per pixel) is the
/// initial guess and the result. Stops when |r_c| <= tolerance |b_c| for all c.
CgOutcome solve_pcg(const CompiledGraph& graph, const SystemWeights& weights,
                    std::vector<double>& x, int max_iterations, double tolerance,
                    std::size_t block_size, CgWorkspace& work);

/// Initial guess: the primal (0 where missing) when warm, else zeros.
std::vector<double> initial_guess(const CompiledGraph& graph, bool warm_start);

/// RGB float image from the 3-per-pixel solution.
Image to_image(const CompiledGraph& graph, const std::vector<double>& x);

/// Runs body(begin, end) on fixed pixel blocks [b*block, min(n, (b+1)*block)) in parallel and
/// sums the returned N-vectors block by block in order: bit-identical at any thread count.
template <std::size_t N, typename Body>
std::array<double, N> reduce_blocks(std::size_t n, std::size_t block, const Body& body) {
    const std::size_t blocks = (n + block - 1) / block;
    std::vector<std::array<double, N>> partial(blocks);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t b = range.begin(); b != range.end(); ++b)
                              partial[b] = body(b * block, std::min(n, (b + 1) * block));
                      });
    std::array<double, N> total{};
    for (const auto& part : partial)
        for (std::size_t k = 0; k < N; ++k) total[k] += part[k];
    return total;
}

/// Runs body(begin, end) over [0, n) in parallel, no reduction (any partition is fine).
template <typename Body>
void for_blocks(std::size_t n, std::size_t block, const Body& body) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, block),
        [&](const tbb::blocked_range<std::size_t>& range) { body(range.begin(), range.end()); });
}

}  // namespace gdmlt::reconstruct::detail
