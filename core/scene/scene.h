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
#include "core/sampling/alias_table.h"
#include "core/sampling/distribution_1d.h"
#include "core/scene/aov.h"
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
    /// Mitsuba 3's `aov` wrapper: the layers to write beside its nested integrator's image.
    std::vector<AovRequest> aovs;
    /// Mitsuba 3's `moment` wrapper: the name its layers carry (its nested integrator's
    /// `name`, or Mitsuba's `_arg_0` for an unnamed one); empty when absent.
    std::string moment;
    ObjectDesc desc;  // the raw element (type, properties, location), empty when absent
};

struct SamplerSettings {
    int sample_count = 4;
    std::uint64_t seed = 0;
};

/// A point sampled on an emitter as seen from a reference point. sample_emitter keeps one named
/// return object (see BsdfSample): it runs at every path vertex.
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

/// A ray leaving an emitter: the first vertex and direction of a light subpath (Veach 1997,
/// sec. 10.2; what pbrt-v4 calls SampleLe). Lights at infinity (directional, environment) send
/// it from a disk of the scene's bounding-sphere radius outside the scene, perpendicular to the
/// direction, so that every point of the scene is reached with the same area density.
struct EmittedRay {
    Vec3f origin = Vec3f::Zero();
    Vec3f n_geometric = Vec3f::Zero();  // area emitters: the unit surface normal; else zero
    Vec3f direction = Vec3f::UnitZ();   // unit, away from the emitter
    /// What leaves along `direction`: radiance (area, environment), intensity in W/sr (point,
    /// spot), irradiance on a surface facing the beam (directional).
    Rgb radiance = Rgb::Zero();
    /// Area density of `origin` (per m^2; point and spot lights: a probability) and solid-angle
    /// density of `direction` (directional light: 1, a delta). Their product includes the
    /// choice of the emitter: in the position density for bounded emitters, in the direction
    /// density for the environment (its lights are sampled as one, as in sample_emitter).
    float pdf_position = 0.f;
    float pdf_direction = 0.f;
    /// radiance |cos theta| / (pdf_position pdf_direction): the light subpath's throughput after
    /// its first vertex (the cosine at the origin; 1 for points and disks facing the beam).
    Rgb weight = Rgb::Zero();
    int emitter = -1;  // the chosen emitter (for the environment: the one whose sampler ran)
    bool delta_position = false;   // point and spot lights
    bool delta_direction = false;  // directional light
    bool at_infinity = false;      // directional and environment lights
    bool valid() const { return pdf_position > 0.f && pdf_direction > 0.f; }
};

/// The densities of an emitted ray (EmittedRay's pdf_position and pdf_direction), for MIS.
struct EmissionPdf {
    float position = 0.f;
    float direction = 0.f;
};

class Scene {
  public:
    Scene(std::vector<Shape> shapes, std::vector<Bsdf> bsdfs, std::vector<Emitter> emitters,
          Camera camera, IntegratorSettings integrator, SamplerSettings sampler,
          SceneFeatures features, std::map<std::string, std::size_t> counts);

    const std::vector<Shape>& shapes() const { return shapes_; }
    const std::vector<Bsdf>& bsdfs() const { return bsdfs_; }
    const std::vector<Emitter>& emitters() const { return emitters_; }
    const Camera& camera() const { return camera_; }
    /// Renders with another reconstruction filter than the file's: the gradient-domain
    /// integrators sample with the box filter and filter their reconstructed image afterwards.
    void set_film_filter(const PixelFilter& filter) { camera_.set_film_filter(filter); }
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
    /// Packets of up to Accelerator::kPacketSize rays traced together; turn each hit into an
    /// interaction with interaction(ray, hit) (the same as intersect(ray) gives). `coherent`:
    /// see Accelerator::intersect_packet.
    void intersect_packet(const RayPacket& rays, HitPacket& hits, bool coherent = false) const {
        accelerator_->intersect_packet(rays, hits, coherent);
    }
    void occluded_packet(const RayPacket& rays,
                         std::array<bool, Accelerator::kPacketSize>& occluded) const {
        accelerator_->occluded_packet(rays, occluded);
    }
    /// Full differential geometry at `hit`, found along `ray`; invalid() for a miss.
    SurfaceInteraction interaction(const Ray& ray, const RayHit& hit) const;

    /// Chooses an emitter (proportionally to its power among bounded emitters; the lights at
    /// infinity as a group get the share of one more light, see the constructor) and a point
    /// on it, as seen from `ref_p` (used for the ray offset only). Infinite
    /// emitters (constant, envmap) are sampled as one environment: a direction chosen through
    /// any of them carries the radiance of all of them and their combined density, which is
    /// what a BSDF-sampled ray that escapes sees (environment(), pdf_environment_solid_angle()),
    /// so MIS weights agree on both sides. A light at a point that sends nothing towards
    /// `ref_p` (a spot seen from outside its cone) still gives a valid sample with zero
    /// radiance, whose position a gradient-domain shift reuses.
    EmitterSample sample_emitter(const Vec3f& ref_p, float u_select, const Vec2f& u) const;

    /// What sample_emitter samples when `u_select` chooses an area emitter of constant radiance
    /// on a triangle mesh (most scenes' lights): the triangle it would pick, as an index into
    /// emitter_triangles(), for callers that compute the rest of sample_emitter themselves,
    /// many at once (core/path/diffuse_lanes.h). -1 for every other choice; sample_emitter
    /// handles those. The triangles are tabulated when the scene is built (one lookup here
    /// instead of following shape, mesh, indices and positions per call: the path tracer calls
    /// this at every diffuse vertex).
    struct EmitterTriangle {
        Vec3f a = Vec3f::Zero(), b = Vec3f::Zero(), c = Vec3f::Zero();  // corners
        Vec3f n_geometric = Vec3f::Zero();                              // unit face normal
        Rgb radiance = Rgb::Zero();
        float pmf = 0.f;   // probability of choosing the emitter
        float area = 0.f;  // the emitter's whole area (its points are uniform by area)
    };
    std::int64_t emitter_triangle(float u_select) const;
    /// The table emitter_triangle indexes.
    const std::vector<EmitterTriangle>& emitter_triangles() const { return emitter_triangles_; }

