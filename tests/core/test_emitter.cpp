// SPDX-License-Identifier: GPL-3.0-or-later
// Emitters: the environment map's importance sampler against its pdf (chi-square), its
// orientation against Mitsuba 3, light selection by power with the pdf exposed for MIS,
// textured area lights, spot and directional lights, and their parameters in scene files.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/emitter/emitter.h"
#include "core/image/image_io.h"
#include "core/sampling/rng.h"
#include "tests/support/chi2.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// A 32 x 16 lat-long image: a dim gradient plus a bright blob and a black band, so that the
/// sampler's density varies by three orders of magnitude and has zero regions.
std::vector<Rgb> test_envmap_texels(int w, int h) {
    std::vector<Rgb> texels;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float u = (x + 0.5f) / static_cast<float>(w),
                        v = static_cast<float>(y) / static_cast<float>(h - 1);
            Rgb c = Rgb(0.05f + 0.1f * u, 0.1f, 0.05f + 0.1f * v);
            if (x >= 20 && x <= 22 && y >= 4 && y <= 5) c += Rgb(40.f, 30.f, 20.f);
            if (x >= 5 && x <= 8) c = Rgb::Zero();
            texels.push_back(c);
        }
    return texels;
}

EnvmapEmitter test_envmap(const Mat3f& world_from_local) {
    EnvmapEmitter e;
    e.data =
        std::make_shared<const EnvmapData>(make_envmap_data(32, 16, test_envmap_texels(32, 16)));
    e.world_from_local = world_from_local;
    e.local_from_world = world_from_local.transpose();
    e.scale = 2.f;
    return e;
}

TEST(EnvmapEmitter, SamplesMatchPdf) {
    // Seed 1, 200000 samples (Chi2Settings defaults) at 32 x 32 sub-samples per bin: the
    // density has 1/sin(theta) poles, integrable but steep, which the default 12 x 12
    // integration would under-resolve. Two orientations: the map's poles on the chi-square
    // grid's pole, and on its equator (a rotated to_world). Sidak over the two.
    const Mat3f pole_up =
        Eigen::AngleAxisf(-0.5f * kPi, Vec3f::UnitX()).toRotationMatrix();  // local y -> world z
    const Mat3f tilted =
        Eigen::AngleAxisf(0.7f, Vec3f(1.f, 2.f, 3.f).normalized()).toRotationMatrix();
    test::Chi2Settings settings;
    settings.sub_samples = 32;
    for (const Mat3f& rotation : {pole_up, tilted}) {
        const EnvmapEmitter e = test_envmap(rotation);
        int mismatches = 0;
        const auto r = test::chi2_sphere_test(
            [&](Pcg32& rng) -> std::optional<Vec3f> {
                const EnvmapEmitter::Sample s = e.sample({rng.next_float(), rng.next_float()});
                if (!(s.pdf_solid_angle > 0.f)) return std::nullopt;
                // The density a sample reports is the one pdf() gives for its direction, except
                // within float round-off of a cell edge, where the direction -> (u, v) round
                // trip may land in the neighbouring cell (a few per million samples).
                if (std::abs(s.pdf_solid_angle - e.pdf_solid_angle(s.direction)) >
                    2e-3f * s.pdf_solid_angle)
                    ++mismatches;
                return s.direction;
            },
            [&](const Vec3f& d) { return static_cast<double>(e.pdf_solid_angle(d)); }, settings);
        EXPECT_GT(r.p_value, test::sidak_alpha(2)) << r.summary;
        EXPECT_LT(mismatches, 20);
    }
}

