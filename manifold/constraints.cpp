// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/constraints.h"

#include <cmath>

namespace gdmlt::manifold {
namespace {

/// Derivative of the unit direction w = (y - x)/|y - x| when y moves by e (x fixed):
/// dw = (e - w (w.e)) / l (the projection of e orthogonal to w, over the distance).
Vec3d unit_direction_derivative(const Vec3d& w, double length, const Vec3d& e) {
    return (e - w * w.dot(e)) / length;
}

}  // namespace

std::optional<ConstraintFrame> constraint_frame(const SurfacePoint& point) {
    ConstraintFrame f;
    f.n = point.n_shading;
    const Vec3d& r = point.frame_reference;
    const Vec3d s_unnormalised = r - f.n * f.n.dot(r);
    const double length2 = s_unnormalised.squaredNorm();
    if (!(length2 > 1e-12 * r.squaredNorm()) || !(length2 > 0.0)) {
        // The reference (nearly) along the normal: a sphere pole. Frame::from_normal_and_tangent
        // falls back to an arbitrary frame there, and so do we. Its derivative is taken as the
        // parallel transport of the frame (only the part normal to the surface: n.ds = -dn.s),
        // which is exact wherever H is along n, i.e. at the solution of a delta vertex.
        const Tangents st = tangents_around(f.n);
        f.s = st[0];
        f.t = st[1];
        for (int k = 0; k < 2; ++k) {
            const Vec3d& dn = point.dn_shading_dtangent[k];
            f.dn_dtangent[k] = dn;
            f.ds_dtangent[k] = -f.n * dn.dot(f.s);
            f.dt_dtangent[k] = -f.n * dn.dot(f.t);
        }
        return f;
    }
    const double length = std::sqrt(length2);
    f.s = s_unnormalised / length;
    f.t = f.n.cross(f.s);
    for (int k = 0; k < 2; ++k) {
        const Vec3d& dn = point.dn_shading_dtangent[k];
        const Vec3d& dr = point.dframe_reference_dtangent[k];
        // s~ = r - n (n.r)  =>  ds~ = dr - dn (n.r) - n (dn.r + n.dr)
        const Vec3d ds_unnormalised = dr - dn * f.n.dot(r) - f.n * (dn.dot(r) + f.n.dot(dr));
        // d(s~/|s~|) = (I - s s^T) ds~ / |s~|
        const Vec3d ds = (ds_unnormalised - f.s * f.s.dot(ds_unnormalised)) / length;
        f.dn_dtangent[k] = dn;
        f.ds_dtangent[k] = ds;
        f.dt_dtangent[k] = dn.cross(f.s) + f.n.cross(ds);
    }
    return f;
}

std::optional<Vec3d> generalized_half_vector(const Vec3d& x_previous, const Vec3d& x,
                                             const Vec3d& x_next, double eta) {
    const Vec3d to_previous = x_previous - x, to_next = x_next - x;
    const double l_i = to_previous.norm(), l_o = to_next.norm();
    if (!(l_i > 0.0) || !(l_o > 0.0) || !std::isfinite(l_i) || !std::isfinite(l_o))
        return std::nullopt;
    return Vec3d(to_previous / l_i + eta * (to_next / l_o));
}

std::optional<Vec2d> half_vector_slope(const Vec3d& x_previous, const SurfacePoint& vertex,
                                       const Vec3d& x_next, double eta) {
    const std::optional<Vec3d> h = generalized_half_vector(x_previous, vertex.p, x_next, eta);
    const std::optional<ConstraintFrame> f = constraint_frame(vertex);
    if (!h || !f) return std::nullopt;
    const double h_n = h->dot(f->n);
    // H nearly in the tangent plane: no slope (a grazing micro-normal).
    if (!(std::abs(h_n) > 1e-12 * h->norm())) return std::nullopt;
    return Vec2d(h->dot(f->s) / h_n, h->dot(f->t) / h_n);
}

std::optional<Vec2d> constraint_value(const Vec3d& x_previous, const SurfacePoint& vertex,
                                      const Vec3d& x_next, double eta, const Vec2d& sigma) {
    const std::optional<Vec3d> h = generalized_half_vector(x_previous, vertex.p, x_next, eta);
    const std::optional<ConstraintFrame> f = constraint_frame(vertex);
    if (!h || !f) return std::nullopt;
    const double h_n = h->dot(f->n);
    return Vec2d(h->dot(f->s) - sigma.x() * h_n, h->dot(f->t) - sigma.y() * h_n);
}

std::optional<ConstraintBlocks> constraint_blocks(const Vec3d& x_previous,
                                                  const Tangents& tangents_previous,
                                                  const ChainVertex& vertex, const Vec3d& x_next,
                                                  const Tangents& tangents_next,
                                                  const Vec2d& sigma) {
    const Vec3d& x = vertex.geometry.p;
    const Vec3d to_previous = x_previous - x, to_next = x_next - x;
    const double l_i = to_previous.norm(), l_o = to_next.norm();
    if (!(l_i > 0.0) || !(l_o > 0.0) || !std::isfinite(l_i) || !std::isfinite(l_o))
        return std::nullopt;
    const Vec3d w_i = to_previous / l_i, w_o = to_next / l_o;
    const double eta = vertex.eta;
    const Vec3d h = w_i + eta * w_o;
    const std::optional<ConstraintFrame> frame = constraint_frame(vertex.geometry);
    if (!frame) return std::nullopt;
    const ConstraintFrame& f = *frame;

    ConstraintBlocks blocks;
    blocks.h_dot_n = h.dot(f.n);
    blocks.value =
        Vec2d(h.dot(f.s) - sigma.x() * blocks.h_dot_n, h.dot(f.t) - sigma.y() * blocks.h_dot_n);

    // d c = (dH.s + H.ds - sigma_x (dH.n + H.dn),  dH.t + H.dt - sigma_y (dH.n + H.dn))
    const auto dc = [&](const Vec3d& dh, const Vec3d& ds, const Vec3d& dt, const Vec3d& dn) {
        const double dh_n = dh.dot(f.n) + h.dot(dn);
        return Vec2d(dh.dot(f.s) + h.dot(ds) - sigma.x() * dh_n,
                     dh.dot(f.t) + h.dot(dt) - sigma.y() * dh_n);
    };
    const Vec3d zero = Vec3d::Zero();
    for (int k = 0; k < 2; ++k) {
        // x_{i-1} moves: only w_i turns.
        const Vec3d dh_a = unit_direction_derivative(w_i, l_i, tangents_previous[k]);
        blocks.a.col(k) = dc(dh_a, zero, zero, zero);
        // x_{i+1} moves: only w_o turns, scaled by eta'.
        const Vec3d dh_c = eta * unit_direction_derivative(w_o, l_o, tangents_next[k]);
        blocks.c.col(k) = dc(dh_c, zero, zero, zero);
        // x_i moves: both directions turn (the far ends are fixed, so each direction changes by
        // minus the derivative w.r.t. its far end) and the shading frame turns with the surface.
        const Vec3d& e = vertex.geometry.tangents[k];
        const Vec3d dh_b =
            -unit_direction_derivative(w_i, l_i, e) - eta * unit_direction_derivative(w_o, l_o, e);
        blocks.b.col(k) = dc(dh_b, f.ds_dtangent[k], f.dt_dtangent[k], f.dn_dtangent[k]);
    }
    if (!blocks.a.allFinite() || !blocks.b.allFinite() || !blocks.c.allFinite())
        return std::nullopt;
    return blocks;
}

std::optional<ChainSystem> chain_system(const SpecularChain& chain, const Tangents& end_tangents,
                                        SlopeTarget target) {
    const std::size_t k = chain.size();
    if (k == 0) return std::nullopt;
    ChainSystem system;
    system.matrix = BlockTridiagonal(k);
    system.values.assign(k, Vec2d::Zero());
    system.h_dot_n.assign(k, 0.0);
    // The start is pinned, so row 0's lower block is never used; any tangents will do.
    const Tangents start_tangents = tangents_around(Vec3d::UnitZ());
    for (std::size_t i = 0; i < k; ++i) {
        const ChainVertex& v = chain.vertices[i];
        const Tangents& previous =
            i == 0 ? start_tangents : chain.vertices[i - 1].geometry.tangents;
        const Tangents& next = i + 1 == k ? end_tangents : chain.vertices[i + 1].geometry.tangents;
        const Vec3d& x_previous = chain.position(i);
        const Vec3d& x_next = chain.position(i + 2);
        Vec2d sigma = v.half_vector_slope;
        if (target == SlopeTarget::Current) {
            const std::optional<Vec2d> slope =
                half_vector_slope(x_previous, v.geometry, x_next, v.eta);
            if (!slope) return std::nullopt;
            sigma = *slope;
        }
        const std::optional<ConstraintBlocks> blocks =
            constraint_blocks(x_previous, previous, v, x_next, next, sigma);
        if (!blocks) return std::nullopt;
        system.matrix.lower[i] = blocks->a;
        system.matrix.diagonal[i] = blocks->b;
        system.matrix.upper[i] = blocks->c;
        system.values[i] = blocks->value;
        system.h_dot_n[i] = blocks->h_dot_n;
    }
    // upper[k-1] stays: the solver does not use it, but it sets the last row's scale.
    system.end_coupling = system.matrix.upper[k - 1];
    return system;
}

}  // namespace gdmlt::manifold
