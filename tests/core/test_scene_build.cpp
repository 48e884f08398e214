// SPDX-License-Identifier: GPL-3.0-or-later
// SceneDesc -> Scene: every malformed input gives a clear error with file and line; shapes get
// Mitsuba's geometry; features say what occurs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "core/scene/scene.h"
#include "core/scene/spectrum_rgb.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// Builds and returns the error message ("" when it built).
std::string build_error(const std::string& body, bool lenient = false) {
    try {
        BuildOptions options;
        options.lenient = lenient;
        test::scene_from_xml(body, options);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

const std::string kLight = R"(<shape type="rectangle"><emitter type="area"/></shape>)";

TEST(SceneBuild, UnknownPluginIsAnErrorWithFileAndLine) {
    const std::string message = build_error("\n<shape type=\"teapot\"/>");
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
    EXPECT_NE(message.find("teapot"), std::string::npos) << message;
}

TEST(SceneBuild, UnknownPluginIsOnlyAWarningWhenLenient) {
    EXPECT_EQ(build_error(kLight + "<shape type=\"teapot\"/>", true), "");
}

TEST(SceneBuild, PluginsOutOfScopeSaySoWithFileAndLine) {
    // Each family the README puts out of scope, nested where Mitsuba 3 puts it: the error names
    // the element, says "not supported" and why, and points at its line; "unknown" is kept for
    // names that are not plugins at all.
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"<integrator type=\"volpath\"/>", "participating media"},
        {"<medium type=\"homogeneous\" id=\"fog\"/>", "participating media"},
        {"<shape type=\"sphere\"><bsdf type=\"principled\"/></shape>", "principled"},
        {"<bsdf type=\"pplastic\" id=\"p\"/>", "polarisation"},
        {"<integrator type=\"stokes\"><integrator type=\"path\"/></integrator>", "polarisation"},
        {"<shape type=\"bsplinecurve\"/>", "curves"},
        {"<shape type=\"sdfgrid\"/>", "SDF grids"},
        {"<bsdf type=\"hair\" id=\"h\"/>", "hair"},
    };
    for (const auto& [element, reason] : cases) {
        const std::string message = build_error("\n\n" + element + kLight);
        EXPECT_NE(message.find("test.xml:4"), std::string::npos) << message;
        EXPECT_NE(message.find("is not supported"), std::string::npos) << message;
        EXPECT_NE(message.find(reason), std::string::npos) << message;
        EXPECT_EQ(message.find("unknown"), std::string::npos) << message;
        // --lenient: a warning, and the rest of the scene loads.
        EXPECT_EQ(build_error(element + kLight, true), "") << element;
    }
    // A <volume> is not even an object tag here: the parser says the same.
    const std::string volume = build_error("\n\n<volume type=\"gridvolume\" name=\"albedo\"/>");
    EXPECT_NE(volume.find("test.xml:4"), std::string::npos) << volume;
    EXPECT_NE(volume.find("participating media"), std::string::npos) << volume;
    EXPECT_NE(build_error("<bsdf type=\"velvet\" id=\"v\"/>").find("unknown BSDF"),
              std::string::npos);
}

TEST(SceneBuild, UnknownPropertyIsAnErrorNamingIt) {
    const std::string message = build_error(
        "<bsdf type=\"diffuse\" id=\"a\">\n<float name=\"roughnes\" value=\"0.1\"/></bsdf>" +
        kLight);
    EXPECT_NE(message.find("roughnes"), std::string::npos) << message;
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
}

TEST(SceneBuild, WrongPropertyTypeIsAnError) {
    const std::string message = build_error(
        R"(<integrator type="path"><string name="max_depth" value="deep"/></integrator>)" + kLight);
    EXPECT_NE(message.find("max_depth"), std::string::npos) << message;
    EXPECT_NE(message.find("integer"), std::string::npos) << message;
}

TEST(SceneBuild, MissingMeshFileIsAnErrorNamingTheFile) {
    const std::string message = build_error(
        R"(<shape type="obj"><string name="filename" value="nowhere/missing.obj"/></shape>)");
    EXPECT_NE(message.find("missing.obj"), std::string::npos) << message;
    EXPECT_NE(message.find("test.xml:2"), std::string::npos) << message;
}

TEST(SceneBuild, NanVertexIsAnError) {
    const auto dir = std::filesystem::temp_directory_path() / "gdmlt_test_scene_build";
    std::filesystem::create_directories(dir);
    const auto path = dir / "nan.obj";
    std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n";
    const std::string message = build_error(
        "<shape type=\"obj\"><string name=\"filename\" value=\"" + path.string() + "\"/></shape>");
    EXPECT_NE(message.find("nan.obj"), std::string::npos) << message;
    std::filesystem::remove_all(dir);
}

TEST(SceneBuild, ZeroAreaLightIsAnError) {
    const std::string message = build_error(
        R"(<shape type="disk"><transform name="to_world"><scale value="1e-25"/></transform>
           <emitter type="area"/></shape>)");
    EXPECT_NE(message.find("zero area"), std::string::npos) << message;
}

