// SPDX-License-Identifier: GPL-3.0-or-later
// Bidirectional gradients (G-BDPT shifts, mlt/gradient_sample.h) and bidirectional GDMLT: the
// estimator's differences against BDPT's independent pixel values, the chain's reconstructed
// image against the path tracer's, determinism.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <functional>

#include "core/image/neighbour_set.h"
#include "core/render/render_path.h"
#include "mlt/gdmlt.h"
#include "mlt/gradient_sample.h"
#include "reconstruct/reconstruct.h"
#include "tests/support/chi2.h"
#include "tests/support/pixel_difference.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

struct PixelPair {
    int x, y;
    Vec2i offset;
};

/// For each pair (pixel, pixel + offset): the bidirectional estimate of I_b(j) - I_b(i) (2 x
/// `samples` base samples, seed 31) against the difference of BDPT's two pixel values
/// (`samples` each, seed 57), and each end's primal against BDPT's pixel. I_b is what both
/// estimate: camera strategies (t >= 2) of paths of 2 to 8 segments. Every z within 4 (with
/// 3 x pairs tests a false alarm has probability ~1e-3), and the differences must not all be
/// within noise of zero (else the test could not tell a wrong sign or weight).
void check_bidirectional_differences(const Scene& scene, const std::vector<PixelPair>& pairs,
                                     int samples) {
    int informative = 0;
    manifold::ShiftCounters shifts;
    for (const PixelPair& p : pairs) {
        const test::BidirectionalDifference g = test::bidirectional_pixel_difference(
            scene, manifold::ShiftKind::Auto, p.x, p.y, samples, 31, shifts, p.offset);
        const test::MeanEstimate a =
            test::bdpt_camera_strategies_pixel(scene, p.x, p.y, samples, 57);
        const test::MeanEstimate b = test::bdpt_camera_strategies_pixel(
            scene, p.x + p.offset.x(), p.y + p.offset.y(), samples, 57);
        const double bdpt_se = std::hypot(a.standard_error, b.standard_error);
        const double combined = std::hypot(g.difference.standard_error, bdpt_se);
        EXPECT_NEAR(g.difference.mean, b.mean - a.mean, 4.0 * combined)
            << "pixel " << p.x << "," << p.y << " offset " << p.offset.transpose() << ": gradient "
            << g.difference.mean << " +- " << g.difference.standard_error << ", BDPT "
            << b.mean - a.mean << " +- " << bdpt_se;
        EXPECT_NEAR(g.primal_here.mean, a.mean,
                    4.0 * std::hypot(g.primal_here.standard_error, a.standard_error));
        EXPECT_NEAR(g.primal_there.mean, b.mean,
                    4.0 * std::hypot(g.primal_there.standard_error, b.standard_error));
        if (std::abs(b.mean - a.mean) > 4.0 * bdpt_se) ++informative;
    }
    EXPECT_GE(informative, 1);
    // Shifts ran and most succeeded (the estimator is not the "every shift fails" special case).
    EXPECT_GT(shifts.shifts, 1000u);
    EXPECT_GT(static_cast<double>(shifts.by_status[0]), 0.5 * static_cast<double>(shifts.shifts));
}

TEST(BidirectionalGradients, DifferencesMatchBdptOnACornellBoxWithAGlassSphere) {
    // 16x16 box: pairs on the tall box's edge, across the glass sphere's silhouette and inside
    // it (refracted paths, manifold shifts), horizontal, vertical and at distance 2.
    const Scene scene = test::scene_from_xml(test::cornell_box_xml(16, true));
    check_bidirectional_differences(
        scene,
        {{7, 8, Vec2i(1, 0)}, {9, 12, Vec2i(1, 0)}, {11, 11, Vec2i(0, 1)}, {10, 13, Vec2i(2, 0)}},
        20000);
}

TEST(BidirectionalGradients, DifferencesMatchBdptWithTheLightSealedInGlass) {
    // Every path's light crossed the glass: connections and light tracing carry it. (Pixels
    // that see the light through the glass are left out: their rare, very bright samples make
    // a standard error from 20000 samples unreliable; at 200000 they agree, z 0.5.)
    const Scene scene = test::scene_from_xml(test::sealed_light_box_xml(16));
    check_bidirectional_differences(
        scene,
        {{7, 9, Vec2i(1, 0)}, {4, 12, Vec2i(0, 1)}, {9, 5, Vec2i(0, 1)}, {11, 13, Vec2i(1, 1)}},
        20000);
}

