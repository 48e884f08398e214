// SPDX-License-Identifier: GPL-3.0-or-later
// BSDF sampling against pdf (chi-square), sample weights against eval/pdf, delta lobes against
// the Fresnel equations, and no NaN anywhere.
#include <gtest/gtest.h>

#include <complex>
#include <cstdio>
#include <string>
#include <vector>

#include "core/bsdf/bsdf.h"
#include "core/bsdf/fresnel.h"
#include "core/geometry/interaction.h"
#include "core/math/frame.h"
#include "core/sampling/rng.h"
#include "core/sampling/warp.h"
#include "core/texture/texture.h"
#include "tests/support/chi2.h"

namespace gdmlt {
namespace {

Vec3f direction_at(float theta_deg, float phi_deg = 30.f) {
    const float theta = degrees_to_radians(theta_deg), phi = degrees_to_radians(phi_deg);
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

const Vec2f kUv(0.25f, 0.5f);

TEST(DiffuseBsdf, SamplesMatchPdfAtSeveralIncidentAngles) {
    const Bsdf bsdf(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)});
    const float angles[] = {0.f, 45.f, 89.9f};
    for (float angle : angles) {
        const Vec3f wo = direction_at(angle);
        const auto r = test::chi2_sphere_test(
            [&](Pcg32& rng) -> std::optional<Vec3f> {
                const BsdfSample s =
                    bsdf.sample(kUv, wo, rng.next_float(), {rng.next_float(), rng.next_float()});
                if (!s.valid()) return std::nullopt;
                return s.wi;
            },
            [&](const Vec3f& wi) { return static_cast<double>(bsdf.pdf(kUv, wo, wi)); });
        EXPECT_GT(r.p_value, test::sidak_alpha(3)) << "theta_o = " << angle << ": " << r.summary;
    }
}

TEST(DiffuseBsdf, SampleWeightEqualsEvalOverPdf) {
    const Bsdf bsdf(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)});
    Pcg32 rng(5, 2);
    for (int i = 0; i < 1000; ++i) {
        const Vec3f wo = direction_at(89.f * rng.next_float(), 360.f * rng.next_float());
        const BsdfSample s =
            bsdf.sample(kUv, wo, rng.next_float(), {rng.next_float(), rng.next_float()});
        if (!s.valid()) continue;
        const Rgb expected = bsdf.eval(kUv, wo, s.wi) / bsdf.pdf(kUv, wo, s.wi);
        EXPECT_NEAR(s.weight[0], expected[0], 1e-4f * expected[0]);
        EXPECT_NEAR(s.weight[2], expected[2], 1e-4f * expected[2]);
        EXPECT_FLOAT_EQ(s.pdf_solid_angle, bsdf.pdf(kUv, wo, s.wi));
    }
}

TEST(DiffuseBsdf, IsBlackFromBehindUnlessTwoSided) {
    const Vec3f wo_back = direction_at(120.f), wi_back = direction_at(150.f, 200.f);
    const Bsdf one_sided(DiffuseBsdf{Rgb::Constant(0.8f)});
    EXPECT_TRUE(is_black(one_sided.eval(kUv, wo_back, wi_back)));
    EXPECT_FALSE(one_sided.sample(kUv, wo_back, 0.5f, {0.3f, 0.3f}).valid());
    const Bsdf two = Bsdf::two_sided(DiffuseBsdf{Rgb::Constant(0.8f)}, std::nullopt);
    const Rgb f = two.eval(kUv, wo_back, wi_back);
    EXPECT_NEAR(f[0], 0.8f * kInvPi * std::abs(wi_back.z()), 1e-6f);
    const BsdfSample s = two.sample(kUv, wo_back, 0.5f, {0.3f, 0.3f});
    ASSERT_TRUE(s.valid());
    EXPECT_LT(s.wi.z(), 0.f);  // sampled on the back side, where wo is
}