TEST(SceneBuild, NegativeReflectanceIsAnError) {
    const std::string message = build_error(
        R"(<bsdf type="diffuse" id="b"><rgb name="reflectance" value="0.5, -0.1, 0.5"/></bsdf>)" +
        kLight);
    EXPECT_NE(message.find("negative"), std::string::npos) << message;
}

TEST(SceneBuild, NonUniformScaleOfASphereIsAnError) {
    const std::string message = build_error(
        R"(<shape type="sphere"><transform name="to_world"><scale value="1, 2, 1"/></transform></shape>)" +
        kLight);
    EXPECT_NE(message.find("similarity"), std::string::npos) << message;
}

/// A scene whose sensor carries `sampler` and `film` bodies, and an integrator element.
std::string sensor_with(const std::string& sampler, const std::string& film,
                        const std::string& integrator = "") {
    return integrator + R"(<sensor type="perspective"><sampler type="independent">)" + sampler +
           R"(</sampler><film type="hdrfilm">)" + film +
           R"(<rfilter type="box"/></film></sensor>)" + kLight;
}

TEST(SceneBuild, IntegersBeyond32BitsAreErrorsNotTruncations) {
    // Each of these once became a small number silently (2^31 spp -> 1, 2^32 + 1 -> 1).
    const std::string w = R"(<integer name="width" value="8"/><integer name="height" value="8"/>)";
    for (
        const std::string& bad :
        {sensor_with(R"(<integer name="sample_count" value="2147483648"/>)", w),
         sensor_with("", R"(<integer name="width" value="4294967297"/>)"),
         sensor_with(
             "", w,
             R"(<integrator type="path"><integer name="max_depth" value="4294967297"/></integrator>)"),
         sensor_with("", w + R"(<integer name="crop_offset_x" value="2147483647"/>)"),
         sensor_with("", w + R"(<integer name="crop_offset_x" value="-2147483648"/>)")}) {
        const std::string message = build_error(bad);
        EXPECT_FALSE(message.empty()) << bad;
        EXPECT_NE(message.find("test.xml:"), std::string::npos) << message;
    }
    const std::string message =
        build_error(sensor_with(R"(<integer name="sample_count" value="2147483648"/>)", w));
    EXPECT_NE(message.find("sample_count"), std::string::npos) << message;
    EXPECT_NE(message.find("32-bit"), std::string::npos) << message;
    // The largest int still builds.
    EXPECT_EQ(build_error(sensor_with(R"(<integer name="sample_count" value="2147483647"/>)", w)),
              "");
}

TEST(SceneBuild, GeometryAndCamerasBeyondTheTraceableWorldAreErrorsNotAborts) {
    // Each of these was accepted and then aborted every integrator inside Embree (a ray origin
    // beyond 1.8e18 fails its ray.valid() check) or traced infinities.
    const std::string camera = R"(<sensor type="perspective">)";
    for (
        const std::string& bad : {
            camera + R"(<float name="near_clip" value="inf"/></sensor>)" + kLight,
            camera + R"(<float name="near_clip" value="1e20"/></sensor>)" + kLight,
            camera + R"(<float name="near_clip" value="0"/></sensor>)" + kLight,
            camera + R"(<float name="far_clip" value="0.005"/></sensor>)" + kLight,
            camera + R"(<float name="far_clip" value="nan"/></sensor>)" + kLight,
            camera + R"(<transform name="to_world"><translate x="1e38"/></transform></sensor>)" +
                kLight,
            std::string(R"(<shape type="sphere"><float name="radius" value="inf"/></shape>)"),
            std::string(R"(<shape type="sphere"><float name="radius" value="1e30"/></shape>)"),
            std::string(
                R"(<shape type="rectangle"><transform name="to_world"><scale value="-1e308"/></transform></shape>)"),
            std::string(
                R"(<emitter type="point"><point name="position" x="0" y="1e30" z="0"/></emitter>)"),
        }) {
        const std::string message = build_error("\n" + bad);
        EXPECT_NE(message.find("test.xml:3"), std::string::npos) << bad << ": " << message;
    }
    // Large but traceable scenes still build.
    EXPECT_EQ(
        build_error(camera + R"(<transform name="to_world"><translate x="1e6"/></transform>)" +
                    R"(<float name="near_clip" value="1e3"/></sensor>)" +
                    R"(<shape type="sphere"><float name="radius" value="1e9"/></shape>)"),
        "");
}

TEST(SceneBuild, APinholeCameraTakesAFocusDistanceWithoutEffect) {
    // Mitsuba 3's projective cameras all read focus_distance, and its own cbox.xml gives one
    // to its pinhole camera: accepted, and the camera's rays are those of the same camera
    // without it.
    const std::string camera = R"(<sensor type="perspective"><float name="fov" value="30"/>
        <transform name="to_world"><lookat origin="0, 1, 5" target="0, 0, 0" up="0, 1, 0"/>
        </transform>)";
    const Scene plain = test::scene_from_xml(camera + "</sensor>" + kLight);
    const Scene focused = test::scene_from_xml(
        camera + R"(<float name="focus_distance" value="2.5"/></sensor>)" + kLight);
    for (const Vec2f& film_position : {Vec2f(0.5f, 0.5f), Vec2f(10.25f, 3.75f)}) {
        const Ray a = plain.camera().generate_ray(film_position);
        const Ray b = focused.camera().generate_ray(film_position);
        EXPECT_EQ(a.origin, b.origin);
        EXPECT_EQ(a.direction, b.direction);
        EXPECT_EQ(a.t_max, b.t_max);
    }
}