TEST(BidirectionalGradients, DifferencesMatchBdptInAGlossyHighlightOfAnEnvironment) {
    // scenes/materials_envmap.xml at 128x128: the sun's highlight on the rough anisotropic gold
    // sphere, where NEE (s = 1) and BSDF sampling (s = 0) shift a path to different offsets
    // (the case that biased the unidirectional estimator's joint weights 1.5x,
    // GradientEstimator.DifferenceAcrossAGlossyHighlightOfAnEnvironmentMatchesThePathTracer).
    // The light subpaths start at infinity, so light tracing is not shifted here.
    const Scene scene = test::repository_scene("materials_envmap");
    check_bidirectional_differences(scene, {{108, 58, Vec2i(1, 0)}, {109, 60, Vec2i(0, 1)}}, 20000);
}

/// Per sample, the shifted light tracing terms' values: per pixel (their primal) and per edge
/// (their differences, oriented as GDMLT splats them: I(to) - I(from)).
struct LightTracingSums {
    std::vector<double> pixel, pixel2, edge, edge2;
    int samples = 0;
    std::uint64_t shifts = 0, shifted_ok = 0, terms = 0;
};
LightTracingSums light_tracing_sums(const Scene& scene, const NeighbourSet& neighbours, int samples,
                                    std::uint64_t seed) {
    LightTracingSums sums;
    sums.pixel.assign(neighbours.pixel_count(), 0.0);
    sums.pixel2 = sums.pixel;
    sums.edge.assign(neighbours.edges().size(), 0.0);
    sums.edge2 = sums.edge;
    sums.samples = samples;
    PathSamplerSettings path;
    path.max_depth = 8;
    mlt::BidirectionalGradientScratch scratch;
    mlt::BidirectionalGradientSample g;
    PathCounters counters;
    manifold::ShiftCounters shifts;
    std::vector<double> pixel(sums.pixel.size()), edge(sums.edge.size());
    const Film& film = scene.camera().film();
    for (int i = 0; i < samples; ++i) {
        IndependentStream stream(derive_stream(seed, static_cast<std::uint64_t>(i)));
        const Vec2f u = stream.next_2d();
        const Vec2f film_position(u.x() * static_cast<float>(film.width),
                                  u.y() * static_cast<float>(film.height));
        const std::size_t camera_pixel = crop_pixel_index(film, film_position);
        std::vector<mlt::LinkEstimate> estimates(neighbours.links(camera_pixel).size());
        mlt::sample_bidirectional_gradients(
            scene, film_position, stream, path, manifold::ShiftKind::Auto,
            neighbours.links(camera_pixel), estimates, &neighbours, scratch, g, counters, shifts);
        EXPECT_EQ(g.nonfinite, 0);
        std::fill(pixel.begin(), pixel.end(), 0.0);
        std::fill(edge.begin(), edge.end(), 0.0);
        for (const auto& term : g.light_terms) {
            pixel[term.pixel] += luminance(term.primal);
            const std::span<const NeighbourLink> links = neighbours.links(term.pixel);
            for (std::uint32_t k = 0; k < term.count; ++k) {
                const double d = luminance(g.light_estimates[term.first + k].difference());
                edge[static_cast<std::size_t>(links[k].edge)] += links[k].from_end ? d : -d;
            }
            ++sums.terms;
        }
        for (std::size_t p = 0; p < pixel.size(); ++p) {
            sums.pixel[p] += pixel[p];
            sums.pixel2[p] += pixel[p] * pixel[p];
        }
        for (std::size_t e = 0; e < edge.size(); ++e) {
            sums.edge[e] += edge[e];
            sums.edge2[e] += edge[e] * edge[e];
        }
    }
    sums.shifts = shifts.shifts;
    sums.shifted_ok = shifts.by_status[0];
    return sums;
}

