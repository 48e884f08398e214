// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// An explicit camera path: the vertices a unidirectional sampler visited, with what each vertex
// needs for shift mappings and MIS (Kettunen et al. 2015, sec. 4; Lehtinen et al. 2013,
// sec. 4): how the path continued (direction, f and pdf in solid angle, delta or not, which
// random numbers chose it) and the next-event sample taken there.
//
// Measures: a path's value f and pdf are products over its vertices of per-vertex factors in
// the solid-angle measure of the direction leaving that vertex (the camera's first direction
// has pdf 1: the film position is the primary sample). f / pdf is the path tracer's throughput.
#include <vector>

#include "core/bsdf/roughness_class.h"
#include "core/geometry/interaction.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"

namespace gdmlt {

struct PathVertex {
    SurfaceInteraction si;
    /// The BSDF's class (diffuse > glossy > delta; most connectable lobe of mixed BSDFs).
    RoughnessClass roughness = RoughnessClass::Diffuse;

    // How the path continued from this vertex (valid when `continued`).
    bool continued = false;
    Vec3f wi_world = Vec3f::Zero();  // unit direction to the next vertex
    Rgb f = Rgb::Zero();  // eval (f * |cos|); for a delta lobe: weight * lobe probability
    float pdf = 0.f;      // solid angle; for a delta lobe: the lobe's probability
    bool delta = false;   // the continuation came from a delta lobe
    bool transmission = false;
    float u_lobe = 0.f;  // the random numbers that chose it (for replay shifts)
    Vec2f u_direction = Vec2f::Zero();

    // Next-event estimation from this vertex (valid when `light.valid()`).
    EmitterSample light;
    bool light_visible = false;
    /// For offset paths: log Jacobian of the next-event direction, offset from base (the light
    /// point is shared, so it is the area-to-solid-angle ratio). 0 on base paths.
    double log_light_jacobian = 0.0;

    /// A vertex a shift may reconnect to or from: its BSDF is broad and the path did not
    /// leave it through a delta lobe.
    bool connectable() const { return roughness == RoughnessClass::Diffuse && !delta; }
};

struct Path {
    Vec2f film_position = Vec2f::Zero();
    /// The thin lens's sample (Camera::draw_lens_sample): offsets keep it, so a shift moves
    /// the film position only, as with the pinhole.
    Vec2f lens_sample = Vec2f(0.5f, 0.5f);
    Vec3f camera_position = Vec3f::Zero();  // the camera ray's origin
    Vec3f camera_direction = Vec3f::UnitZ();
    std::vector<PathVertex> vertices;  // surface vertices x_1 .. x_n in order
    /// The last continuation escaped the scene (environment light) in this direction.
    bool escaped = false;
    Vec3f escape_direction = Vec3f::Zero();
    /// The vertices carry the random numbers that chose their continuations (u_lobe,
    /// u_direction). False for a light subpath written in camera order: a shift may then only
    /// use maps that depend on the geometry (reconnection, half vector, manifold walks, a delta
    /// lobe's mirror or refraction), never replay numbers.
    bool replayable = true;
};

/// Samples a camera path through `film_position` with the same decisions and random-number
/// layout as sample_path_radiance (kCameraDimensions are taken by the caller for the film
/// position, then kDimensionsPerBounce per vertex) and records its vertices. Russian roulette
/// is not applied (shifts need the whole path; max_depth bounds it).
Path sample_camera_path(const Scene& scene, const Vec2f& film_position, SampleStream& stream,
                        const PathSamplerSettings& settings, PathCounters& counters);
/// The same into `path`, whose vertex storage is reused (no allocation once it is large enough).
void sample_camera_path(const Scene& scene, const Vec2f& film_position, SampleStream& stream,
                        const PathSamplerSettings& settings, PathCounters& counters, Path& path);
/// Empties `path` (a default Path) but keeps its vertices' storage for reuse.
void reset_keeping_capacity(Path& path);

}  // namespace gdmlt
