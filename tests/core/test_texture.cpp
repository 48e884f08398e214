// SPDX-License-Identifier: GPL-3.0-or-later
// Textures: Mitsuba's bitmap conventions (texel centres, v = 0 at the first row, repeat),
// sRGB linearisation of 8-bit files, checkerboard parity, float textures, and their use in
// scene files (nested and referenced <texture>, errors for what is not understood).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/image/image_io.h"
#include "core/sampling/rng.h"
#include "core/texture/texture.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// A 4 x 2 bitmap whose texel (x, y) holds (x, y, 10), the layout Mitsuba 3 was probed with.
BitmapTexture ramp_bitmap() {
    std::vector<Rgb> texels;
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 4; ++x)
            texels.emplace_back(static_cast<float>(x), static_cast<float>(y), 10.f);
    BitmapTexture b;
    b.data = std::make_shared<const BitmapData>(make_bitmap_data(4, 2, texels, "ramp"));
    return b;
}

TEST(BitmapTexture, TexelCentresHoldTheirValuesWithRowZeroAtVZero) {
    // Values Mitsuba 3.9 returns for the same image (bitmap plugin, bilinear, repeat).
    const BitmapTexture b = ramp_bitmap();
    const auto expect_rgb = [&](Vec2f uv, Rgb expected) {
        const Rgb v = b.eval(uv);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], expected[c], 1e-5f) << uv.transpose();
    };
    expect_rgb({0.125f, 0.25f}, Rgb(0.f, 0.f, 10.f));
    expect_rgb({0.125f, 0.75f}, Rgb(0.f, 1.f, 10.f));
    expect_rgb({0.375f, 0.25f}, Rgb(1.f, 0.f, 10.f));
    expect_rgb({0.25f, 0.5f}, Rgb(0.5f, 0.5f, 10.f));
    // Repeat: at u = 0 the lookup blends the last and the first column.
    expect_rgb({0.f, 0.f}, Rgb(1.5f, 0.5f, 10.f));
    expect_rgb({0.999f, 0.25f}, Rgb(1.512f, 0.f, 10.f));
}

TEST(BitmapTexture, WrapModesAndNearestFilter) {
    BitmapTexture b = ramp_bitmap();
    b.filter = FilterMode::Nearest;
    EXPECT_FLOAT_EQ(b.eval({0.3f, 0.2f})[0], 1.f);
    EXPECT_FLOAT_EQ(b.eval({1.3f, 0.2f})[0], 1.f);   // repeat
    EXPECT_FLOAT_EQ(b.eval({-0.2f, 0.2f})[0], 3.f);  // repeat, negative
    b.wrap = WrapMode::Clamp;
    EXPECT_FLOAT_EQ(b.eval({1.3f, 0.2f})[0], 3.f);
    EXPECT_FLOAT_EQ(b.eval({-0.2f, 0.2f})[0], 0.f);
    b.wrap = WrapMode::Mirror;
    EXPECT_FLOAT_EQ(b.eval({1.1f, 0.2f})[0], 3.f);  // 1.1 mirrors to 0.9
}

TEST(BitmapTexture, BilinearLookupsMatchTheirDefinitionInEveryWrapMode) {
    // Bilinear filtering at texel centres (i + 0.5) / n with the wrap applied to each of the
    // four texels, written out here from the definitions, against eval() on a 61 x 61 grid of
    // (u, v) over [-1.3, 2.3]^2: inside the image, on its last column and row, and wrapped.
    // Float sums of four terms agree to a few ulps of the values (at most 10): 1e-5.
    const BitmapTexture ramp = ramp_bitmap();
    for (const WrapMode mode : {WrapMode::Repeat, WrapMode::Mirror, WrapMode::Clamp}) {
        BitmapTexture b = ramp;
        b.wrap = mode;
        const auto wrap = [&](int i, int n) {
            if (mode == WrapMode::Clamp) return std::clamp(i, 0, n - 1);
            const int period = mode == WrapMode::Repeat ? n : 2 * n;
            const int r = ((i % period) + period) % period;
            return r < n ? r : 2 * n - 1 - r;
        };
        const auto texel = [&](int x, int y) {
            return Rgb(static_cast<float>(wrap(x, 4)), static_cast<float>(wrap(y, 2)), 10.f);
        };
        for (int i = 0; i <= 60; ++i)
            for (int j = 0; j <= 60; ++j) {
                const float u = -1.3f + 3.6f * static_cast<float>(i) / 60.f;
                const float v = -1.3f + 3.6f * static_cast<float>(j) / 60.f;
                const float x = u * 4.f - 0.5f, y = v * 2.f - 0.5f;
                const int x0 = static_cast<int>(std::floor(x)),
                          y0 = static_cast<int>(std::floor(y));
                const float fx = x - std::floor(x), fy = y - std::floor(y);
                const Rgb want =
                    (1.f - fy) * ((1.f - fx) * texel(x0, y0) + fx * texel(x0 + 1, y0)) +
                    fy * ((1.f - fx) * texel(x0, y0 + 1) + fx * texel(x0 + 1, y0 + 1));
                const Rgb got = b.eval({u, v});
                for (int c = 0; c < 3; ++c)
                    ASSERT_NEAR(got[c], want[c], 1e-5f) << "u " << u << " v " << v;
            }
    }
}