/// 60000 samples (seed 5) of an 8x8 scene: every edge's summed differences of shifted light
/// tracing terms against the difference of the same terms' pixel values from 60000 independent
/// samples (seed 6). Per edge z = (difference of means) / combined standard error; unbiased
/// estimates give a mean z^2 near 1; bound 2 (about 6 standard deviations of that mean over
/// ~100 edges, heavy tails included), every z^2 under 36.
void check_shifted_light_tracing(const Scene& scene) {
    const NeighbourSet neighbours = NeighbourSet::lattice(8, 8);
    const LightTracingSums g = light_tracing_sums(scene, neighbours, 60000, 5);
    const LightTracingSums r = light_tracing_sums(scene, neighbours, 60000, 6);
    const auto mean_se = [](double sum, double sum2, int n) {
        const double m = sum / n;
        return std::pair{m, std::sqrt(std::max(0.0, sum2 / n - m * m) / (n - 1))};
    };
    double sum_z2 = 0.0;
    int count = 0, informative = 0;
    for (std::size_t e = 0; e < neighbours.edges().size(); ++e) {
        const GradientEdge& edge = neighbours.edges()[e];
        const auto [d, d_se] = mean_se(g.edge[e], g.edge2[e], g.samples);
        const auto [a, a_se] = mean_se(r.pixel[static_cast<std::size_t>(edge.from)],
                                       r.pixel2[static_cast<std::size_t>(edge.from)], r.samples);
        const auto [b, b_se] = mean_se(r.pixel[static_cast<std::size_t>(edge.to)],
                                       r.pixel2[static_cast<std::size_t>(edge.to)], r.samples);
        const double se2 = d_se * d_se + a_se * a_se + b_se * b_se;
        if (!(se2 > 0.0)) continue;
        const double z2 = (d - (b - a)) * (d - (b - a)) / se2;
        EXPECT_LT(z2, 36.0) << "edge " << edge.from << "->" << edge.to << ": shifted " << d
                            << " +- " << d_se << ", pixels " << b - a;
        sum_z2 += z2;
        ++count;
        if (std::abs(b - a) > 4.0 * std::sqrt(a_se * a_se + b_se * b_se)) ++informative;
    }
    EXPECT_GT(count, 80);
    EXPECT_GT(informative, 10);
    EXPECT_LT(sum_z2 / count, 2.0);
    // Light tracing was shifted, mostly with success (through the glass: manifold walks).
    EXPECT_GT(g.terms, 10000u);
    EXPECT_GT(static_cast<double>(g.shifted_ok), 0.5 * static_cast<double>(g.shifts));
    ::testing::Test::RecordProperty("mean_z2", std::to_string(sum_z2 / count));
}

TEST(BidirectionalGradients, ShiftedLightTracingDifferencesMatchItsPixelValuesThroughGlass) {
    // Light tracing carries the caustics of the sealed light: shifts walk the glass.
    check_shifted_light_tracing(test::scene_from_xml(test::sealed_light_box_xml(8)));
}

TEST(BidirectionalGradients, ShiftedLightTracingDifferencesMatchItsPixelValuesInADiffuseBox) {
    // Light tracing shares the walls with the other strategies: its MIS weights are far from 1
    // (without the offset's own weight this fails, mean z^2 14; through glass it passes, 1.1).
    check_shifted_light_tracing(test::scene_from_xml(test::cornell_box_xml(8)));
}

mlt::GdmltSettings bidirectional_gdmlt(std::uint64_t seed, double mutations_per_pixel) {
    mlt::GdmltSettings s;
    s.seed = seed;
    s.mutations_per_pixel = mutations_per_pixel;
    s.chains = 64;
    s.bootstrap_samples = 100000;
    s.bootstrap_relative_error = 0.01;
    s.path.max_depth = 8;
    s.bidirectional = true;
    return s;
}

void check_l2_image(const Scene& scene, std::uint64_t seed, double max_rel_mse,
                    const std::function<void(mlt::GdmltSettings&)>& configure) {
    const RenderOutput reference = test::reference_render(scene);
    mlt::GdmltSettings s = bidirectional_gdmlt(seed, 1024);
    configure(s);
    // The lights cover a few pixels' corners at 16x16: the very direct pass needs many samples
    // per pixel to be as precise as the reference.
    s.very_direct_samples = 4096;
    const mlt::GdmltOutput out = mlt::render_gdmlt(scene, s);
    EXPECT_EQ(out.stats.nonfinite_dropped, 0u);
    EXPECT_EQ(out.stats.replay_mismatches, 0u);
    reconstruct::ReconstructConfig l2;
    l2.method = reconstruct::Method::l2;
    const Image final_image = reconstruct::reconstruct_buffers(out.buffers, l2).image;
    const double ref_mean = test::mean_luminance(reference.image);
    const double b_relative_error = out.stats.b_standard_error / out.stats.b;
    EXPECT_LT(b_relative_error, 0.015);
    EXPECT_NEAR(test::mean_luminance(final_image) / ref_mean, 1.0, 0.01 + 3.0 * b_relative_error);
    const double rel_mse = test::relative_mse(final_image.pixels, reference.image.pixels);
    EXPECT_LT(rel_mse, max_rel_mse);
    ::testing::Test::RecordProperty("relMSE", std::to_string(rel_mse));
}

TEST(GdmltBidirectional, L2ImageConvergesToThePathTracersWithAGlassSphere) {
    // 16x16, 1024 proposals per pixel (seed 9) against the path tracer at 4096 spp: the L2
    // image's mean (the primal's plus the unshifted layer's) within 1% plus 3 of b*'s standard
    // errors, and a small relMSE (a wrong sign or weight on an edge, or light tracing splatted
    // without its 1/pixels, gives errors of tens of percent).
    // Light tracing shifted (its differences and primal in the reconstructed layers).
    check_l2_image(test::scene_from_xml(test::cornell_box_xml(16, true)), 9, 0.01,
                   [](mlt::GdmltSettings& s) { s.shift_light_tracing = true; });
}

