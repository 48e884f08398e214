// SPDX-License-Identifier: GPL-3.0-or-later
// The feature pass (core/render/feature_pass.h) on scenes whose features are known in closed
// form. Every scene is a sensor_xml camera on the z axis looking at the origin (square film,
// fov along x), so a film position (fx, fy) looks along d = (-a, -b, 1) in camera space with
// a = (2 fx / W - 1) tan(fov / 2), b likewise, and a plane perpendicular to the axis at
// distance D along it is reached after D |d| = D sqrt(1 + a^2 + b^2).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "core/render/feature_pass.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

constexpr int kResolution = 32;
constexpr float kFovDeg = 20.f;

// A dim constant environment: without any emitter the scene builder warns; escaped feature
// paths do not look at it.
const std::string kEnvironment =
    R"(<emitter type="constant"><rgb name="radiance" value="0.1"/></emitter>)";

double tan_half_fov() {
    return std::tan(static_cast<double>(kFovDeg) * 0.5 * 3.14159265358979323846 / 180.0);
}

/// The range of D sqrt(1 + a^2 + b^2) over pixel (x, y)'s footprint: every jittered sample
/// lies in it, so their mean does too. The function is convex in (a, b): its minimum is at the
/// footprint point nearest (0, 0), its maximum at the corner farthest from it.
struct DepthRange {
    double min = 0.0, max = 0.0;
};
DepthRange unfolded_depth_range(int x, int y, double axial_distance) {
    const double t = tan_half_fov();
    const auto extent = [&](int i) {
        const double lo = (2.0 * i / kResolution - 1.0) * t;
        const double hi = (2.0 * (i + 1) / kResolution - 1.0) * t;
        const double nearest = std::clamp(0.0, lo, hi);
        const double farthest = std::max(std::abs(lo), std::abs(hi));
        return std::pair{nearest, farthest};
    };
    const auto [a_min, a_max] = extent(x);
    const auto [b_min, b_max] = extent(y);
    return {axial_distance * std::sqrt(1.0 + a_min * a_min + b_min * b_min),
            axial_distance * std::sqrt(1.0 + a_max * a_max + b_max * b_max)};
}

/// Depth within the footprint's range, widened by 1e-4 relative for float round-off (the
/// intersection and the segment lengths are computed in float: about 1e-6 relative). Wrong
/// geometry fails by much more: measuring from the near-clip ray origin instead of the camera
/// would be 0.01 / 2 = 5e-3 relative short, one segment too many or too few a factor.
/// The variance of a mean of n >= 2 values in a range r is at most r^2 / (4 (n - 1)) <= r^2 / 4;
/// 1e-9 absolute covers float rounding of the samples (about (1e-7)^2), while the
/// cancellation of a float sum-of-squares formula (about 4 * 1e-7 for depths near 2) would not
/// pass.
void expect_depth(const FeatureImages& f, int x, int y, double axial_distance) {
    const DepthRange r = unfolded_depth_range(x, y, axial_distance);
    const double tolerance = 1e-4 * r.max;
    EXPECT_GE(f.depth(x, y), r.min - tolerance) << "pixel " << x << ", " << y;
    EXPECT_LE(f.depth(x, y), r.max + tolerance) << "pixel " << x << ", " << y;
    const double range = r.max - r.min;
    EXPECT_LE(f.depth_variance(x, y), range * range / 4.0 + 1e-9) << "pixel " << x << ", " << y;
}

/// Every sample of a pixel saw the same flat surface whose sampling weight is a constant: a
/// diffuse one's is the reflectance exactly ((R / pi) cos / (cos / pi)), a perfect mirror's 1.
/// So 1e-5 covers float round-off only, and the albedo and normal variances are those of
/// constants: Welford's update gives exactly 0
/// (1e-12 allows nothing a wrong formula would produce).
void expect_constant_surface(const FeatureImages& f, int x, int y, const Rgb& reflectance,
                             const Vec3f& normal) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(f.albedo(x, y, c), reflectance[c], 1e-5) << "pixel " << x << ", " << y;
        EXPECT_NEAR(f.normal(x, y, c), normal[c], 1e-5) << "pixel " << x << ", " << y;
    }
    EXPECT_LE(f.albedo_variance(x, y), 1e-12);
    EXPECT_LE(f.normal_variance(x, y), 1e-12);
}