TEST(BitmapTexture, GradientMatchesFiniteDifferencesOfTheLuminance) {
    // The bump map's height gradient (Mitsuba 3's eval_1_grad) against central differences of
    // luminance(eval) with step 1e-3, through a to_uv that scales, rotates and shears (the
    // chain rule's transpose) on the non-square 4 x 2 ramp, in every wrap mode, at 400 points
    // (Pcg32 seed 4) whose stencil stays inside one bilinear cell (where eval is smooth).
    // Float differences of values ~10 over 2e-3 carry ~1e-2 of rounding: tolerance 0.03 on
    // gradients of size 1-10.
    BitmapTexture b = ramp_bitmap();
    b.data = std::make_shared<const BitmapData>(
        make_bitmap_data(4, 2,
                         {Rgb(1, 2, 3), Rgb(4, 1, 0), Rgb(2, 2, 2), Rgb(0, 5, 1), Rgb(3, 0, 1),
                          Rgb(1, 1, 1), Rgb(6, 2, 0), Rgb(2, 3, 4)},
                         "mixed"));
    b.to_uv.linear << 1.3f, 0.4f, -0.7f, 0.9f;
    b.to_uv.offset = Vec2f(0.2f, -0.1f);
    Pcg32 rng(4, 1);
    int checked = 0;
    for (const WrapMode mode : {WrapMode::Repeat, WrapMode::Mirror, WrapMode::Clamp}) {
        b.wrap = mode;
        for (int i = 0; i < 400; ++i) {
            const Vec2f uv(rng.next_float() * 3.f - 1.f, rng.next_float() * 3.f - 1.f);
            const float h = 1e-3f;
            // Skip stencils that cross a cell boundary (texel centres' grid).
            bool crosses = false;
            for (const Vec2f& d : {Vec2f(h, 0.f), Vec2f(0.f, h)})
                for (const float sgn : {-1.f, 1.f}) {
                    const Vec2f a = b.to_uv.apply(uv), c = b.to_uv.apply(uv + sgn * d);
                    const auto cell = [](float t, int n) {
                        return static_cast<int>(std::floor(t * static_cast<float>(n) - 0.5f));
                    };
                    crosses = crosses || cell(a.x(), 4) != cell(c.x(), 4) ||
                              cell(a.y(), 2) != cell(c.y(), 2);
                }
            if (crosses) continue;
            const auto f = [&](const Vec2f& p) {
                return static_cast<double>(luminance(b.eval(p)));
            };
            const Vec2f grad = b.gradient(uv);
            const double fd_u = (f(uv + Vec2f(h, 0.f)) - f(uv - Vec2f(h, 0.f))) / (2.0 * h);
            const double fd_v = (f(uv + Vec2f(0.f, h)) - f(uv - Vec2f(0.f, h))) / (2.0 * h);
            ASSERT_NEAR(grad.x(), fd_u, 0.03) << "uv " << uv.transpose();
            ASSERT_NEAR(grad.y(), fd_v, 0.03) << "uv " << uv.transpose();
            ++checked;
        }
    }
    EXPECT_GT(checked, 900);  // of 1200: most stencils lie inside a cell
    b.filter = FilterMode::Nearest;
    EXPECT_EQ(b.gradient(Vec2f(0.3f, 0.3f)), Vec2f::Zero());
}

