// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/block_tridiagonal.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

namespace gdmlt::manifold {
namespace {

template <int Columns>
using Block = Eigen::Matrix<double, 2, Columns>;

template <int Columns>
std::optional<BlockSolution<Columns>> dense_solve(const BlockTridiagonal& system,
                                                  std::span<const Block<Columns>> rhs,
                                                  const BlockSolveSettings& settings) {
    const std::size_t n = system.size();
    const Eigen::MatrixXd m = system.dense();
    if (!m.allFinite()) return std::nullopt;
    Eigen::FullPivLU<Eigen::MatrixXd> lu(m);
    // Singular when a pivot is small relative to the largest entry of any block (the ignored
    // corner blocks included, as in the pivot test of thomas_solve).
    double scale = m.cwiseAbs().maxCoeff();
    if (n > 0) {
        scale = std::max({scale, system.lower.front().cwiseAbs().maxCoeff(),
                          system.upper.back().cwiseAbs().maxCoeff()});
    }
    const auto& lu_matrix = lu.matrixLU();
    for (Eigen::Index i = 0; i < lu_matrix.rows(); ++i)
        if (!(std::abs(lu_matrix(i, i)) > settings.singular_threshold * scale)) return std::nullopt;
    const auto n2 = static_cast<Eigen::Index>(2 * n);
    Eigen::MatrixXd b(n2, Columns);
    for (std::size_t i = 0; i < n; ++i) b.middleRows(static_cast<Eigen::Index>(2 * i), 2) = rhs[i];
    const Eigen::MatrixXd x = lu.solve(b);
    if (!x.allFinite()) return std::nullopt;
    BlockSolution<Columns> out;
    out.used_dense_fallback = true;
    out.x.assign(n, Block<Columns>::Zero());
    for (std::size_t i = 0; i < n; ++i)
        out.x[i] = x.middleRows(static_cast<Eigen::Index>(2 * i), 2);
    for (Eigen::Index i = 0; i < n2; ++i)
        out.log_abs_determinant += std::log(std::abs(lu_matrix(i, i)));
    if (!std::isfinite(out.log_abs_determinant)) return std::nullopt;
    return out;
}

template <int Columns>
std::optional<BlockSolution<Columns>> thomas_solve(const BlockTridiagonal& system,
                                                   std::span<const Block<Columns>> rhs,
                                                   const BlockSolveSettings& settings) {
    const std::size_t n = system.size();
    if (rhs.size() != n) return std::nullopt;
    BlockSolution<Columns> out;
    if (n == 0) return out;
    ChainArray<Mat2d> pivot_inverse(n, Mat2d::Zero());
    ChainArray<Block<Columns>> y(n, Block<Columns>::Zero());
    // Forward elimination: D_0 = B_0, D_i = B_i - A_i D_{i-1}^-1 C_{i-1}; same on the rhs.
    for (std::size_t i = 0; i < n; ++i) {
        Mat2d d = system.diagonal[i];
        y[i] = rhs[i];
        if (i > 0) {
            const Mat2d l = system.lower[i] * pivot_inverse[i - 1];
            d -= l * system.upper[i - 1];
            y[i] -= l * y[i - 1];
        }
        const double det = d.determinant();
        // Relative to the row's own blocks (lower[0] and upper[n-1] included, although they do
        // not enter the matrix): a pivot that is tiny only because the whole row is tiny is not
        // singular, a pivot much smaller than its row's couplings is.
        const double scale = std::max(
            {d.cwiseAbs().maxCoeff(), system.lower[i].cwiseAbs().maxCoeff(),
             system.diagonal[i].cwiseAbs().maxCoeff(), system.upper[i].cwiseAbs().maxCoeff()});
        if (!std::isfinite(det) || !(std::abs(det) > settings.singular_threshold * scale * scale))
            return dense_solve(system, rhs, settings);
        pivot_inverse[i] = Mat2d{{d(1, 1), -d(0, 1)}, {-d(1, 0), d(0, 0)}} / det;
        out.log_abs_determinant += std::log(std::abs(det));
    }
    // Back substitution: X_{n-1} = D^-1 Y_{n-1}, X_i = D_i^-1 (Y_i - C_i X_{i+1}).
    out.x.assign(n, Block<Columns>::Zero());
    out.x[n - 1] = pivot_inverse[n - 1] * y[n - 1];
    for (std::size_t i = n - 1; i-- > 0;)
        out.x[i] = pivot_inverse[i] * (y[i] - system.upper[i] * out.x[i + 1]);
    for (const auto& xi : out.x)
        if (!xi.allFinite()) return std::nullopt;
    if (!std::isfinite(out.log_abs_determinant)) return std::nullopt;
    return out;
}

}  // namespace

Eigen::MatrixXd BlockTridiagonal::dense() const {
    const std::size_t n = size();
    const auto n2 = static_cast<Eigen::Index>(2 * n);
    Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n2, n2);
    for (std::size_t i = 0; i < n; ++i) {
        const auto r = static_cast<Eigen::Index>(2 * i);
        m.block<2, 2>(r, r) = diagonal[i];
        if (i > 0) m.block<2, 2>(r, r - 2) = lower[i];
        if (i + 1 < n) m.block<2, 2>(r, r + 2) = upper[i];
    }
    return m;
}

std::optional<BlockSolution<1>> solve(const BlockTridiagonal& system, std::span<const Vec2d> rhs,
                                      const BlockSolveSettings& settings) {
    return thomas_solve<1>(system, rhs, settings);
}

std::optional<BlockSolution<2>> solve(const BlockTridiagonal& system, std::span<const Mat2d> rhs,
                                      const BlockSolveSettings& settings) {
    return thomas_solve<2>(system, rhs, settings);
}

std::optional<double> log_abs_determinant(const BlockTridiagonal& system,
                                          const BlockSolveSettings& settings) {
    const std::optional<BlockSolution<1>> s =
        solve(system, as_span(ChainArray<Vec2d>(system.size(), Vec2d::Zero())), settings);
    if (!s) return std::nullopt;
    return s->log_abs_determinant;
}

}  // namespace gdmlt::manifold
