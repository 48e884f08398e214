// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Half-vector constraints of a specular chain and their derivative blocks (Jakob & Marschner
// 2012, sec. 4.1 and 4.2; the block structure of eq. 6 there). Everything in double.
//
// At an interior vertex x_i with w_i = (x_{i-1} - x_i)/l_i and w_o = (x_{i+1} - x_i)/l_o, the
// generalized half vector is H = w_i + eta' w_o (Walter et al. 2007 for refraction; eta' as in
// ChainVertex::eta). A chain is valid when, at each vertex, H is parallel to the vertex's
// target micro-normal m, which has slope sigma = (m.s / m.n, m.t / m.n) in the shading frame
// (s, t, n): sigma = 0 for a delta vertex, the stored slope for a glossy one.
//
// We write that condition without normalising H:
//     c_i = (H.s - sigma_x H.n,  H.t - sigma_y H.n)  = 0.
// It has the same solutions as Mitsuba's "normalised half vector projected on the tangent
// frame" but stays well conditioned at eta' -> 1, where |H| -> 0 on the manifold (the index-
// matched case that Mitsuba special-cases), and is sign-free (H and -H both satisfy it). The
// Newton predictor and G~ are invariant to this row scaling. Where a Jacobian is taken in
// half-vector coordinates (generalized_geometry.h), rows are divided by H.n, which turns c_i
// into the derivative of the half-vector slope exactly (sigma set to the current slope).
//
// Shading frame: s = normalize(r - n (n.r)), t = n x s, with n the shading normal and r the
// point's frame_reference (dp_du on a sphere, the texture's dp/du or an edge on a triangle); the
// same frame as Frame::from_normal_and_tangent, so that half-vector slopes agree with the core.
// The frame moves with x_i (the normal turns, dp_du changes on a sphere): those terms are part
// of B_i (Jakob & Marschner 2012, sec. 4.2 "the tangent frame rotates").
#include <optional>

#include "manifold/block_tridiagonal.h"
#include "manifold/specular_chain.h"
#include "manifold/surface_point.h"

namespace gdmlt::manifold {

/// The shading frame of the constraint and its derivatives along the vertex's tangents.
struct ConstraintFrame {
    Vec3d s, t, n;
    Tangents ds_dtangent, dt_dtangent, dn_dtangent;
};

/// Empty when the frame is degenerate (the reference parallel to the normal: a sphere pole).
std::optional<ConstraintFrame> constraint_frame(const SurfacePoint& point);

/// H = w_i + eta' w_o, unnormalised; empty for a zero-length segment.
std::optional<Vec3d> generalized_half_vector(const Vec3d& x_previous, const Vec3d& x,
                                             const Vec3d& x_next, double eta);

/// Slope (H.s / H.n, H.t / H.n) of the generalized half vector; empty when H.n vanishes.
std::optional<Vec2d> half_vector_slope(const Vec3d& x_previous, const SurfacePoint& vertex,
                                       const Vec3d& x_next, double eta);

/// The constraint value c_i for a vertex with target slope `sigma`.
std::optional<Vec2d> constraint_value(const Vec3d& x_previous, const SurfacePoint& vertex,
                                      const Vec3d& x_next, double eta, const Vec2d& sigma);

/// One block row of the constraint Jacobian: a = dc_i / d(tangent coords of x_{i-1}),
/// b = dc_i / d(tangent coords of x_i), c = dc_i / d(tangent coords of x_{i+1}).
struct ConstraintBlocks {
    Mat2d a = Mat2d::Zero(), b = Mat2d::Zero(), c = Mat2d::Zero();
    Vec2d value = Vec2d::Zero();  // c_i itself
    double h_dot_n = 0.0;         // H . n (for the slope scaling)
};

/// Derivative blocks of vertex `vertex`'s constraint; the neighbours move along the given
/// tangent pairs (orthonormal). Empty for zero-length segments or a degenerate frame.
std::optional<ConstraintBlocks> constraint_blocks(const Vec3d& x_previous,
                                                  const Tangents& tangents_previous,
                                                  const ChainVertex& vertex, const Vec3d& x_next,
                                                  const Tangents& tangents_next,
                                                  const Vec2d& sigma);

/// Which target slope the rows use.
enum class SlopeTarget {
    Stored,   // ChainVertex::half_vector_slope: the walk's constraint
    Current,  // the current slope of each vertex (c_i = 0): rows are then H.n times the
              // derivative of the half-vector slope, as Jacobians in half-vector space need
};

/// The constraint Jacobian of a whole chain (Jakob & Marschner 2012, eq. 6): unknowns are the
/// tangent coordinates of x_1..x_k (each vertex's SurfacePoint::tangents); x_0 is pinned; x_{k+1}
/// moves along `end_tangents`, entering through `end_coupling` = dc_k / d(end tangent coords)
/// (also kept as matrix.upper[k-1], which the solver ignores; matrix.lower[0] = dc_1 / dx_0 along
/// arbitrary tangents, likewise ignored).
struct ChainSystem {
    BlockTridiagonal matrix;
    Mat2d end_coupling = Mat2d::Zero();
    ChainArray<Vec2d> values;    // c_i
    ChainArray<double> h_dot_n;  // H.n per vertex
};

/// Empty for a chain without interior vertices, zero-length segments or degenerate frames.
std::optional<ChainSystem> chain_system(const SpecularChain& chain, const Tangents& end_tangents,
                                        SlopeTarget target = SlopeTarget::Stored);

}  // namespace gdmlt::manifold
