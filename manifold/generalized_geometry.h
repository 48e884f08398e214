// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Jacobians of specular chains, in log space (long chains multiply many factors).
//
// Generalized geometry term (Jakob & Marschner 2012, sec. 4.4, the determinant of the tangent-
// space map; Veach's G extended through specular vertices):
//     G~(x_0 <-> x_{k+1}) = |cos theta_0| * dw_0 / dA(x_{k+1})
//                        = |cos theta_0| |cos theta_1| |det T_1| / |x_1 - x_0|^2,
// where T_1 = d(x_1) / d(x_{k+1}) is the 2x2 tangent map obtained from the constraint system
// with x_0 pinned (constraints.h; block solve with the end's coupling block as rhs) and both
// cosines use geometric normals: the chain's vertices move in their geometric tangent planes,
// and with geometric cosines at both ends G~ is reciprocal up to the indices: etendue
// eta^2 cos dA dw is conserved, so G~(x_0 -> x_end) eta_0^2 = G~(x_end -> x_0) eta_end^2 (tested;
// interpolated shading normals break this symmetry, as they break reciprocity). A caller whose
// measurement contribution uses shading-normal cosines multiplies log_solid_angle_per_area() by its
// own cosine instead.
//
// Half-vector Jacobian (Kaplanyan et al. 2014; Jakob & Marschner 2012, sec. 5.3 "offset
// manifolds"; the det(a,b,c) of Mitsuba's glossy chains): with both endpoints pinned, the
// positions x_R of the glossy vertices and the slopes sigma_R of their generalized half vectors
// are two coordinate systems of the same 2|R|-dimensional configuration space (the delta
// vertices' constraints hold throughout). With J the full constraint Jacobian (rows in slope
// units) and J_SS its rows and columns of delta vertices,
//     |det d sigma_R / d x_R| = |det J| / |det J_SS|        (Schur complement),
// and a shift that copies sigma_R from a base chain to an offset chain maps glossy vertex area
// with the Jacobian |d x'_R / d x_R| = |det dx'/dsigma| / |det dx/dsigma| (Manzi et al. 2014,
// sec. 4: the offset keeps the base's half vectors; the determinant ratio between base and
// offset is that shift's Jacobian). Without glossy vertices both are 1.
#include <cmath>

#include "manifold/specular_chain.h"
#include "manifold/walk_failure.h"

namespace gdmlt::manifold {

/// log of a positive Jacobian or geometry term, or why it does not exist (a singular system
/// at a caustic focal configuration, degenerate geometry). Never NaN.
struct LogTerm {
    double log_value = 0.0;
    WalkFailure failure = WalkFailure::None;

    bool ok() const { return failure == WalkFailure::None; }
    /// exp(log_value), 0 on failure; may overflow to +inf for extreme chains, so prefer sums of
    /// log_value where ratios are formed.
    double value() const { return ok() ? std::exp(log_value) : 0.0; }
};

/// Orthonormal tangents of the end's area measure: its geometric tangent plane, or the plane
/// orthogonal to the last segment for a point endpoint.
Tangents end_tangents(const SpecularChain& chain);

/// T_1 = d(tangent coords of x_1) / d(end tangent coords along `end_tangents`), x_0 pinned.
/// Empty for a chain without interior vertices or a singular system.
std::optional<Mat2d> first_vertex_tangent_map(const SpecularChain& chain,
                                              const Tangents& end_tangents,
                                              double singular_threshold = 1e-12);

/// log(dw_0 / dA_end): solid angle at the start per unit area at the end, through the chain.
LogTerm log_solid_angle_per_area(const SpecularChain& chain);

/// log G~ of the chain (geometric cosines; the start's cosine is 1 for a point endpoint).
LogTerm log_generalized_geometry_term(const SpecularChain& chain);

/// log |det d x_R / d sigma_R|: area of the glossy vertices per unit half-vector-slope measure,
/// both endpoints pinned; 0 when the chain has no glossy vertex.
LogTerm log_half_vector_jacobian(const SpecularChain& chain);

/// log of the Jacobian |d x'_R / d x_R| of the manifold shift from `base` to `offset` (same
/// structure; the offset keeps the base's glossy half-vector slopes):
/// log_half_vector_jacobian(offset) - log_half_vector_jacobian(base).
LogTerm log_manifold_shift_jacobian(const SpecularChain& base, const SpecularChain& offset);

}  // namespace gdmlt::manifold
