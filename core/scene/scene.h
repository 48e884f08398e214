// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The immutable scene: shapes with their Embree BVH, BSDFs, emitters, camera, and the summary
// of which effects occur (SceneFeatures) that integrators read to switch machinery off.
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "core/accel/accelerator.h"
#include "core/bsdf/bsdf.h"
#include "core/camera/camera.h"
#include "core/emitter/emitter.h"
#include "core/geometry/interaction.h"
#include "core/geometry/shape.h"
#include "core/sampling/distribution_1d.h"
#include "core/scene/scene_desc.h"

namespace gdmlt {

/// Which effects the scene calls for (integrators switch machinery off from it: simulate only what
/// the scene calls for).
struct SceneFeatures {
    bool has_diffuse = false;
    bool has_glossy = false;
    bool has_delta_reflection = false;
    bool has_delta_transmission = false;
    bool has_transmission = false;
    bool has_textures = false;
    bool has_area_emitters = false;
    bool has_delta_emitters = false;
    bool has_infinite_emitters = false;
    /// A specular chain needs at least one delta or near-delta surface. When false, no
    /// manifold walk or half-vector shift can ever be needed.
    bool specular_chains_possible = false;
    std::set<std::string> bsdf_kinds;  // Mitsuba plugin names that occur
    std::set<std::string> emitter_kinds;
    std::set<std::string> shape_kinds;
};

/// The `<integrator>` block: the path tracer's settings plus every property as written, so that
/// other integrators (pssmlt, gdpt, gdmlt) read their knobs from it. Mitsuba's meaning of
/// max_depth: the longest path, in segments, that contributes (-1 = unbounded; 1 = only
/// directly visible emitters).
struct IntegratorSettings {
    std::string type = "path";
    int max_depth = -1;
    int rr_depth = 5;
    bool hide_emitters = false;
    ObjectDesc desc;  // the raw element (type, properties, location), empty when absent
};

struct SamplerSettings {
    int sample_count = 4;
    std::uint64_t seed = 0;
};

/// A point sampled on an emitter as seen from a reference point.
struct EmitterSample {
    Vec3f p = Vec3f::Zero();            // on the emitter (unused for infinite emitters)
    Vec3f n_geometric = Vec3f::Zero();  // zero for point and infinite emitters
    Vec3f wi = Vec3f::UnitZ();          // unit, from the reference point to the emitter
    float distance = kInfinity;
    /// Radiance arriving at the reference point along -wi (for a point light: I / d^2).
    Rgb radiance = Rgb::Zero();
    /// Density in solid angle at the reference point, including the emitter choice; for a
    /// delta (point) emitter, the discrete probability of choosing it.
    float pdf_solid_angle = 0.f;
    bool delta = false;
    int emitter = -1;
    bool valid() const { return pdf_solid_angle > 0.f; }
};

class Scene {
  public:
    Scene(std::vector<Shape> shapes, std::vector<Bsdf> bsdfs, std::vector<Emitter> emitters,
          PerspectiveCamera camera, IntegratorSettings integrator, SamplerSettings sampler,
          SceneFeatures features, std::map<std::string, std::size_t> counts);

    const std::vector<Shape>& shapes() const { return shapes_; }
    const std::vector<Bsdf>& bsdfs() const { return bsdfs_; }
    const std::vector<Emitter>& emitters() const { return emitters_; }
    const PerspectiveCamera& camera() const { return camera_; }
    const IntegratorSettings& integrator() const { return integrator_; }
    const SamplerSettings& sampler() const { return sampler_; }
    const SceneFeatures& features() const { return features_; }
    /// Statistics of loading: triangles, degenerate triangles dropped, ...
    const std::map<std::string, std::size_t>& counts() const { return counts_; }
    Eigen::AlignedBox3f bounds() const { return accelerator_->bounds(); }
    const Bsdf& bsdf_of(const SurfaceInteraction& si) const {
        return bsdfs_[static_cast<std::size_t>(shapes_[static_cast<std::size_t>(si.shape)].bsdf())];
    }

    /// Closest hit with full differential geometry; invalid() on a miss.
    SurfaceInteraction intersect(const Ray& ray) const;
    bool occluded(const Ray& ray) const { return accelerator_->occluded(ray); }

    /// Chooses an emitter (proportionally to its power among bounded emitters; the lights at
    /// infinity as a group get the share of one more light, see the constructor) and a point
    /// on it, as seen from `ref_p` (used for the ray offset only). Infinite
    /// emitters (constant, envmap) are sampled as one environment: a direction chosen through
    /// any of them carries the radiance of all of them and their combined density, which is
    /// what a BSDF-sampled ray that escapes sees (environment(), pdf_environment_solid_angle()),
    /// so MIS weights agree on both sides.
    EmitterSample sample_emitter(const Vec3f& ref_p, float u_select, const Vec2f& u) const;

    /// Radiance leaving emitter surface point `si` towards direction `w` (unit, world).
    Rgb emitted(const SurfaceInteraction& si, const Vec3f& w) const;
    /// Radiance from infinite emitters arriving along -`direction` (a ray that missed).
    Rgb environment(const Vec3f& direction) const;
    /// Solid-angle density with which sample_emitter would have produced the point `si` on an
    /// area emitter from `ref_p` (including the emitter choice).
    float pdf_emitter_solid_angle(const Vec3f& ref_p, const SurfaceInteraction& si) const;
    /// Same for a direction that escaped to the infinite emitters.
    float pdf_environment_solid_angle(const Vec3f& direction) const;
    bool has_environment() const { return !infinite_emitters_.empty(); }
    /// Probability that sample_emitter chooses emitter `index` (proportional to its estimated
    /// power), for MIS weights of other samplers.
    float emitter_selection_pmf(int index) const {
        return emitter_selection_.pmf(static_cast<std::size_t>(index));
    }

  private:
    std::vector<Shape> shapes_;
    std::vector<Bsdf> bsdfs_;
    std::vector<Emitter> emitters_;
    std::vector<int> infinite_emitters_;
    /// Per emitter: for area emitters with textured radiance on a mesh, the choice of triangle
    /// by area (the uv of a sampled point is needed to look the radiance up); empty otherwise.
    std::vector<Distribution1D> textured_emitter_triangles_;
    Distribution1D emitter_selection_;
    PerspectiveCamera camera_;
    IntegratorSettings integrator_;
    SamplerSettings sampler_;
    SceneFeatures features_;
    std::map<std::string, std::size_t> counts_;
    std::unique_ptr<Accelerator> accelerator_;
    Vec3f bounds_center_ = Vec3f::Zero();
    float bounds_radius_ = 1.f;
};

struct BuildOptions {
    /// Unknown plugins and properties become warnings (printed to stderr) instead of errors.
    bool lenient = false;
};

/// Builds the scene: loads meshes, applies transforms, resolves BSDFs and emitters, commits
/// Embree. Throws InputError with file and line for anything invalid.
Scene build_scene(const SceneDesc& desc, const BuildOptions& options = {});

}  // namespace gdmlt