TEST(EnvmapEmitter, ImportanceSamplingEstimatesTheIntegralOfRadiance) {
    // E[L(d) / pdf(d)] over the sampler = integral of L over the sphere, compared with a
    // 1000 x 2000 midpoint quadrature in (theta, phi); 100000 samples (seed 3), 5 standard
    // errors. A sampler that leaves lit cells out would come out low.
    const EnvmapEmitter e = test_envmap(Mat3f::Identity());
    double quadrature = 0.0;
    constexpr int n = 1000;
    for (int i = 0; i < n; ++i) {
        const double theta = (i + 0.5) * std::numbers::pi / n;
        for (int j = 0; j < 2 * n; ++j) {
            const double phi = (j + 0.5) * std::numbers::pi / n;
            const Vec3f d(static_cast<float>(std::sin(theta) * std::cos(phi)),
                          static_cast<float>(std::cos(theta)),
                          static_cast<float>(std::sin(theta) * std::sin(phi)));
            quadrature += e.eval(d)[0] * std::sin(theta) * sqr(std::numbers::pi / n);
        }
    }
    Pcg32 rng(3, 1);
    double sum = 0.0, sum2 = 0.0;
    constexpr int kSamples = 100000;
    for (int i = 0; i < kSamples; ++i) {
        const EnvmapEmitter::Sample s = e.sample({rng.next_float(), rng.next_float()});
        const double v = s.pdf_solid_angle > 0.f ? s.radiance[0] / s.pdf_solid_angle : 0.0;
        sum += v;
        sum2 += v * v;
    }
    const double mean = sum / kSamples, se = std::sqrt((sum2 / kSamples - mean * mean) / kSamples);
    EXPECT_NEAR(mean, quadrature, 5.0 * se + 1e-3 * quadrature);
}

TEST(EnvmapEmitter, FollowsMitsubasLatLongOrientation) {
    // Mitsuba 3.9's envmap plugin on an 8 x 4 image with texel (x, y) = (x, y, 1) returns
    // these values for these directions (towards the environment, local frame, y up).
    std::vector<Rgb> texels;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 8; ++x)
            texels.emplace_back(static_cast<float>(x), static_cast<float>(y), 1.f);
    EnvmapEmitter e;
    e.data = std::make_shared<const EnvmapData>(make_envmap_data(8, 4, texels));
    const std::pair<Vec3f, Vec2f> expected[] = {
        {{0.f, 0.f, -1.f}, {3.5f, 1.5f}}, {{1.f, 0.f, 0.f}, {1.5f, 1.5f}},
        {{-1.f, 0.f, 0.f}, {5.5f, 1.5f}}, {{0.f, 1.f, 0.f}, {3.5f, 0.f}},
        {{0.f, -1.f, 0.f}, {3.5f, 3.f}},  {{0.01f, 0.f, -1.f}, {3.41088f, 1.5f}}};
    for (const auto& [d, rg] : expected) {
        const Rgb v = e.eval(d.normalized());
        EXPECT_NEAR(v[0], rg.x(), 1e-3f) << d.transpose();
        EXPECT_NEAR(v[1], rg.y(), 1e-3f) << d.transpose();
    }
}

/// Writes the test envmap to a temporary EXR named after `test` (ctest runs tests in parallel
/// processes: a shared name let one test delete another's file).
std::string write_test_envmap(const std::string& test) {
    const std::string path =
        (std::filesystem::temp_directory_path() / ("gdmlt_test_envmap_" + test + ".exr")).string();
    Image image(32, 16, 3);
    const std::vector<Rgb> texels = test_envmap_texels(32, 16);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 32; ++x)
            for (int c = 0; c < 3; ++c)
                image(x, y, c) = texels[static_cast<std::size_t>(y * 32 + x)][c];
    write_exr(path, {ExrLayer{"", {"R", "G", "B"}, image}});
    return path;
}

