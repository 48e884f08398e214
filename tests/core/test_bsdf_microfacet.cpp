// SPDX-License-Identifier: GPL-3.0-or-later
// Rough conductor, rough dielectric, plastic and rough plastic: sample() against pdf()
// (chi-square, over roughness, incident angle and IOR grids), sample weights against eval/pdf,
// Helmholtz reciprocity, the refraction scaling law, energy conservation (white furnace), and
// finiteness on degenerate inputs.
//
// Chi-square tests: each TEST runs a list of cases, every case at the Sidak-corrected level of
// tests/support/chi2.h for all cases of the file (1% false alarms for the whole file), 50000
// samples per case from the fixed seed 1. Narrow and grazing lobes are tested in the space of half
// vectors, magnified about the normal (HemisphereZoom) with exact Jacobians, so alpha = 0.001
// lobes are tested at the bins' resolution rather than falling into one bin.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <vector>

#include "core/bsdf/bsdf.h"
#include "core/bsdf/fresnel.h"
#include "core/bsdf/microfacet.h"
#include "core/math/frame.h"
#include "core/sampling/rng.h"
#include "tests/support/chi2.h"

namespace gdmlt {
namespace {

const Vec2f kUv(0.25f, 0.5f);

Vec3f direction_at(float theta_deg, float phi_deg = 30.f) {
    const float theta = degrees_to_radians(theta_deg), phi = degrees_to_radians(phi_deg);
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// --- Chi-square machinery ---------------------------------------------------------------------

/// Which scattered directions a test looks at. Restricting to one side tests that lobe's shape
/// *and* its probability: samples elsewhere count as failures and the pdf is zero there, so the
/// failed-sample bin must match 1 - P(lobe).
enum class Lobe { All, Reflection, Transmission };

/// Maps the upper hemisphere of half vectors onto the cap theta' <= theta_max of the sphere,
/// cos(theta_max) = -0.9, after stretching slopes by 1 / alpha (the map under which an
/// anisotropic microfacet lobe becomes the alpha = 1 one, Heitz 2014, Sec. 5.3). Every lobe then
/// spans a good part of the sphere whatever its alpha, and the hemisphere's edge (where the
/// density drops to zero) lands on the z = -0.9 edge of the chi-square bins, so no bin
/// straddles it.
///  - stretch: slope (x, y) -> (x / alpha_u, y / alpha_v); d omega = cos^3(theta) d slope, so
///    d omega / d omega_s = alpha_u alpha_v cos^3(theta) / cos^3(theta_s);
///  - cap: with u = tan(theta_s / 2) in [0, 1] and u' = tan(theta'/2) in [0, U], u' = U u /
///    (U - (U - 1) u), azimuth kept; the area element is 4 u du dphi / (1 + u^2)^2, so
///    d omega_s / d omega' = (u / u') (du / du') ((1 + u'^2) / (1 + u^2))^2.
class HalfVectorMap {
  public:
    HalfVectorMap(double alpha_u, double alpha_v) : au_(alpha_u), av_(alpha_v) {}
    Vec3f forward(const Vec3f& h) const {
        const Vec3d s = Vec3d(h.x() / au_, h.y() / av_, h.z()).normalized();
        const double r = std::hypot(s.x(), s.y());
        const double u = r / (1.0 + s.z());
        const double up = kU * u / (kU - (kU - 1.0) * u);
        return from_tan_half(s.x(), s.y(), r, up).cast<float>();
    }
    /// The half vector of a mapped direction and d omega_h / d omega'; nullopt outside the cap.
    std::optional<Vec3f> inverse(const Vec3f& w, double* jacobian) const {
        const Vec3d wd = w.cast<double>();
        if (!(wd.z() > -0.9)) return std::nullopt;
        const double r = std::hypot(wd.x(), wd.y());
        double u = 0.0, cap_jacobian = 1.0 / (kU * kU);
        if (r > 0.0) {
            const double up = r / (1.0 + wd.z());
            u = kU * up / (kU + (kU - 1.0) * up);
            const double du_dup = kU * kU / sqr(kU + (kU - 1.0) * up);
            cap_jacobian = (u / up) * du_dup * sqr((1.0 + up * up) / (1.0 + u * u));
        }
        const Vec3d s = r > 0.0 ? from_tan_half(wd.x(), wd.y(), r, u) : Vec3d::UnitZ();
        const Vec3d h = Vec3d(s.x() * au_, s.y() * av_, s.z()).normalized();
        const double stretch_jacobian = au_ * av_ * std::pow(h.z(), 3) / std::pow(s.z(), 3);
        *jacobian = cap_jacobian * stretch_jacobian;
        return h.cast<float>();
    }

  private:
    static Vec3d from_tan_half(double x, double y, double r, double t) {
        const double z = (1.0 - t * t) / (1.0 + t * t), sn = 2.0 * t / (1.0 + t * t);
        return {x / r * sn, y / r * sn, z};
    }
    // tan(theta_max / 2) with cos(theta_max) = -0.9: sqrt((1 - c) / (1 + c)) = sqrt(19).
    static constexpr double kU = 4.358898943540674;
    double au_, av_;
};

struct Chi2Case {
    std::string name;
    Bsdf bsdf;
    Vec3f wo;
    Lobe lobe = Lobe::All;
    float alpha_u = 1.f, alpha_v = 1.f;  // the stretch of the half-vector domain
    /// Test in the space of (generalised) half vectors instead of directions: see run_chi2.
    bool half_vector = false;
    float interface_eta = 1.f;  // int/ext of a dielectric, for the refraction half vector
};

/// The chi-square test of one case.
///
/// Direction space: scattered directions, optionally magnified about the lobe's peak.
///
/// Half-vector space: each sampled wi is mapped to its half vector h (wo + wi for reflection,
/// wo + eta_rel wi for refraction, Walter et al. 2007 eq. 16, turned to +z), and the density
/// claimed by pdf() is carried over with the Jacobian computed here: |d omega_i / d omega_h| =
/// 4 |wi.h| for reflection (Walter eq. 14) and (wo.h + eta_rel wi.h)^2 / (eta_rel^2 |wi.h|) for
/// refraction (eq. 17). This is the domain where narrow and grazing lobes are well shaped:
/// at 89.9 degrees a reflected lobe is an arc ~alpha cos(theta_o) thin in direction space,
/// which no bin grid resolves, but an ordinary alpha-wide cap of half vectors.
test::Chi2Result run_chi2(const Chi2Case& c) {
    test::Chi2Settings settings;
    // 50000 samples in 16 x 32 bins: every lobe spreads over many bins in its domain, so this
    // keeps the power to see a few-percent error while the whole file runs in seconds. The
    // expected counts are integrated more finely than the default, because lobes are cut by
    // the surface, by visibility and by total internal reflection along curves across bins.
    settings.samples = 50000;
    settings.z_bins = 16;
    settings.phi_bins = 32;
    settings.sub_samples = c.half_vector ? 16 : 32;  // half-vector lobes are smooth and round
    const auto keep = [&](const Vec3f& wi) {
        if (c.lobe == Lobe::Reflection) return wi.z() * c.wo.z() > 0.f;
        if (c.lobe == Lobe::Transmission) return wi.z() * c.wo.z() < 0.f;
        return true;
    };
    if (c.half_vector) {
        const HalfVectorMap map(std::max(c.alpha_u, kMinMicrofacetAlpha),
                                std::max(c.alpha_v, kMinMicrofacetAlpha));
        const float eta_rel = c.wo.z() > 0.f ? c.interface_eta : 1.f / c.interface_eta;
        const auto half_vector = [&](const Vec3f& wi) -> Vec3f {
            const bool reflection = wi.z() * c.wo.z() > 0.f;
            Vec3d h = reflection ? Vec3d(c.wo.cast<double>() + wi.cast<double>())
                                 : Vec3d(c.wo.cast<double>() + eta_rel * wi.cast<double>());
            h.normalize();
            if (h.z() < 0.0) h = -h;
            return h.cast<float>();
        };
        // The direction whose half vector is h on the tested lobe, and |d omega_i / d omega_h|.
        const auto direction = [&](const Vec3f& h, double* jacobian) -> std::optional<Vec3f> {
            const float wo_h = c.wo.dot(h);
            if (!(h.z() > 0.f) || !(wo_h * c.wo.z() > 0.f)) return std::nullopt;
            if (c.lobe != Lobe::Transmission) {
                const Vec3f wi = 2.f * wo_h * h - c.wo;
                *jacobian = 4.0 * std::abs(static_cast<double>(wi.dot(h)));
                return wi;
            }
            const FresnelDielectric f = fresnel_dielectric(wo_h, c.interface_eta);
            if (f.reflectance >= 1.f) return std::nullopt;
            const Vec3f wi =
                (-f.eta_ti * c.wo + (f.eta_ti * wo_h + f.cos_theta_t) * h).normalized();
            const double wi_h = wi.dot(h), denom = wo_h + f.eta_it * wi_h;
            *jacobian = denom * denom / (static_cast<double>(f.eta_it) * f.eta_it * std::abs(wi_h));
            return wi;
        };
        return test::chi2_sphere_test(
            [&](Pcg32& rng) -> std::optional<Vec3f> {
                const float u_lobe = rng.next_float();
                const Vec2f u(rng.next_float(), rng.next_float());
                const BsdfSample s = c.bsdf.sample(kUv, c.wo, u_lobe, u);
                if (!s.valid() || s.delta || !keep(s.wi)) return std::nullopt;
                return map.forward(half_vector(s.wi));
            },
            [&](const Vec3f& h_zoomed) {
                double zoom_jacobian = 0.0, jacobian = 0.0;
                const std::optional<Vec3f> h = map.inverse(h_zoomed, &zoom_jacobian);
                if (!h) return 0.0;
                const std::optional<Vec3f> wi = direction(*h, &jacobian);
                if (!wi || !keep(*wi)) return 0.0;
                return static_cast<double>(c.bsdf.pdf(kUv, c.wo, *wi)) * jacobian * zoom_jacobian;
            },
            settings);
    }
    return test::chi2_sphere_test(
        [&](Pcg32& rng) -> std::optional<Vec3f> {
            const float u_lobe = rng.next_float();
            const Vec2f u(rng.next_float(), rng.next_float());
            const BsdfSample s = c.bsdf.sample(kUv, c.wo, u_lobe, u);
            // Delta samples are not in pdf(): they count as failures.
            if (!s.valid() || s.delta || !keep(s.wi)) return std::nullopt;
            return s.wi;
        },
        [&](const Vec3f& wi) {
            return keep(wi) ? static_cast<double>(c.bsdf.pdf(kUv, c.wo, wi)) : 0.0;
        },
        settings);
}

/// Upper bound on the number of chi-square cases in this file: each is run at the Sidak level
/// for this many tests, so the whole file has at most a 1% chance of a false alarm.
constexpr int kChi2CasesInFile = 250;

void expect_all_pass(const std::vector<Chi2Case>& cases) {
    const double alpha = test::sidak_alpha(kChi2CasesInFile);
    for (const Chi2Case& c : cases) {
        const test::Chi2Result r = run_chi2(c);
        EXPECT_GT(r.p_value, alpha) << c.name << ": " << r.summary;
    }
}

/// A case in the domain where its lobe is resolved: half vectors, stretched by the lobe's
/// alphas, for narrow (alpha < 0.3) or anisotropic lobes and for refraction; plain directions
/// otherwise, which also checks the Jacobians of pdf() independently of the test's own.
/// Grazing reflection is tested in direction space, where the horizon is a bin edge.
Chi2Case make_case(std::string name, Bsdf bsdf, const Vec3f& wo, Lobe lobe, float alpha_u,
                   float alpha_v, float theta_deg, float interface_eta = 1.f) {
    Chi2Case c{std::move(name), std::move(bsdf), wo, lobe};
    // Refraction always goes to half vectors: there the density's jump where the refraction
    // half vector turns over (h.z = 0) is the domain's edge, a bin edge.
    c.half_vector =
        (std::min(alpha_u, alpha_v) < 0.3f && theta_deg <= 85.f) || lobe == Lobe::Transmission;
    c.alpha_u = alpha_u;
    c.alpha_v = alpha_v;
    c.interface_eta = interface_eta;
    return c;
}

/// Incident angles per alpha. At 89.9 degrees a reflected lobe is an arc ~2 alpha cos(theta_o)
/// thin in direction space: 3.5e-6 rad at alpha = 0.001, ~60 float ulps of a unit vector, so
/// a stored wi no longer determines its half vector to within the lobe width; and the chi-square
/// grid cannot resolve such arcs at all (nor, in half-vector space, the visibility and horizon
/// cuts that then pass within a fraction of alpha of the peak). Narrow lobes are therefore
/// checked at 85 degrees and the 89.9-degree case at alpha >= 0.3, in direction space where the
/// horizon is a bin edge.
std::vector<float> thetas_for(float alpha) {
    if (alpha < 0.3f) return {0.f, 45.f, 85.f};
    return {0.f, 45.f, 89.9f};
}

MicrofacetRoughness roughness(MicrofacetType type, float alpha_u, float alpha_v,
                              bool visible = true) {
    MicrofacetRoughness r;
    r.type = type;
    r.alpha_u = alpha_u;
    r.alpha_v = alpha_v;
    r.sample_visible = visible;
    return r;
}

const char* type_name(MicrofacetType t) {
    return t == MicrofacetType::Ggx ? "ggx" : "beckmann";
}

std::string describe(const char* bsdf, MicrofacetType t, float au, float av, float theta,
                     float eta = 0.f) {
    std::ostringstream s;
    s << bsdf << " " << type_name(t) << " alpha=(" << au << "," << av << ") theta_o=" << theta;
    if (eta > 0.f) s << " eta=" << eta;
    return s.str();
}

Bsdf rough_conductor(MicrofacetType t, float au, float av, bool visible = true) {
    return Bsdf(RoughConductorBsdf{roughness(t, au, av, visible), Rgb(0.2f, 0.9f, 1.1f),
                                   Rgb(3.9f, 2.4f, 2.1f), false, Rgb::Ones()});
}
Bsdf rough_dielectric(MicrofacetType t, float au, float av, float eta, bool visible = true) {
    return Bsdf(RoughDielectricBsdf{roughness(t, au, av, visible), eta, Rgb::Ones(), Rgb::Ones()});
}

std::vector<Chi2Case> conductor_cases(MicrofacetType type, std::initializer_list<float> alphas) {
    std::vector<Chi2Case> cases;
    for (float alpha : alphas)
        for (float theta : thetas_for(alpha)) {
            const Vec3f wo = direction_at(theta);
            cases.push_back(make_case(describe("roughconductor", type, alpha, alpha, theta),
                                      rough_conductor(type, alpha, alpha), wo, Lobe::All, alpha,
                                      alpha, theta));
        }
    return cases;
}

std::vector<Chi2Case> anisotropic_conductor_cases(MicrofacetType type) {
    std::vector<Chi2Case> cases;
    // Anisotropic lobes, stretched back to round in the half-vector domain.
    for (const auto& [au, av] : {std::pair{0.05f, 0.4f}, std::pair{0.3f, 0.01f}})
        for (float theta : {30.f, 60.f}) {
            const Vec3f wo = direction_at(theta, 70.f);
            cases.push_back(make_case(describe("roughconductor", type, au, av, theta),
                                      rough_conductor(type, au, av), wo, Lobe::All, au, av, theta));
        }
    // Sampling all normals instead of the visible ones (sample_visible = false).
    for (float theta : {20.f, 70.f}) {
        const Vec3f wo = direction_at(theta);
        cases.push_back(make_case(describe("roughconductor(all normals)", type, 0.2f, 0.2f, theta),
                                  rough_conductor(type, 0.2f, 0.2f, false), wo, Lobe::All, 0.2f,
                                  0.2f, theta));
    }
    return cases;
}

TEST(RoughConductorBsdf, GgxSamplesMatchPdfForNarrowLobes) {
    expect_all_pass(conductor_cases(MicrofacetType::Ggx, {0.001f, 0.01f, 0.05f}));
}
TEST(RoughConductorBsdf, GgxSamplesMatchPdfForBroadLobesUpToGrazing) {
    expect_all_pass(conductor_cases(MicrofacetType::Ggx, {0.3f, 1.f}));
}
TEST(RoughConductorBsdf, GgxSamplesMatchPdfWhenAnisotropicOrSamplingAllNormals) {
    expect_all_pass(anisotropic_conductor_cases(MicrofacetType::Ggx));
}
TEST(RoughConductorBsdf, BeckmannSamplesMatchPdfForNarrowLobes) {
    expect_all_pass(conductor_cases(MicrofacetType::Beckmann, {0.001f, 0.01f, 0.05f}));
}
TEST(RoughConductorBsdf, BeckmannSamplesMatchPdfForBroadLobesUpToGrazing) {
    expect_all_pass(conductor_cases(MicrofacetType::Beckmann, {0.3f, 1.f}));
}
TEST(RoughConductorBsdf, BeckmannSamplesMatchPdfWhenAnisotropicOrSamplingAllNormals) {
    expect_all_pass(anisotropic_conductor_cases(MicrofacetType::Beckmann));
}

/// Both lobes of a rough dielectric, each tested on its own, from outside (wo above) and
/// inside (wo below).
std::vector<Chi2Case> dielectric_cases(MicrofacetType type, float eta,
                                       std::initializer_list<float> alphas,
                                       std::initializer_list<float> thetas_wanted) {
    std::vector<Chi2Case> cases;
    for (float alpha : alphas)
        for (float theta_wanted : thetas_wanted)
            for (bool inside : {false, true}) {
                // See thetas_for: 89.9 degrees becomes 85 for narrow lobes.
                const float theta = alpha < 0.3f && theta_wanted > 85.f ? 85.f : theta_wanted;
                const Vec3f wo = inside ? Vec3f(-direction_at(theta)) : direction_at(theta);
                const Bsdf b = rough_dielectric(type, alpha, alpha, eta);
                const std::string name =
                    describe("roughdielectric", type, alpha, alpha, theta, eta) +
                    (inside ? " inside" : " outside");
                cases.push_back(make_case(name + " reflection", b, wo, Lobe::Reflection, alpha,
                                          alpha, theta, eta));
                const FresnelDielectric f = fresnel_dielectric(wo.z(), eta);
                // Under total internal reflection there is no refraction lobe. A nearly
                // index-matched interface refracts into a lobe only alpha |eta - 1| wide, which
                // float directions cannot resolve (the half vector wo + eta wi cancels to a few
                // digits); it is checked by NearlyIndexMatchedInterfaceTransmitsStraightThrough.
                if (f.reflectance < 1.f && std::abs(eta - 1.f) > 1e-3f)
                    cases.push_back(make_case(name + " transmission", b, wo, Lobe::Transmission,
                                              alpha, alpha, theta, eta));
            }
    return cases;
}

TEST(RoughDielectricBsdf, GgxSamplesMatchPdfForNarrowLobes) {
    expect_all_pass(
        dielectric_cases(MicrofacetType::Ggx, 1.5f, {0.001f, 0.1f}, {0.f, 45.f, 89.9f}));
}
TEST(RoughDielectricBsdf, GgxSamplesMatchPdfForBroadLobesUpToGrazing) {
    expect_all_pass(dielectric_cases(MicrofacetType::Ggx, 1.5f, {1.f}, {0.f, 45.f, 89.9f}));
}
TEST(RoughDielectricBsdf, BeckmannSamplesMatchPdfForNearlySmoothLobes) {
    expect_all_pass(dielectric_cases(MicrofacetType::Beckmann, 1.5f, {0.001f}, {0.f, 45.f, 89.9f}));
}
TEST(RoughDielectricBsdf, BeckmannSamplesMatchPdfForNarrowLobes) {
    expect_all_pass(dielectric_cases(MicrofacetType::Beckmann, 1.5f, {0.1f}, {0.f, 45.f, 89.9f}));
}
TEST(RoughDielectricBsdf, BeckmannSamplesMatchPdfForBroadLobesUpToGrazing) {
    expect_all_pass(dielectric_cases(MicrofacetType::Beckmann, 1.5f, {1.f}, {0.f, 45.f, 89.9f}));
}
TEST(RoughDielectricBsdf, SamplesMatchPdfForNearlyMatchedIor) {
    auto cases = dielectric_cases(MicrofacetType::Ggx, 1.0001f, {0.001f, 0.3f, 1.f}, {30.f, 89.9f});
    auto more = dielectric_cases(MicrofacetType::Beckmann, 1.0001f, {0.001f, 1.f}, {30.f, 89.9f});
    cases.insert(cases.end(), more.begin(), more.end());
    expect_all_pass(cases);
}
TEST(RoughDielectricBsdf, GgxSamplesMatchPdfForInverseIor) {
    expect_all_pass(
        dielectric_cases(MicrofacetType::Ggx, 1.f / 1.5f, {0.001f, 0.3f, 1.f}, {30.f, 89.9f}));
}
TEST(RoughDielectricBsdf, BeckmannSamplesMatchPdfForInverseIor) {
    expect_all_pass(
        dielectric_cases(MicrofacetType::Beckmann, 1.f / 1.5f, {0.001f, 1.f}, {30.f, 89.9f}));
}
TEST(RoughDielectricBsdf, SamplesMatchPdfWhenAnisotropicOrSamplingAllNormals) {
    std::vector<Chi2Case> cases;
    const Vec3f wo = direction_at(50.f, 120.f);
    // One refraction lobe in direction space, so that the refraction Jacobian of pdf() is also
    // checked against plain sampled directions, not only against the test's own Jacobian.
    Chi2Case direct = make_case("roughdielectric ggx alpha=1 transmission in direction space",
                                rough_dielectric(MicrofacetType::Ggx, 1.f, 1.f, 1.5f), wo,
                                Lobe::Transmission, 1.f, 1.f, 50.f, 1.5f);
    direct.half_vector = false;
    cases.push_back(direct);
    cases.push_back(make_case("roughdielectric ggx anisotropic (0.05, 0.5) transmission",
                              rough_dielectric(MicrofacetType::Ggx, 0.05f, 0.5f, 1.5f), wo,
                              Lobe::Transmission, 0.05f, 0.5f, 50.f, 1.5f));
    cases.push_back(make_case("roughdielectric beckmann all normals reflection",
                              rough_dielectric(MicrofacetType::Beckmann, 0.2f, 0.2f, 1.5f, false),
                              wo, Lobe::Reflection, 0.2f, 0.2f, 50.f, 1.5f));
    cases.push_back(make_case("roughdielectric beckmann all normals transmission",
                              rough_dielectric(MicrofacetType::Beckmann, 0.2f, 0.2f, 1.5f, false),
                              wo, Lobe::Transmission, 0.2f, 0.2f, 50.f, 1.5f));
    expect_all_pass(cases);
}

TEST(RoughDielectricBsdf, NearlyIndexMatchedInterfaceTransmitsStraightThrough) {
    // eta = 1.0001: reflection is ~1e-9 likely and refraction bends by at most sqrt(2 (eta - 1))
    // = 0.014 rad (on facets seen at grazing incidence, ~1e-4 rad on typical ones), so every
    // sample continues along -wo, with weight at most 1 (radiance scaled by 1/eta^2).
    for (MicrofacetType type : {MicrofacetType::Ggx, MicrofacetType::Beckmann})
        for (float alpha : {0.001f, 0.3f, 1.f})
            for (float theta : {0.f, 30.f, 80.f}) {
                const Bsdf b = rough_dielectric(type, alpha, alpha, 1.0001f);
                Pcg32 rng(41, 1);
                int transmitted = 0, valid = 0;
                for (int i = 0; i < 2000; ++i) {
                    const Vec3f wo = direction_at(theta, 360.f * rng.next_float());
                    const BsdfSample s =
                        b.sample(kUv, wo, rng.next_float(), {rng.next_float(), rng.next_float()});
                    if (!s.valid()) continue;
                    ++valid;
                    if (!s.transmission) continue;
                    ++transmitted;
                    EXPECT_LT((s.wi + wo).norm(), 2e-2f) << type_name(type) << " alpha " << alpha;
                    EXPECT_LE(s.weight[0], 1.f);
                    EXPECT_GT(s.weight[0], 0.f);
                }
                EXPECT_EQ(transmitted, valid)
                    << type_name(type) << " alpha " << alpha << " theta " << theta;
                EXPECT_GT(valid, 1500);
            }
}

TEST(PlasticBsdf, DiffuseSamplesMatchPdfAndMirrorSamplesHaveTheRestOfTheProbability) {
    // Delta (coat) samples count as failures: their expected share is 1 - int pdf, which is
    // the probability of choosing the coat's mirror lobe.
    std::vector<Chi2Case> cases;
    for (float eta : {1.49f, 1.0001f, 1.f / 1.5f})
        for (float theta : {0.f, 45.f, 89.9f})
            cases.push_back(
                {"plastic eta=" + std::to_string(eta) + " theta=" + std::to_string(theta),
                 Bsdf(make_plastic(eta, Rgb(0.3f, 0.5f, 0.7f), Rgb::Ones(), false)),
                 direction_at(theta)});
    expect_all_pass(cases);
}

std::vector<Chi2Case> rough_plastic_cases(MicrofacetType type) {
    // The coat lobe is tested down to alpha = 0.1 here: below that its half-vector domain
    // would squeeze the diffuse base into a sliver (and direction space cannot resolve the
    // coat); the coat's sampling is the rough conductor's microfacet code, tested to 0.001.
    std::vector<Chi2Case> cases;
    for (float alpha : {0.1f, 0.6f})
        for (float theta : thetas_for(alpha)) {
            const Vec3f wo = direction_at(theta);
            cases.push_back(
                make_case(describe("roughplastic", type, alpha, alpha, theta),
                          Bsdf(make_rough_plastic(type, alpha, true, 1.5f, Rgb(0.4f, 0.5f, 0.6f),
                                                  Rgb::Ones(), false)),
                          wo, Lobe::All, alpha, alpha, theta));
        }
    return cases;
}

TEST(RoughPlasticBsdf, GgxSamplesMatchPdf) {
    expect_all_pass(rough_plastic_cases(MicrofacetType::Ggx));
}
TEST(RoughPlasticBsdf, BeckmannSamplesMatchPdf) {
    expect_all_pass(rough_plastic_cases(MicrofacetType::Beckmann));
}

// --- Mask and blend (Mitsuba's mask and blendbsdf)
// ------------------------------------------------

TEST(MaskBsdf, NestedSamplesMatchPdfAndTheNullLobeHasTheRestOfTheProbability) {
    // The null lobe is a delta: as a plastic's coat, its samples count as failures, expected
    // with probability 1 - int pdf = 1 - opacity int pdf_nested. An opacity left out of pdf()
    // or of the sample's choice fails both the shape and that share.
    std::vector<Chi2Case> cases;
    for (float theta : {0.f, 60.f}) {
        cases.push_back(
            make_case(describe("mask(0.35) roughconductor", MicrofacetType::Ggx, 0.3f, 0.3f, theta),
                      Bsdf::mask(0.35f, rough_conductor(MicrofacetType::Ggx, 0.3f, 0.3f)),
                      direction_at(theta), Lobe::All, 0.3f, 0.3f, theta));
        cases.push_back(
            {"mask(0.7) plastic theta=" + std::to_string(theta),
             Bsdf::mask(0.7f, Bsdf(make_plastic(1.49f, Rgb(0.3f, 0.5f, 0.7f), Rgb::Ones(), false))),
             direction_at(theta)});
    }
    expect_all_pass(cases);
}

TEST(BlendBsdf, SamplesMatchTheMixturePdf) {
    // Two broad lobes (direction space resolves them); and a diffuse blended with a mirror,
    // whose delta share 0.6 is checked as the failed-sample bin.
    std::vector<Chi2Case> cases;
    for (float theta : {0.f, 45.f, 80.f}) {
        cases.push_back(
            {"blend(0.3, roughplastic, roughconductor) theta=" + std::to_string(theta),
             Bsdf::blend(0.3f,
                         Bsdf(make_rough_plastic(MicrofacetType::Ggx, 0.4f, true, 1.5f,
                                                 Rgb(0.4f, 0.5f, 0.6f), Rgb::Ones(), false)),
                         rough_conductor(MicrofacetType::Beckmann, 0.5f, 0.5f)),
             direction_at(theta)});
        cases.push_back(
            {"blend(0.6, diffuse, conductor) theta=" + std::to_string(theta),
             Bsdf::blend(0.6f, Bsdf(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)}), Bsdf(ConductorBsdf{})),
             direction_at(theta)});
    }
    expect_all_pass(cases);
}

TEST(NormalMapBsdf, SamplesMatchPdfInTheTiltedFrame) {
    // A constant normal tilted by ~35 degrees (rgb (0.8, 0.35, 0.85) -> n = (0.6, -0.3, 0.7)):
    // directions drawn in the tilted frame and dropped where they cross the shading frame's
    // horizon, against pdf() (the dropped share is the failed-sample bin).
    std::vector<Chi2Case> cases;
    for (float theta : {0.f, 50.f, 80.f}) {
        cases.push_back(
            {"normalmap(roughplastic) theta=" + std::to_string(theta),
             Bsdf::normal_map(Rgb(0.8f, 0.35f, 0.85f),
                              Bsdf(make_rough_plastic(MicrofacetType::Ggx, 0.4f, true, 1.5f,
                                                      Rgb(0.4f, 0.5f, 0.6f), Rgb::Ones(), false))),
             direction_at(theta, 200.f)});
        cases.push_back(
            {"normalmap(diffuse) theta=" + std::to_string(theta),
             Bsdf::normal_map(Rgb(0.8f, 0.35f, 0.85f), Bsdf(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)})),
             direction_at(theta, 20.f)});
    }
    expect_all_pass(cases);
}