    /// A ray leaving an emitter chosen by power as in sample_emitter (`u_select`), at a point
    /// chosen by `u_position` (uniform by area) in a direction chosen by `u_direction`:
    /// cosine-weighted about an area light's normal, uniform over the sphere (point light) or
    /// the spot's cone, the beam of a directional light, importance-sampled environment
    /// directions. Invalid (pdfs 0) when nothing can be emitted that way.
    EmittedRay sample_emitted_ray(float u_select, const Vec2f& u_position,
                                  const Vec2f& u_direction) const;
    /// Densities with which sample_emitted_ray produces a ray leaving bounded emitter `emitter`
    /// along unit `direction`; `n_geometric` is the normal at the point of an area emitter.
    EmissionPdf pdf_emitted_ray(int emitter, const Vec3f& n_geometric,
                                const Vec3f& direction) const;
    /// Same for a ray from the environment travelling along unit `direction` into the scene.
    EmissionPdf pdf_environment_ray(const Vec3f& direction) const;
    /// Radius of the disk that rays of lights at infinity start from (the scene's bounding
    /// sphere), centred on bounds_center().
    float bounds_radius() const { return bounds_radius_; }
    Vec3f bounds_center() const { return bounds_center_; }

    /// Radiance leaving emitter surface point `si` towards direction `w` (unit, world).
    Rgb emitted(const SurfaceInteraction& si, const Vec3f& w) const;
    /// Radiance from infinite emitters arriving along -`direction` (a ray that missed).
    Rgb environment(const Vec3f& direction) const;
    /// Solid-angle density with which sample_emitter would have produced the point `si` on an
    /// area emitter from `ref_p` (including the emitter choice).
    float pdf_emitter_solid_angle(const Vec3f& ref_p, const SurfaceInteraction& si) const;
    /// Same for a direction that escaped to the infinite emitters.
    float pdf_environment_solid_angle(const Vec3f& direction) const;
    /// environment() and pdf_environment_solid_angle() together, from one direction -> (u, v)
    /// map per environment map: what an escaping ray needs for its MIS weight, at half the cost
    /// of the two calls; the same numbers as they give.
    struct EnvironmentValue {
        Rgb radiance = Rgb::Zero();
        float pdf_solid_angle = 0.f;
    };
    EnvironmentValue environment_with_pdf(const Vec3f& direction) const;
    /// environment_with_pdf(sample.direction) for a direction `envmap` (chosen with
    /// probability `pmf`) sampled, taken from the sample's own (u, v) when it is the scene's
    /// only infinite emitter.
    EnvironmentValue environment_of_sample(const EnvmapEmitter& envmap,
                                           const EnvmapEmitter::Sample& sample, float pmf) const;
    bool has_environment() const { return !infinite_emitters_.empty(); }
    /// Probability that sample_emitter chooses emitter `index` (proportional to its estimated
    /// power), for MIS weights of other samplers.
    /// Radiance arriving from delta-position emitter `index` (point, spot, projector) at
    /// distance sqrt(dist2) along the unit direction `w` leaving it: its intensity towards w
    /// over dist2. For shifted next-event samples, which keep the light's position but see it
    /// along another direction.
    Rgb delta_position_radiance(int index, const Vec3f& w, float dist2) const {
        return delta_intensity_towards(emitters_[static_cast<std::size_t>(index)], w) / dist2;
    }
    float emitter_selection_pmf(int index) const {
        return emitter_selection_.pmf(static_cast<std::size_t>(index));
    }

  private:
    /// The emitter choice both emitter samplers make (by power), with `u_select` remapped to
    /// [0, 1) within the chosen emitter's interval for reuse (the primitive of a mesh light).
    struct EmitterChoice {
        std::size_t index = 0;
        float pmf = 0.f;
        float u_remapped = 0.f;
    };
    EmitterChoice choose_emitter(float u_select) const;
    struct AreaPoint {
        Vec3f p = Vec3f::Zero(), n = Vec3f::Zero();
        TexturePoint texture;  // where the radiance texture is read
    };
    /// A point uniformly distributed by area on area emitter `index` (density 1 / area), with
    /// its texture lookup (uv, triangle, barycentrics) when the radiance is textured.
    AreaPoint sample_area_emitter_point(std::size_t index, float u_primitive, const Vec2f& u) const;

    std::vector<Shape> shapes_;
    std::vector<Bsdf> bsdfs_;
    std::vector<Emitter> emitters_;
    std::vector<int> infinite_emitters_;
    /// Per emitter: for area emitters with textured radiance on a mesh, the choice of triangle
    /// by area (the uv of a sampled point is needed to look the radiance up); empty otherwise.
    std::vector<Distribution1D> textured_emitter_triangles_;
    AliasTable emitter_selection_;  // by power, in constant time (alias_table.h)
    /// emitter_triangle's table: every triangle of each constant-radiance area emitter on a
    /// mesh, emitter after emitter, and per emitter the index of its first triangle (-1 for
    /// the others).
    std::vector<EmitterTriangle> emitter_triangles_;
    std::vector<std::int64_t> first_emitter_triangle_;
    Camera camera_;
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