TEST(DielectricBsdf, ChoosesReflectionWithTheFresnelProbability) {
    const Bsdf glass(DielectricBsdf{1.5f, Rgb::Ones(), Rgb::Ones()});
    for (float angle : {0.f, 60.f, 85.f}) {
        const Vec3f wo = direction_at(angle);
        const float F = fresnel_dielectric(wo.z(), 1.5f).reflectance;
        Pcg32 rng(9, static_cast<std::uint64_t>(angle));
        constexpr int kSamples = 40000;
        int reflections = 0;
        for (int i = 0; i < kSamples; ++i) {
            const BsdfSample s = glass.sample(kUv, wo, rng.next_float(), {0.5f, 0.5f});
            ASSERT_TRUE(s.valid());
            ASSERT_TRUE(s.delta);
            if (!s.transmission) {
                ++reflections;
                EXPECT_NEAR((s.wi - reflect_local(wo)).norm(), 0.f, 1e-6f);
                EXPECT_FLOAT_EQ(s.weight[0], 1.f);
            } else {
                // Snell's law, and radiance scaled by 1/eta^2 on entering.
                const float sin_i = std::sqrt(1.f - wo.z() * wo.z());
                const float sin_t = std::sqrt(1.f - s.wi.z() * s.wi.z());
                EXPECT_NEAR(sin_i, 1.5f * sin_t, 1e-5f);
                EXPECT_LT(s.wi.z(), 0.f);
                EXPECT_NEAR(s.weight[1], 1.f / (1.5f * 1.5f), 1e-6f);
                EXPECT_FLOAT_EQ(s.eta, 1.5f);
            }
        }
        // Binomial: 5 standard deviations.
        const double sigma = std::sqrt(kSamples * F * (1.0 - F));
        EXPECT_NEAR(reflections, kSamples * F, 5.0 * sigma + 1.0) << "theta = " << angle;
    }
}

TEST(DielectricBsdf, TotallyReflectsBeyondTheCriticalAngleInside) {
    const Bsdf glass(DielectricBsdf{1.5f, Rgb::Ones(), Rgb::Ones()});
    // Inside the glass (wo below the surface) at 60 degrees: sin 60 * 1.5 > 1.
    const Vec3f wo = -direction_at(60.f);
    for (float u : {0.f, 0.5f, 0.999f}) {
        const BsdfSample s = glass.sample(kUv, wo, u, {0.5f, 0.5f});
        ASSERT_TRUE(s.valid());
        EXPECT_FALSE(s.transmission);
        EXPECT_LT(s.wi.z(), 0.f);
    }
}

TEST(DielectricBsdf, RefractionFromInsideScalesRadianceUp) {
    const Bsdf glass(DielectricBsdf{1.5f, Rgb::Ones(), Rgb::Ones()});
    const Vec3f wo = -direction_at(10.f);
    const BsdfSample s = glass.sample(kUv, wo, 0.999f, {0.5f, 0.5f});
    ASSERT_TRUE(s.transmission);
    EXPECT_NEAR(s.weight[0], 1.5f * 1.5f, 1e-5f);
    EXPECT_NEAR(s.eta, 1.f / 1.5f, 1e-6f);
}

TEST(ThinDielectricBsdf, TransmitsStraightThroughWithoutScaling) {
    const Bsdf thin(ThinDielectricBsdf{1.5f, Rgb::Ones(), Rgb::Ones()});
    const Vec3f wo = direction_at(30.f);
    const BsdfSample s = thin.sample(kUv, wo, 0.999f, {0.5f, 0.5f});
    ASSERT_TRUE(s.transmission);
    EXPECT_NEAR((s.wi + wo).norm(), 0.f, 1e-6f);
    EXPECT_FLOAT_EQ(s.weight[0], 1.f);
    // Reflection probability includes the internal bounces: R' = 2R / (1 + R).
    const float R = fresnel_dielectric(wo.z(), 1.5f).reflectance;
    const BsdfSample reflect = thin.sample(kUv, wo, 2.f * R / (1.f + R) - 1e-4f, {0.5f, 0.5f});
    EXPECT_FALSE(reflect.transmission);
    const BsdfSample transmit = thin.sample(kUv, wo, 2.f * R / (1.f + R) + 1e-4f, {0.5f, 0.5f});
    EXPECT_TRUE(transmit.transmission);
}