/// Normal-mapped BSDFs with a steep normal, for the adjoint and weight tests.
std::vector<std::pair<std::string, Bsdf>> normal_mapped_bsdfs() {
    const Rgb normal(0.85f, 0.3f, 0.75f);  // n ~ (0.7, -0.4, 0.5): flips at grazing views
    return {
        {"normalmap(diffuse)", Bsdf::normal_map(normal, Bsdf(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)}))},
        {"normalmap(roughconductor)",
         Bsdf::normal_map(normal, rough_conductor(MicrofacetType::Ggx, 0.3f, 0.1f))},
        {"normalmap(roughdielectric)",
         Bsdf::normal_map(normal, rough_dielectric(MicrofacetType::Beckmann, 0.3f, 0.3f, 1.5f))},
        {"normalmap(diffuse), no flip, no shadowing",
         Bsdf::normal_map(normal, Bsdf(DiffuseBsdf{Rgb(0.5f, 0.6f, 0.7f)}), false, false)}};
}

TEST(NormalMapBsdf, ImportanceModeIsTheAdjointOfRadianceMode) {
    // Light tracing and BDPT see the normal-mapped BSDF through its Importance mode: it must be
    // the adjoint (Veach 1997, eq. 3.18), eval_I(wi, wo) / |cos wo| = eval_R(wo, wi) / |cos wi|,
    // with the frame decided by the camera-side direction in both. Relative 1e-4 (float).
    for (const auto& [name, bsdf] : normal_mapped_bsdfs()) {
        Pcg32 rng(23, 4);
        int nonzero = 0;
        for (int i = 0; i < 3000; ++i) {
            Vec3f wo = direction_at(89.f * rng.next_float(), 360.f * rng.next_float());
            Vec3f wi = direction_at(89.f * rng.next_float(), 360.f * rng.next_float());
            if (bsdf.has_transmission() && rng.next_float() < 0.5f) wi = -wi;
            const Rgb radiance = bsdf.eval(kUv, wo, wi, TransportMode::Radiance) / std::abs(wi.z());
            const Rgb importance =
                bsdf.eval(kUv, wi, wo, TransportMode::Importance) / std::abs(wo.z());
            nonzero += radiance[0] > 0.f ? 1 : 0;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(importance[c], radiance[c], 1e-4f * std::max(radiance[c], 1e-3f))
                    << name << " wo " << wo.transpose() << " wi " << wi.transpose();
        }
        EXPECT_GT(nonzero, 500) << name;
    }
}