TEST(SceneBuild, ThinLensAndOrthographicSensorsAsMitsubaReadsThem) {
    const std::string pose =
        R"(<transform name="to_world"><lookat origin="0, 1, 5" target="0, 0, 0" up="0, 1, 0"/></transform>)";
    // A thin lens: its aperture and focus read; without aperture_radius, or with a scaling
    // to_world (Mitsuba 3 refuses both), an error at the sensor.
    const Scene lens = test::scene_from_xml(
        R"(<sensor type="thinlens"><float name="aperture_radius" value="0.2"/>
        <float name="focus_distance" value="4"/>)" +
        pose + "</sensor>" + kLight);
    EXPECT_EQ(lens.camera().projection(), Projection::ThinLens);
    EXPECT_TRUE(lens.camera().needs_lens_sample());
    // The lens point for u = (1, 0.5) is the disk's rim on camera +x, 0.2 from the centre.
    EXPECT_NEAR((lens.camera().lens_position(Vec2f(1.f, 0.5f)) - Vec3f(0.f, 1.f, 5.f)).norm(), 0.2f,
                1e-5f);
    std::string message = build_error("\n<sensor type=\"thinlens\">" + pose + "</sensor>" + kLight);
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
    EXPECT_NE(message.find("aperture_radius"), std::string::npos) << message;
    message = build_error(
        R"(<sensor type="thinlens"><float name="aperture_radius" value="0.2"/>
        <transform name="to_world"><scale value="2"/></transform></sensor>)" +
        kLight);
    EXPECT_NE(message.find("must not scale"), std::string::npos) << message;
    // An orthographic camera: parallel rays along the view direction, scaled by to_world.
    const Scene ortho = test::scene_from_xml(
        R"(<sensor type="orthographic"><transform name="to_world"><scale x="2" y="2"/>
        <lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform></sensor>)" +
        kLight);
    EXPECT_EQ(ortho.camera().projection(), Projection::Orthographic);
    EXPECT_FALSE(ortho.camera().needs_lens_sample());
    const Ray corner = ortho.camera().generate_ray(Vec2f(0.f, 0.f));
    // Mitsuba's default film is 768 x 576: the top-left corner sees camera (1, 0.75) times 2;
    // camera +x is world -x here (looking down -z), so world (-2, 1.5).
    EXPECT_NEAR(corner.origin.x(), -2.f, 1e-5f);
    EXPECT_NEAR(corner.origin.y(), 1.5f, 1e-5f);
    EXPECT_NEAR((corner.direction - Vec3f(0.f, 0.f, -1.f)).norm(), 0.f, 1e-6f);
    message = build_error("<sensor type=\"fisheye\"/>" + kLight);
    EXPECT_NE(message.find("supported: perspective, thinlens, orthographic"), std::string::npos)
        << message;
}

TEST(SceneBuild, AMomentIntegratorRendersItsFirstNestedIntegrator) {
    // Mitsuba 3's test scenes wrap their integrator in `moment`, whose image is the first
    // nested integrator's.
    const Scene scene = test::scene_from_xml(R"(<integrator type="moment">
        <integrator type="bdpt" name="first"><integer name="max_depth" value="3"/></integrator>
        <integrator type="path" name="second"/></integrator>)" +
                                             kLight);
    EXPECT_EQ(scene.integrator().type, "bdpt");
    EXPECT_EQ(scene.integrator().max_depth, 3);
    const std::string message = build_error("\n<integrator type=\"moment\"></integrator>" + kLight);
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
    EXPECT_NE(message.find("nested"), std::string::npos) << message;
}

TEST(SceneBuild, ATopLevelAreaEmitterIsTheEmitterOfTheShapesThatReferToIt) {
    // Mitsuba's cbox-rgb.xml declares its area light last, at the top, and the luminaire's
    // shape refers to it: one emitter, the shape's, as Mitsuba 3 builds it.
    const Scene scene = test::scene_from_xml(R"(<shape type="rectangle"><ref id="lamp"/></shape>
        <shape type="sphere"/>
        <emitter type="area" id="lamp"><rgb name="radiance" value="2, 3, 4"/></emitter>)");
    ASSERT_EQ(scene.emitters().size(), 1u);
    const auto* area = std::get_if<AreaEmitter>(&scene.emitters()[0]);
    ASSERT_NE(area, nullptr);
    EXPECT_EQ(area->shape, 0);
    // Referred to by nothing, it is still an error (Mitsuba 3 drops it without a word).
    const std::string message = build_error("\n<emitter type=\"area\" id=\"lost\"/>" + kLight);
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
}