TEST(SceneEmitters, EnvironmentSamplesCarryTheWholeEnvironmentAndItsDensity) {
    // With a constant and an envmap together, a direction sampled through either must carry
    // the sum of both radiances and the combined density, exactly what a BSDF-sampled ray
    // that escapes sees (environment(), pdf_environment_solid_angle()); MIS then agrees. With
    // the envmap alone, the sample's radiance and density come from its own (u, v), not from
    // the direction mapped back (Scene::environment_of_sample): the same values, except that
    // the float round trip of a sample within 2e-7 rad of a sampling cell's edge (the test
    // map's cells are 1/32 by 1/16 of (u, v)) may find the neighbour's density; seed 7, 2000
    // samples: at most 2 such (expected 1e-5 of them).
    const std::string path = write_test_envmap("environment_samples");
    const std::string envmap = R"(
        <emitter type="envmap"><string name="filename" value=")" +
                               path + R"("/><float name="scale" value="2"/>
            <transform name="to_world"><rotate y="1" angle="30"/></transform></emitter>)";
    const std::string sphere = R"(<shape type="sphere"><float name="radius" value="0.1"/></shape>)";
    const Scene both = test::scene_from_xml(
        envmap + R"(<emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>)" +
        sphere);
    // The envmap as the only infinite emitter, chosen with probability 1/2 beside a light.
    const Scene alone = test::scene_from_xml(
        envmap + R"(<shape type="sphere"><point name="center" x="0" y="0" z="-3"/>
            <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>)" +
        sphere);
    std::filesystem::remove(path);
    for (const Scene* scene : {&both, &alone}) {
        EXPECT_TRUE(scene->has_environment());
        Pcg32 rng(7, 7);
        int checked = 0, other_cell = 0;
        for (int i = 0; i < 2000; ++i) {
            const EmitterSample s = scene->sample_emitter(Vec3f(0.f, 0.f, 5.f), rng.next_float(),
                                                          {rng.next_float(), rng.next_float()});
            if (!s.valid() || !std::isinf(s.distance)) continue;  // the light
            ++checked;
            const float pdf = scene->pdf_environment_solid_angle(s.wi);
            if (scene == &alone && !(std::abs(pdf - s.pdf_solid_angle) <= 1e-4f * pdf))
                ++other_cell;
            else
                EXPECT_NEAR(s.pdf_solid_angle, pdf, 1e-4f * s.pdf_solid_angle);
            // Alone, the radiance is read at the sample's (u, v), which the round trip misses by
            // up to 1e-6 of a texel (2e-7 rad over cells of 2 pi / 32 and pi / 15 rad): the
            // bilinear radiance then moves by that times the steepest step between texels (40,
            // at the sun's rim) times the scale (2), 8e-5; twice that is allowed.
            const Rgb env = scene->environment(s.wi);
            const float round_trip = scene == &alone ? 2.f * 1e-6f * 40.f * 2.f : 0.f;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(s.radiance[c], env[c], 1e-5f * env[c] + round_trip);
        }
        EXPECT_GT(checked, scene == &alone ? 900 : 1900);
        EXPECT_LE(other_cell, 2);
    }
    // Only infinite emitters: their selection probabilities sum to one.
    EXPECT_NEAR(both.emitter_selection_pmf(0) + both.emitter_selection_pmf(1), 1.f, 1e-6f);
}

TEST(SceneEmitters, ChoosesBoundedLightsByPowerAndGivesTheInfiniteOnesOneShare) {
    // Two area lights: 1 m^2 at radiance 1 and 4 m^2 at radiance 2 -> power ratio 1 : 8.
    const std::string lights = R"(
        <shape type="rectangle"><transform name="to_world"><scale value="0.5"/></transform>
            <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
        <shape type="rectangle"><transform name="to_world"><translate z="2"/></transform>
            <emitter type="area"><rgb name="radiance" value="2"/></emitter></shape>)";
    const Scene two = test::scene_from_xml(lights);
    EXPECT_NEAR(two.emitter_selection_pmf(0), 1.f / 9.f, 1e-6f);
    EXPECT_NEAR(two.emitter_selection_pmf(1), 8.f / 9.f, 1e-6f);
    // Adding an environment: it gets 1/2 (one infinite light: n / (n + 1)), the bounded ones
    // share the other half by power.
    const Scene with_sky = test::scene_from_xml(
        lights + R"(<emitter type="constant"><rgb name="radiance" value="0.01"/></emitter>)");
    EXPECT_NEAR(with_sky.emitter_selection_pmf(2), 0.5f, 1e-6f);
    EXPECT_NEAR(with_sky.emitter_selection_pmf(1), 0.5f * 8.f / 9.f, 1e-6f);
}

