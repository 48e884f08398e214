// SPDX-License-Identifier: GPL-3.0-or-later
// Every integrator converges to the path tracer's image through a thin lens, through an
// orthographic camera and up to a pinhole's far clip plane, all with Mitsuba's Gaussian film
// filter, in a scene lit by point, spot and directional lights (and a dim environment): the
// camera's lens sample, its light tracing connections (CameraConnection), BDPT's first-vertex
// density (Camera::pdf_area), the clipped camera rays and the shifts' fixed lens point all take
// part somewhere.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <string>

#include "core/render/render_bdpt.h"
#include "core/render/render_path.h"
#include "core/render/render_ptracer.h"
#include "mlt/gdmlt.h"
#include "mlt/gdpt.h"
#include "mlt/pssmlt.h"
#include "reconstruct/reconstruct.h"
#include "tests/support/chi2.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

constexpr int kResolution = 16;

std::string film_xml() {
    const std::string res = std::to_string(kResolution);
    return R"(<sampler type="independent"/><film type="hdrfilm"><integer name="width" value=")" +
           res + R"("/><integer name="height" value=")" + res +
           R"("/><rfilter type="gaussian"/></film>)";
}

/// A thin lens focused on the sphere (distance 4.3), its aperture wide enough to blur the
/// wall behind it by several pixels.
std::string thin_lens_xml() {
    return R"(<sensor type="thinlens"><float name="fov" value="45"/>
        <float name="aperture_radius" value="0.25"/><float name="focus_distance" value="4.3"/>
        <transform name="to_world"><lookat origin="0, 1.5, 4" target="0, 0, 0" up="0, 1, 0"/></transform>)" +
           film_xml() + "</sensor>";
}

/// An orthographic view 3.6 units wide, from above and in front.
std::string orthographic_xml() {
    return R"(<sensor type="orthographic"><float name="near_clip" value="0.1"/>
        <transform name="to_world"><scale x="1.8" y="1.8"/>
            <lookat origin="0, 3, 5" target="0, -0.3, 0" up="0, 1, 0"/></transform>)" +
           film_xml() + "</sensor>";
}

/// A pinhole whose far clip plane (camera depth 5.5) cuts the back wall's lower part, the far
/// end of the floor and the rough metal sphere in two: there camera rays end and see the
/// environment, and light paths cannot reach the camera.
std::string far_clip_xml() {
    return R"(<sensor type="perspective"><float name="fov" value="45"/><float name="far_clip" value="5.5"/>
        <transform name="to_world"><lookat origin="0, 1.5, 4" target="0, 0, 0" up="0, 1, 0"/></transform>)" +
           film_xml() + "</sensor>";
}

/// A floor, a back wall, a diffuse sphere and a rough metal sphere under the three delta lights
/// and a dim constant environment.
Scene delta_light_scene(const std::string& sensor) {
    return test::scene_from_xml(sensor + R"(
        <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>
        <shape type="rectangle"><transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/>
            <translate y="-1"/></transform><ref id="grey"/></shape>
        <shape type="rectangle"><transform name="to_world"><scale value="3"/><translate z="-2"/></transform>
            <ref id="grey"/></shape>
        <shape type="sphere"><point name="center" value="-0.3, -0.3, 0.2"/><float name="radius" value="0.7"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.7, 0.5"/></bsdf></shape>
        <shape type="sphere"><point name="center" value="0.9, -0.6, -0.6"/><float name="radius" value="0.4"/>
            <bsdf type="roughconductor"><float name="alpha" value="0.3"/></bsdf></shape>
        <emitter type="point"><point name="position" value="1.5, 1.5, 1"/><rgb name="intensity" value="4"/></emitter>
        <emitter type="spot"><rgb name="intensity" value="20"/><float name="cutoff_angle" value="25"/>
            <transform name="to_world"><lookat origin="-1.5, 2, 1.5" target="0, -0.5, 0" up="0, 1, 0"/></transform></emitter>
        <emitter type="directional"><vector name="direction" value="-0.3, -1, -0.4"/><rgb name="irradiance" value="0.8"/></emitter>
        <emitter type="constant"><rgb name="radiance" value="0.05"/></emitter>)");
}