TEST(SceneBuild, SpectraOnEmittersAreEmissionSpectra) {
    // As in Mitsuba 3's RGB variants: a uniform spectrum on an emitter is the equal-energy
    // white in sRGB (not grey), and wavelength:value pairs on an emitter are not weighted by
    // D65 nor clamped to 1 (core/scene/spectrum_rgb.h; the values are tested there).
    const Scene scene = test::scene_from_xml(R"(
        <emitter type="point"><spectrum name="intensity" value="2"/></emitter>
        <emitter type="constant"><spectrum name="radiance" value="400:0, 500:8, 600:15.6, 700:18.4"/></emitter>)");
    ASSERT_EQ(scene.emitters().size(), 2u);
    const auto& point = std::get<PointEmitter>(scene.emitters()[0]);
    const Rgb white = spectrum_text_to_rgb("2", SpectrumUse::Emission);
    EXPECT_GT(white[0], 2.3f);  // purple: more red and blue than green
    for (int c = 0; c < 3; ++c) EXPECT_EQ(point.intensity[c], white[c]);
    const auto& constant = std::get<ConstantEmitter>(scene.emitters()[1]);
    const Rgb light =
        spectrum_text_to_rgb("400:0, 500:8, 600:15.6, 700:18.4", SpectrumUse::Emission);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(constant.radiance[c], light[c]);
    // A malformed spectrum is an error at its line.
    const std::string message = build_error(
        "\n<emitter type=\"point\"><spectrum name=\"intensity\" value=\"500:1, "
        "400:2\"/></emitter>");
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
    EXPECT_NE(message.find("increase"), std::string::npos) << message;
}

TEST(SceneBuild, TheDirectIntegratorIsThePathTracerOfDepthTwo) {
    // Mitsuba 3's `direct` (a dozen scenes of its data repository): the same expectation as
    // its path tracer with max_depth 2; its sample counts only change the noise.
    const Scene scene = test::scene_from_xml(R"(<integrator type="direct">
        <integer name="emitter_samples" value="4"/><integer name="bsdf_samples" value="0"/>
        <boolean name="hide_emitters" value="true"/></integrator>)" +
                                             kLight);
    EXPECT_EQ(scene.integrator().type, "path");
    EXPECT_EQ(scene.integrator().max_depth, 2);
    EXPECT_TRUE(scene.integrator().hide_emitters);
    const std::string message = build_error(
        "\n<integrator type=\"direct\"><integer name=\"max_depth\" value=\"3\"/></integrator>" +
        kLight);
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
    EXPECT_NE(message.find("max_depth"), std::string::npos) << message;
}

TEST(SceneBuild, WithoutAFieldOfViewTheCameraHasMitsubasFiftyMillimetreLens) {
    // Mitsuba 3 (parse_fov): focal_length, "50mm" by default, on a 36 x 24 mm film's
    // diagonal. At 4:3 the half-diagonal's tangent is 43.27 / 100, so tan(fov_x / 2) =
    // 0.43267 * 4 / 5.
    const std::string film = R"(<film type="hdrfilm"><integer name="width" value="64"/>
        <integer name="height" value="48"/><rfilter type="box"/></film>)";
    const Scene lens =
        test::scene_from_xml(R"(<sensor type="perspective">)" + film + "</sensor>" + kLight);
    const float expected = static_cast<float>(std::sqrt(36.0 * 36.0 + 24.0 * 24.0) / 100.0 * 0.8);
    EXPECT_NEAR(lens.camera().tan_half_fov_x(), expected, 1e-6f);
    const Scene f35 = test::scene_from_xml(
        R"(<sensor type="perspective"><string name="focal_length" value="35mm"/>)" + film +
        "</sensor>" + kLight);
    EXPECT_NEAR(f35.camera().tan_half_fov_x(), expected * 50.f / 35.f, 1e-6f);
    for (const std::string bad :
         {R"(<string name="focal_length" value="wide"/>)",
          R"(<string name="focal_length" value="35mm"/><float name="fov" value="40"/>)"}) {
        const std::string message =
            build_error("\n<sensor type=\"perspective\">" + bad + film + "</sensor>" + kLight);
        EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
    }
}

TEST(SceneBuild, MitsubasOtherSamplersAndATopLevelSamplerGiveTheirSampleCount) {
    // Mitsuba's stratified, multijitter, orthogonal and ldsampler converge to the independent
    // sampler's image; their sample_count is kept. A sampler declared at the top for the
    // sensor that refers to it (Mitsuba's docs/scenes/sampler_*.xml) is the sensor's.
    for (const std::string kind : {"independent", "stratified", "multijitter", "ldsampler"}) {
        const Scene scene = test::scene_from_xml(
            R"(<sensor type="perspective"><sampler type=")" + kind +
            R"("><integer name="sample_count" value="9"/><boolean name="jitter" value="false"/></sampler></sensor>)" +
            kLight);
        EXPECT_EQ(scene.sampler().sample_count, 9) << kind;
    }
    const Scene declared = test::scene_from_xml(R"(<sampler type="independent" id="s">
        <integer name="sample_count" value="7"/></sampler>
        <sensor type="perspective"><ref id="s"/></sensor>)" +
                                                kLight);
    EXPECT_EQ(declared.sampler().sample_count, 7);
    const std::string message =
        build_error("\n<sensor type=\"perspective\"><sampler type=\"sobol\"/></sensor>" + kLight);
    EXPECT_NE(message.find("test.xml:3"), std::string::npos) << message;
}