TEST(SceneEmitters, TexturedAreaLightSamplesCarryTheRadianceAtTheirPoint) {
    // Light sampling must look the texture up at the sampled point: compare with the radiance
    // a ray that hits the same point sees (Scene::emitted).
    for (const char* shape : {"rectangle", "sphere"}) {
        const Scene scene = test::scene_from_xml(std::string(R"(<shape type=")") + shape + R"(">
            <transform name="to_world"><translate z="-3"/></transform>
            <emitter type="area"><texture type="checkerboard" name="radiance">
                <rgb name="color0" value="5, 4, 3"/><rgb name="color1" value="0.5, 1, 2"/>
                <transform name="to_uv"><scale value="3"/></transform></texture></emitter></shape>)");
        Pcg32 rng(9, 1);
        int checked = 0;
        for (int i = 0; i < 500; ++i) {
            const Vec3f ref(0.f, 0.f, 0.f);
            const EmitterSample s =
                scene.sample_emitter(ref, rng.next_float(), {rng.next_float(), rng.next_float()});
            if (!s.valid()) continue;
            const SurfaceInteraction si = scene.intersect(Ray{ref, s.wi});
            if (!si.valid() || (si.p - s.p).norm() > 1e-3f) continue;  // the far side of the sphere
            // Points on a checker edge may round to either side: skip those within 1e-3 of one.
            const Vec2f uv3 = 3.f * si.uv;
            const Vec2f frac = uv3 - uv3.array().floor().matrix();
            if ((((frac.array() * 2.f) - (frac.array() * 2.f).round()).abs() < 2e-3f).any())
                continue;
            ++checked;
            const Rgb seen = scene.emitted(si, -s.wi);
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(s.radiance[c], seen[c], 1e-5f) << shape;
        }
        EXPECT_GT(checked, 100) << shape;
    }
}

TEST(SceneEmitters, SpotAndDirectionalLightsFollowMitsubasDefinitions) {
    const Scene scene = test::scene_from_xml(R"(
        <emitter type="spot"><rgb name="intensity" value="8"/><float name="cutoff_angle" value="30"/>
            <float name="beam_width" value="10"/>
            <transform name="to_world"><lookat origin="0, 0, 2" target="0, 0, 0" up="0, 1, 0"/></transform></emitter>
        <emitter type="directional"><vector name="direction" value="0, -1, 0"/><rgb name="irradiance" value="3"/></emitter>
        <shape type="rectangle"/>)");
    EXPECT_TRUE(scene.features().has_delta_emitters);
    const auto& spot = std::get<SpotEmitter>(scene.emitters()[0]);
    // Full intensity inside the beam, linear in angle to zero at the cutoff.
    EXPECT_FLOAT_EQ(spot.intensity_towards(Vec3f(0.f, 0.f, -1.f))[0], 8.f);
    const auto towards = [](float deg) {
        return Vec3f(std::sin(degrees_to_radians(deg)), 0.f, -std::cos(degrees_to_radians(deg)));
    };
    EXPECT_NEAR(spot.intensity_towards(towards(20.f))[0], 8.f * 0.5f, 1e-4f);
    EXPECT_NEAR(spot.intensity_towards(towards(31.f))[0], 0.f, 1e-6f);
    // Directional: irradiance from the opposite of its travel direction, at infinity.
    Pcg32 rng(1, 2);
    bool saw_spot = false, saw_directional = false;
    for (int i = 0; i < 200; ++i) {
        const EmitterSample s =
            scene.sample_emitter(Vec3f(0.f, 0.f, 0.f), rng.next_float(), {0.5f, 0.5f});
        ASSERT_TRUE(s.valid());
        EXPECT_TRUE(s.delta);
        if (std::isinf(s.distance)) {
            saw_directional = true;
            EXPECT_NEAR((s.wi - Vec3f::UnitY()).norm(), 0.f, 1e-6f);
            EXPECT_FLOAT_EQ(s.radiance[0], 3.f);
        } else {
            saw_spot = true;
            EXPECT_NEAR(s.radiance[0], 8.f / 4.f, 1e-5f);  // I / d^2 on the axis at distance 2
        }
        EXPECT_NEAR(s.pdf_solid_angle, scene.emitter_selection_pmf(s.emitter), 1e-6f);
    }
    EXPECT_TRUE(saw_spot && saw_directional);
}

TEST(SceneEmitters, SpotTextureIsProjectedOverTheCutoffCone) {
    // Mitsuba 3's spot texture: a local direction (x, y, z) reads the texture at
    // (1/2 + x / (2 z tan(cutoff)), 1/2 + y / (2 z tan(cutoff))). The lookat frame puts local x
    // along cross(up, axis) = world -x and local y along world y. A checkerboard (color0 where
    // u and v fall in the same half) tells the quadrants apart; beam = cutoff: no falloff.
    const Scene scene = test::scene_from_xml(R"(
        <emitter type="spot"><rgb name="intensity" value="8"/><float name="cutoff_angle" value="30"/>
            <float name="beam_width" value="30"/>
            <texture name="texture" type="checkerboard"><rgb name="color0" value="1"/><rgb name="color1" value="0.25"/></texture>
            <transform name="to_world"><lookat origin="0, 0, 2" target="0, 0, 0" up="0, 1, 0"/></transform></emitter>
        <shape type="rectangle"/>)");
    const auto& spot = std::get<SpotEmitter>(scene.emitters()[0]);
    const float t = std::tan(degrees_to_radians(30.f));
    const auto world = [&](float x, float y) { return Vec3f(-x * t, y * t, -1.f).normalized(); };
    EXPECT_NEAR(spot.intensity_towards(world(-0.5f, -0.5f))[0], 8.f, 1e-4f);  // uv (1/4, 1/4)
    EXPECT_NEAR(spot.intensity_towards(world(0.5f, 0.5f))[0], 8.f, 1e-4f);    // uv (3/4, 3/4)
    EXPECT_NEAR(spot.intensity_towards(world(0.5f, -0.5f))[0], 2.f, 1e-4f);   // uv (3/4, 1/4)
    EXPECT_NEAR(spot.intensity_towards(world(-0.5f, 0.5f))[0], 2.f, 1e-4f);   // uv (1/4, 3/4)
    EXPECT_EQ(spot.intensity_towards(world(1.2f, 0.f))[0], 0.f);              // beyond the cutoff
}

TEST(SceneEmitters, ProjectorIrradianceOnThePlaneAtUnitDistanceIsUniform) {
    // Mitsuba 3's projector: its intensity pi scale E(uv) / cos^3 makes the irradiance on the
    // plane one unit along its axis pi scale E wherever the image falls (here a constant
    // texture, 0.5, scale 2: pi), and zero beyond the image (fov 60 along x, a 1 x 1 texture:
    // the image is |x|, |y| < tan 30 on that plane). Every next-event sample is the projector's
    // (one emitter), a delta in position at the pinhole.
    const Scene scene = test::scene_from_xml(R"(
        <emitter type="projector"><rgb name="irradiance" value="0.5"/><float name="scale" value="2"/>
            <float name="fov" value="60"/>
            <transform name="to_world"><lookat origin="1, 2, 3" target="1, 2, 4" up="0, 1, 0"/></transform></emitter>
        <shape type="rectangle"/>)");
    const float half = std::tan(degrees_to_radians(30.f));
    for (const float x : {-0.9f, -0.5f, 0.f, 0.3f, 0.95f})
        for (const float y : {-0.9f, 0.f, 0.6f}) {
            const Vec3f p(1.f + x * half, 2.f + y * half, 4.f);
            const EmitterSample s = scene.sample_emitter(p, 0.5f, {0.5f, 0.5f});
            ASSERT_TRUE(s.valid()) << x << " " << y;
            EXPECT_TRUE(s.delta);
            EXPECT_NEAR((s.p - Vec3f(1.f, 2.f, 3.f)).norm(), 0.f, 1e-6f);
            EXPECT_NEAR(s.radiance[0] * std::abs(s.wi.z()), kPi, 1e-4f * kPi) << x << " " << y;
        }
    // Outside the image and behind the projector: black, but still a sample of the light's
    // position (which gradient-domain shifts reuse for offsets the light does reach).
    for (const Vec3f& p : {Vec3f(1.f + 1.1f * half, 2.f, 4.f), Vec3f(1.f, 2.f, 2.f)}) {
        const EmitterSample s = scene.sample_emitter(p, 0.5f, {});
        EXPECT_TRUE(s.valid());
        EXPECT_TRUE(is_black(s.radiance)) << s.radiance.transpose();
        EXPECT_NEAR((s.p - Vec3f(1.f, 2.f, 3.f)).norm(), 0.f, 1e-6f);
    }

    // The texture as Mitsuba's perspective projection maps it: uv (0, 0) at the image's top
    // left, seen along the axis with up +y and left = cross(up, axis) = world +x here. A
    // checkerboard's color0 (same halves) lies top-left and bottom-right.
    const Scene checks = test::scene_from_xml(R"(
        <emitter type="projector"><float name="fov" value="60"/>
            <texture name="irradiance" type="checkerboard"><rgb name="color0" value="1"/><rgb name="color1" value="0.25"/></texture>
            <transform name="to_world"><lookat origin="1, 2, 3" target="1, 2, 4" up="0, 1, 0"/></transform></emitter>
        <shape type="rectangle"/>)");
    const auto irradiance_at = [&](float left, float up) {
        const EmitterSample s = checks.sample_emitter(
            Vec3f(1.f + left * half, 2.f + up * half, 4.f), 0.5f, {0.5f, 0.5f});
        return s.radiance[0] * std::abs(s.wi.z()) / kPi;
    };
    EXPECT_NEAR(irradiance_at(0.5f, 0.5f), 1.f, 1e-4f);
    EXPECT_NEAR(irradiance_at(-0.5f, -0.5f), 1.f, 1e-4f);
    EXPECT_NEAR(irradiance_at(-0.5f, 0.5f), 0.25f, 1e-4f);
    EXPECT_NEAR(irradiance_at(0.5f, -0.5f), 0.25f, 1e-4f);
}

TEST(SceneEmitters, RejectsInvalidEmitterParameters) {
    EXPECT_THROW(
        test::scene_from_xml(R"(<emitter type="spot"><float name="cutoff_angle" value="10"/>
        <float name="beam_width" value="20"/></emitter>)"),
        InputError);
    EXPECT_THROW(test::scene_from_xml(R"(<emitter type="envmap"/>)"), InputError);
    EXPECT_THROW(
        test::scene_from_xml(
            R"(<emitter type="envmap"><string name="filename" value="missing.exr"/></emitter>)"),
        InputError);
    EXPECT_THROW(
        test::scene_from_xml(
            R"(<emitter type="directional"><vector name="direction" value="0, 0, 0"/></emitter>)"),
        InputError);
    EXPECT_THROW(test::scene_from_xml(
                     R"(<emitter type="spot"><float name="cuttoff_angle" value="10"/></emitter>)"),
                 InputError);
}

}  // namespace
}  // namespace gdmlt

