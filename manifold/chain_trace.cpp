// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/chain_trace.h"

#include <cmath>

#include "core/geometry/ray.h"
#include "manifold/constraints.h"

namespace gdmlt::manifold {

EndPlane end_plane(const Vec3d& origin, const Vec3d& normal) {
    EndPlane plane;
    plane.origin = origin;
    plane.normal = normal;
    plane.tangents = tangents_around(normal);
    return plane;
}

SurfacePoint trace_surface(const Scene& scene, const Vec3d& origin, const Vec3d& n_geometric,
                           const Vec3d& direction) {
    const Vec3f direction_f = direction.cast<float>().normalized();
    const Ray ray = spawn_ray(origin.cast<float>(), n_geometric.cast<float>(), direction_f);
    const SurfaceInteraction si = scene.intersect(ray);
    if (!si.valid()) return SurfacePoint{};
    const Shape& shape = scene.shapes()[static_cast<std::size_t>(si.shape)];
    const std::optional<SurfacePoint> refined =
        refine_hit(shape, si.shape, si.primitive, origin, direction, static_cast<double>(si.t));
    return refined ? *refined : SurfacePoint{};
}

ScatterOutcome scatter(const Vec3d& w_i, const SurfacePoint& point, bool reflection, double eta,
                       const Vec2d& sigma) {
    ScatterOutcome out;
    const double cos_i_geometric = w_i.dot(point.n_geometric);
    const double cos_i_shading = w_i.dot(point.n_shading);
    if (cos_i_geometric * cos_i_shading <= 0.0) {
        out.failure = WalkFailure::LeftManifold;
        return out;
    }
    const std::optional<ConstraintFrame> frame = constraint_frame(point);
    if (!frame) {
        out.failure = WalkFailure::DegenerateChain;
        return out;
    }
    Vec3d m = sigma.x() * frame->s + sigma.y() * frame->t + frame->n;
    m.normalize();
    if (reflection) {
        out.w_o = 2.0 * w_i.dot(m) * m - w_i;
    } else {
        // Refraction through m with eta' = eta_next / eta_previous: w_o such that
        // w_i + eta' w_o is parallel to m (Walter et al. 2007, eq. 16 rearranged).
        if (w_i.dot(m) < 0.0) m = -m;
        const double cos_i = w_i.dot(m);
        const double inv_eta = 1.0 / eta;
        const double sin2_t = inv_eta * inv_eta * (1.0 - cos_i * cos_i);
        if (!(sin2_t < 1.0)) {
            out.failure = WalkFailure::TotalInternalReflection;
            return out;
        }
        const double cos_t = std::sqrt(1.0 - sin2_t);
        out.w_o = -inv_eta * w_i + (inv_eta * cos_i - cos_t) * m;
    }
    const double length = out.w_o.norm();
    if (!(length > 0.0) || !std::isfinite(length)) {
        out.failure = WalkFailure::DegenerateChain;
        return out;
    }
    out.w_o /= length;
    // Reflection stays on the incident side of both normals, refraction crosses both.
    const double side = reflection ? 1.0 : -1.0;
    const double cos_o_geometric = out.w_o.dot(point.n_geometric);
    const double cos_o_shading = out.w_o.dot(point.n_shading);
    if (!(side * cos_o_geometric * cos_i_geometric > 0.0) ||
        !(side * cos_o_shading * cos_i_shading > 0.0))
        out.failure = WalkFailure::LeftManifold;
    return out;
}

ChainOutcome project_chain(const Scene& scene, const SpecularChain& like, const Vec3d& direction,
                           const EndPlane& plane) {
    ChainOutcome out;
    out.chain = like;
    Vec3d origin = like.start.p;
    Vec3d n_origin = like.start.n_geometric;
    Vec3d d = direction;
    for (ChainVertex& v : out.chain.vertices) {
        const SurfacePoint hit = trace_surface(scene, origin, n_origin, d);
        if (!hit.valid() || hit.shape != v.geometry.shape) {
            out.failure = WalkFailure::LeftManifold;
            return out;
        }
        const Vec3d w_i = -d;
        if ((w_i.dot(hit.n_geometric) > 0.0) != v.previous_on_front) {
            out.failure = WalkFailure::LeftManifold;
            return out;
        }
        const ScatterOutcome s = scatter(w_i, hit, v.reflection, v.eta, v.half_vector_slope);
        if (s.failure != WalkFailure::None) {
            out.failure = s.failure;
            return out;
        }
        v.geometry = hit;
        origin = hit.p;
        n_origin = hit.n_geometric;
        d = s.w_o;
    }
    const double denominator = plane.normal.dot(d);
    // A ray (nearly) parallel to the end plane: the end point would jump arbitrarily far.
    if (!(std::abs(denominator) > 1e-12)) {
        out.failure = WalkFailure::LeftManifold;
        return out;
    }
    const double t = plane.normal.dot(plane.origin - origin) / denominator;
    if (!(t > 0.0) || !std::isfinite(t)) {
        out.failure = WalkFailure::LeftManifold;
        return out;
    }
    out.chain.end.p = origin + t * d;
    return out;
}

std::optional<double> transmission_eta(const Bsdf& bsdf) {
    // A mask's or blend's transmission may be its null lobe or a nested model's: the vertex
    // alone does not say which, so a chain through one is not walked.
    if (bsdf.is_composite()) return std::nullopt;
    if (const auto* dielectric = std::get_if<DielectricBsdf>(&bsdf.front()))
        return static_cast<double>(dielectric->eta);
    if (const auto* rough = std::get_if<RoughDielectricBsdf>(&bsdf.front()))
        return static_cast<double>(rough->eta);
    if (std::holds_alternative<ThinDielectricBsdf>(bsdf.front())) return 1.0;
    return std::nullopt;
}

}  // namespace gdmlt::manifold