TEST(SceneBuild, RectangleFacesAlongItsTransformedNormal) {
    // Mitsuba's rectangle spans [-1,1]^2 at z = 0 facing +z; rotating by -90 degrees about x
    // turns it into a floor at y = -1 facing +y.
    const Scene scene = test::scene_from_xml(R"(
        <shape type="rectangle"><transform name="to_world">
            <rotate x="1" angle="-90"/><translate y="-1"/></transform></shape>)");
    const SurfaceInteraction si =
        scene.intersect(Ray{Vec3f(0.2f, 3.f, 0.1f), -Vec3f::UnitY(), kInfinity});
    ASSERT_TRUE(si.valid());
    EXPECT_NEAR(si.p.y(), -1.f, 1e-6f);
    EXPECT_NEAR(si.n_geometric.y(), 1.f, 1e-6f);
    EXPECT_NEAR(si.shading.n.y(), 1.f, 1e-6f);
    EXPECT_NEAR(scene.shapes()[0].surface_area(), 4.f, 1e-5f);
}

TEST(SceneBuild, CubeIsClosedWithOutwardNormals) {
    const Scene scene = test::scene_from_xml(R"(
        <shape type="cube"><transform name="to_world"><scale value="0.5, 1, 2"/></transform></shape>)");
    EXPECT_NEAR(scene.shapes()[0].surface_area(), 2.f * (0.5f * 1.f + 1.f * 2.f + 0.5f * 2.f) * 4.f,
                1e-4f);
    const Vec3f directions[] = {Vec3f::UnitX(),  -Vec3f::UnitX(), Vec3f::UnitY(),
                                -Vec3f::UnitY(), Vec3f::UnitZ(),  -Vec3f::UnitZ()};
    for (const Vec3f& d : directions) {
        const SurfaceInteraction si =
            scene.intersect(Ray{Vec3f(0.01f, 0.02f, 0.03f) + 10.f * d, -d, kInfinity});
        ASSERT_TRUE(si.valid());
        EXPECT_NEAR(si.n_geometric.dot(d), 1.f, 1e-5f) << d.transpose();
    }
}

TEST(SceneBuild, SphereHasExactNormalsAndConsistentDifferentials) {
    const Scene scene = test::scene_from_xml(R"(
        <shape type="sphere"><point name="center" value="1, 2, 3"/><float name="radius" value="0.5"/></shape>)");
    const Vec3f origin(1.3f, 2.2f, 10.f);
    const SurfaceInteraction si = scene.intersect(Ray{origin, -Vec3f::UnitZ(), kInfinity});
    ASSERT_TRUE(si.valid());
    EXPECT_NEAR((si.p - Vec3f(1, 2, 3)).norm(), 0.5f, 1e-6f);
    EXPECT_NEAR((si.n_geometric - (si.p - Vec3f(1, 2, 3)) / 0.5f).norm(), 0.f, 1e-5f);
    // dp/du and dp/dv agree with finite differences of the parametrisation.
    const Shape& shape = scene.shapes()[0];
    const float h = 1e-3f;
    const SurfaceInteraction a = shape.interaction_at(0, si.surface_param + Vec2f(h, 0.f));
    const SurfaceInteraction b = shape.interaction_at(0, si.surface_param - Vec2f(h, 0.f));
    EXPECT_NEAR(((a.p - b.p) / (2.f * h) - si.dp_du).norm(), 0.f, 2e-3f * si.dp_du.norm());
    EXPECT_NEAR(((a.shading.n - b.shading.n) / (2.f * h) - si.dn_du).norm(), 0.f,
                2e-3f * si.dn_du.norm());
}