namespace gdmlt {
namespace {

// --- Emitted rays: the first vertex of light subpaths (BDPT, light tracing) ---

/// One emitter of each kind that sample_emitted_ray handles, each alone in a scene with a
/// unit sphere so that the bounds (and the disk lights at infinity start from) are known.
struct EmitterCase {
    const char* name;
    std::string xml;
    /// Emitted power (channel 0), computed here from the definition, not from the sampler.
    double power;
};

std::vector<EmitterCase> emitter_cases(const std::string& envmap_path) {
    // Spot, intensity 8, cutoff 30, beam 10: I(theta) = 8 inside 10 degrees, falling linearly
    // in angle to 0 at 30; its power 2 pi integral of I sin(theta) dtheta by the midpoint rule.
    double spot_power = 0.0;
    const int steps = 200000;
    const double cutoff = degrees_to_radians(30.0), beam = degrees_to_radians(10.0);
    for (int i = 0; i < steps; ++i) {
        const double theta = (i + 0.5) * cutoff / steps;
        const double intensity = theta <= beam ? 8.0 : 8.0 * (cutoff - theta) / (cutoff - beam);
        spot_power += 2.0 * kPi * intensity * std::sin(theta) * cutoff / steps;
    }
    const std::string sphere = R"(<shape type="sphere"><float name="radius" value="1"/></shape>)";
    // The unit sphere and the 2 x 2 rectangle at z = 1.5 are bounded by a box whose half
    // diagonal is the disk radius r: sqrt(1 + 1 + (1.5 + 1)^2 / 4) ... computed by the scene.
    return {
        {"area rectangle",
         sphere + R"(<shape type="rectangle"><transform name="to_world"><scale value="0.5, 2, 1"/>
            <rotate x="1" angle="30"/><translate z="1.5"/></transform>
            <emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter></shape>)",
         kPi * 3.0 * (1.0 * 4.0)},  // pi L A, A = 1 x 4
        {"area sphere",
         R"(<shape type="sphere"><float name="radius" value="0.5"/>
            <emitter type="area"><rgb name="radiance" value="2"/></emitter></shape>)",
         kPi * 2.0 * (4.0 * kPi * 0.25)},
        {"point", sphere + R"(<emitter type="point"><point name="position" value="0, 0, 2"/>
            <rgb name="intensity" value="3"/></emitter>)",
         4.0 * kPi * 3.0},
        {"spot", sphere + R"(<emitter type="spot"><rgb name="intensity" value="8"/>
            <float name="cutoff_angle" value="30"/><float name="beam_width" value="10"/>
            <transform name="to_world"><lookat origin="0.3, 0.2, 2" target="0, 0, 0"
            up="0, 1, 0"/></transform></emitter>)",
         spot_power},
        // Lights at infinity: the power through the disk, E pi r^2 and pi r^2 integral of L
        // over the sphere (constant: 4 pi L); r is filled in by the test.
        {"directional", sphere + R"(<emitter type="directional"><vector name="direction"
            value="1, -2, 0.5"/><rgb name="irradiance" value="3"/></emitter>)",
         3.0},
        {"constant", sphere + R"(<emitter type="constant"><rgb name="radiance" value="0.7"/>
            </emitter>)",
         4.0 * kPi * 0.7},
        {"envmap",
         sphere + R"(<emitter type="envmap"><string name="filename" value=")" + envmap_path +
             R"("/><transform name="to_world"><rotate y="1" angle="30"/>
            </transform></emitter>)",
         0.0},  // filled in by the test from environment() (an independent quadrature)
    };
}

