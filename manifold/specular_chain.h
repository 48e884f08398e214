// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// A specular chain: the vertices between two non-specular endpoints (Jakob & Marschner 2012,
// sec. 4: the "specular manifold" of a path segment x_0 ... x_{k+1} whose interior vertices
// x_1..x_k each satisfy a half-vector constraint).
//
// Ordering: `start` is x_0, the endpoint the walk keeps fixed and traces rays from; `end` is
// x_{k+1}, the endpoint the walk moves. A caller that wants to pin the other end uses reversed().
// "Direction of travel" below means start -> end (the direction rays are traced), which need not
// be the direction light flows: the generalized half-vector constraint is symmetric.
#include <span>

#include "core/bsdf/roughness_class.h"
#include "core/scene/scene.h"
#include "manifold/chain_array.h"
#include "manifold/surface_point.h"
#include "manifold/walk_failure.h"

namespace gdmlt::manifold {

/// A chain endpoint: a surface point (n_geometric set) or a point in space (camera pinhole,
/// point light: n_geometric zero).
struct ChainEndpoint {
    Vec3d p = Vec3d::Zero();
    Vec3d n_geometric = Vec3d::Zero();  // unit, or zero when not on a surface
    std::int32_t shape = -1;            // scene shape index, -1 when not on a surface
    bool on_surface() const { return !n_geometric.isZero(); }
};

/// An interior vertex of a chain: a specular (delta) or glossy-treated-as-specular surface point.
struct ChainVertex {
    SurfacePoint geometry;
    /// eta' = (index on the side of the next vertex) / (index on the side of the previous
    /// vertex): the relative IOR across the interface in the direction of travel; 1 for a
    /// reflection (and for an index-matched or thin-dielectric transmission).
    double eta = 1.0;
    bool reflection = true;
    /// Side of the previous vertex w.r.t. n_geometric (true: the normal's side). A walk or a
    /// projection may not change it (a chain cannot switch sides; Jakob and Marschner 2012, sec.
    /// 4).
    bool previous_on_front = true;
    /// Delta: the half vector is the normal (slope 0). Glossy: the vertex keeps the slope of its
    /// generalized half vector (`half_vector_slope`), an "offset manifold" (Jakob & Marschner
    /// 2012, sec. 5.3; Kaplanyan et al. 2014 half-vector space).
    RoughnessClass roughness = RoughnessClass::Delta;
    /// Slope coordinates (h.s / h.n, h.t / h.n) of the generalized half vector h in the shading
    /// frame (s, t, n) (constraints.h); the walk keeps it fixed. Zero for delta vertices.
    Vec2d half_vector_slope = Vec2d::Zero();
};

struct SpecularChain {
    ChainEndpoint start;               // x_0, fixed by the walk
    ChainArray<ChainVertex> vertices;  // x_1 .. x_k
    ChainEndpoint end;                 // x_{k+1}, moved by the walk

    std::size_t size() const { return vertices.size(); }
    /// Position of chain vertex i in 0..k+1 (0 = start, k+1 = end).
    const Vec3d& position(std::size_t i) const;
    /// The same chain traversed end -> start: eta' inverted, sides updated, slopes kept (the
    /// slope of w_i + eta' w_o equals that of w_o + w_i / eta').
    SpecularChain reversed() const;
    /// Sum of segment lengths: the length scale that relative tolerances refer to.
    double length() const;
};

/// A chain, or why it could not be built.
struct ChainOutcome {
    SpecularChain chain;
    WalkFailure failure = WalkFailure::None;
    bool ok() const { return failure == WalkFailure::None; }
};

/// An endpoint on a surface, from a float interaction (re-evaluated in double).
ChainEndpoint endpoint_at(const Scene& scene, const SurfaceInteraction& si);
/// An endpoint not on a surface (pinhole camera, point light).
ChainEndpoint point_endpoint(const Vec3d& p);

/// Builds the chain of existing path vertices (e.g. the specular vertices of a sampled path,
/// in start -> end order). Reflection versus refraction is decided geometrically from the sides
/// of the neighbours (as in Mitsuba's manifold code), eta from the BSDF, the roughness class
/// from Bsdf::roughness_class(); glossy vertices store their current half-vector slope. Fails
/// with DegenerateChain for a diffuse interior vertex, a zero-length segment, a refraction
/// through a non-transmissive BSDF, or shading and geometric normals that disagree about a side.
ChainOutcome build_chain(const Scene& scene, const ChainEndpoint& start,
                         std::span<const SurfaceInteraction> vertices, const ChainEndpoint& end);

/// How a traced chain scatters at each vertex.
enum class Scatter { Reflection, Refraction };

/// Builds a chain by tracing from `start` in unit `direction` and scattering specularly at
/// each hit as `scatters` says. The end is the next surface hit after the last vertex
/// (`end_distance` <= 0) or the point at `end_distance` along the last ray (a point endpoint).
/// Fails with LeftManifold (a miss), TotalInternalReflection, Occluded (the free end point lies
/// behind a surface) or DegenerateChain (the surface cannot scatter that way).
ChainOutcome trace_new_chain(const Scene& scene, const ChainEndpoint& start, const Vec3d& direction,
                             std::span<const Scatter> scatters, double end_distance);

}  // namespace gdmlt::manifold
