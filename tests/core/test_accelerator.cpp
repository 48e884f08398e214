// SPDX-License-Identifier: GPL-3.0-or-later
// Accelerator's packet queries (RayPacket / HitPacket, the path tracer's wavefront) against its
// one-ray queries: the same triangle for every ray, the same verdict for every shadow ray, and
// a miss reported as RayHit{}.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/accel/accelerator.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// Checks `scene`'s packet queries against its one-ray queries (see the test below);
/// `counted_seen` is how many rays hit shapes for which `counted` is true.
template <class Counted>
void expect_packets_agree_with_single_rays(const Scene& scene, Counted counted, int& counted_seen) {
    // The box with a glass sphere (40x40 film). 2000 rays (Pcg32 stream seed 21) from points
    // in and in front of the box in uniform directions, a third of them cut short: hits on
    // walls and sphere, misses through the open front, and short rays that stop before any
    // surface. Packets of 1, 7 and 16 rays, so that lanes past `count` hold the previous
    // packet's rays. Hits are compared by shape and triangle, exactly (a packet and a single
    // ray may round t or a barycentric differently in the last bits, which moves a hit to
    // the neighbouring triangle only for rays within an ulp of an edge: none among these),
    // and t to 1e-5 relative. Shadow queries use the same rays.
    const Accelerator accelerator(scene.shapes());
    const Eigen::AlignedBox3f box = accelerator.bounds();
    Pcg32 rng(21, 22);
    std::vector<Ray> rays;
    for (int i = 0; i < 2000; ++i) {
        Ray ray;
        const Vec3f lo = box.min(), size = box.sizes();
        // z up to 1.5x the box's depth: some origins lie in front of its open side.
        ray.origin = lo + Vec3f(rng.next_float() * size.x(), rng.next_float() * size.y(),
                                rng.next_float() * 1.5f * size.z());
        ray.direction = warp::square_to_uniform_sphere(Vec2f(rng.next_float(), rng.next_float()));
        if (i % 3 == 0) ray.t_max = rng.next_float() * 0.2f * size.norm();
        rays.push_back(ray);
    }
    int hits_seen = 0, misses_seen = 0, blocked_seen = 0, unblocked_seen = 0;
    counted_seen = 0;
    RayPacket packet;
    HitPacket hits;
    std::array<bool, Accelerator::kPacketSize> blocked{};
    for (const int size : {1, 7, 16}) {
        for (std::size_t first = 0; first + static_cast<std::size_t>(size) <= rays.size();
             first += static_cast<std::size_t>(size)) {
            packet.count = size;
            for (int k = 0; k < size; ++k) packet.set(k, rays[first + static_cast<std::size_t>(k)]);
            accelerator.intersect_packet(packet, hits);
            accelerator.occluded_packet(packet, blocked);
            for (int k = 0; k < size; ++k) {
                const Ray& ray = rays[first + static_cast<std::size_t>(k)];
                const RayHit expected = accelerator.intersect(ray);
                const RayHit hit = hits.hit(k);
                SCOPED_TRACE(testing::Message() << "packet of " << size << ", ray " << first + k);
                ASSERT_EQ(hit.shape, expected.shape);
                if (expected.valid()) {
                    ++hits_seen;
                    if (counted(scene.shapes()[static_cast<std::size_t>(expected.shape)]))
                        ++counted_seen;
                    ASSERT_EQ(hit.primitive, expected.primitive);
                    ASSERT_NEAR(hit.t, expected.t, 1e-5f * expected.t);
                    ASSERT_NEAR(hit.barycentric.x(), expected.barycentric.x(), 1e-4f);
                    ASSERT_NEAR(hit.barycentric.y(), expected.barycentric.y(), 1e-4f);
                } else {
                    ++misses_seen;
                    ASSERT_EQ(hit.t, kInfinity);
                    ASSERT_EQ(hit.primitive, 0u);
                    ASSERT_EQ(hit.barycentric, Vec2f::Zero());
                }
                const bool expected_blocked = accelerator.occluded(ray);
                ASSERT_EQ(blocked[static_cast<std::size_t>(k)], expected_blocked);
                ++(expected_blocked ? blocked_seen : unblocked_seen);
            }
        }
    }
    // Each kind of outcome occurred often enough to have been compared.
    EXPECT_GT(hits_seen, 1000);
    EXPECT_GT(misses_seen, 300);
    EXPECT_GT(blocked_seen, 1000);
    EXPECT_GT(unblocked_seen, 300);
}

TEST(Accelerator, PacketQueriesAgreeWithOneRayQueries) {
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(40, true));
    int hits = 0;
    expect_packets_agree_with_single_rays(
        scene, [](const Shape&) { return true; }, hits);
}

TEST(Accelerator, PacketQueriesAgreeWithOneRayQueriesOnInstances) {
    // The same box with a shapegroup (a cube) placed three times, once mirrored: the packets'
    // hits must name the instance (Embree's instID), as the one-ray hits do
    // (SceneBuild.AnInstanceIsItsShapegroupsShapesUnderItsTransform checks those).
    const std::string group = R"(<shape type="shapegroup" id="g"><shape type="cube">
        <transform name="to_world"><scale value="0.08"/></transform></shape></shape>)";
    std::string instances;
    for (const char* to_world :
         {R"(<rotate y="1" angle="30"/><translate value="0.3, 0.15, 0.3"/>)",
          R"(<scale x="-1.5" y="0.7" z="1"/><translate value="0.7, 0.4, 0.6"/>)",
          R"(<translate value="0.5, 0.8, 0.2"/>)"})
        instances += R"(<shape type="instance"><ref id="g"/><transform name="to_world">)" +
                     std::string(to_world) + "</transform></shape>";
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(40) + group + instances);
    int instance_hits = 0;
    expect_packets_agree_with_single_rays(
        scene, [](const Shape& shape) { return shape.is_instance(); }, instance_hits);
    EXPECT_GT(instance_hits, 30);
}

}  // namespace
}  // namespace gdmlt
