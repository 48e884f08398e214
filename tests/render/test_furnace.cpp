// SPDX-License-Identifier: GPL-3.0-or-later
// Furnace tests: scenes whose exact answer is known, rendered by the path tracer. Each test
// states its seed and budget; tolerances are 5 standard errors of the image mean, the standard
// error estimated from the per-pixel spread (pixels are independent), plus float round-off.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/render/render_path.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

RenderOutput render(const Scene& scene, int spp, std::uint64_t seed) {
    return test::render_unbounded(scene, spp, seed);
}

void expect_mean(const Image& image, const Rgb& expected) {
    test::expect_image_mean(image, expected, 1e-5);
}

TEST(Furnace, ConvexDiffuseSphereInConstantLightReflectsAlbedoTimesRadiance) {
    // Every point of a convex sphere sees the environment over its whole hemisphere, so the
    // reflected radiance is exactly albedo * L (one bounce; nothing inter-reflects).
    const Scene scene = test::scene_from_xml(test::sensor_xml(16, 8.f, "0, 0, 5") + R"(
        <emitter type="constant"><rgb name="radiance" value="1, 2, 0.5"/></emitter>
        <shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.5, 0.8"/></bsdf></shape>)");
    const RenderOutput out = render(scene, 64, 1);
    expect_mean(out.image, Rgb(0.3f * 1.f, 0.5f * 2.f, 0.8f * 0.5f));
}

TEST(Furnace, ClosedEmittingDiffuseSphereSeenFromInsideSumsTheGeometricSeries) {
    // Inside a closed sphere whose inner surface emits Le and reflects with albedo a, the
    // radiance everywhere is Le (1 + a + a^2 + ...) = Le / (1 - a): tests inter-reflection,
    // NEE + MIS on an area light, and Russian roulette (no depth limit).
    const Scene scene = test::scene_from_xml(test::sensor_xml(16, 60.f, "0, 0, 0.5") + R"(
        <shape type="sphere"><float name="radius" value="1"/><boolean name="flip_normals" value="true"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.25, 0.75"/></bsdf>
            <emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter></shape>)");
    const RenderOutput out = render(scene, 64, 2);
    expect_mean(out.image, Rgb(2.f, 1.f / 0.75f, 4.f));
}

TEST(Furnace, SmoothGlassSphereInConstantLightReturnsTheEnvironmentRadiance) {
    // A lossless dielectric (IOR 1.5) in a uniform environment: every path ends in the
    // environment with weight 1 (1/eta^2 on entering cancels eta^2 on leaving).
    const Scene scene = test::scene_from_xml(test::sensor_xml(16, 20.f, "0, 0, 4") + R"(
        <emitter type="constant"><rgb name="radiance" value="0.7, 0.7, 0.7"/></emitter>
        <shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>)");
    const RenderOutput out = render(scene, 16, 3);
    expect_mean(out.image, Rgb::Constant(0.7f));
    EXPECT_EQ(out.stats.nonfinite_samples_dropped, 0u);
}

/// A floor, a back wall, a glass sphere and a small area light: diffuse and delta vertices,
/// next-event estimation that is blocked and unblocked, rays that escape.
Scene determinism_scene(int resolution) {
    return test::scene_from_xml(test::sensor_xml(resolution, 40.f, "0, 0, 3.9") + R"(
        <shape type="rectangle"><transform name="to_world"><translate value="0, 0, -1"/></transform></shape>
        <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/><translate y="-1"/></transform></shape>
        <shape type="sphere"><point name="center" value="0.3, -0.5, 0"/><float name="radius" value="0.4"/>
            <bsdf type="dielectric"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate y="0.9"/></transform>
            <emitter type="area"><rgb name="radiance" value="10, 10, 10"/></emitter></shape>)");
}

TEST(Determinism, SameSeedGivesTheSameImageAtOneAndTwoThreads) {
    // 64x64: 16 tiles of kPixelPassTileSize, so that two threads really share the work (at
    // 24x24 a stream that depended on the thread went unnoticed).
    const Scene scene = determinism_scene(64);
    const auto [one, two] = test::at_one_and_two_threads([&] { return render(scene, 4, 42); });
    EXPECT_TRUE(one.image == two.image);
    const RenderOutput other_seed = render(scene, 4, 43);
    EXPECT_FALSE(one.image == other_seed.image);
}

TEST(Determinism, AGaussianFilmGivesTheSameImageAtOneAndTwoThreads) {
    // The splatting film (core/render/splat_film.h): samples reach pixels of other tiles, and
    // the image is still the same at one and two threads.
    Scene scene = determinism_scene(64);
    scene.set_film_filter(PixelFilter::gaussian(0.5f));
    const auto [one, two] = test::at_one_and_two_threads([&] { return render(scene, 4, 42); });
    EXPECT_TRUE(one.image == two.image);
    const RenderOutput box = render(determinism_scene(64), 4, 42);
    EXPECT_FALSE(one.image == box.image);  // the filter did take part
}

}  // namespace
}  // namespace gdmlt