TEST(ConductorBsdf, NormalIncidenceReflectanceMatchesTheClosedForm) {
    // At normal incidence F = ((n-1)^2 + k^2) / ((n+1)^2 + k^2).
    const Rgb eta(0.2f, 0.9f, 1.1f), k(3.9f, 2.4f, 2.1f);
    const Bsdf metal(ConductorBsdf{eta, k, false, Rgb::Ones()});
    const BsdfSample s = metal.sample(kUv, Vec3f::UnitZ(), 0.5f, {0.5f, 0.5f});
    ASSERT_TRUE(s.valid());
    for (int c = 0; c < 3; ++c) {
        const float expected =
            (sqr(eta[c] - 1.f) + k[c] * k[c]) / (sqr(eta[c] + 1.f) + k[c] * k[c]);
        EXPECT_NEAR(s.weight[c], expected, 1e-5f);
    }
    EXPECT_NEAR((s.wi - Vec3f::UnitZ()).norm(), 0.f, 1e-6f);
}

TEST(ConductorBsdf, ReflectanceApproachesOneAtGrazingIncidence) {
    EXPECT_NEAR(fresnel_conductor(1e-4f, 0.2f, 3.9f), 1.f, 1e-3f);
    EXPECT_NEAR(fresnel_dielectric(1e-5f, 1.5f).reflectance, 1.f, 1e-3f);
}

/// 0.5 (|r_s|^2 + |r_p|^2) from the complex amplitudes in double, the textbook form that
/// fresnel_conductor's real arithmetic rewrites.
double conductor_reflectance_complex(double cos_i, double eta, double k) {
    using C = std::complex<double>;
    const C eta_c(eta, k);
    const C cos_t = std::sqrt(C(1.0) - C(1.0 - cos_i * cos_i) / (eta_c * eta_c));
    const C r_p = (eta_c * cos_i - cos_t) / (eta_c * cos_i + cos_t);
    const C r_s = (C(cos_i) - eta_c * cos_t) / (C(cos_i) + eta_c * cos_t);
    return 0.5 * (std::norm(r_s) + std::norm(r_p));
}

TEST(ConductorBsdf, RealArithmeticFresnelIsTheComplexFormula) {
    // Every tabulated metal's (eta, k) lies in 0.03..6 x 0..12 (Mitsuba 3's conductor table);
    // the grid adds k = 0 (no absorption, including eta < 1 with total internal reflection,
    // and eta = 1 where F must vanish even at grazing incidence) and cosines down to 1e-6. The
    // tolerance is float rounding: the largest error measured was 2.3e-7 (a few ulps of F <= 1;
    // the std::complex<float> code this replaced was off by 2.6e-6 at eta = 0.9, k = 1e-3 and by
    // 1 at eta = 1, cos 1e-6), while a wrong term (a sin^2 for a sin^4, a dropped 4 eta^2 k^2)
    // is off by 1e-2 or more.
    double worst = 0.0;
    const float etas[] = {0.03f, 0.2f, 0.5f, 0.9f, 1.f, 1.1f, 1.5f, 2.5f, 6.f};
    const float ks[] = {0.f, 1e-3f, 0.1f, 0.5f, 2.4f, 3.9f, 7.f, 12.f};
    int cases = 0;
    for (float eta : etas)
        for (float k : ks)
            for (int i = 0; i <= 400; ++i) {
                const float cos_i = i == 0 ? 0.f : i == 1 ? 1e-6f : static_cast<float>(i) / 400.f;
                const double expected = conductor_reflectance_complex(cos_i, eta, k);
                const float f = fresnel_conductor(cos_i, eta, k);
                ASSERT_TRUE(f >= 0.f && f <= 1.f);
                ++cases;
                if (!std::isfinite(expected)) continue;  // 0 / 0 at cos 0, eta 1, k 0 only
                worst = std::max(worst, std::abs(static_cast<double>(f) - expected));
                EXPECT_NEAR(f, expected, 1e-6) << "cos " << cos_i << " eta " << eta << " k " << k;
            }
    EXPECT_EQ(cases, 9 * 8 * 401);
    std::printf("largest |F - F_complex|: %.3g\n", worst);
}