TEST(SceneBuild, SphereParametrisationMatchesDoublePrecisionEverywhere) {
    // Hits all over a sphere (radius 0.5 at (1, 2, 3); 20,000 directions, Pcg32 stream seed
    // 12, plus the poles, points 1e-4 and 1e-6 rad from them, and both sides of the phi seam):
    // surface_param against phi = atan2(y, x) (in [0, 2 pi)) and theta = acos(z) in double,
    // dp/du and dp/dv against their formulas in double, and interaction_at of the parameters
    // back to the point. Tolerances: the angles within 4e-7 (trig.h's atan2 is within 2e-7,
    // plus the roundings of the direction and the division by pi), the derivatives within
    // 1e-6 of their scale (a few float roundings), the round trip within 2e-6 r (angles
    // within 4e-7 move the point by 2 pi x 4e-7 r at most, plus the point's roundings). Seen
    // failing with theta taken as atan2(z, rho) (v off by up to 0.5) and with the ratios for
    // cos phi and sin phi swapped.
    const Vec3f center(1, 2, 3);
    const float radius = 0.5f;
    const Scene scene = test::scene_from_xml(
        R"(<shape type="sphere"><point name="center" value="1, 2, 3"/><float name="radius" value="0.5"/></shape>)");
    const Shape& shape = scene.shapes()[0];
    std::vector<Vec3f> directions = {Vec3f::UnitZ(), -Vec3f::UnitZ(), Vec3f::UnitX(),
                                     Vec3f(1.f, -1e-7f, 0.f).normalized(),
                                     Vec3f(1.f, 1e-7f, 0.f).normalized()};
    for (const float off_pole : {1e-4f, 1e-6f})
        for (const float z : {1.f, -1.f})
            directions.push_back(Vec3f(std::sin(off_pole), 0.f, z * std::cos(off_pole)));
    Pcg32 rng(12, 3);
    for (int i = 0; i < 20000; ++i)
        directions.push_back(
            warp::square_to_uniform_sphere(Vec2f(rng.next_float(), rng.next_float())));
    double worst_angle = 0.0, worst_round_trip = 0.0;
    for (const Vec3f& d : directions) {
        // A ray from outside straight at the centre hits at center + radius * d.
        const Vec3f origin = center + 4.f * radius * d;
        const SurfaceInteraction si = scene.intersect(Ray{origin, -d, kInfinity});
        ASSERT_TRUE(si.valid());
        const Vec3d n = ((si.p - center) / radius).cast<double>().normalized();
        double phi = std::atan2(n.y(), n.x());
        if (phi < 0.0) phi += 2.0 * std::numbers::pi;
        const double theta = std::acos(std::clamp(n.z(), -1.0, 1.0));
        const double rho = std::hypot(n.x(), n.y());
        // On the seam phi may land at either end of [0, 2 pi): compare modulo one turn.
        double du = std::abs(si.surface_param.x() - phi / (2.0 * std::numbers::pi));
        du = std::min(du, 1.0 - du);
        const double dv = std::abs(si.surface_param.y() - theta / std::numbers::pi);
        worst_angle = std::max({worst_angle, du, dv});
        ASSERT_LE(du, 4e-7) << d.transpose();
        ASSERT_LE(dv, 4e-7) << d.transpose();
        if (rho > 1e-3) {  // away from the poles, where phi and dp/du are defined
            const Vec3d dp_du = 2.0 * std::numbers::pi * radius * Vec3d(-n.y(), n.x(), 0.0);
            const Vec3d dp_dv =
                std::numbers::pi * radius * Vec3d(n.z() * n.x() / rho, n.z() * n.y() / rho, -rho);
            ASSERT_LE((si.dp_du.cast<double>() - dp_du).norm(), 1e-6 * 2.0 * std::numbers::pi)
                << d.transpose();
            ASSERT_LE((si.dp_dv.cast<double>() - dp_dv).norm(), 1e-6 * std::numbers::pi)
                << d.transpose();
        }
        const SurfaceInteraction back = shape.interaction_at(0, si.surface_param);
        const double round_trip = (back.p - si.p).cast<double>().norm() / radius;
        worst_round_trip = std::max(worst_round_trip, round_trip);
        ASSERT_LE(round_trip, 2e-6) << d.transpose();
    }
    std::printf("worst angle error %.3g, worst round trip %.3g r\n", worst_angle, worst_round_trip);
}

TEST(SceneBuild, MeshNormalDerivativesMatchFiniteDifferences) {
    const auto dir = std::filesystem::temp_directory_path() / "gdmlt_test_mesh_normals";
    std::filesystem::create_directories(dir);
    const auto path = dir / "bent.obj";
    // A bent quad: smooth vertex normals vary across each triangle.
    std::ofstream(path) << "v 0 0 0\nv 1 0 0.3\nv 1 1 0\nv 0 1 0.2\nf 1 2 3\nf 1 3 4\n";
    const Scene scene = test::scene_from_xml(
        "<shape type=\"obj\"><string name=\"filename\" value=\"" + path.string() + "\"/></shape>");
    const Shape& shape = scene.shapes()[0];
    const Vec2f uv(0.3f, 0.2f);
    const SurfaceInteraction si = shape.interaction_at(0, uv);
    ASSERT_GT(si.dn_du.norm() + si.dn_dv.norm(), 1e-3f);
    const float h = 1e-3f;
    for (int axis = 0; axis < 2; ++axis) {
        const Vec2f step = axis == 0 ? Vec2f(h, 0.f) : Vec2f(0.f, h);
        const Vec3f fd = (shape.interaction_at(0, uv + step).shading.n -
                          shape.interaction_at(0, uv - step).shading.n) /
                         (2.f * h);
        const Vec3f analytic = axis == 0 ? si.dn_du : si.dn_dv;
        EXPECT_NEAR((fd - analytic).norm(), 0.f, 1e-3f) << "axis " << axis;
    }
    std::filesystem::remove_all(dir);
}

