// SPDX-License-Identifier: GPL-3.0-or-later
// DiffuseLanes (the path tracer's vectorised diffuse vertex) against finish_vertex (the one-path
// estimator every integrator runs): the same vertex, the same numbers, the same result, bit
// for bit, on every instruction set the kernel is built for that this processor has.
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <span>
#include <vector>

#include "core/path/diffuse_lanes.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// A vertex finish_vertex was run on, with what it left.
struct Reference {
    RayHit hit;
    SurfaceInteraction si;
    VertexNumbers u;
    PathState before, after;
    NextEventRay next_event;
    PathCounters counters;
};

bool same_bits(float a, float b) {
    return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b);
}
bool same_bits(const Vec3f& a, const Vec3f& b) {
    return same_bits(a.x(), b.x()) && same_bits(a.y(), b.y()) && same_bits(a.z(), b.z());
}
bool same_bits(const Rgb& a, const Rgb& b) {
    return same_bits(a[0], b[0]) && same_bits(a[1], b[1]) && same_bits(a[2], b[2]);
}

/// Diffuse vertices of camera paths through random pixels, each path continued by the scalar
/// estimator, stopping at `wanted` vertices that DiffuseLanes handles.
std::vector<Reference> diffuse_vertices(const Scene& scene, const DiffuseLanes& lanes,
                                        const PathSamplerSettings& settings, std::size_t wanted,
                                        std::uint64_t seed) {
    std::vector<Reference> out;
    IndependentStream pixels(seed);
    const Film& film = scene.camera().film();
    for (std::uint64_t path = 0; out.size() < wanted && path < 100 * wanted; ++path) {
        IndependentStream stream(seed * 7919 + path);
        const Vec2f film_position(pixels.next_1d() * static_cast<float>(film.crop_width),
                                  pixels.next_1d() * static_cast<float>(film.crop_height));
        PathCounters counters;
        PathState state = start_path(scene.camera().generate_ray(film_position), counters);
        while (state.active && out.size() < wanted) {
            Reference r;
            RayPacket packet;  // one ray, traced as the wavefront traces: in a packet
            packet.set(0, state.ray);
            packet.count = 1;
            HitPacket hits;
            scene.intersect_packet(packet, hits);
            r.hit = hits.hit(0);
            const SurfaceInteraction si = scene.interaction(state.ray, r.hit);
            r.si = si;
            r.u = draw_vertex_numbers(stream);
            if (!begin_vertex(scene, si, settings, state)) break;
            r.before = state;
            finish_vertex(scene, si, r.u, settings, r.counters, state, r.next_event);
            r.after = state;
            if (lanes.handles(si)) out.push_back(r);
        }
    }
    return out;
}

/// What the test saw, so that it cannot pass on vertices that never take a branch.
struct Coverage {
    int shadow_rays = 0, no_shadow_ray = 0, continued = 0, ended = 0, seen_from_behind = 0,
        shadow_to_infinity = 0, from_hit = 0, from_interaction = 0;
};