/// `runs` renders of `render(seed)` (seeds 100 ..): their average image, and its mean
/// luminance with the standard error from the runs' spread.
test::IndependentRenders repeated(const std::function<Image(std::uint64_t)>& render, int runs) {
    return test::independent_renders(
        [&](std::uint64_t seed) {
            RenderOutput out;
            out.image = render(seed);
            return out;
        },
        runs);
}

/// The path tracer's reference: 8 runs of 1024 spp (seeds 100-107), depth 8.
const test::IndependentRenders& reference(const Scene& scene, const std::string& key) {
    static std::map<std::string, test::IndependentRenders> cache;
    auto it = cache.find(key);
    if (it != cache.end()) return it->second;
    return cache[key] = repeated(
               [&](std::uint64_t seed) {
                   RenderSettings r;
                   r.spp = 1024;
                   r.seed = seed;
                   r.path.max_depth = 8;
                   return render_path(scene, r).image;
               },
               8);
}

/// `runs` runs of the integrator against the reference: image means within 5 combined
/// standard errors (spreads of 6 and 8 runs: Student's t with ~10 degrees of freedom puts 5
/// at a two-sided 0.05%), the combined error at most 1% (so a 5% bias fails; measured
/// 0.25-0.9%), and the relMSE of the average image below `max_rel_mse` (each case's bound
/// about 2x its measurement, seeds 100-105 against the reference's 100-107).
void expect_converges(const Scene& scene, const std::string& key,
                      const std::function<Image(std::uint64_t)>& render, double max_rel_mse,
                      int runs = 6) {
    const test::IndependentRenders& pt = reference(scene, key);
    const test::IndependentRenders ours = repeated(render, runs);
    const double combined = std::hypot(ours.standard_error, pt.standard_error);
    EXPECT_LT(combined, 0.01 * pt.mean) << "too few samples to tell";
    EXPECT_NEAR(ours.mean, pt.mean, 5.0 * combined);
    const double rel_mse = test::relative_mse(ours.average.pixels, pt.average.pixels);
    EXPECT_LT(rel_mse, max_rel_mse);
    ::testing::Test::RecordProperty("relMSE", std::to_string(rel_mse));
    ::testing::Test::RecordProperty("mean_ratio", std::to_string(ours.mean / pt.mean));
    std::printf("%s: relMSE %.5f, mean ratio %.4f (se %.4f)\n", key.c_str(), rel_mse,
                ours.mean / pt.mean, combined / pt.mean);
}

enum class Integrator { Ptracer, Bdpt, Pssmlt, Mmlt, Gdpt, Gdmlt, GdmltBidirectional };

Image render_with(const Scene& scene, Integrator integrator, std::uint64_t seed) {
    switch (integrator) {
        case Integrator::Ptracer: {
            RenderSettings r;
            r.spp = 512;
            r.seed = seed;
            r.path.max_depth = 8;
            return render_ptracer(scene, r).image;
        }
        case Integrator::Bdpt: {
            BdptRenderSettings b;
            b.spp = 256;
            b.seed = seed;
            b.bdpt.max_depth = 8;
            return render_bdpt(scene, b).image;
        }
        case Integrator::Pssmlt:
        case Integrator::Mmlt: {
            mlt::PssmltSettings s;
            s.seed = seed;
            s.mutations_per_pixel = integrator == Integrator::Mmlt ? 8192 : 512;
            s.bootstrap_samples = 100000;
            s.chains = 64;
            s.path.max_depth = 8;
            s.bidirectional = integrator == Integrator::Pssmlt;  // PSSMLT over BDPT's samples
            s.multiplexed = integrator == Integrator::Mmlt;
            const mlt::PssmltOutput out = mlt::render_pssmlt(scene, s);
            EXPECT_EQ(out.stats.nonfinite_dropped, 0u);
            EXPECT_EQ(out.stats.replay_mismatches, 0u);
            return out.image;
        }
        case Integrator::Gdpt: {
            mlt::GdptSettings s;
            s.spp = 512;
            s.seed = seed;
            s.path.max_depth = 8;
            const mlt::GdptOutput out =
                mlt::render_gdpt(scene, s, NeighbourSet::lattice(kResolution, kResolution));
            EXPECT_EQ(out.stats.nonfinite_dropped, 0u);
            reconstruct::ReconstructConfig l2;
            l2.method = reconstruct::Method::l2;
            return reconstruct::reconstruct_buffers(out.buffers, l2).image;
        }
        case Integrator::Gdmlt:
        case Integrator::GdmltBidirectional: {
            mlt::GdmltSettings s;
            s.seed = seed;
            s.mutations_per_pixel = 512;
            s.chains = 64;
            // b's error is part of each run's spread; bidirectional samples' b is noisier.
            s.bootstrap_samples = integrator == Integrator::GdmltBidirectional ? 400000 : 100000;
            s.bootstrap_relative_error = 0.0;
            s.path.max_depth = 8;
            s.very_direct_samples = 256;
            s.gdpt_share = 0.0;  // the chains alone
            s.bidirectional = integrator == Integrator::GdmltBidirectional;
            const mlt::GdmltOutput out = mlt::render_gdmlt(scene, s);
            EXPECT_EQ(out.stats.nonfinite_dropped, 0u);
            EXPECT_EQ(out.stats.replay_mismatches, 0u);
            reconstruct::ReconstructConfig l2;
            l2.method = reconstruct::Method::l2;
            return reconstruct::reconstruct_buffers(out.buffers, l2).image;
        }
    }
    return {};
}