int shape_index(const Scene& scene, const std::string& id) {
    for (std::size_t i = 0; i < scene.shapes().size(); ++i)
        if (scene.shapes()[i].id() == id) return static_cast<int>(i);
    ADD_FAILURE() << "no shape " << id;
    return -2;
}

FeatureSettings settings_with(int spp, std::uint64_t seed, int max_specular_bounces = 8) {
    FeatureSettings s;
    s.spp = spp;
    s.seed = seed;
    s.max_specular_bounces = max_specular_bounces;
    return s;
}

TEST(FeaturePass, DiffusePlaneFillingTheViewGivesItsReflectanceNormalAndDistance) {
    // Plane z = 0 (normal +z, half-size 1) seen from (0, 0, 2): at fov 20 the view's half-width
    // there is 2 tan 10 deg = 0.35, so the plane fills it. Seed 7, 4 spp (the default).
    const Scene scene =
        test::scene_from_xml(test::sensor_xml(kResolution, kFovDeg, "0, 0, 2") + kEnvironment + R"(
        <shape type="rectangle" id="plane">
            <bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.6, 0.9"/></bsdf></shape>)");
    const FeatureImages f = render_features(scene, settings_with(4, 7));
    ASSERT_EQ(f.spp, 4);
    EXPECT_FALSE(f.interrupted);
    ASSERT_EQ(f.albedo.width, kResolution);
    ASSERT_EQ(f.albedo.height, kResolution);
    // Only camera rays: no delta surface to follow.
    EXPECT_EQ(f.counters.camera_rays, 4u * kResolution * kResolution);
    EXPECT_EQ(f.counters.bounce_rays, 0u);
    const int plane = shape_index(scene, "plane");
    for (int y = 0; y < kResolution; ++y)
        for (int x = 0; x < kResolution; ++x) {
            expect_constant_surface(f, x, y, Rgb(0.3f, 0.6f, 0.9f), Vec3f::UnitZ());
            expect_depth(f, x, y, 2.0);
            EXPECT_EQ(f.shape_id(x, y), static_cast<float>(plane));
        }
}

TEST(FeaturePass, BackOfASheetGetsTheNormalFacingTheCamera) {
    // The same plane seen from behind, from (0, 0, -2): its shading normal +z points away from
    // the camera and must be turned to -z. Two-sided, so the albedo is the reflectance too.
    // Seed 8, 4 spp.
    const Scene scene =
        test::scene_from_xml(test::sensor_xml(kResolution, kFovDeg, "0, 0, -2") + kEnvironment + R"(
        <shape type="rectangle"><bsdf type="twosided"><bsdf type="diffuse">
            <rgb name="reflectance" value="0.3, 0.6, 0.9"/></bsdf></bsdf></shape>)");
    const FeatureImages f = render_features(scene, settings_with(4, 8));
    for (int y = 0; y < kResolution; ++y)
        for (int x = 0; x < kResolution; ++x) {
            expect_constant_surface(f, x, y, Rgb(0.3f, 0.6f, 0.9f), -Vec3f::UnitZ());
            expect_depth(f, x, y, 2.0);
        }
}

TEST(FeaturePass, EscapedPathsHaveZeroFeaturesAndNoShape) {
    // A plane of half-size 0.1 at the origin seen from (0, 0, 2) covers the central 0.1 / 0.35
    // of the view; the pixels of the image's border see nothing. Seed 9, 4 spp.
    const Scene scene =
        test::scene_from_xml(test::sensor_xml(kResolution, kFovDeg, "0, 0, 2") + kEnvironment + R"(
        <shape type="rectangle"><transform name="to_world"><scale value="0.1"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>)");
    const FeatureImages f = render_features(scene, settings_with(4, 9));
    for (const auto& [x, y] : {std::pair{0, 0}, std::pair{kResolution - 1, 0},
                               std::pair{0, kResolution - 1}, std::pair{5, 17}}) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_EQ(f.albedo(x, y, c), 0.f);
            EXPECT_EQ(f.normal(x, y, c), 0.f);
        }
        EXPECT_EQ(f.depth(x, y), 0.f);
        EXPECT_EQ(f.shape_id(x, y), -1.f);
    }
    // The centre sees the plane (guards against an image that is escaped everywhere).
    EXPECT_EQ(f.shape_id(kResolution / 2, kResolution / 2), 0.f);
    EXPECT_NEAR(f.albedo(kResolution / 2, kResolution / 2, 0), 0.5f, 1e-5);
}