TEST(MaskBsdf, PassesStraightThroughWithTheProbabilityOfTransparency) {
    // Opacity from a checkerboard: 0.25 on one square, 0.9 on the other (Mitsuba's scalar
    // checkerboard swaps the colours; which square is which does not matter here). Seed 3,
    // 20000 draws per uv: the null lobe's frequency is 1 - opacity within 4 binomial standard
    // errors (<= 0.0123); each null sample goes exactly straight on with weight 1.
    CheckerboardTexture checker;
    checker.color0 = Rgb::Constant(0.25f);
    checker.color1 = Rgb::Constant(0.9f);
    const FloatTexture opacity{RgbTexture(TextureModel(checker))};
    const Bsdf nested(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)});
    const Bsdf mask = Bsdf::mask(opacity, nested);
    EXPECT_TRUE(mask.has_transmission());
    EXPECT_FALSE(mask.is_delta());
    EXPECT_TRUE(mask.lobes().delta_transmission);
    Pcg32 rng(3, 1);
    for (const Vec2f& uv : {Vec2f(0.25f, 0.25f), Vec2f(0.75f, 0.25f)}) {
        const float alpha = opacity.eval(uv);
        const Vec3f wo = direction_at(40.f, 75.f);
        const int n = 20000;
        int null_count = 0;
        for (int i = 0; i < n; ++i) {
            const BsdfSample s =
                mask.sample(uv, wo, rng.next_float(), {rng.next_float(), rng.next_float()});
            ASSERT_TRUE(s.valid());
            if (!s.delta) continue;
            ++null_count;
            EXPECT_TRUE(s.transmission);
            EXPECT_EQ(s.wi, Vec3f(-wo));
            EXPECT_EQ(s.weight[1], 1.f);
            EXPECT_EQ(s.eta, 1.f);
            EXPECT_FLOAT_EQ(s.pdf_solid_angle, 1.f - alpha);
        }
        const double expected = 1.0 - alpha;
        EXPECT_NEAR(null_count / static_cast<double>(n), expected,
                    4.0 * std::sqrt(expected * (1.0 - expected) / n))
            << "opacity " << alpha;
        const Vec3f wi = direction_at(20.f, 200.f);
        EXPECT_FLOAT_EQ(mask.eval(uv, wo, wi)[2], alpha * nested.eval(uv, wo, wi)[2]);
        EXPECT_FLOAT_EQ(mask.pdf(uv, wo, wi), alpha * nested.pdf(uv, wo, wi));
    }
    // `null` passes everything: a delta surface with nothing to evaluate.
    const Bsdf null = Bsdf::null();
    EXPECT_TRUE(null.is_delta());
    const BsdfSample s = null.sample(kUv, direction_at(70.f), 0.3f, {0.2f, 0.9f});
    EXPECT_EQ(s.wi, Vec3f(-direction_at(70.f)));
    EXPECT_EQ(s.pdf_solid_angle, 1.f);
    EXPECT_TRUE(is_black(null.eval(kUv, direction_at(70.f), direction_at(10.f))));
}

