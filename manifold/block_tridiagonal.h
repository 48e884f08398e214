// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Block-tridiagonal linear systems with 2x2 blocks, the shape of a specular chain's constraint
// Jacobian (Jakob & Marschner 2012, sec. 4.2, eq. 6): row i couples vertex i to its neighbours,
//     lower[i] X_{i-1} + diagonal[i] X_i + upper[i] X_{i+1} = R_i,   i = 0..n-1
// (lower[0] and upper[n-1] do not enter the matrix, but they count in the scale of their row for
// the singularity test: a chain's first and last rows couple to the pinned or moved endpoints).
// Solved by the block Thomas algorithm (block LU without pivoting, O(n)); its pivots D_i also give
// log|det| (the determinant of a block-tridiagonal matrix is the product of the pivot determinants,
// Salkuyeh 2006). When a pivot is nearly singular although the matrix may not be, block LU without
// pivoting is unreliable, so we fall back to a dense fully pivoted LU of the 2n x 2n matrix (chains
// are short) and report singularity only when that fails too.
#include <optional>
#include <span>

#include "manifold/chain_array.h"
#include "manifold/surface_point.h"

namespace gdmlt::manifold {

struct BlockTridiagonal {
    ChainArray<Mat2d> lower, diagonal, upper;  // all of size n

    explicit BlockTridiagonal(std::size_t n = 0)
        : lower(n, Mat2d::Zero()), diagonal(n, Mat2d::Zero()), upper(n, Mat2d::Zero()) {}
    std::size_t size() const { return diagonal.size(); }
    /// The dense 2n x 2n matrix (tests, fallback).
    Eigen::MatrixXd dense() const;
};

struct BlockSolveSettings {
    /// A pivot D_i is "nearly singular" when |det D_i| <= threshold * s^2, s the largest entry
    /// of D_i and of row i's blocks, and the dense
    /// matrix is singular when its smallest LU pivot is <= threshold * its largest.
    double singular_threshold = 1e-12;
};

/// Solution blocks X_i (2 x m each, m = 1 or 2) and log|det| of the matrix.
template <int Columns>
struct BlockSolution {
    ChainArray<Eigen::Matrix<double, 2, Columns>> x;
    double log_abs_determinant = 0.0;
    bool used_dense_fallback = false;
};

/// Solves the system for right-hand sides with one column (a displacement) or two (a tangent
/// map). Empty when the matrix is singular (relative to the threshold) or not finite.
std::optional<BlockSolution<1>> solve(const BlockTridiagonal& system, std::span<const Vec2d> rhs,
                                      const BlockSolveSettings& settings = {});
std::optional<BlockSolution<2>> solve(const BlockTridiagonal& system, std::span<const Mat2d> rhs,
                                      const BlockSolveSettings& settings = {});

/// log|det| of the matrix alone; empty when singular.
std::optional<double> log_abs_determinant(const BlockTridiagonal& system,
                                          const BlockSolveSettings& settings = {});

}  // namespace gdmlt::manifold