TEST(NormalMapBsdf, SampleWeightsAreEvalOverPdfInBothModes) {
    for (const auto& [name, bsdf] : normal_mapped_bsdfs())
        for (const TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
            Pcg32 rng(29, 2);
            int checked = 0;
            for (int i = 0; i < 3000; ++i) {
                Vec3f wo = direction_at(88.f * rng.next_float(), 360.f * rng.next_float());
                if (bsdf.has_transmission() && rng.next_float() < 0.5f) wo = -wo;
                const BsdfSample s = bsdf.sample(kUv, wo, rng.next_float(),
                                                 {rng.next_float(), rng.next_float()}, mode);
                if (!s.valid()) continue;
                const float pdf = bsdf.pdf(kUv, wo, s.wi);
                const Rgb f = bsdf.eval(kUv, wo, s.wi, mode);
                ASSERT_GT(pdf, 0.f) << name;
                EXPECT_NEAR(s.pdf_solid_angle, pdf, 1e-3f * pdf) << name;
                for (int c = 0; c < 3; ++c)
                    EXPECT_NEAR(s.weight[c], f[c] / pdf, 1e-3f * f[c] / pdf + 1e-6f)
                        << name << (mode == TransportMode::Radiance ? " radiance" : " importance");
                ++checked;
            }
            EXPECT_GT(checked, 1000) << name;
        }
}