TEST(Checkerboard, ScalarFormSwapsTheColoursAsMitsubaEvaluatesIt) {
    // Mitsuba 3's checkerboard: eval (colour) is color0 where u and v fall in the same half of
    // their period, eval_1 (scalar, e.g. roughness) is color0 where they fall in different
    // halves. Rendering Mitsuba's textured rough conductor test scene showed the difference.
    CheckerboardTexture c;
    c.color0 = Rgb::Constant(0.05f);
    c.color1 = Rgb::Constant(0.3f);
    const RgbTexture colour{TextureModel(c)};
    const FloatTexture scalar{colour};
    for (const Vec2f& same : {Vec2f(0.25f, 0.25f), Vec2f(0.75f, 0.75f), Vec2f(1.2f, 0.1f)}) {
        EXPECT_FLOAT_EQ(colour.eval(same)[0], 0.05f);
        EXPECT_FLOAT_EQ(scalar.eval(same), 0.3f);
    }
    for (const Vec2f& different : {Vec2f(0.25f, 0.75f), Vec2f(0.75f, 0.25f)}) {
        EXPECT_FLOAT_EQ(colour.eval(different)[0], 0.3f);
        EXPECT_FLOAT_EQ(scalar.eval(different), 0.05f);
    }
}

TEST(BitmapTexture, LinearisesEightBitFilesUnlessRaw) {
    // An 8-bit sRGB PNG written from linear values reads back linear (to 8-bit quantisation).
    const std::string path =
        (std::filesystem::temp_directory_path() / "gdmlt_test_texture.png").string();
    Image linear(2, 1, 3);
    const float values[2] = {0.2f, 0.8f};
    for (int x = 0; x < 2; ++x)
        for (int c = 0; c < 3; ++c) linear(x, 0, c) = values[x];
    write_png_srgb(path, linear);
    const BitmapData decoded = load_bitmap(path, false);
    const BitmapData raw = load_bitmap(path, true);
    for (int x = 0; x < 2; ++x) {
        EXPECT_NEAR(decoded.texel(x, 0)[0], values[x], 0.01f);
        EXPECT_NEAR(raw.texel(x, 0)[0], linear_to_srgb(values[x]), 0.003f);
    }
    std::filesystem::remove(path);
}

TEST(CheckerboardTexture, UsesColor0WhereBothHalvesAgree) {
    const CheckerboardTexture c;  // Mitsuba defaults 0.4 / 0.2
    EXPECT_FLOAT_EQ(c.eval({0.25f, 0.25f})[0], 0.4f);
    EXPECT_FLOAT_EQ(c.eval({0.75f, 0.25f})[0], 0.2f);
    EXPECT_FLOAT_EQ(c.eval({0.25f, 0.75f})[0], 0.2f);
    EXPECT_FLOAT_EQ(c.eval({0.75f, 0.75f})[0], 0.4f);
    CheckerboardTexture scaled;
    scaled.to_uv.linear = Eigen::Matrix2f::Identity() * 4.f;  // four periods per unit
    EXPECT_FLOAT_EQ(scaled.eval({0.0625f, 0.0625f})[0], 0.4f);
    EXPECT_FLOAT_EQ(scaled.eval({0.1875f, 0.0625f})[0], 0.2f);
}

TEST(FloatTexture, ReadsLuminanceAndReportsItsRange) {
    const FloatTexture constant(0.3f);
    EXPECT_FLOAT_EQ(constant.eval({0.5f, 0.5f}), 0.3f);
    EXPECT_FLOAT_EQ(constant.min_value(), 0.3f);
    CheckerboardTexture c;
    c.color0 = Rgb::Constant(0.05f);
    c.color1 = Rgb::Constant(0.5f);
    const FloatTexture checker{RgbTexture(TextureModel(c))};
    // A scalar checkerboard is color0 where u and v fall in different halves (Mitsuba 3).
    EXPECT_NEAR(checker.eval({0.75f, 0.25f}), 0.05f, 1e-6f);
    EXPECT_NEAR(checker.min_value(), 0.05f, 1e-6f);
    EXPECT_NEAR(checker.max_value(), 0.5f, 1e-6f);
}

TEST(SceneTextures, NestedAndReferencedTexturesReachTheBsdfs) {
    const Scene scene = test::scene_from_xml(R"(
        <texture type="checkerboard" id="checks"><rgb name="color0" value="0.9"/><rgb name="color1" value="0.1"/></texture>
        <shape type="rectangle"><bsdf type="diffuse"><ref name="reflectance" id="checks"/></bsdf></shape>
        <shape type="rectangle"><transform name="to_world"><translate z="1"/></transform>
            <bsdf type="roughconductor"><texture type="checkerboard" name="alpha">
                <float name="color0" value="0.01"/><float name="color1" value="0.5"/></texture></bsdf></shape>
        <emitter type="constant"/>)");
    EXPECT_TRUE(scene.features().has_textures);
    const auto& diffuse = std::get<DiffuseBsdf>(scene.bsdfs()[0].front());
    EXPECT_NEAR(diffuse.reflectance.eval({0.25f, 0.25f})[0], 0.9f, 1e-6f);
    EXPECT_NEAR(diffuse.reflectance.eval({0.75f, 0.25f})[0], 0.1f, 1e-6f);
    const Bsdf& metal = scene.bsdfs()[1];
    // Textured roughness: per-uv classes, and the sharpest place summarises the surface (the
    // scalar checkerboard's color0, 0.01, where u and v fall in different halves).
    EXPECT_EQ(metal.roughness_class_at({0.75f, 0.25f}), RoughnessClass::Glossy);
    EXPECT_EQ(metal.roughness_class_at({0.25f, 0.25f}), RoughnessClass::Diffuse);
    EXPECT_EQ(metal.roughness_class(), RoughnessClass::Glossy);
}