TEST(GdmltBidirectional, L2ImageConvergesToThePathTracersWithTheLightSealedInGlass) {
    // Light tracing unshifted, from the chains' states (added after the solve). The path
    // tracer's reference is noisy here (it reaches the light only through the glass by BSDF
    // sampling): measured 0.013.
    check_l2_image(test::scene_from_xml(test::sealed_light_box_xml(16)), 10, 0.03,
                   [](mlt::GdmltSettings& s) { s.light_tracing_pass = false; });
}

TEST(GdmltBidirectional, WithALightTracingPassTheImageStillConvergesToThePathTracers) {
    // Light tracing's share from a pass of its own (render_ptracer with BDPT's weights) and the
    // other strategies from the chains: the two halves' weights must sum to one on every path,
    // which needs the same subpaths (depth cap, no roulette) and the same light tracing scale
    // on both sides. Same scene, seed and bounds as the test above; 256 light paths per pixel
    // (light tracing carries most of the light here); the light tracing scale at 0.2 (which
    // moves light from the pass to the chains: a side that ignored it would be off by that).
    check_l2_image(test::scene_from_xml(test::sealed_light_box_xml(16)), 10, 0.03,
                   [](mlt::GdmltSettings& s) {
                       s.light_tracing_pass = true;
                       s.light_tracing_spp = 256;
                       s.light_tracing_mis = 0.2;
                   });
}

TEST(GdmltBidirectional, AutoChoosesBidirectionalSamplesWhereLightLeavesThroughGlass) {
    // The light sealed in a glass sphere: every emitted ray meets the glass first. The box
    // with a glass sphere: only the rays towards the sphere (it subtends a small part of the
    // light's hemisphere). The diffuse box: none. Deterministic (fixed numbers).
    const mlt::BidirectionalChoice sealed =
        mlt::choose_bidirectional(test::scene_from_xml(test::sealed_light_box_xml(8)));
    EXPECT_TRUE(sealed.bidirectional);
    EXPECT_EQ(sealed.rays, 4096);
    EXPECT_GT(sealed.specular_first_hit_fraction, 0.99);
    const mlt::BidirectionalChoice sphere =
        mlt::choose_bidirectional(test::scene_from_xml(test::cornell_box_xml(8, true)));
    EXPECT_FALSE(sphere.bidirectional);
    EXPECT_GT(sphere.specular_first_hit_fraction, 0.0);
    EXPECT_LT(sphere.specular_first_hit_fraction, 0.3);
    const mlt::BidirectionalChoice diffuse =
        mlt::choose_bidirectional(test::scene_from_xml(test::cornell_box_xml(8)));
    EXPECT_FALSE(diffuse.bidirectional);
    EXPECT_EQ(diffuse.specular_first_hit_fraction, 0.0);
}

/// The same seed gives bit-identical buffers at one and two threads (light sealed in glass,
/// 12x12, 16 proposals per pixel), with light tracing as `configure` sets it. Returns the
/// one-thread render.
mlt::GdmltOutput expect_same_buffers_at_one_and_two_threads(
    const std::function<void(mlt::GdmltSettings&)>& configure) {
    const Scene scene = test::scene_from_xml(test::sealed_light_box_xml(12));
    mlt::GdmltSettings s = bidirectional_gdmlt(4, 16);
    s.chains = 40;
    s.bootstrap_samples = 4000;
    s.bootstrap_relative_error = 0.0;
    configure(s);
    const auto [one, two] =
        test::at_one_and_two_threads([&] { return mlt::render_gdmlt(scene, s); });
    EXPECT_TRUE(one.buffers.primal == two.buffers.primal);
    EXPECT_TRUE(one.buffers.dx == two.buffers.dx);
    EXPECT_TRUE(one.buffers.dy == two.buffers.dy);
    EXPECT_TRUE(one.buffers.very_direct == two.buffers.very_direct);
    EXPECT_GT(test::mean_luminance(one.buffers.primal), 0.0);
    return one;
}

TEST(GdmltBidirectional, SameSeedGivesTheSameBuffersAtOneAndTwoThreads) {
    expect_same_buffers_at_one_and_two_threads(
        [](mlt::GdmltSettings& s) { s.shift_light_tracing = true; });
}

TEST(GdmltBidirectional, WithALightTracingPassTheSameSeedGivesTheSameBuffersAtOneAndTwoThreads) {
    const mlt::GdmltOutput one =
        expect_same_buffers_at_one_and_two_threads([](mlt::GdmltSettings& s) {
            s.light_tracing_pass = true;
            // 9216 light paths: three work items of 4096, so both threads trace.
            s.light_tracing_spp = 64;
        });
    EXPECT_GT(one.stats.light_paths, 0u);
    EXPECT_GT(test::mean_luminance(one.buffers.very_direct), 0.0);
}

}  // namespace
}  // namespace gdmlt