// --- Weights, reciprocity, scaling law ----------------------------------------------------------

std::vector<std::pair<std::string, Bsdf>> glossy_bsdfs() {
    return {
        {"roughconductor ggx", rough_conductor(MicrofacetType::Ggx, 0.2f, 0.2f)},
        {"roughconductor beckmann aniso", rough_conductor(MicrofacetType::Beckmann, 0.1f, 0.4f)},
        {"roughconductor all normals", rough_conductor(MicrofacetType::Ggx, 0.3f, 0.3f, false)},
        {"roughdielectric ggx", rough_dielectric(MicrofacetType::Ggx, 0.3f, 0.3f, 1.5f)},
        {"roughdielectric beckmann",
         rough_dielectric(MicrofacetType::Beckmann, 0.2f, 0.2f, 1.f / 1.33f)},
        {"roughdielectric all normals",
         rough_dielectric(MicrofacetType::Beckmann, 0.2f, 0.2f, 1.5f, false)},
        {"plastic", Bsdf(make_plastic(1.49f, Rgb(0.3f, 0.5f, 0.7f), Rgb::Ones(), true))},
        {"roughplastic", Bsdf(make_rough_plastic(MicrofacetType::Ggx, 0.2f, true, 1.5f,
                                                 Rgb(0.3f, 0.5f, 0.7f), Rgb::Ones(), false))},
        // Two-sided inside: a mask transmits, so half the incident directions come from behind.
        {"mask(twosided roughconductor)",
         Bsdf::mask(0.8f, Bsdf::two_sided(rough_conductor(MicrofacetType::Ggx, 0.2f, 0.2f).front(),
                                          std::nullopt))},
        {"blend(roughplastic, roughconductor)",
         Bsdf::blend(0.3f,
                     Bsdf(make_rough_plastic(MicrofacetType::Ggx, 0.2f, true, 1.5f,
                                             Rgb(0.3f, 0.5f, 0.7f), Rgb::Ones(), false)),
                     rough_conductor(MicrofacetType::Beckmann, 0.1f, 0.4f))}};
}

