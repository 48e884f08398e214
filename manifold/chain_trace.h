// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// Tracing specular chains through the scene in double precision: the "projection" step of the
// manifold walk (Jakob & Marschner 2012, sec. 4.3: after a step in the tangent space, trace a
// ray from the fixed endpoint and scatter it at each vertex so that every half-vector
// constraint holds exactly; only the end point's position is then off its target).
//
// The float accelerator (Scene::intersect, rays from spawn_ray) decides which primitive is hit;
// refine_hit() recomputes the hit in double from the unoffset double origin, so chains are
// exact to double round-off whatever the float ray offsets are.
#include "manifold/specular_chain.h"
#include "manifold/walk_failure.h"

namespace gdmlt::manifold {

/// The plane in which the walk moves the chain's end point (the "parameterisation plane").
struct EndPlane {
    Vec3d origin = Vec3d::Zero();
    Vec3d normal = Vec3d::UnitZ();  // unit
    Tangents tangents{Vec3d::UnitX(), Vec3d::UnitY()};
};

/// A plane through `origin` with unit `normal` and tangents around it.
EndPlane end_plane(const Vec3d& origin, const Vec3d& normal);

/// The first surface hit from `origin` (a surface point with geometric normal `n_geometric`, or
/// a free point with zero normal) in unit `direction`, in double; invalid() on a miss or when the
/// double intersection does not confirm the float one.
SurfacePoint trace_surface(const Scene& scene, const Vec3d& origin, const Vec3d& n_geometric,
                           const Vec3d& direction);

/// The outgoing direction at a chain vertex for incoming unit w_i (pointing to the previous
/// vertex): reflection about, or refraction through, the micro-normal of slope `sigma` in the
/// shading frame, such that the vertex's constraint holds (constraints.h). Fails with
/// TotalInternalReflection, or LeftManifold when the directions fall on sides of the geometric
/// and shading normals that contradict each other or the scattering type (light leaks through
/// shading normals are rejected as in Mitsuba's propagation and G-PT's strictNormals).
struct ScatterOutcome {
    Vec3d w_o = Vec3d::Zero();
    WalkFailure failure = WalkFailure::None;
};
ScatterOutcome scatter(const Vec3d& w_i, const SurfacePoint& point, bool reflection, double eta,
                       const Vec2d& sigma);

/// Traces a chain like `like` (same shapes, scattering types, eta', slopes, sides) from
/// like.start in unit `direction`, and intersects the last ray with `plane`, which gives the
/// new end position (the end keeps like.end's normal and shape). Fails with LeftManifold,
/// TotalInternalReflection or DegenerateChain.
ChainOutcome project_chain(const Scene& scene, const SpecularChain& like, const Vec3d& direction,
                           const EndPlane& plane);

/// Relative index eta = int/ext of a transmissive BSDF (1 for a thin dielectric, whose
/// transmission passes straight through); empty when the BSDF does not transmit.
std::optional<double> transmission_eta(const Bsdf& bsdf);

}  // namespace gdmlt::manifold