TEST(FeaturePass, MirrorShowsTheFeaturesOfThePlaneItReflects) {
    // A perfect mirror at z = 0 (normal +z) seen from (0, 0, 2) reflects every camera ray back
    // to a diffuse wall at z = 4 facing -z (behind the camera, which is no geometry). Unfolded,
    // the wall is a plane at axial distance 2 + 4 = 6: depth 6 |d|, and the wall is large
    // enough (half-size 2 > 6 tan 10 deg = 1.06). Seed 10, 4 spp.
    const Scene scene =
        test::scene_from_xml(test::sensor_xml(kResolution, kFovDeg, "0, 0, 2") + kEnvironment + R"(
        <shape type="rectangle" id="mirror">
            <bsdf type="conductor"><string name="material" value="none"/></bsdf></shape>
        <shape type="rectangle" id="wall">
            <transform name="to_world"><scale value="2"/><rotate y="1" angle="180"/><translate z="4"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf></shape>)");
    const FeatureImages f = render_features(scene, settings_with(4, 10));
    const int wall = shape_index(scene, "wall");
    for (int y = 0; y < kResolution; ++y)
        for (int x = 0; x < kResolution; ++x) {
            // The ray arrives at the wall travelling +z, so the normal facing it is -z (the
            // wall's own normal).
            expect_constant_surface(f, x, y, Rgb(0.2f, 0.5f, 0.8f), -Vec3f::UnitZ());
            expect_depth(f, x, y, 6.0);
            EXPECT_EQ(f.shape_id(x, y), static_cast<float>(wall));
        }
    EXPECT_EQ(f.counters.bounce_rays, f.counters.camera_rays);

    // With no specular bounce allowed the mirror itself is the feature vertex: its sampling
    // weight (1 for a perfect mirror), its normal, distance 2 |d|.
    const FeatureImages first_hit = render_features(scene, settings_with(4, 10, 0));
    const int mirror = shape_index(scene, "mirror");
    for (int y = 0; y < kResolution; ++y)
        for (int x = 0; x < kResolution; ++x) {
            expect_constant_surface(first_hit, x, y, Rgb::Ones(), Vec3f::UnitZ());
            expect_depth(first_hit, x, y, 2.0);
            EXPECT_EQ(first_hit.shape_id(x, y), static_cast<float>(mirror));
        }
}

// A glass sphere (radius 0.5 at the origin) in front of an orange diffuse wall at z = -2,
// seen from (0, 0, 4). Reflections off the sphere go back towards +z, where there is nothing;
// refracted paths leave the sphere towards the wall (a sphere has no total internal
// reflection for rays entering it). So each feature sample sees the wall (albedo exactly
// kWallReflectance) or nothing (albedo 0), except after 8 internal reflections, which at
// the Fresnel reflectance of glass (4% head-on, up to 100% at grazing entry, but the same
// angle at every internal bounce) does not happen in these few thousand paths.
const Rgb kWallReflectance(0.8f, 0.3f, 0.1f);

std::string glass_scene_xml(int resolution = kResolution) {
    return test::sensor_xml(resolution, kFovDeg, "0, 0, 4") + kEnvironment + R"(
        <shape type="sphere"><float name="radius" value="0.5"/>
            <bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf></shape>
        <shape type="rectangle" id="wall">
            <transform name="to_world"><scale value="10"/><translate z="-2"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.3, 0.1"/></bsdf></shape>)";
}

/// Distance from the sphere's centre (the origin) to the ray through pixel (x, y)'s centre,
/// from the camera at (0, 0, 4): 4 sin(angle off the axis).
double ray_distance_to_origin(int x, int y) {
    const double t = tan_half_fov();
    const double a = (2.0 * (x + 0.5) / kResolution - 1.0) * t;
    const double b = (2.0 * (y + 0.5) / kResolution - 1.0) * t;
    const double tan2 = a * a + b * b;
    return 4.0 * std::sqrt(tan2 / (1.0 + tan2));
}

