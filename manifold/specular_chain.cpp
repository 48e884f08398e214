// SPDX-License-Identifier: GPL-3.0-or-later
#include "manifold/specular_chain.h"

#include "manifold/chain_trace.h"
#include "manifold/constraints.h"

namespace gdmlt::manifold {
namespace {

const Bsdf* bsdf_of_shape(const Scene& scene, std::int32_t shape) {
    if (shape < 0 || static_cast<std::size_t>(shape) >= scene.shapes().size()) return nullptr;
    const int index = scene.shapes()[static_cast<std::size_t>(shape)].bsdf();
    if (index < 0 || static_cast<std::size_t>(index) >= scene.bsdfs().size()) return nullptr;
    return &scene.bsdfs()[static_cast<std::size_t>(index)];
}

/// Fills the optical description of a vertex whose geometry is set; the neighbours decide
/// reflection versus refraction.
WalkFailure classify_vertex(const Scene& scene, ChainVertex& v, const TexturePoint& at,
                            const Vec3d& w_i, const Vec3d& w_o) {
    const Bsdf* bsdf = bsdf_of_shape(scene, v.geometry.shape);
    if (!bsdf) return WalkFailure::DegenerateChain;
    v.roughness = bsdf->roughness_class_at(at);
    if (v.roughness == RoughnessClass::Diffuse) return WalkFailure::DegenerateChain;
    const double side_i = w_i.dot(v.geometry.n_geometric), side_o = w_o.dot(v.geometry.n_geometric);
    if (side_i * w_i.dot(v.geometry.n_shading) <= 0.0 ||
        side_o * w_o.dot(v.geometry.n_shading) <= 0.0)
        return WalkFailure::LeftManifold;  // a light leak through shading normals
    v.previous_on_front = side_i > 0.0;
    v.reflection = side_i * side_o > 0.0;
    v.eta = 1.0;
    if (!v.reflection) {
        const std::optional<double> eta = transmission_eta(*bsdf);
        if (!eta || !(*eta > 0.0)) return WalkFailure::DegenerateChain;
        v.eta = v.previous_on_front ? *eta : 1.0 / *eta;
    }
    return WalkFailure::None;
}

}  // namespace

const Vec3d& SpecularChain::position(std::size_t i) const {
    if (i == 0) return start.p;
    if (i > vertices.size()) return end.p;
    return vertices[i - 1].geometry.p;
}

SpecularChain SpecularChain::reversed() const {
    SpecularChain r;
    r.start = end;
    r.end = start;
    r.vertices.assign(vertices.rbegin(), vertices.rend());
    for (ChainVertex& v : r.vertices) {
        if (v.reflection) continue;
        v.eta = 1.0 / v.eta;
        v.previous_on_front = !v.previous_on_front;
    }
    return r;
}

double SpecularChain::length() const {
    double sum = 0.0;
    for (std::size_t i = 0; i + 1 < vertices.size() + 2; ++i)
        sum += (position(i + 1) - position(i)).norm();
    return sum;
}

ChainEndpoint endpoint_at(const Scene& scene, const SurfaceInteraction& si) {
    ChainEndpoint e;
    e.shape = si.shape;
    if (si.valid()) {
        const std::optional<SurfacePoint> sp =
            surface_point_from(scene.shapes()[static_cast<std::size_t>(si.shape)], si);
        if (sp) {
            e.p = sp->p;
            e.n_geometric = sp->n_geometric;
            return e;
        }
    }
    e.p = si.p.cast<double>();
    e.n_geometric = si.n_geometric.cast<double>().normalized();
    return e;
}

ChainEndpoint point_endpoint(const Vec3d& p) {
    ChainEndpoint e;
    e.p = p;
    return e;
}

ChainOutcome build_chain(const Scene& scene, const ChainEndpoint& start,
                         std::span<const SurfaceInteraction> vertices, const ChainEndpoint& end) {
    ChainOutcome out;
    out.chain.start = start;
    out.chain.end = end;
    out.chain.vertices.resize(vertices.size());
    for (std::size_t i = 0; i < vertices.size(); ++i) {
        const SurfaceInteraction& si = vertices[i];
        if (!si.valid() || static_cast<std::size_t>(si.shape) >= scene.shapes().size()) {
            out.failure = WalkFailure::DegenerateChain;
            return out;
        }
        const std::optional<SurfacePoint> sp =
            surface_point_from(scene.shapes()[static_cast<std::size_t>(si.shape)], si);
        if (!sp) {
            out.failure = WalkFailure::DegenerateChain;
            return out;
        }
        out.chain.vertices[i].geometry = *sp;
    }
    for (std::size_t i = 0; i < vertices.size(); ++i) {
        ChainVertex& v = out.chain.vertices[i];
        const Vec3d to_previous = out.chain.position(i) - v.geometry.p;
        const Vec3d to_next = out.chain.position(i + 2) - v.geometry.p;
        if (!(to_previous.norm() > 0.0) || !(to_next.norm() > 0.0)) {
            out.failure = WalkFailure::DegenerateChain;
            return out;
        }
        out.failure = classify_vertex(scene, v, vertices[i].texture_point(),
                                      to_previous.normalized(), to_next.normalized());
        if (!out.ok()) return out;
        if (v.roughness == RoughnessClass::Glossy) {
            const std::optional<Vec2d> slope = half_vector_slope(out.chain.position(i), v.geometry,
                                                                 out.chain.position(i + 2), v.eta);
            if (!slope) {
                out.failure = WalkFailure::DegenerateChain;
                return out;
            }
            v.half_vector_slope = *slope;
        }
    }
    return out;
}

ChainOutcome trace_new_chain(const Scene& scene, const ChainEndpoint& start, const Vec3d& direction,
                             std::span<const Scatter> scatters, double end_distance) {
    ChainOutcome out;
    out.chain.start = start;
    Vec3d origin = start.p, n_origin = start.n_geometric, d = direction.normalized();
    for (const Scatter kind : scatters) {
        ChainVertex v;
        v.geometry = trace_surface(scene, origin, n_origin, d);
        if (!v.geometry.valid()) {
            out.failure = WalkFailure::LeftManifold;
            return out;
        }
        const Bsdf* bsdf = bsdf_of_shape(scene, v.geometry.shape);
        const Shape& shape = scene.shapes()[static_cast<std::size_t>(v.geometry.shape)];
        v.roughness =
            bsdf ? bsdf->roughness_class_at(to_interaction(shape, v.geometry).texture_point())
                 : RoughnessClass::Diffuse;
        if (v.roughness == RoughnessClass::Diffuse) {
            out.failure = WalkFailure::DegenerateChain;
            return out;
        }
        const Vec3d w_i = -d;
        v.previous_on_front = w_i.dot(v.geometry.n_geometric) > 0.0;
        v.reflection = kind == Scatter::Reflection;
        if (!v.reflection) {
            const std::optional<double> eta = transmission_eta(*bsdf);
            if (!eta) {
                out.failure = WalkFailure::DegenerateChain;
                return out;
            }
            v.eta = v.previous_on_front ? *eta : 1.0 / *eta;
        }
        const ScatterOutcome s = scatter(w_i, v.geometry, v.reflection, v.eta, Vec2d::Zero());
        if (s.failure != WalkFailure::None) {
            out.failure = s.failure;
            return out;
        }
        origin = v.geometry.p;
        n_origin = v.geometry.n_geometric;
        d = s.w_o;
        out.chain.vertices.push_back(v);
    }
    const SurfacePoint next = trace_surface(scene, origin, n_origin, d);
    if (end_distance > 0.0) {
        if (next.valid() && (next.p - origin).norm() < end_distance) {
            out.failure = WalkFailure::Occluded;
            return out;
        }
        out.chain.end = point_endpoint(origin + end_distance * d);
        return out;
    }
    if (!next.valid()) {
        out.failure = WalkFailure::LeftManifold;
        return out;
    }
    out.chain.end.p = next.p;
    out.chain.end.n_geometric = next.n_geometric;
    out.chain.end.shape = next.shape;
    return out;
}

}  // namespace gdmlt::manifold