/// Runs `references` through DiffuseLanes with `isa`, 256 at a time, and checks every output.
/// Vertices go in through push_hit where the shape allows it (DiffuseLanes::handles_hit), except
/// every third, which goes through push (the SurfaceInteraction) so that both are compared.
void expect_same_as_finish_vertex(const Scene& scene, const PathSamplerSettings& settings,
                                  const std::vector<Reference>& references, SimdIsa isa,
                                  Coverage& seen) {
    DiffuseLanes lanes(scene);
    for (std::size_t first = 0; first < references.size(); first += DiffuseLanes::kCapacity) {
        const std::size_t count = std::min(DiffuseLanes::kCapacity, references.size() - first);
        lanes.clear();
        for (std::size_t k = 0; k < count; ++k) {
            const Reference& r = references[first + k];
            if (lanes.handles_hit(r.hit.shape) && (first + k) % 3 != 0) {
                lanes.push_hit(static_cast<std::uint32_t>(k), r.hit, r.u, r.before, settings);
                ++seen.from_hit;
            } else {
                lanes.push(static_cast<std::uint32_t>(k), r.si, r.u, r.before, settings);
                ++seen.from_interaction;
            }
        }
        lanes.run(isa);
        ASSERT_EQ(lanes.size(), count);
        for (std::size_t k = 0; k < count; ++k) {
            const Reference& r = references[first + k];
            ASSERT_EQ(lanes.id(k), k);
            PathState state = r.before;
            NextEventRay next_event;
            PathCounters counters;
            lanes.finish(k, state, next_event, counters);
            SCOPED_TRACE(testing::Message()
                         << "vertex " << first + k << " at " << r.si.p.transpose());
            ASSERT_EQ(next_event.requested, r.next_event.requested);
            EXPECT_EQ(counters.shadow_rays, r.counters.shadow_rays);
            EXPECT_EQ(counters.bounce_rays, r.counters.bounce_rays);
            if (r.next_event.requested) {
                EXPECT_TRUE(same_bits(next_event.shadow.origin, r.next_event.shadow.origin));
                EXPECT_TRUE(same_bits(next_event.shadow.direction, r.next_event.shadow.direction));
                EXPECT_TRUE(same_bits(next_event.shadow.t_max, r.next_event.shadow.t_max));
                EXPECT_TRUE(same_bits(next_event.contribution, r.next_event.contribution))
                    << next_event.contribution.transpose() << " vs "
                    << r.next_event.contribution.transpose();
                ++seen.shadow_rays;
                if (std::isinf(r.next_event.shadow.t_max)) ++seen.shadow_to_infinity;
            } else {
                ++seen.no_shadow_ray;
            }
            if (-r.before.ray.direction.dot(r.si.shading.n) < 0.f) ++seen.seen_from_behind;
            ASSERT_EQ(state.active, r.after.active);
            EXPECT_TRUE(same_bits(state.radiance, r.after.radiance));
            if (!r.after.active) {
                ++seen.ended;
                continue;
            }
            ++seen.continued;
            EXPECT_TRUE(same_bits(state.ray.origin, r.after.ray.origin));
            EXPECT_TRUE(same_bits(state.ray.direction, r.after.ray.direction))
                << state.ray.direction.transpose() << " vs " << r.after.ray.direction.transpose();
            EXPECT_EQ(state.ray.t_max, r.after.ray.t_max);
            EXPECT_TRUE(same_bits(state.throughput, r.after.throughput));
            EXPECT_TRUE(same_bits(state.prev_pdf_bsdf, r.after.prev_pdf_bsdf));
            EXPECT_EQ(state.prev_delta, r.after.prev_delta);
            EXPECT_TRUE(same_bits(state.prev_p, r.after.prev_p));
            EXPECT_EQ(state.depth, r.after.depth);
            EXPECT_TRUE(same_bits(state.eta_product, r.after.eta_product));
        }
    }
}

/// expect_same_as_finish_vertex on every instruction set this processor has; what the vertices
/// covered (the same on each).
Coverage expect_same_on_every_isa(const Scene& scene, const PathSamplerSettings& settings,
                                  const std::vector<Reference>& references) {
    Coverage seen;
    for (const SimdIsa isa : available_simd_isas()) {
        SCOPED_TRACE(testing::Message() << "instruction set " << static_cast<int>(isa));
        seen = Coverage{};
        expect_same_as_finish_vertex(scene, settings, references, isa, seen);
    }
    return seen;
}

