// SPDX-License-Identifier: GPL-3.0-or-later
// Mitsuba 3's `aov` integrator (core/scene/aov.h, core/render/aov_pass.h): the aovs list as
// Mitsuba spells it, and the first-hit layers of a scene whose answer is known.
#include <gtest/gtest.h>

#include <cmath>

#include "core/render/aov_pass.h"
#include "core/scene/scene_desc.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// A square of side 2 at z = 0 facing +z, seen head-on from z = 4 with a 40-degree field of
/// view: the square fills the middle of the 16x16 image, the rest escapes.
std::string square_xml(const std::string& aovs) {
    return test::sensor_xml(16, 40.f, "0, 0, 4") + R"(
        <integrator type="aov"><string name="aovs" value=")" +
           aovs +
           R"("/><integrator type="path"><integer name="max_depth" value="3"/></integrator></integrator>
        <shape type="rectangle"><bsdf type="diffuse"/></shape>
        <emitter type="constant"/>)";
}

TEST(AovPass, ParsesMitsubasListAndRendersItsNestedIntegrator) {
    const Scene scene =
        test::scene_from_xml(square_xml(" nn:sh_normal, depth.y:depth ,position:position"));
    EXPECT_EQ(scene.integrator().type, "path");
    EXPECT_EQ(scene.integrator().max_depth, 3);
    ASSERT_EQ(scene.integrator().aovs.size(), 3u);
    EXPECT_EQ(scene.integrator().aovs[0].name, "nn");
    EXPECT_EQ(scene.integrator().aovs[0].type, AovType::ShadingNormal);
    EXPECT_EQ(scene.integrator().aovs[1].name, "depth.y");
    EXPECT_EQ(scene.integrator().aovs[1].type, AovType::Depth);
    EXPECT_EQ(scene.integrator().aovs[2].type, AovType::Position);
    for (const char* bad : {"nn:normal", "nn", ":depth", ""})
        EXPECT_THROW(test::scene_from_xml(square_xml(bad)), InputError) << bad;
}

TEST(AovPass, FirstHitLayersOfASquareSeenHeadOn) {
    // Box filter (sensor_xml), 16 samples per pixel, seed 2. Inside the square every sample
    // hits it: depth is the ray's length from the near clip plane (Mitsuba's si.t) to z = 0,
    // sqrt(x^2 + y^2 + 16) - near / cos; position.z = 0; normals +z; uv the rectangle's
    // ((x + 1) / 2, 1 - (y + 1) / 2 in Mitsuba's convention, checked as a spread here);
    // shape index 0. Outside, every layer is 0.
    const Scene scene = test::scene_from_xml(square_xml(
        "d:depth, p:position, g:geo_normal, s:sh_normal, t:uv, i:shape_index, j:prim_index"));
    const std::vector<ExrLayer> layers = render_aovs(scene, scene.integrator().aovs, 16, 2);
    ASSERT_EQ(layers.size(), 7u);
    EXPECT_EQ(layers[0].name, "d");
    EXPECT_EQ(layers[0].channel_names, std::vector<std::string>{"T"});
    EXPECT_EQ(layers[4].channel_names, (std::vector<std::string>{"U", "V"}));
    const Image& depth = layers[0].image;
    const Image& position = layers[1].image;
    const Image& geo = layers[2].image;
    const Image& shading = layers[3].image;
    const Image& uv = layers[4].image;
    // The central 4x4 pixels see the square whole (it spans about +-0.68 of the half-width).
    for (int y = 6; y < 10; ++y)
        for (int x = 6; x < 10; ++x) {
            EXPECT_NEAR(depth(x, y), 4.f, 0.02f) << x << " " << y;
            EXPECT_NEAR(position(x, y, 2), 0.f, 1e-5f);
            EXPECT_NEAR(geo(x, y, 2), 1.f, 1e-6f);
            EXPECT_NEAR(shading(x, y, 2), 1.f, 1e-6f);
            EXPECT_EQ(layers[5].image(x, y), 0.f);  // shape 0
            EXPECT_GE(uv(x, y, 0), 0.f);
            EXPECT_LE(uv(x, y, 0), 1.f);
        }
    // uv grows across the image along x (u) and against y (v), as the rectangle's.
    EXPECT_GT(std::abs(uv(9, 8, 0) - uv(6, 8, 0)), 0.1f);
    EXPECT_GT(std::abs(uv(8, 9, 1) - uv(8, 6, 1)), 0.1f);
    // The corners escape: zero everywhere.
    for (const ExrLayer& layer : layers)
        for (int c = 0; c < layer.image.channels; ++c) EXPECT_EQ(layer.image(0, 0, c), 0.f);
    // The centre pixel (8, 8) covers [0, w] x [0, w] of the square, w = 8 tan(20 deg) / 16 =
    // 0.182: its mean depth is 4 + E[x^2 + y^2] / 8 - near = 4 + 2 w^2 / 24 - 0.01 = 3.9928
    // (second order in x, y). Measured from the camera's centre instead of the near plane it
    // would be 4.0028.
    EXPECT_NEAR(depth(8, 8), 3.9928f, 0.003f);
}

}  // namespace
}  // namespace gdmlt