TEST(EmittedRays, WeightsAverageToTheEmittedPower) {
    // E[weight] = integral of Le |cos| over positions and directions = the emitted power, for
    // any correct pair of sampler and pdfs: the power is computed here from each light's
    // definition (for the environment by quadrature of environment() over the sphere). Seed
    // 11, 400k samples per emitter: the standard error must be below 1% of the power (so a
    // wrong factor of pi or of the pmf fails) and the mean within 5 of them (seven tests, a
    // false alarm has probability 4e-6). A last scene with all bounded lights together checks
    // the emitter choice: the powers add.
    const std::string envmap_path = write_test_envmap("emitted_power");
    std::vector<EmitterCase> cases = emitter_cases(envmap_path);
    std::string all_bounded;
    double all_power = 0.0;
    for (const EmitterCase& c : cases)
        if (std::string(c.name).find("area") == 0 || std::string(c.name) == "point" ||
            std::string(c.name) == "spot") {
            all_bounded += c.xml;
            all_power += c.power;
        }
    // The unit sphere appears several times: that adds no power.
    cases.push_back({"all bounded", all_bounded, all_power});
    for (EmitterCase& c : cases) {
        const Scene scene = test::scene_from_xml(c.xml);
        const double r = scene.bounds_radius();
        if (std::string(c.name) == "directional") c.power *= kPi * r * r;
        if (std::string(c.name) == "constant") c.power *= kPi * r * r;
        if (std::string(c.name) == "envmap") {
            // Midpoint quadrature in (z, phi), 1000 x 2000: the map is bilinear between texels
            // and the grid resolves each texel by tens of points.
            double integral = 0.0;
            const int nz = 1000, nphi = 2000;
            for (int i = 0; i < nz; ++i)
                for (int j = 0; j < nphi; ++j) {
                    const double z = -1.0 + 2.0 * (i + 0.5) / nz;
                    const double phi = 2.0 * kPi * (j + 0.5) / nphi;
                    const double s = std::sqrt(1.0 - z * z);
                    const Vec3f d(static_cast<float>(s * std::cos(phi)),
                                  static_cast<float>(s * std::sin(phi)), static_cast<float>(z));
                    integral += scene.environment(d)[0] * (2.0 / nz) * (2.0 * kPi / nphi);
                }
            c.power = kPi * r * r * integral;
        }
        Pcg32 rng(11, 1);
        const int n = 400000;
        double sum = 0.0, sum2 = 0.0;
        int valid = 0, other_cell = 0;
        for (int i = 0; i < n; ++i) {
            const EmittedRay ray =
                scene.sample_emitted_ray(rng.next_float(), {rng.next_float(), rng.next_float()},
                                         {rng.next_float(), rng.next_float()});
            if (!ray.valid()) continue;
            ++valid;
            const double w = ray.weight[0];
            sum += w;
            sum2 += w * w;
            // The densities it reports are the ones pdf_emitted_ray gives for its ray.
            const EmissionPdf pdf =
                scene.pdf_emitted_ray(ray.emitter, ray.n_geometric, ray.direction);
            ASSERT_NEAR(pdf.position, ray.pdf_position, 1e-5f * ray.pdf_position) << c.name;
            // The environment map reports the density of the (u, v) it sampled, which
            // pdf_emitted_ray finds again through the direction: the float round trip (within
            // 2e-7 rad, core/math/trig.h) lands in the neighbouring sampling cell when the
            // sample lies that close to one of the cells' edges, counted below.
            if (std::string(c.name) == "envmap" &&
                !(std::abs(pdf.direction - ray.pdf_direction) <= 1e-4f * ray.pdf_direction)) {
                ++other_cell;
                ASSERT_GT(pdf.direction, 0.f) << c.name;
            } else {
                ASSERT_NEAR(pdf.direction, ray.pdf_direction, 1e-4f * ray.pdf_direction) << c.name;
            }
            // Lights at infinity start outside the scene's bounding sphere.
            if (ray.at_infinity) {
                ASSERT_GT((ray.origin - scene.bounds_center()).norm(), 0.999f * r) << c.name;
            }
        }
        // Edges lie every 1/32 in u and 1/16 in v, so a strip of +-2e-7 rad around them holds
        // about 1e-5 of the sphere's directions, and of the samples where the map is flat
        // near edges: at most 2e-5 of them (8 of 400k, with seed 11: 1).
        EXPECT_LE(other_cell, n / 50000) << c.name;
        EXPECT_GT(valid, n * 9 / 10) << c.name;
        const double mean = sum / n;
        const double se = std::sqrt(std::max(sum2 / n - mean * mean, 0.0) / (n - 1));
        EXPECT_LT(se, 0.01 * c.power) << c.name;
        // Lights sampled exactly by their emission (area, point, directional, constant) give
        // every ray the same weight (se 0): then float rounding, 1e-5, is the tolerance.
        EXPECT_NEAR(mean, c.power, 5.0 * se + 1e-5 * c.power) << c.name << ": se " << se;
    }
    std::filesystem::remove(envmap_path);
}