TEST(MicrofacetBsdfs, SampleWeightEqualsEvalOverPdf) {
    // Tolerance 1e-3 relative: the closed-form weights use the sampled normal, eval/pdf the
    // half vector recomputed from (wo, wi), which differ by float round-off.
    for (const auto& [name, bsdf] : glossy_bsdfs()) {
        Pcg32 rng(11, 5);
        int checked = 0;
        for (int i = 0; i < 2000; ++i) {
            Vec3f wo = direction_at(88.f * rng.next_float(), 360.f * rng.next_float());
            if (bsdf.has_transmission() && rng.next_float() < 0.5f) wo = -wo;
            const BsdfSample s =
                bsdf.sample(kUv, wo, rng.next_float(), {rng.next_float(), rng.next_float()});
            if (!s.valid() || s.delta) continue;
            const float pdf = bsdf.pdf(kUv, wo, s.wi);
            const Rgb f = bsdf.eval(kUv, wo, s.wi);
            ASSERT_GT(pdf, 0.f) << name;
            EXPECT_NEAR(s.pdf_solid_angle, pdf, 1e-3f * pdf) << name;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(s.weight[c], f[c] / pdf, 1e-3f * f[c] / pdf + 1e-6f)
                    << name << " channel " << c;
            ++checked;
        }
        EXPECT_GT(checked, 1000) << name;
    }
}