TEST(SceneBuild, AMeshAttributeTextureReadsThePlyValuesWhereTheRayLands) {
    // One triangle with red, green and blue vertex colours as reflectance (Mitsuba 3's
    // mesh_attribute), once as written and once mirrored by to_world (which swaps two corners
    // of every triangle to keep the winding: the corner values must swap with them). Where a
    // ray lands at (x, y) of the triangle, the reflectance is (1 - x - y, x, y) in both.
    constexpr const char* kSky = R"(<emitter type="constant"/>)";  // nothing in the rays' way
    const auto dir = std::filesystem::temp_directory_path() / "gdmlt_test_mesh_attribute";
    std::filesystem::create_directories(dir);
    const auto path = dir / "rgb.ply";
    std::ofstream(path) << "ply\nformat ascii 1.0\nelement vertex 3\n"
                           "property float x\nproperty float y\nproperty float z\n"
                           "property float r\nproperty float g\nproperty float b\n"
                           "element face 1\nproperty list uchar int vertex_indices\n"
                           "end_header\n0 0 0 1 0 0\n1 0 0 0 1 0\n0 1 0 0 0 1\n3 0 1 2\n";
    const std::string ply =
        R"(<shape type="ply"><string name="filename" value=")" + path.string() + R"("/>)";
    const std::string bsdf = R"(<bsdf type="twosided"><bsdf type="diffuse">
        <texture type="mesh_attribute" name="reflectance"><string name="name" value="vertex_color"/>
        </texture></bsdf></bsdf>)";
    const Scene scene = test::scene_from_xml(
        std::string(kSky) + ply + bsdf + "</shape>" + ply +
        R"(<transform name="to_world"><scale x="-1"/><translate z="-2"/></transform>)" + bsdf +
        "</shape>");
    for (const float mirror : {1.f, -1.f}) {
        for (const Vec2f& xy : {Vec2f(0.2f, 0.3f), Vec2f(0.6f, 0.1f), Vec2f(0.05f, 0.9f)}) {
            Ray ray;
            ray.origin = Vec3f(mirror * xy.x(), xy.y(), 1.f);
            ray.direction = Vec3f(0.f, 0.f, -1.f);
            const SurfaceInteraction si = scene.intersect(ray);
            ASSERT_TRUE(si.valid());
            EXPECT_NEAR(si.p.z(), mirror > 0.f ? 0.f : -2.f, 1e-5f);
            const Vec3f up = si.shading.to_local(Vec3f(0.f, 0.f, 1.f));
            const Rgb reflectance =
                scene.bsdf_of(si).eval(si.texture_point(), up, up) * kPi / std::abs(up.z());
            const Rgb expected(1.f - xy.x() - xy.y(), xy.x(), xy.y());
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(reflectance[c], expected[c], 1e-5f)
                    << "mirror " << mirror << " at " << xy.transpose() << " channel " << c;
        }
    }
    // A name no mesh has, or one without the vertex_/face_ prefix: errors at the texture.
    std::string message =
        build_error(std::string(kSky) + ply +
                    R"(<bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance">
        <string name="name" value="vertex_weight"/></texture></bsdf></shape>)");
    EXPECT_NE(message.find("no mesh of the scene has an attribute 'vertex_weight'"),
              std::string::npos)
        << message;
    message = build_error(std::string(kSky) + ply +
                          R"(<bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance">
        <string name="name" value="color"/></texture></bsdf></shape>)");
    EXPECT_NE(message.find("must start with vertex_ or face_"), std::string::npos) << message;
    std::filesystem::remove_all(dir);
}

