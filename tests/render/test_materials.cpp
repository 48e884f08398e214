// SPDX-License-Identifier: GPL-3.0-or-later
// Furnace renders with the new materials and emitters: scenes whose exact answer is known,
// rendered by the path tracer. Tolerances are 5 standard errors of the image mean (from the
// per-pixel spread) plus the stated model or float error.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/image/image_io.h"
#include "core/render/render_path.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

RenderOutput render(const Scene& scene, int spp, std::uint64_t seed) {
    return test::render_unbounded(scene, spp, seed);
}

void expect_mean(const RenderOutput& out, const Rgb& expected, double relative_model_error) {
    test::expect_image_mean(out.image, expected, relative_model_error);
    EXPECT_EQ(out.stats.nonfinite_samples_dropped, 0u);
}

TEST(MaterialFurnace, WhitePlasticSphereInConstantLightReturnsTheEnvironmentRadiance) {
    // A smooth plastic with a white base is lossless (the coat reflects F, the base returns
    // 1 - F through the coat: eta^2 (1 - F_dr,int) = 1 - F_dr,ext), and a convex sphere sees
    // only the environment: every pixel is L. Seed 4, 64 spp at 16 x 16; model error 1e-3
    // (the numerically integrated diffuse Fresnel reflectances).
    const Scene scene = test::scene_from_xml(test::sensor_xml(16, 20.f, "0, 0, 4") + R"(
        <emitter type="constant"><rgb name="radiance" value="0.6, 0.8, 1.0"/></emitter>
        <shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="plastic"><rgb name="diffuse_reflectance" value="1"/></bsdf></shape>)");
    expect_mean(render(scene, 64, 4), Rgb(0.6f, 0.8f, 1.f), 1e-3);
}

TEST(MaterialFurnace, NearlySmoothRoughGlassSphereReturnsTheEnvironmentRadiance) {
    // GGX alpha = 0.001 glass behaves as smooth glass: lossless, and the 1/eta^2 on entering
    // cancels eta^2 on leaving. Model error 0.5%: single-scattering masking loses a little
    // energy at grazing facets. Seed 5, 32 spp.
    const Scene scene = test::scene_from_xml(test::sensor_xml(16, 20.f, "0, 0, 4") + R"(
        <emitter type="constant"><rgb name="radiance" value="0.7"/></emitter>
        <shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha" value="0.001"/>
                <float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>)");
    expect_mean(render(scene, 32, 5), Rgb::Constant(0.7f), 5e-3);
}

TEST(MaterialFurnace, DiffuseSphereInAUniformEnvironmentMapReflectsAlbedoTimesRadiance) {
    // As the constant-light furnace, through the envmap's importance sampling, MIS and file
    // reading: a uniform 16 x 8 EXR times scale 2 gives radiance 2 * (0.5, 1, 1.5) everywhere.
    const std::string path =
        (std::filesystem::temp_directory_path() / "gdmlt_test_uniform_env.exr").string();
    Image env(16, 8, 3);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 16; ++x)
            for (int c = 0; c < 3; ++c) env(x, y, c) = 0.5f * static_cast<float>(c + 1);
    write_exr(path, {ExrLayer{"", {"R", "G", "B"}, env}});
    const Scene scene = test::scene_from_xml(test::sensor_xml(16, 8.f, "0, 0, 5") + R"(
        <emitter type="envmap"><string name="filename" value=")" +
                                             path + R"("/><float name="scale" value="2"/>
            <transform name="to_world"><rotate x="1" angle="40"/></transform></emitter>
        <shape type="sphere"><float name="radius" value="1"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.5, 0.8"/></bsdf></shape>)");
    std::filesystem::remove(path);
    expect_mean(render(scene, 64, 6), Rgb(0.3f * 1.f, 0.5f * 2.f, 0.8f * 3.f), 1e-4);
}

TEST(MaterialFurnace, DirectionalLightOnADiffusePlaneGivesAlbedoTimesIrradianceOverPi) {
    // A plane facing a directional light (irradiance E, normal incidence), seen head-on: one
    // bounce, L = rho E / pi everywhere (no other surface, no environment). Seed 7, 16 spp.
    const Scene scene = test::scene_from_xml(test::sensor_xml(16, 20.f, "0, 0, 3") + R"(
        <emitter type="directional"><vector name="direction" value="0, 0, -1"/><rgb name="irradiance" value="2, 3, 4"/></emitter>
        <shape type="rectangle"><transform name="to_world"><scale value="5"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>)");
    expect_mean(render(scene, 16, 7), Rgb(2.f, 3.f, 4.f) * (0.5f * kInvPi), 1e-4);
}

}  // namespace
}  // namespace gdmlt