TEST(MicrofacetBsdfs, ReflectionIsReciprocal) {
    // Helmholtz: f(wo, wi) = f(wi, wo) with f = eval / |cos theta_i|, for every model without
    // refraction and for the reflection lobe of the rough dielectric. Relative 1e-4 (float).
    for (const auto& [name, bsdf] : glossy_bsdfs()) {
        Pcg32 rng(17, 1);
        for (int i = 0; i < 2000; ++i) {
            const Vec3f wo = direction_at(89.f * rng.next_float(), 360.f * rng.next_float());
            const Vec3f wi = direction_at(89.f * rng.next_float(), 360.f * rng.next_float());
            const Rgb f_forward = bsdf.eval(kUv, wo, wi) / wi.z();
            const Rgb f_backward = bsdf.eval(kUv, wi, wo) / wo.z();
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(f_forward[c], f_backward[c], 1e-4f * std::max(f_forward[c], 1e-3f))
                    << name;
        }
    }
}

TEST(RoughDielectricBsdf, RefractionObeysTheRadianceScalingLaw) {
    // Veach 1997, eq. 5.12: f(wi -> wo) / eta_o^2 = f(wo -> wi) / eta_i^2 for the radiance BSDF,
    // where eta_o, eta_i are the indices on the sides of wo and wi. And the adjoint (importance)
    // BSDF is the transposed radiance BSDF (eq. 5.13 ff.).
    for (MicrofacetType type : {MicrofacetType::Ggx, MicrofacetType::Beckmann})
        for (float eta : {1.5f, 1.f / 1.33f}) {
            const Bsdf b = rough_dielectric(type, 0.4f, 0.4f, eta);
            Pcg32 rng(23, 2);
            int checked = 0;
            for (int i = 0; i < 4000; ++i) {
                const Vec3f wo = direction_at(89.f * rng.next_float(), 360.f * rng.next_float());
                const Vec3f wi = -direction_at(89.f * rng.next_float(), 360.f * rng.next_float());
                const float eta_o = 1.f, eta_i = eta;  // wo outside (index 1), wi inside
                const float f_forward = b.eval(kUv, wo, wi)[0] / std::abs(wi.z());
                const float f_backward = b.eval(kUv, wi, wo)[0] / std::abs(wo.z());
                if (!(f_forward > 1e-30f)) continue;  // zero, or float denormals
                ++checked;
                // Relative 2e-3 (float; the half vector is recomputed from each side); a
                // wrong eta^2 factor would be off by 50% or more.
                EXPECT_NEAR(f_forward / (eta_o * eta_o), f_backward / (eta_i * eta_i),
                            2e-3f * f_forward / (eta_o * eta_o));
                const float f_adjoint =
                    b.eval(kUv, wi, wo, TransportMode::Importance)[0] / std::abs(wo.z());
                EXPECT_NEAR(f_adjoint, f_forward, 2e-3f * f_forward);
            }
            EXPECT_GT(checked, 500);
        }
}

// --- White furnace -------------------------------------------------------------------------------

// Hemispherical-spherical albedo as the mean sample weight of 10000 samples (seed 31) with
// white parameters, over alpha and incident angle. Bound: albedo <= 1 + 5 standard errors +
// 1e-4 (float). Dielectrics are tested in importance (flux) mode: the radiance BSDF
// legitimately exceeds 1 when leaving a denser medium (radiance grows by eta^2).
// Single-scattering microfacet models lose energy at high alpha, so albedo well below 1 is
// expected there; lossless near-smooth limits are checked to be close to 1.
double expect_albedo_at_most_one(const std::string& name, const Bsdf& b, const Vec3f& wo,
                                 TransportMode mode) {
    Pcg32 rng(31, 0);
    RgbD sum = RgbD::Zero(), sum2 = RgbD::Zero();
    constexpr int kSamples = 10000;
    for (int i = 0; i < kSamples; ++i) {
        const BsdfSample s =
            b.sample(kUv, wo, rng.next_float(), {rng.next_float(), rng.next_float()}, mode);
        if (!s.valid()) continue;
        sum += s.weight.cast<double>();
        sum2 += s.weight.cast<double>().square();
    }
    const RgbD mean = sum / kSamples;
    const RgbD se = ((sum2 / kSamples - mean.square()).max(0.0) / kSamples).sqrt();
    for (int c = 0; c < 3; ++c) EXPECT_LE(mean[c], 1.0 + 5.0 * se[c] + 1e-4) << name;
    return mean[1];
}

const float kFurnaceAlphas[] = {0.f, 0.001f, 0.1f, 0.5f, 1.f};
const float kFurnaceThetas[] = {0.f, 45.f, 80.f, 89.9f};

std::string furnace_tag(MicrofacetType type, float alpha, float theta) {
    return std::string(type_name(type)) + " alpha=" + std::to_string(alpha) +
           " theta=" + std::to_string(theta);
}