TEST(BlendBsdf, EvaluatesTheWeightedSumOfItsComponentsAndTheirDeltaLobesAtTheirShare) {
    // f = (1 - w) f_first + w f_second (Mitsuba 3's blendbsdf), pdf likewise; a mirror's
    // sample keeps its weight and carries its selection probability w as its lobe probability.
    const Bsdf first(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)});
    const Bsdf second = Bsdf::two_sided(DiffuseBsdf{Rgb(0.9f, 0.1f, 0.3f)}, std::nullopt);
    const Bsdf blend = Bsdf::blend(0.3f, first, second);
    const Vec3f wo = direction_at(35.f), wi = direction_at(60.f, 250.f);
    for (int c = 0; c < 3; ++c)
        EXPECT_FLOAT_EQ(blend.eval(kUv, wo, wi)[c],
                        0.7f * first.eval(kUv, wo, wi)[c] + 0.3f * second.eval(kUv, wo, wi)[c]);
    EXPECT_FLOAT_EQ(blend.pdf(kUv, wo, wi),
                    0.7f * first.pdf(kUv, wo, wi) + 0.3f * second.pdf(kUv, wo, wi));
    // From behind only the two-sided component answers, at its share.
    const Vec3f wo_back = -direction_at(35.f), wi_back = -direction_at(60.f, 250.f);
    EXPECT_FLOAT_EQ(blend.eval(kUv, wo_back, wi_back)[0],
                    0.3f * second.eval(kUv, wo_back, wi_back)[0]);

    const Bsdf mirror(ConductorBsdf{});
    const Bsdf with_mirror = Bsdf::blend(0.25f, first, mirror);
    const BsdfSample s = with_mirror.sample(kUv, wo, 0.1f, {0.4f, 0.6f});  // u < w: the mirror
    ASSERT_TRUE(s.valid());
    EXPECT_TRUE(s.delta);
    EXPECT_FLOAT_EQ(s.pdf_solid_angle, 0.25f);
    EXPECT_FLOAT_EQ(s.weight[0], mirror.sample(kUv, wo, 0.4f, {0.4f, 0.6f}).weight[0]);
    EXPECT_TRUE(with_mirror.lobes().delta_reflection && with_mirror.lobes().diffuse_reflection);
    EXPECT_EQ(with_mirror.roughness_class(), RoughnessClass::Diffuse);
    EXPECT_FALSE(with_mirror.is_delta());
}

TEST(BumpMapBsdf, IsTheNormalMapOfTheDisplacedSurfacesNormal) {
    // A flat surface point (shading frame = world, dp/d(param) = (2, 0, 0) and (0, 2, 0), uv =
    // param / 2, so dp/du = (4, 0, 0), dp/dv = (0, 4, 0) in texture uv) under a height bitmap
    // with scale 0.3: Blinn's displaced normal is (-4 a, -4 b, 16) normalised with (a, b) = 0.3
    // grad h. The bump map must evaluate as the normal map whose normal is exactly that
    // (tangent along dp/du as the normal map's, (1, 0, 0)), for 200 direction pairs (Pcg32 seed
    // 12) on both sides, radiance and importance: the same frame, flip and shadowing term.
    // Turning dp/d(param) into texture uv is what fails without the uv Jacobian (a, b halved).
    BitmapTexture height;
    height.data = std::make_shared<const BitmapData>(
        make_bitmap_data(3, 2,
                         {Rgb(0.1f, 0.1f, 0.1f), Rgb(0.6f, 0.6f, 0.6f), Rgb(0.2f, 0.2f, 0.2f),
                          Rgb(0.9f, 0.9f, 0.9f), Rgb(0.3f, 0.3f, 0.3f), Rgb(0.5f, 0.5f, 0.5f)},
                         "height"));
    SurfaceInteraction si;
    si.shape = 0;
    si.dp_du = Vec3f(2.f, 0.f, 0.f);
    si.dp_dv = Vec3f(0.f, 2.f, 0.f);
    si.duv_du = Vec2f(0.5f, 0.f);
    si.duv_dv = Vec2f(0.f, 0.5f);
    si.uv = Vec2f(0.37f, 0.61f);
    const Vec2f grad = 0.3f * height.gradient(si.uv);
    ASSERT_GT(grad.norm(), 0.1f);  // the test needs a tilt
    const Vec3f n = Vec3f(-4.f * grad.x(), -4.f * grad.y(), 16.f).normalized();
    const Bsdf diffuse(DiffuseBsdf{Rgb(0.8f, 0.6f, 0.4f)});
    const Bsdf bumped = Bsdf::bump_map(RgbTexture(TextureModel(height)), 0.3f, diffuse);
    const Bsdf mapped = Bsdf::normal_map(RgbTexture(Rgb(0.5f * (n.array() + 1.f))), diffuse);
    Pcg32 rng(12, 1);
    for (int i = 0; i < 200; ++i) {
        const Vec3f wo = warp::square_to_uniform_sphere({rng.next_float(), rng.next_float()});
        const Vec3f wi = warp::square_to_uniform_sphere({rng.next_float(), rng.next_float()});
        for (const TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
            const Rgb a = bumped.eval(si.texture_point(), wo, wi, mode);
            const Rgb b = mapped.eval(si.texture_point(), wo, wi, mode);
            for (int c = 0; c < 3; ++c) ASSERT_NEAR(a[c], b[c], 1e-5f) << i;
        }
        ASSERT_NEAR(bumped.pdf(si.texture_point(), wo, wi), mapped.pdf(si.texture_point(), wo, wi),
                    1e-5f);
    }
    // Without the surface (a bare uv) the frame is the shading frame: the nested BSDF's value
    // with the terminator term of an unperturbed normal (1).
    const Vec3f up(0.f, 0.f, 1.f), tilted = Vec3f(0.3f, 0.f, 1.f).normalized();
    EXPECT_NEAR(bumped.eval(si.uv, up, tilted)[0], diffuse.eval(si.uv, up, tilted)[0], 1e-6f);
}