TEST(EmittedRays, DirectionsFollowTheirPdf) {
    // Chi-square of sampled directions against pdf_emitted_ray's direction density: cosine
    // about a rectangle light's normal, uniform (point), uniform in a spot's cone, the
    // environment's importance sampling (the ray travels opposite to the sampled direction).
    // Seed 1, 200k samples, 64 x 64 sub-samples per bin (the envmap's density is steep near
    // its poles); Sidak over the four.
    const std::string envmap_path = write_test_envmap("emitted_directions");
    const std::vector<EmitterCase> cases = emitter_cases(envmap_path);
    test::Chi2Settings settings;
    settings.sub_samples = 64;
    for (const EmitterCase& c : cases) {
        const std::string name = c.name;
        if (name != "area rectangle" && name != "point" && name != "spot" && name != "envmap")
            continue;
        const Scene scene = test::scene_from_xml(c.xml);
        Vec3f normal = Vec3f::Zero();
        int emitter = -1;
        const auto r = test::chi2_sphere_test(
            [&](Pcg32& rng) -> std::optional<Vec3f> {
                const EmittedRay ray =
                    scene.sample_emitted_ray(rng.next_float(), {rng.next_float(), rng.next_float()},
                                             {rng.next_float(), rng.next_float()});
                if (!ray.valid()) return std::nullopt;
                normal = ray.n_geometric;  // one normal: the rectangle is flat
                emitter = ray.emitter;
                return ray.direction;
            },
            [&](const Vec3f& w) { return scene.pdf_emitted_ray(emitter, normal, w).direction; },
            settings);
        EXPECT_GT(r.p_value, test::sidak_alpha(4)) << name << ": " << r.summary;
        EXPECT_NEAR(r.pdf_integral, 1.0, 0.01) << name << ": " << r.summary;
    }
    std::filesystem::remove(envmap_path);
}

}  // namespace
}  // namespace gdmlt