TEST(RoughConductorBsdf, WhiteFurnaceAlbedoNeverExceedsOne) {
    for (MicrofacetType type : {MicrofacetType::Ggx, MicrofacetType::Beckmann})
        for (float alpha : kFurnaceAlphas) {
            const Bsdf mirror(RoughConductorBsdf{roughness(type, alpha, alpha), Rgb::Zero(),
                                                 Rgb::Ones(), true, Rgb::Ones()});
            for (float theta : kFurnaceThetas) {
                const std::string tag = furnace_tag(type, alpha, theta);
                const double a = expect_albedo_at_most_one(
                    "rough mirror " + tag, mirror, direction_at(theta), TransportMode::Radiance);
                if (alpha <= 0.001f && theta < 80.f) {
                    EXPECT_GT(a, 0.99) << "near-smooth mirror " << tag;
                }
            }
        }
}

TEST(RoughDielectricBsdf, WhiteFurnaceAlbedoNeverExceedsOneFromEitherSide) {
    for (MicrofacetType type : {MicrofacetType::Ggx, MicrofacetType::Beckmann})
        for (float alpha : kFurnaceAlphas)
            for (float eta : {1.5f, 1.f / 1.5f}) {
                const Bsdf glass = rough_dielectric(type, alpha, alpha, eta);
                for (float theta : kFurnaceThetas) {
                    const std::string tag =
                        furnace_tag(type, alpha, theta) + " eta=" + std::to_string(eta);
                    const Vec3f wo = direction_at(theta);
                    const double a = expect_albedo_at_most_one("rough glass " + tag, glass, wo,
                                                               TransportMode::Importance);
                    const double a_in = expect_albedo_at_most_one(
                        "rough glass inside " + tag, glass, -wo, TransportMode::Importance);
                    if (alpha <= 0.001f && theta < 80.f) {
                        EXPECT_GT(a, 0.99) << "near-smooth glass " << tag;
                        EXPECT_GT(a_in, 0.99) << "near-smooth glass inside " << tag;
                    }
                }
            }
}

TEST(PlasticBsdf, WhiteFurnaceAlbedoNeverExceedsOne) {
    for (MicrofacetType type : {MicrofacetType::Ggx, MicrofacetType::Beckmann})
        for (float alpha : {0.f, 0.1f, 1.f}) {
            const Bsdf plastic(
                make_rough_plastic(type, alpha, true, 1.5f, Rgb::Ones(), Rgb::Ones(), false));
            for (float theta : kFurnaceThetas)
                expect_albedo_at_most_one("roughplastic " + furnace_tag(type, alpha, theta),
                                          plastic, direction_at(theta), TransportMode::Radiance);
        }
    // Smooth plastic with a white base is exactly lossless: F_i + (1 - F_i) (1 - F_dr,ext) /
    // (eta^2 (1 - F_dr,int)) = 1, because eta^2 (1 - F_dr,int) = 1 - F_dr,ext.
    for (float theta : {0.f, 60.f, 89.f}) {
        const double a = expect_albedo_at_most_one(
            "plastic", Bsdf(make_plastic(1.49f, Rgb::Ones(), Rgb::Ones(), false)),
            direction_at(theta), TransportMode::Radiance);
        EXPECT_NEAR(a, 1.0, 0.02) << "white plastic at " << theta;
    }
}

TEST(Fresnel, DiffuseReflectancesOfBothSidesSatisfyTheReciprocityIdentity) {
    // eta^2 (1 - F_dr(1/eta)) = 1 - F_dr(eta): what enters diffusely must be able to leave.
    for (float eta : {1.1f, 1.33f, 1.5f, 2.4f}) {
        const float inside = fresnel_diffuse_reflectance(1.f / eta),
                    outside = fresnel_diffuse_reflectance(eta);
        EXPECT_NEAR(eta * eta * (1.f - inside), 1.f - outside, 1e-4f) << "eta " << eta;
    }
    EXPECT_NEAR(fresnel_diffuse_reflectance(1.f), 0.f, 1e-6f);
}

// --- Robustness
// -----------------------------------------------------------------------------------

TEST(MicrofacetBsdfs, NoNanOrInfForDegenerateInputs) {
    std::vector<Bsdf> bsdfs;
    for (MicrofacetType type : {MicrofacetType::Ggx, MicrofacetType::Beckmann})
        for (float alpha : {0.f, 1e-6f, 0.001f, 1.f, 4.f})
            for (bool visible : {true, false}) {
                bsdfs.push_back(rough_conductor(type, alpha, alpha, visible));
                bsdfs.push_back(rough_conductor(type, alpha, 0.5f, visible));
                for (float eta : {1.5f, 1.0001f, 1.f / 1.5f})
                    bsdfs.push_back(rough_dielectric(type, alpha, alpha, eta, visible));
                if (alpha == 0.f || alpha == 4.f)  // the coat tables take a moment to build
                    bsdfs.push_back(Bsdf(make_rough_plastic(
                        type, alpha, visible, 1.5f, Rgb::Constant(0.5f), Rgb::Ones(), true)));
                bsdfs.push_back(
                    Bsdf::two_sided(RoughConductorBsdf{roughness(type, alpha, alpha, visible),
                                                       Rgb::Zero(), Rgb::Ones(), true, Rgb::Ones()},
                                    std::nullopt));
            }
    bsdfs.push_back(Bsdf(make_plastic(1.49f, Rgb::Constant(0.5f), Rgb::Ones(), false)));
    bsdfs.push_back(Bsdf(make_plastic(1.0001f, Rgb::Ones(), Rgb::Zero(), true)));
    // Grazing, exactly on the surface (z = 0 and -0), normal, back-facing, nearly opposite.
    const std::vector<Vec3f> directions = {Vec3f::UnitZ(),
                                           -Vec3f::UnitZ(),
                                           Vec3f::UnitX(),
                                           Vec3f(0.f, 1.f, -0.f),
                                           direction_at(89.999f),
                                           -direction_at(89.999f),
                                           Vec3f(1.f, 0.f, 1e-30f).normalized(),
                                           Vec3f(-1.f, 0.f, 1e-7f).normalized(),
                                           direction_at(45.f),
                                           -direction_at(45.f, 210.f)};
    for (const Bsdf& b : bsdfs)
        for (const Vec3f& wo : directions) {
            for (const Vec3f& wi : directions)
                for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
                    ASSERT_TRUE(is_finite(b.eval(kUv, wo, wi, mode)));
                    ASSERT_TRUE(std::isfinite(b.pdf(kUv, wo, wi)));
                    ASSERT_TRUE((b.eval(kUv, wo, wi, mode) >= 0.f).all());
                }
            for (float u : {0.f, 0.5f, 0x1.fffffep-1f})
                for (float u2 : {0.f, 0.25f, 0x1.fffffep-1f}) {
                    const BsdfSample s = b.sample(kUv, wo, u, {u2, 1.f - u2});
                    ASSERT_TRUE(is_finite(s.weight));
                    ASSERT_TRUE(s.wi.allFinite());
                    ASSERT_TRUE(std::isfinite(s.pdf_solid_angle));
                }
        }
}