TEST(Bsdf, NoNanOrInfForDegenerateDirections) {
    std::vector<Bsdf> bsdfs = {
        Bsdf(DiffuseBsdf{Rgb::Constant(0.5f)}),
        Bsdf(DielectricBsdf{1.5f, Rgb::Ones(), Rgb::Ones()}),
        Bsdf(DielectricBsdf{1.0001f, Rgb::Ones(), Rgb::Ones()}),
        Bsdf(DielectricBsdf{1.f / 1.5f, Rgb::Ones(), Rgb::Ones()}),
        Bsdf(ThinDielectricBsdf{1.5f, Rgb::Ones(), Rgb::Ones()}),
        Bsdf(ConductorBsdf{Rgb(0.2f, 0.9f, 1.1f), Rgb(3.9f, 2.4f, 2.1f), false, Rgb::Ones()}),
        Bsdf::two_sided(DiffuseBsdf{Rgb::Constant(0.5f)}, std::nullopt),
        Bsdf::mask(0.5f, Bsdf(DielectricBsdf{1.5f, Rgb::Ones(), Rgb::Ones()})),
        Bsdf::blend(0.5f, Bsdf(DiffuseBsdf{Rgb::Constant(0.5f)}), Bsdf(ConductorBsdf{})),
        Bsdf::null()};
    const std::vector<Vec3f> directions = {
        Vec3f::UnitZ(),        -Vec3f::UnitZ(),        Vec3f::UnitX(),
        direction_at(89.999f), -direction_at(89.999f), Vec3f(1.f, 0.f, 1e-30f).normalized(),
        Vec3f(0.f, 1.f, -0.f)};
    for (const Bsdf& b : bsdfs)
        for (const Vec3f& wo : directions) {
            for (const Vec3f& wi : directions) {
                EXPECT_TRUE(is_finite(b.eval(kUv, wo, wi)));
                EXPECT_TRUE(std::isfinite(b.pdf(kUv, wo, wi)));
            }
            for (float u : {0.f, 0.5f, 0x1.fffffep-1f}) {
                const BsdfSample s = b.sample(kUv, wo, u, {u, 1.f - u});
                EXPECT_TRUE(is_finite(s.weight));
                EXPECT_TRUE(s.wi.allFinite());
                EXPECT_TRUE(std::isfinite(s.pdf_solid_angle));
            }
        }
}