TEST(FeaturePass, GlassShowsTheWallBehindItAlongTheLikelierLobe) {
    // Seed 11, 16 spp. Inside the disc (centre rays at most 0.45 from the centre of the
    // sphere of radius 0.5: incidence at most 64 degrees), glass of index 1.5 reflects at most
    // about 10% at either interface, so the walk takes the refraction at both and every sample
    // reaches the wall: the wall's features, constant within the pixel as if it were seen
    // directly (albedo and normal variance exactly 0), and the wall's shape id. Sampling the
    // lobes by their Fresnel probability instead sends about 8% of the samples to the
    // environment (albedo 0, no shape): most pixels' 16 samples mix the two, and sample 0's
    // shape id is a coin toss between them.
    const Scene scene = test::scene_from_xml(glass_scene_xml());
    const FeatureImages f = render_features(scene, settings_with(16, 11));
    ASSERT_EQ(f.spp, 16);
    const int wall = shape_index(scene, "wall");
    // A pixel's footprint reaches at most half a diagonal, 4 * 2 tan(10 deg) / 32 / sqrt 2
    // = 0.031, from its centre ray near the sphere; 0.05 keeps whole footprints on one side
    // of the silhouette.
    const double margin = 0.05;
    int glass_pixels = 0;
    for (int y = 0; y < kResolution; ++y)
        for (int x = 0; x < kResolution; ++x) {
            const double d = ray_distance_to_origin(x, y);
            if (d > 0.5 + margin) {
                // The wall seen directly: plain diffuse features.
                expect_constant_surface(f, x, y, kWallReflectance, Vec3f::UnitZ());
                expect_depth(f, x, y, 6.0);
                EXPECT_EQ(f.shape_id(x, y), static_cast<float>(wall));
                continue;
            }
            if (d > 0.5 - margin) continue;
            ++glass_pixels;
            expect_constant_surface(f, x, y, kWallReflectance, Vec3f::UnitZ());
            EXPECT_EQ(f.shape_id(x, y), static_cast<float>(wall)) << "pixel " << x << ", " << y;
            // Through the glass the path to the wall is longer than the straight line to it.
            EXPECT_GT(f.depth(x, y), 6.0) << "pixel " << x << ", " << y;
        }
    ASSERT_GT(glass_pixels, 50);
}

TEST(FeaturePass, BitIdenticalAtOneAndTwoThreads) {
    // The glass scene follows random Fresnel choices, so any dependence of a sample's random
    // numbers on scheduling would show. Seed 12, 4 spp at 64x64: 16 tiles, so that two
    // threads really share them (at 16x16, one tile, a stream that depended on the thread went
    // unnoticed); a different seed must differ.
    const Scene scene = test::scene_from_xml(glass_scene_xml(64));
    const auto [one, two] =
        test::at_one_and_two_threads([&] { return render_features(scene, settings_with(4, 12)); });
    EXPECT_TRUE(one.albedo == two.albedo);
    EXPECT_TRUE(one.normal == two.normal);
    EXPECT_TRUE(one.depth == two.depth);
    EXPECT_TRUE(one.shape_id == two.shape_id);
    EXPECT_TRUE(one.albedo_variance == two.albedo_variance);
    EXPECT_TRUE(one.normal_variance == two.normal_variance);
    EXPECT_TRUE(one.depth_variance == two.depth_variance);
    // Another seed moves the samples within the pixels (the depth through the glass shows it).
    const FeatureImages other_seed = render_features(scene, settings_with(4, 13));
    EXPECT_FALSE(one.depth == other_seed.depth);
}

TEST(FeaturePass, CancelledBeforeStartReturnsEmptyFeatures) {
    // Cancelled before the first pixel: nothing is sampled, and the images say so (spp 0,
    // no shape, zero features) instead of holding garbage.
    const Scene scene = test::scene_from_xml(glass_scene_xml());
    const std::atomic<bool> cancel{true};
    const FeatureImages f = render_features(scene, settings_with(4, 14), &cancel);
    EXPECT_TRUE(f.interrupted);
    EXPECT_EQ(f.spp, 0);
    EXPECT_EQ(f.counters.camera_rays, 0u);
    ASSERT_EQ(f.shape_id.width, kResolution);
    for (float id : f.shape_id.pixels) EXPECT_EQ(id, -1.f);
    for (float a : f.albedo.pixels) EXPECT_EQ(a, 0.f);
}

}  // namespace
}  // namespace gdmlt