TEST(SceneBuild, AnInstanceIsItsShapegroupsShapesUnderItsTransform) {
    // Instances of two groups against the same shapes written out with both transforms: the
    // same hits, ray by ray (400 rays from a grid towards a point behind the shapes). Group 1 (a
    // sphere and a rectangle, each with its own to_world) under two similarities; group 2 (a
    // bent quad with smooth vertex normals) under a uniform mirror and under an uneven
    // mirroring stretch. The group's meshes are stored once and shared (MeshInstance), the
    // spheres are copied. Shading normals are compared where the scale is uniform: elsewhere a
    // written-out mesh normalises each transformed vertex normal before interpolating, and an
    // instance maps the interpolated object normal (Shape::interaction).
    const auto dir = std::filesystem::temp_directory_path() / "gdmlt_test_instance";
    std::filesystem::create_directories(dir);
    const auto bent = dir / "bent.obj";
    std::ofstream(bent) << "v -1 -1 0\nv 1 -1 0.5\nv 1 1 0\nv -1 1 0.4\n"
                           "vn 0.2 0 1\nvn 0 0.3 1\nvn -0.3 0.1 1\nvn 0 -0.2 1\n"
                           "f 1//1 2//2 3//3\nf 1//1 3//3 4//4\n";
    const std::string bent_shape = R"(<shape type="obj"><string name="filename" value=")" +
                                   bent.string() + R"("/><transform name="to_world">)";
    const std::string sphere_local = R"(<scale value="0.5"/><translate value="-1, 0, 0"/>)";
    const std::string rectangle_local = R"(<scale value="1.2"/><rotate y="1" angle="-80"/>)";
    const std::string bent_local = R"(<rotate x="1" angle="20"/>)";
    struct Placement {
        std::string group, to_world;
        bool uniform_scale;
    };
    const Placement placements[] = {
        {"group", R"(<rotate y="1" angle="45"/><translate z="2"/>)", true},
        {"group", R"(<rotate x="1" angle="-25"/><scale value="1.5"/>)", true},
        {"bent", R"(<scale x="-1.5" y="1.5" z="1.5"/><translate value="1, 1, -1"/>)", true},
        {"bent", R"(<scale x="-0.8" y="1.3" z="1"/><translate value="-1, -1, 1"/>)", false}};
    std::string grouped = R"(<shape type="shapegroup" id="group">
        <shape type="sphere"><transform name="to_world">)" +
                          sphere_local + R"(</transform></shape>
        <shape type="rectangle"><transform name="to_world">)" +
                          rectangle_local + R"(</transform></shape></shape>
        <shape type="shapegroup" id="bent">)" +
                          bent_shape + bent_local + "</transform></shape></shape>";
    std::string flat;
    std::vector<bool> uniform_scale(1, true);  // the light
    for (const Placement& place : placements) {
        grouped += R"(<shape type="instance"><ref id=")" + place.group +
                   R"("/><transform name="to_world">)" + place.to_world + "</transform></shape>";
        if (place.group == "group") {
            flat += R"(<shape type="sphere"><transform name="to_world">)" + sphere_local +
                    place.to_world + "</transform></shape>";
            flat += R"(<shape type="rectangle"><transform name="to_world">)" + rectangle_local +
                    place.to_world + "</transform></shape>";
            uniform_scale.insert(uniform_scale.end(), 2, place.uniform_scale);
        } else {
            flat += bent_shape + bent_local + place.to_world + "</transform></shape>";
            uniform_scale.push_back(place.uniform_scale);
        }
    }
    const Scene a = test::scene_from_xml(kLight + grouped);
    const Scene b = test::scene_from_xml(kLight + flat);
    std::filesystem::remove_all(dir);
    EXPECT_EQ(a.counts().at("instances"), 4u);
    ASSERT_EQ(a.shapes().size(), b.shapes().size());
    // The meshes are shared: each group mesh is one object, whatever the instance count.
    const auto& rectangle_1 = std::get<MeshInstance>(a.shapes()[2].geometry());
    const auto& rectangle_2 = std::get<MeshInstance>(a.shapes()[4].geometry());
    EXPECT_EQ(rectangle_1.object.get(), rectangle_2.object.get());
    EXPECT_TRUE(std::holds_alternative<Sphere>(a.shapes()[1].geometry()));
    EXPECT_EQ(std::get<MeshInstance>(a.shapes()[5].geometry()).object.get(),
              std::get<MeshInstance>(a.shapes()[6].geometry()).object.get());
    for (std::size_t i = 0; i < a.shapes().size(); ++i)
        EXPECT_NEAR(a.shapes()[i].surface_area(), b.shapes()[i].surface_area(),
                    1e-5f * b.shapes()[i].surface_area())
            << i;
    std::vector<int> hits_by_shape(a.shapes().size(), 0);
    const Vec3f target(0.13f, -0.21f, -3.f);
    for (int i = 0; i < 20; ++i)
        for (int j = 0; j < 20; ++j) {
            Ray ray;
            ray.origin = Vec3f(-4.f + 0.4f * static_cast<float>(i),
                               -4.f + 0.4f * static_cast<float>(j), 8.f);
            ray.direction = (target - ray.origin).normalized();
            const SurfaceInteraction ha = a.intersect(ray), hb = b.intersect(ray);
            ASSERT_EQ(ha.valid(), hb.valid()) << i << " " << j;
            if (!ha.valid()) continue;
            ASSERT_EQ(ha.shape, hb.shape) << i << " " << j;
            ++hits_by_shape[static_cast<std::size_t>(ha.shape)];
            EXPECT_NEAR((ha.p - hb.p).norm(), 0.f, 1e-5f);
            EXPECT_NEAR((ha.n_geometric - hb.n_geometric).norm(), 0.f, 1e-5f);
            if (uniform_scale[static_cast<std::size_t>(ha.shape)])
                EXPECT_NEAR((ha.shading.n - hb.shading.n).norm(), 0.f, 1e-5f);
            else
                EXPECT_GT(ha.shading.n.dot(hb.shading.n), 0.99f);
        }
    // Every instanced shape is seen by some of the rays.
    for (std::size_t shape = 1; shape < hits_by_shape.size(); ++shape)
        EXPECT_GE(hits_by_shape[shape], 5) << shape;
    // What an instance may not hold.
    EXPECT_NE(
        build_error(kLight + R"(<shape type="instance"/>)").find("needs a <ref> to a shapegroup"),
        std::string::npos);
    const std::string emitting = build_error(kLight + R"(<shape type="shapegroup" id="g">
        <shape type="sphere"><emitter type="area"/></shape></shape>
        <shape type="instance"><ref id="g"/></shape>)");
    EXPECT_NE(emitting.find("cannot emit"), std::string::npos) << emitting;
    const std::string nested = build_error(kLight + R"(<shape type="shapegroup" id="g">
        <shape type="sphere"/></shape><shape type="shapegroup" id="h"><shape type="instance"><ref id="g"/></shape></shape>
        <shape type="instance"><ref id="h"/></shape>)");
    EXPECT_NE(nested.find("nested instancing is not supported"), std::string::npos) << nested;
}

TEST(SceneBuild, FeaturesSayWhichEffectsOccur) {
    const Scene diffuse_only = test::scene_from_xml(kLight + R"(<shape type="cube"/>)");
    EXPECT_TRUE(diffuse_only.features().has_diffuse);
    EXPECT_FALSE(diffuse_only.features().specular_chains_possible);
    const Scene glass =
        test::scene_from_xml(kLight + R"(<shape type="sphere"><bsdf type="dielectric"/></shape>)");
    EXPECT_TRUE(glass.features().has_delta_transmission);
    EXPECT_TRUE(glass.features().specular_chains_possible);
    EXPECT_EQ(glass.features().bsdf_kinds.count("dielectric"), 1u);
}

}  // namespace
}  // namespace gdmlt