TEST(Bsdf, ReportsItsRoughnessClass) {
    EXPECT_EQ(Bsdf(DiffuseBsdf{}).roughness_class(), RoughnessClass::Diffuse);
    EXPECT_EQ(Bsdf(DielectricBsdf{}).roughness_class(), RoughnessClass::Delta);
    EXPECT_EQ(Bsdf(ConductorBsdf{}).roughness_class(), RoughnessClass::Delta);
    EXPECT_EQ(classify_alpha(5e-4f), RoughnessClass::Delta);
    EXPECT_EQ(classify_alpha(0.1f), RoughnessClass::Glossy);
    EXPECT_EQ(classify_alpha(0.5f), RoughnessClass::Diffuse);
}

TEST(Frame, IsOrthonormalForAnyNormal) {
    Pcg32 rng(4, 4);
    for (int i = 0; i < 1000; ++i) {
        Vec3f n(rng.next_float() - 0.5f, rng.next_float() - 0.5f, rng.next_float() - 0.5f);
        if (i == 0) n = -Vec3f::UnitZ();
        n.normalize();
        const Frame f = Frame::from_normal(n);
        EXPECT_NEAR(f.s.dot(f.t), 0.f, 1e-5f);
        EXPECT_NEAR(f.s.dot(f.n), 0.f, 1e-5f);
        EXPECT_NEAR(f.s.norm(), 1.f, 1e-5f);
        EXPECT_NEAR(f.t.norm(), 1.f, 1e-5f);
        const Vec3f v(0.3f, -0.2f, 0.9f);
        EXPECT_NEAR((f.to_world(f.to_local(v)) - v).norm(), 0.f, 1e-5f);
    }
}

TEST(Conductor, EveryMaterialOfMitsuba3IsKnownAndPhysical) {
    // Mitsuba 3's conductor plugin documents these names (its material table): each must be
    // known, with finite non-negative eta and k, and a normal-incidence reflectance
    // ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2) in [0, 1] per channel.
    const std::vector<std::string> names = {
        "a-C",        "Ag",         "Al",        "AlAs",         "AlAs_palik",
        "AlSb",       "AlSb_palik", "Au",        "Be",           "Be_palik",
        "Cr",         "CsI",        "CsI_palik", "Cu",           "Cu2O",
        "Cu2O_palik", "Cu_palik",   "CuO",       "CuO_palik",    "d-C",
        "d-C_palik",  "Hg",         "Hg_palik",  "HgTe",         "HgTe_palik",
        "Ir",         "Ir_palik",   "K",         "K_palik",      "Li",
        "Li_palik",   "MgO",        "MgO_palik", "Mo",           "Mo_palik",
        "Na_palik",   "Nb",         "Nb_palik",  "Ni_palik",     "Rh",
        "Rh_palik",   "Se",         "Se-e",      "Se-e_palik",   "Se_palik",
        "SiC",        "SiC_palik",  "SnTe",      "SnTe_palik",   "Ta",
        "Ta_palik",   "Te",         "Te-e",      "Te-e_palik",   "Te_palik",
        "ThF4",       "ThF4_palik", "TiC",       "TiC_palik",    "TiN",
        "TiN_palik",  "TiO2",       "TiO2-e",    "TiO2-e_palik", "TiO2_palik",
        "V_palik",    "VC",         "VC_palik",  "VN",           "VN_palik",
        "W"};
    for (const std::string& name : names) {
        const auto ior = lookup_conductor(name);
        ASSERT_TRUE(ior.has_value()) << name;
        for (int c = 0; c < 3; ++c) {
            const float eta = ior->eta[c], k = ior->k[c];
            EXPECT_TRUE(std::isfinite(eta) && eta >= 0.f) << name << " eta " << eta;
            EXPECT_TRUE(std::isfinite(k) && k >= 0.f) << name << " k " << k;
            const float r =
                ((eta - 1.f) * (eta - 1.f) + k * k) / ((eta + 1.f) * (eta + 1.f) + k * k);
            EXPECT_TRUE(r >= 0.f && r <= 1.f) << name << " reflectance " << r;
        }
    }
    EXPECT_FALSE(lookup_conductor("unobtainium").has_value());
    EXPECT_NE(conductor_names().find("a-C"), std::string::npos);
}

}  // namespace
}  // namespace gdmlt
