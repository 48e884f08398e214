// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/generalized_geometry.h"

#include "manifold/block_tridiagonal.h"
#include "manifold/constraints.h"

namespace gdmlt::manifold {
namespace {

LogTerm failed(WalkFailure reason) {
    return LogTerm{0.0, reason};
}

LogTerm checked(double log_value) {
    if (!std::isfinite(log_value)) return failed(WalkFailure::SingularMatrix);
    return LogTerm{log_value, WalkFailure::None};
}

}  // namespace

Tangents end_tangents(const SpecularChain& chain) {
    if (chain.end.on_surface()) {
        // The same basis a surface point would have; any orthonormal pair gives the same |det|.
        return tangents_around(chain.end.n_geometric);
    }
    const Vec3d last = chain.end.p - chain.position(chain.size());
    const double length = last.norm();
    return tangents_around(length > 0.0 ? Vec3d(last / length) : Vec3d::UnitZ());
}

std::optional<Mat2d> first_vertex_tangent_map(const SpecularChain& chain, const Tangents& tangents,
                                              double singular_threshold) {
    const std::optional<ChainSystem> system = chain_system(chain, tangents);
    if (!system) return std::nullopt;
    ChainArray<Mat2d> rhs(chain.size(), Mat2d::Zero());
    rhs.back() = -system->end_coupling;
    const std::optional<BlockSolution<2>> solution =
        solve(system->matrix, as_span(rhs), BlockSolveSettings{singular_threshold});
    if (!solution) return std::nullopt;
    return solution->x[0];
}

LogTerm log_solid_angle_per_area(const SpecularChain& chain) {
    const std::size_t k = chain.size();
    const Vec3d first = chain.position(1) - chain.start.p;
    const double distance2 = first.squaredNorm();
    if (!(distance2 > 0.0) || !std::isfinite(distance2))
        return failed(WalkFailure::DegenerateChain);
    const Vec3d w = first / std::sqrt(distance2);
    if (k == 0) {
        // Ordinary dw/dA = |cos theta_end| / d^2 (Veach 1997, eq. 8.3).
        const double cos_end =
            chain.end.on_surface() ? std::abs(chain.end.n_geometric.dot(w)) : 1.0;
        return checked(std::log(cos_end) - std::log(distance2));
    }
    const std::optional<Mat2d> t1 = first_vertex_tangent_map(chain, end_tangents(chain));
    if (!t1) return failed(WalkFailure::SingularMatrix);
    const double cos_1 = std::abs(chain.vertices[0].geometry.n_geometric.dot(w));
    return checked(std::log(cos_1) + std::log(std::abs(t1->determinant())) - std::log(distance2));
}

LogTerm log_generalized_geometry_term(const SpecularChain& chain) {
    LogTerm term = log_solid_angle_per_area(chain);
    if (!term.ok() || !chain.start.on_surface()) return term;
    const Vec3d first = chain.position(1) - chain.start.p;
    const double cos_0 = std::abs(chain.start.n_geometric.dot(first.normalized()));
    return checked(term.log_value + std::log(cos_0));
}

LogTerm log_half_vector_jacobian(const SpecularChain& chain) {
    const std::size_t k = chain.size();
    ChainArray<std::size_t> delta, glossy;
    for (std::size_t i = 0; i < k; ++i)
        (chain.vertices[i].roughness == RoughnessClass::Glossy ? glossy : delta).push_back(i);
    if (glossy.empty()) return LogTerm{};
    // Both endpoints pinned: the end's tangents do not enter (its coupling block is dropped).
    std::optional<ChainSystem> system =
        chain_system(chain, tangents_around(Vec3d::UnitZ()), SlopeTarget::Current);
    if (!system) return failed(WalkFailure::DegenerateChain);
    // Glossy rows in slope units: d sigma = dc / (H.n) where c = 0 (constraints.h).
    double log_row_scale = 0.0;
    for (const std::size_t i : glossy) {
        const double h_n = system->h_dot_n[i];
        if (!(std::abs(h_n) > 0.0)) return failed(WalkFailure::DegenerateChain);
        log_row_scale -= 2.0 * std::log(std::abs(h_n));
    }
    const std::optional<double> log_det_full = log_abs_determinant(system->matrix);
    if (!log_det_full) return failed(WalkFailure::SingularMatrix);
    // J_SS: rows and columns of the delta vertices. Removing the glossy vertices splits the
    // chain into runs of consecutive delta vertices that no longer couple: still
    // block-tridiagonal, with zero coupling across each removed vertex.
    double log_det_delta = 0.0;
    if (!delta.empty()) {
        BlockTridiagonal reduced(delta.size());
        for (std::size_t j = 0; j < delta.size(); ++j) {
            const std::size_t i = delta[j];
            reduced.diagonal[j] = system->matrix.diagonal[i];
            if (j > 0 && delta[j - 1] + 1 == i) reduced.lower[j] = system->matrix.lower[i];
            if (j + 1 < delta.size() && delta[j + 1] == i + 1)
                reduced.upper[j] = system->matrix.upper[i];
        }
        const std::optional<double> log_det = log_abs_determinant(reduced);
        if (!log_det) return failed(WalkFailure::SingularMatrix);
        log_det_delta = *log_det;
    }
    // |det dx_R/dsigma_R| = |det J_SS| / |det J| (J with glossy rows in slope units).
    return checked(log_det_delta - (*log_det_full + log_row_scale));
}

LogTerm log_manifold_shift_jacobian(const SpecularChain& base, const SpecularChain& offset) {
    if (base.size() != offset.size()) return failed(WalkFailure::DegenerateChain);
    for (std::size_t i = 0; i < base.size(); ++i)
        if (base.vertices[i].roughness != offset.vertices[i].roughness)
            return failed(WalkFailure::DegenerateChain);
    const LogTerm b = log_half_vector_jacobian(base);
    if (!b.ok()) return b;
    const LogTerm o = log_half_vector_jacobian(offset);
    if (!o.ok()) return o;
    return checked(o.log_value - b.log_value);
}

}  // namespace gdmlt::manifold
