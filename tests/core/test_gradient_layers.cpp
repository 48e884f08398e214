// SPDX-License-Identifier: GPL-3.0-or-later
// Gradient buffers <-> EXR layers: a file written and read back gives the same buffers, with
// extra edges in the same order, so `gdmlt reconstruct` re-solves exactly the render's system.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <limits>
#include <random>

#include "core/image/gradient_layers.h"
#include "core/image/neighbour_set.h"
#include "core/scene/scene_desc.h"
#include "tests/support/scene_fixtures.h"

namespace gdmlt {
namespace {

/// A graph over 7x5 pixels with every edge of a radius-2 window chosen at random (seed 3), so
/// that lattice edges are missing in places and offsets of every sign occur.
NeighbourSet random_graph(std::uint32_t seed, bool full_lattice) {
    const int w = 7, h = 5;
    std::mt19937 rng(seed);
    std::bernoulli_distribution keep(0.3);
    std::vector<GradientEdge> edges;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int dy = 0; dy <= 2; ++dy)
                for (int dx = -2; dx <= 2; ++dx) {
                    if (dy == 0 && dx <= 0) continue;
                    if (x + dx < 0 || x + dx >= w || y + dy >= h) continue;
                    const bool unit = (dy == 0 && dx == 1) || (dy == 1 && dx == 0);
                    if (!(unit && full_lattice) && !keep(rng)) continue;
                    // List some edges backwards: storage must orient them.
                    const int a = y * w + x, b = (y + dy) * w + x + dx;
                    edges.push_back(keep(rng) ? GradientEdge{b, a} : GradientEdge{a, b});
                }
    std::shuffle(edges.begin(), edges.end(), rng);
    return NeighbourSet::from_edges(w, h, edges);
}

GradientBuffers buffers_of(const NeighbourSet& set, bool with_variances) {
    std::vector<RgbD> d;
    for (std::size_t e = 0; e < set.edges().size(); ++e)
        d.emplace_back(0.5 * static_cast<double>(e), -1.0 * static_cast<double>(e), 0.25);
    GradientBuffers b;
    store_edge_differences(set, d, b);
    b.primal = Image(set.width(), set.height(), 3, 0.75f);
    b.very_direct = Image(set.width(), set.height(), 3, 0.125f);
    if (with_variances) {
        b.primal_variance = Image(set.width(), set.height(), 1, 0.01f);
        for (std::size_t e = 0; e < b.extra_edges.size(); ++e)
            b.extra_variances.push_back(0.001f * static_cast<float>(e));
    }
    return b;
}

void expect_same(const GradientBuffers& a, const GradientBuffers& b) {
    EXPECT_EQ(a.primal, b.primal);
    EXPECT_EQ(a.dx, b.dx);
    EXPECT_EQ(a.dy, b.dy);
    EXPECT_EQ(a.very_direct, b.very_direct);
    EXPECT_EQ(a.sample_count, b.sample_count);
    EXPECT_EQ(a.primal_variance, b.primal_variance);
    EXPECT_EQ(a.dx_variance, b.dx_variance);
    EXPECT_EQ(a.dy_variance, b.dy_variance);
    EXPECT_EQ(a.extra_edges, b.extra_edges);
    EXPECT_EQ(a.extra_differences, b.extra_differences);
    EXPECT_EQ(a.extra_variances, b.extra_variances);
}

GradientBuffers write_and_read(const GradientBuffers& b, const std::string& name) {
    const auto path = std::filesystem::temp_directory_path() /
                      ("gdmlt_test_" + std::to_string(::getpid()) + "_" + name + ".exr");
    write_exr(path.string(), gradient_layers(b));
    GradientBuffers back = gradient_buffers_from_layers(read_exr(path.string()), path.string());
    std::filesystem::remove(path);
    return back;
}

TEST(GradientLayers, EveryLatticeLayerAndVarianceRoundTripsExactly) {
    // Every layer `gdmlt reconstruct` needs to reproduce a render's solve comes back bit for
    // bit, including infinite variances (pixels with fewer than 2 samples); dropping any of
    // them from gradient_layers or gradient_buffers_from_layers fails here.
    const int w = 9, h = 6;
    GradientBuffers b;
    b.primal = test::ramp_image(w, h, 3, 0.25f);
    b.dx = test::ramp_image(w, h, 3, -1.f);
    b.dy = test::ramp_image(w, h, 3, 2.f);
    b.very_direct = test::ramp_image(w, h, 3, 5.f);
    b.sample_count = test::ramp_image(w, h, 1, 16.f);
    b.primal_variance = test::ramp_image(w, h, 1, 1e-3f);
    b.primal_variance(4, 2) = std::numeric_limits<float>::infinity();
    b.dx_variance = test::ramp_image(w, h, 1, 3e-3f);
    b.dy_variance = test::ramp_image(w, h, 3, 7e-3f);  // the per-channel form comes back as R, G, B
    expect_same(b, write_and_read(b, "lattice"));

    // Absent layers stay absent (GDMLT: no sample counts; here no variances either).
    GradientBuffers chain;
    chain.primal = b.primal;
    chain.dx = b.dx;
    const GradientBuffers c = write_and_read(chain, "chain");
    expect_same(chain, c);
    EXPECT_TRUE(c.dy.pixels.empty());
    EXPECT_TRUE(c.sample_count.pixels.empty());
}

TEST(GradientLayers, AGraphWithMissingLatticeEdgesSurvivesAnExrRoundTrip) {
    for (const bool full : {false, true})
        for (const bool variances : {false, true}) {
            const GradientBuffers b = buffers_of(random_graph(3, full), variances);
            ASSERT_EQ(b.dx.pixels.empty(), !full);
            ASSERT_FALSE(b.extra_edges.empty());
            expect_same(b, write_and_read(b, "graph"));
        }
}

TEST(GradientLayers, EdgeLayersHoldForwardOffsetsWithNanWhereNoEdge) {
    const GradientBuffers b = buffers_of(random_graph(5, false), false);
    for (const ExrLayer& l : gradient_layers(b)) {
        if (l.name.rfind("edge_", 0) != 0) continue;
        int nan = 0, finite = 0;
        for (const float v : l.image.pixels) (std::isnan(v) ? nan : finite) += 1;
        EXPECT_GT(nan, 0) << l.name;
        EXPECT_GT(finite, 0) << l.name;
    }
}

TEST(GradientLayers, RejectsFilesWithoutPrimalOrDifferences) {
    GradientBuffers b;
    b.primal = Image(3, 2, 3, 1.f);
    EXPECT_THROW(gradient_buffers_from_layers(gradient_layers(b), "x.exr"), InputError);
    EXPECT_THROW(gradient_buffers_from_layers({}, "x.exr"), InputError);
    // A backward offset layer is malformed (writers only produce forward ones).
    std::vector<ExrLayer> layers = gradient_layers(b);
    layers.push_back({"edge_1_-1", {"R", "G", "B"}, Image(3, 2, 3, 0.f)});
    EXPECT_THROW(gradient_buffers_from_layers(layers, "x.exr"), InputError);
}

}  // namespace
}  // namespace gdmlt