TEST(MicrofacetDistribution, ErfinvIsWithinFloatPrecision) {
    // erfinv (Giles' polynomials, no refinement) against erf inverted by bisection in long
    // double, on 20001 floats across (-1, 1) and the last floats below 1: relative error below
    // 2.5e-7 (measured 1.7e-7, about two float ulps), which is what the sampled normals keep.
    const auto reference = [](long double x) {
        long double lo = -10.L, hi = 10.L;
        for (int k = 0; k < 120; ++k) {
            const long double mid = 0.5L * (lo + hi);
            (std::erf(mid) > x ? hi : lo) = mid;
        }
        return 0.5L * (lo + hi);
    };
    std::vector<float> xs;
    for (int i = -10000; i <= 10000; ++i) xs.push_back(static_cast<float>(i) / 10000.5f);
    float near_one = 0x1.fffffep-1f;
    for (int k = 0; k < 8; ++k, near_one = std::nextafter(near_one, 0.f)) {
        xs.push_back(near_one);
        xs.push_back(-near_one);
    }
    for (const float x : xs) {
        const long double want = reference(x);
        const long double got = erfinv(x);
        if (x == 0.f) {
            EXPECT_EQ(got, 0.L);
            continue;
        }
        EXPECT_LT(std::abs(static_cast<double>((got - want) / want)), 2.5e-7) << x;
    }
}

TEST(MicrofacetDistribution, BeckmannVisibleSlopeInvertsItsCdf) {
    // The sampled x slope for u must sit where the visible-slope CDF (Heitz & d'Eon 2014,
    // Sec. 4.2: C(x) = cos (1 + erf x) / 2 + sin exp(-x^2) / (2 sqrt(pi)), normalised by its
    // value at cot theta) reaches u. The CDF is evaluated in long double. The float slope moves F
    // by erfinv's 2e-7 of x times the density (< 0.6), and the sampler stops within 1e-6 of F
    // (measured worst 1.03e-6), so 2e-6 bounds what a correct sampler misses by. Polar angles
    // from normal incidence to 0.01 degrees from grazing, u on 1001 points across (0, 1).
    for (const double theta_deg : {0.0, 1e-3, 10.0, 45.0, 70.0, 85.0, 89.0, 89.99}) {
        const double theta = theta_deg * std::numbers::pi / 180.0;
        const auto cos_t = static_cast<float>(std::cos(theta)),
                   sin_t = static_cast<float>(std::sin(theta));
        const auto cdf = [&](long double x) {
            return 0.5L * cos_t * (1.L + std::erf(x)) +
                   0.5L * sin_t / std::sqrt(std::numbers::pi_v<long double>) * std::exp(-x * x);
        };
        const long double total = sin_t > 0.f ? cdf(static_cast<long double>(cos_t) / sin_t)
                                              : static_cast<long double>(cos_t);
        double worst = 0.0;
        for (int i = 1; i <= 1001; ++i) {
            const float u = static_cast<float>(i) / 1002.f;
            const float x = sample_beckmann_visible_slope_x(cos_t, sin_t, u);
            ASSERT_TRUE(std::isfinite(x)) << theta_deg << " " << u;
            if (sin_t > 0.f) {
                ASSERT_LE(x, cos_t / sin_t * (1.f + 1e-6f));
            }
            worst = std::max(worst, static_cast<double>(std::abs(cdf(x) / total - u)));
        }
        EXPECT_LT(worst, 2e-6) << "theta " << theta_deg;
    }
}

TEST(MicrofacetDistribution, VisibleNormalsIntegrateToOne) {
    // int D_wo(m) dm = 1 and int D(m) cos(theta_m) dm = 1 (Walter eq. 4; Heitz 2014 eq. 16),
    // by the midpoint rule on (cos theta, phi) at 400 x 400: a check of D and Lambda together
    // that is independent of the samplers.
    for (MicrofacetType type : {MicrofacetType::Ggx, MicrofacetType::Beckmann})
        for (float alpha : {0.2f, 0.7f})
            for (float theta : {0.f, 60.f, 85.f}) {
                const MicrofacetDistribution d(type, alpha, 0.6f * alpha);
                const Vec3f wo = direction_at(theta);
                constexpr int n = 400;
                double projected = 0.0, visible = 0.0;
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j < n; ++j) {
                        const double z = (i + 0.5) / n,
                                     phi = 2.0 * std::numbers::pi * (j + 0.5) / n;
                        const double r = std::sqrt(1.0 - z * z);
                        const Vec3f m(static_cast<float>(r * std::cos(phi)),
                                      static_cast<float>(r * std::sin(phi)), static_cast<float>(z));
                        const double dw = (1.0 / n) * (2.0 * std::numbers::pi / n);
                        projected += d.pdf_all(m) * dw;
                        visible += d.pdf_visible(wo, m) * dw;
                    }
                EXPECT_NEAR(projected, 1.0, 5e-3) << type_name(type) << " alpha " << alpha;
                EXPECT_NEAR(visible, 1.0, 5e-3)
                    << type_name(type) << " alpha " << alpha << " theta " << theta;
            }
}

TEST(Bsdf, ClassifiesMixedLobesByTheirMostConnectableLobe) {
    EXPECT_EQ(Bsdf(make_plastic(1.49f, Rgb::Constant(0.5f), Rgb::Ones(), false)).roughness_class(),
              RoughnessClass::Diffuse);
    EXPECT_EQ(Bsdf(make_rough_plastic(MicrofacetType::Ggx, 0.05f, true, 1.5f, Rgb::Constant(0.5f),
                                      Rgb::Ones(), false))
                  .roughness_class(),
              RoughnessClass::Diffuse);
    const BsdfLobes plastic =
        Bsdf(make_plastic(1.49f, Rgb::Constant(0.5f), Rgb::Ones(), false)).lobes();
    EXPECT_TRUE(plastic.diffuse_reflection && plastic.delta_reflection);
    EXPECT_EQ(plastic.sharpest_class, RoughnessClass::Delta);
    EXPECT_EQ(rough_conductor(MicrofacetType::Ggx, 0.0005f, 0.0005f).roughness_class(),
              RoughnessClass::Delta);
    EXPECT_EQ(rough_conductor(MicrofacetType::Ggx, 0.05f, 0.05f).roughness_class(),
              RoughnessClass::Glossy);
    EXPECT_EQ(rough_conductor(MicrofacetType::Ggx, 0.5f, 0.5f).roughness_class(),
              RoughnessClass::Diffuse);
    // Anisotropic: the narrow axis decides.
    EXPECT_EQ(rough_conductor(MicrofacetType::Ggx, 0.5f, 0.05f).roughness_class(),
              RoughnessClass::Glossy);
    EXPECT_EQ(rough_dielectric(MicrofacetType::Beckmann, 0.1f, 0.1f, 1.5f).roughness_class(),
              RoughnessClass::Glossy);
    // A sampled coat reflection reports the coat's class, a base sample the diffuse class.
    const Bsdf coat(make_plastic(1.49f, Rgb::Constant(0.5f), Rgb::Ones(), false));
    EXPECT_EQ(coat.sample(kUv, direction_at(85.f), 0.f, {0.5f, 0.5f}).sampled_class,
              RoughnessClass::Delta);
    EXPECT_EQ(coat.sample(kUv, direction_at(85.f), 0.9999f, {0.5f, 0.5f}).sampled_class,
              RoughnessClass::Diffuse);
}

}  // namespace
}  // namespace gdmlt