struct Case {
    const char* name;
    Integrator integrator;
    double thin_lens_bound, orthographic_bound, far_clip_bound;
};

class EveryIntegrator : public ::testing::TestWithParam<Case> {};

TEST_P(EveryIntegrator, ConvergesToThePathTracerThroughAThinLens) {
    const Scene scene = delta_light_scene(thin_lens_xml());
    ASSERT_TRUE(scene.camera().needs_lens_sample());
    expect_converges(
        scene, "thin lens",
        [&](std::uint64_t seed) { return render_with(scene, GetParam().integrator, seed); },
        GetParam().thin_lens_bound);
}

TEST_P(EveryIntegrator, ConvergesToThePathTracerThroughAnOrthographicCamera) {
    const Scene scene = delta_light_scene(orthographic_xml());
    ASSERT_EQ(scene.camera().projection(), Projection::Orthographic);
    expect_converges(
        scene, "orthographic",
        [&](std::uint64_t seed) { return render_with(scene, GetParam().integrator, seed); },
        GetParam().orthographic_bound);
}

TEST_P(EveryIntegrator, ConvergesToThePathTracerUpToAFarClipPlane) {
    const Scene scene = delta_light_scene(far_clip_xml());
    ASSERT_EQ(scene.camera().far_clip(), 5.5f);
    expect_converges(
        scene, "far clip",
        [&](std::uint64_t seed) { return render_with(scene, GetParam().integrator, seed); },
        GetParam().far_clip_bound);
}

INSTANTIATE_TEST_SUITE_P(
    Cameras, EveryIntegrator,
    // relMSE measured (thin lens / orthographic / far clip): ptracer 8.2e-4 / 9.4e-4 / 6.4e-4,
    // bdpt 5.5e-4 / 6.9e-4 / 7.1e-4, pssmlt 1.4e-3 / 1.1e-3 / 9.4e-4, mmlt 9.6e-4 / 1.1e-3 /
    // 7.8e-4, gdpt 5.1e-4 / 4.0e-4 / 5.3e-4, gdmlt 4.7e-3 / 4.9e-3 / 9.7e-3 (the chains'
    // correlated noise), bidirectional gdmlt 3.7e-3 / 4.5e-3 / 5.3e-3.
    ::testing::Values(Case{"ptracer", Integrator::Ptracer, 0.002, 0.002, 0.0015},
                      Case{"bdpt", Integrator::Bdpt, 0.0015, 0.0015, 0.0015},
                      Case{"pssmlt", Integrator::Pssmlt, 0.003, 0.003, 0.002},
                      Case{"mmlt", Integrator::Mmlt, 0.0025, 0.0025, 0.0016},
                      Case{"gdpt", Integrator::Gdpt, 0.0012, 0.001, 0.0011},
                      Case{"gdmlt", Integrator::Gdmlt, 0.01, 0.01, 0.02},
                      Case{"gdmlt_bidirectional", Integrator::GdmltBidirectional, 0.008, 0.009,
                           0.011}),
    [](const ::testing::TestParamInfo<Case>& param) { return std::string(param.param.name); });

}  // namespace
}  // namespace gdmlt