TEST(DiffuseLanes, CornellBoxVerticesAreFinishVertexBitForBit) {
    // The box with its rectangle light (emitter samples computed in the lanes) and a glass
    // sphere (its vertices go through finish_vertex; the diffuse vertices after it carry
    // eta_product and throughput changed by refraction). Russian roulette from the second
    // vertex so that it decides often. 2000 vertices from seed 3.
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(32, true));
    PathSamplerSettings settings;
    settings.max_depth = 10;
    settings.rr_depth = 2;
    const DiffuseLanes lanes(scene);
    const std::vector<Reference> references = diffuse_vertices(scene, lanes, settings, 2000, 3);
    ASSERT_EQ(references.size(), 2000u);
    const Coverage seen = expect_same_on_every_isa(scene, settings, references);
    EXPECT_GT(seen.shadow_rays, 500);
    EXPECT_GT(seen.no_shadow_ray, 50);  // light behind the vertex, or the back of the light
    EXPECT_GT(seen.continued, 500);
    EXPECT_GT(seen.ended, 100);  // Russian roulette
    EXPECT_GT(seen.from_hit, 1000);
    EXPECT_GT(seen.from_interaction, 600);
}

TEST(DiffuseLanes, TwoSidedSurfacesAndOtherEmittersAreFinishVertexBitForBit) {
    // A two-sided sheet with a different back (seen from both sides), a one-sided diffuse floor,
    // a point light, a spherical area light (neither is a mesh: their samples come from
    // Scene::sample_emitter) and a constant environment (shadow rays to infinity). Seed 5.
    const Scene scene = test::scene_from_xml(test::sensor_xml(32, 60.f, "0.3, 0.8, 3") + R"(
        <bsdf type="diffuse" id="floor"><rgb name="reflectance" value="0.5, 0.4, 0.3"/></bsdf>
        <shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/>
            <translate y="-1"/></transform><ref id="floor"/></shape>
        <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="60"/></transform>
            <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.7, 0.4"/></bsdf>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.1, 0.6"/></bsdf></bsdf></shape>
        <shape type="sphere"><point name="center" value="-1, 1, 0"/><float name="radius" value="0.2"/>
            <emitter type="area"><rgb name="radiance" value="20, 15, 10"/></emitter></shape>
        <emitter type="point"><point name="position" value="1, 1.5, 1"/><rgb name="intensity" value="5"/></emitter>
        <emitter type="constant"><rgb name="radiance" value="0.3"/></emitter>)");
    PathSamplerSettings settings;
    settings.max_depth = 8;
    settings.rr_depth = 3;
    const DiffuseLanes lanes(scene);
    const std::vector<Reference> references = diffuse_vertices(scene, lanes, settings, 2000, 5);
    ASSERT_EQ(references.size(), 2000u);
    const Coverage seen = expect_same_on_every_isa(scene, settings, references);
    EXPECT_GT(seen.shadow_rays, 500);
    EXPECT_GT(seen.shadow_to_infinity, 50);
    EXPECT_GT(seen.seen_from_behind, 20);  // the sheet's back (38 vertices from seed 5)
    EXPECT_GT(seen.continued, 500);
    EXPECT_GT(seen.ended, 50);
    EXPECT_GT(seen.from_hit, 1000);
    EXPECT_GT(seen.from_interaction, 600);
}

TEST(DiffuseLanes, HandlesConstantDiffuseSurfacesOnly) {
    // A textured diffuse surface and a glass sphere are finish_vertex's; constant diffuse ones,
    // one- or two-sided, are the lanes'.
    const Scene scene = test::scene_from_xml(test::sensor_xml(8, 40.f, "0, 0, 4") + R"(
        <shape type="rectangle"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>
        <shape type="rectangle"><bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf></shape>
        <shape type="rectangle"><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>
        <shape type="sphere"><bsdf type="dielectric"/></shape>
        <emitter type="constant"/>)");
    const DiffuseLanes lanes(scene);
    SurfaceInteraction si;
    const bool expected[] = {true, false, true, false};
    for (std::int32_t shape = 0; shape < 4; ++shape) {
        si.shape = shape;
        EXPECT_EQ(lanes.handles(si), expected[shape]) << "shape " << shape;
    }
}

}  // namespace
}  // namespace gdmlt