TEST(SceneTextures, RejectsUnknownTexturePropertiesAndStrayChildren) {
    EXPECT_THROW(test::scene_from_xml(R"(<shape type="rectangle"><bsdf type="diffuse">
        <texture type="checkerboard" name="reflectance"><float name="colour0" value="1"/></texture></bsdf></shape>)"),
                 InputError);
    EXPECT_THROW(test::scene_from_xml(R"(<shape type="rectangle"><bsdf type="diffuse">
        <texture type="checkerboard" name="reflectanse"/></bsdf></shape>)"),
                 InputError);
    EXPECT_THROW(test::scene_from_xml(R"(<shape type="rectangle"><bsdf type="diffuse">
        <texture type="bitmap" name="reflectance"><string name="filename" value="does_not_exist.png"/></texture></bsdf></shape>)"),
                 InputError);
    EXPECT_THROW(test::scene_from_xml(R"(<shape type="rectangle"><bsdf type="roughconductor">
        <float name="alpha_x" value="0.1"/></bsdf></shape>)"),
                 InputError);
    // Mitsuba's roughplastic is isotropic.
    EXPECT_THROW(test::scene_from_xml(R"(<shape type="rectangle"><bsdf type="roughplastic">
        <float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.2"/></bsdf></shape>)"),
                 InputError);
}

TEST(SceneBsdfs, ReadsMitsubaParametersAndDefaults) {
    const Scene scene = test::scene_from_xml(R"(
        <shape type="rectangle"><bsdf type="roughconductor"><string name="distribution" value="ggx"/>
            <float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.3"/><string name="material" value="Au"/></bsdf></shape>
        <shape type="rectangle"><bsdf type="roughdielectric"><float name="alpha" value="0.2"/>
            <string name="int_ior" value="water"/></bsdf></shape>
        <shape type="rectangle"><bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.2, 0.4, 0.6"/></bsdf></shape>
        <shape type="rectangle"><bsdf type="roughplastic"><boolean name="nonlinear" value="true"/></bsdf></shape>
        <emitter type="constant"/>)");
    const auto& metal = std::get<RoughConductorBsdf>(scene.bsdfs()[0].front());
    EXPECT_EQ(metal.roughness.type, MicrofacetType::Ggx);
    EXPECT_FLOAT_EQ(metal.roughness.alpha_u.eval({0.f, 0.f}), 0.05f);
    EXPECT_FLOAT_EQ(metal.roughness.alpha_v.eval({0.f, 0.f}), 0.3f);
    EXPECT_FALSE(metal.perfect_mirror);
    const auto& glass = std::get<RoughDielectricBsdf>(scene.bsdfs()[1].front());
    EXPECT_EQ(glass.roughness.type, MicrofacetType::Beckmann);  // Mitsuba's default
    EXPECT_NEAR(glass.eta, 1.333f / 1.000277f, 1e-4f);
    const auto& plastic = std::get<PlasticBsdf>(scene.bsdfs()[2].front());
    EXPECT_NEAR(plastic.eta, 1.49f / 1.000277f, 1e-5f);
    EXPECT_NEAR(plastic.fdr_internal, fresnel_diffuse_reflectance(1.f / plastic.eta), 1e-6f);
    const auto& rough = std::get<RoughPlasticBsdf>(scene.bsdfs()[3].front());
    EXPECT_FLOAT_EQ(rough.alpha, 0.1f);
    EXPECT_TRUE(rough.nonlinear);
    EXPECT_TRUE(scene.features().has_glossy);
    EXPECT_TRUE(scene.features().has_delta_reflection);  // the smooth plastic's coat
    EXPECT_TRUE(scene.features().bsdf_kinds.count("roughplastic"));
}

}  // namespace
}  // namespace gdmlt
