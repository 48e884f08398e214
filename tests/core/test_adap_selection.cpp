// SPDX-License-Identifier: GPL-3.0-or-later
// ADAP neighbour selection on hand-made feature images: an edge in one feature only (albedo,
// normal, depth, shape) is never crossed where the window offers neighbours on the pixel's own
// side; the graph is symmetric, keeps unit links on both axes, and is a lattice where the
// features are flat. Features here are exact (no variance layers): tau = 0.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>

#include "core/render/adap_selection.h"

namespace gdmlt {
namespace {

constexpr int kW = 12, kH = 10;

/// Flat features: grey albedo, normal +z, depth 2, shape 0.
FeatureImages flat_features() {
    FeatureImages f;
    f.albedo = Image(kW, kH, 3, 0.5f);
    f.normal = Image(kW, kH, 3, 0.f);
    for (std::size_t i = 0; i < f.normal.pixel_count(); ++i) f.normal.pixels[3 * i + 2] = 1.f;
    f.depth = Image(kW, kH, 1, 2.f);
    f.shape_id = Image(kW, kH, 1, 0.f);
    return f;
}

/// Features with a vertical edge between x = 5 and x = 6, made by `change` on the right side.
FeatureImages edge_features(const std::function<void(FeatureImages&, int x, int y)>& change) {
    FeatureImages f = flat_features();
    for (int y = 0; y < kH; ++y)
        for (int x = 6; x < kW; ++x) change(f, x, y);
    return f;
}

int side(int pixel) {
    return pixel % kW >= 6 ? 1 : 0;
}

/// Edges with one end on each side of the feature edge.
int crossing_edges(const NeighbourSet& set) {
    int n = 0;
    for (const GradientEdge& e : set.edges()) n += side(e.from) != side(e.to);
    return n;
}

void expect_no_crossing(const FeatureImages& f, const char* what) {
    const NeighbourSet set = select_adap_neighbours(f, AdapSettings{});
    // Every pixel finds K = 4 equally similar candidates on its own side within radius 2 (its
    // own-side lattice neighbours and diagonals), so no edge crosses.
    EXPECT_EQ(crossing_edges(set), 0) << what;
    // The lattice would cross kH times.
    EXPECT_EQ(crossing_edges(NeighbourSet::lattice(kW, kH)), kH);
}

bool on_border(int pixel) {
    const int x = pixel % kW, y = pixel / kW;
    return x == 0 || y == 0 || x == kW - 1 || y == kH - 1;
}

/// Flat features: the lattice, plus (on the border, where fewer than K = 4 unit neighbours
/// exist) the nearest diagonals.
void expect_lattice_inside(const NeighbourSet& set) {
    const NeighbourSet lattice = NeighbourSet::lattice(kW, kH);
    for (const GradientEdge& e : lattice.edges())
        EXPECT_NE(std::find(set.edges().begin(), set.edges().end(), e), set.edges().end());
    for (const GradientEdge& e : set.edges()) {
        const bool in_lattice =
            std::find(lattice.edges().begin(), lattice.edges().end(), e) != lattice.edges().end();
        EXPECT_TRUE(in_lattice || on_border(e.from) || on_border(e.to)) << e.from << "-" << e.to;
    }
}

TEST(AdapSelection, AFlatImageGivesTheLatticeAwayFromTheBorder) {
    expect_lattice_inside(select_adap_neighbours(flat_features(), AdapSettings{}));
}

TEST(AdapSelection, NeverCrossesAnEdgeInAlbedoAlone) {
    expect_no_crossing(edge_features([](FeatureImages& f, int x, int y) {
                           for (int c = 0; c < 3; ++c) f.albedo(x, y, c) = 0.9f;
                       }),
                       "albedo");
}

TEST(AdapSelection, NeverCrossesAnEdgeInNormalAlone) {
    expect_no_crossing(edge_features([](FeatureImages& f, int x, int y) {
                           f.normal(x, y, 0) = 1.f;
                           f.normal(x, y, 2) = 0.f;
                       }),
                       "normal");
}

TEST(AdapSelection, NeverCrossesAnEdgeInDepthAlone) {
    expect_no_crossing(edge_features([](FeatureImages& f, int x, int y) { f.depth(x, y) = 3.f; }),
                       "depth");
}

TEST(AdapSelection, NeverCrossesAnEdgeInShapeAlone) {
    expect_no_crossing(
        edge_features([](FeatureImages& f, int x, int y) { f.shape_id(x, y) = 7.f; }), "shape");
}

TEST(AdapSelection, NoiseWithinTheFeaturesVarianceIsNotAnEdge) {
    // Albedo steps by 0.1 (|d|^2 = 0.03 over RGB, weight exp(-3) with sigma 0.1) but each
    // pixel's albedo mean has variance 0.01 per channel: tau = 3 * 0.02 = 0.06 covers it, so the
    // step counts as noise and the graph is the lattice again.
    FeatureImages f = edge_features([](FeatureImages& g, int x, int y) {
        for (int c = 0; c < 3; ++c) g.albedo(x, y, c) = 0.6f;
    });
    EXPECT_EQ(crossing_edges(select_adap_neighbours(f, AdapSettings{})), 0);
    f.albedo_variance = Image(kW, kH, 1, 0.01f);
    expect_lattice_inside(select_adap_neighbours(f, AdapSettings{}));
}

TEST(AdapSelection, GraphIsSymmetricAndEveryPixelHasUnitLinksOnBothAxes) {
    // A one-pixel-wide stripe of another albedo at x = 4 and a checkerboard of shapes in the
    // lower half: pixels with no similar lattice neighbour on an axis.
    FeatureImages f = flat_features();
    for (int y = 0; y < kH; ++y) f.albedo(4, y, 0) = 0.f;
    for (int y = kH / 2; y < kH; ++y)
        for (int x = 0; x < kW; ++x) f.shape_id(x, y) = static_cast<float>((x + y) % 2);
    for (const bool mutual : {false, true}) {
        AdapSettings s;
        s.mutual = mutual;
        const NeighbourSet set = select_adap_neighbours(f, s);
        for (std::size_t p = 0; p < set.pixel_count(); ++p) {
            bool horizontal = false, vertical = false;
            for (const NeighbourLink& link : set.links(p)) {
                horizontal = horizontal || (link.offset.y() == 0 && std::abs(link.offset.x()) == 1);
                vertical = vertical || (link.offset.x() == 0 && std::abs(link.offset.y()) == 1);
                // Symmetric: the other end has the opposite link on the same edge.
                const auto other = static_cast<std::size_t>(static_cast<int>(p) +
                                                            link.offset.y() * kW + link.offset.x());
                bool back = false;
                for (const NeighbourLink& l : set.links(other))
                    back = back || (l.edge == link.edge && l.offset == Vec2i(-link.offset));
                EXPECT_TRUE(back) << "pixel " << p;
            }
            EXPECT_TRUE(horizontal && vertical) << "pixel " << p << " mutual " << mutual;
        }
        // The stripe's pixels have no similar neighbour: they keep their unit links anyway, and
        // the shapes' checkerboard pushes the lower half towards diagonals (same parity).
        bool diagonal = false;
        for (const GradientEdge& e : set.edges())
            diagonal = diagonal || (e.to - e.from == kW + 1 && e.from / kW >= kH / 2);
        EXPECT_TRUE(diagonal) << "mutual " << mutual;
    }
}

TEST(AdapSelection, EveryPixelKeepsItsNearestSimilarCandidatesThenTheMostSimilarOthers) {
    // Union symmetrisation: each pixel's own K choices are all among its links. K = 6 on a depth
    // ramp that steepens to the right, so that some pixels have K candidates with
    // w >= min_similarity (then the nearest of them count) and others fewer (then the most
    // similar of the rest fill up).
    FeatureImages f = flat_features();
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            f.depth(x, y) = 1.f + 0.004f * static_cast<float>(x * x * x + y);
    AdapSettings s;
    s.neighbours = 6;
    const NeighbourSet set = select_adap_neighbours(f, s);
    int pixels_with_few_similar = 0, pixels_with_enough = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            const int i = y * kW + x;
            struct C {
                Vec2i offset;
                float w;
            };
            std::vector<C> similar, other;
            for (int dy = -2; dy <= 2; ++dy)
                for (int dx = -2; dx <= 2; ++dx) {
                    if ((dx == 0 && dy == 0) || x + dx < 0 || y + dy < 0 || x + dx >= kW ||
                        y + dy >= kH)
                        continue;
                    const float w = adap_similarity(f, s, i, i + dy * kW + dx);
                    (w >= s.min_similarity ? similar : other).push_back({Vec2i(dx, dy), w});
                }
            const auto linked = [&](const Vec2i& o) {
                for (const NeighbourLink& l : set.links(static_cast<std::size_t>(i)))
                    if (l.offset == o) return true;
                return false;
            };
            if (similar.size() >= 6) {
                ++pixels_with_enough;
                // Every similar candidate nearer than the 6th nearest similar one is linked.
                std::vector<int> d2;
                for (const C& c : similar) d2.push_back(c.offset.squaredNorm());
                std::sort(d2.begin(), d2.end());
                for (const C& c : similar)
                    EXPECT_TRUE(c.offset.squaredNorm() >= d2[5] || linked(c.offset))
                        << x << "," << y << " near similar";
            } else {
                ++pixels_with_few_similar;
                for (const C& c : similar) EXPECT_TRUE(linked(c.offset)) << x << "," << y;
                // The rest by similarity: every other candidate more similar than the one that
                // filled the last place is linked.
                std::vector<float> w;
                for (const C& c : other) w.push_back(c.w);
                std::sort(w.begin(), w.end(), std::greater<>());
                const float last = w[5 - similar.size()];
                for (const C& c : other)
                    EXPECT_TRUE(c.w <= last || linked(c.offset)) << x << "," << y << " fill";
            }
        }
    // Both regimes occur, or the test checks only one rule.
    EXPECT_GT(pixels_with_enough, 10);
    EXPECT_GT(pixels_with_few_similar, 10);
}

TEST(AdapSelection, SimilarityFollowsTheThresholdedExponential) {
    FeatureImages f = flat_features();
    f.albedo(1, 0, 0) = 0.7f;  // |d|^2 = 0.04 against pixel 0
    AdapSettings s;
    // 1e-6 relative: single-precision exp of the same argument computed in another order.
    EXPECT_NEAR(adap_similarity(f, s, 0, 1), std::exp(-0.04f / (0.1f * 0.1f)), 1e-6);
    f.albedo_variance = Image(kW, kH, 1, 0.005f);  // tau = 3 * 0.01 = 0.03
    EXPECT_NEAR(adap_similarity(f, s, 0, 1), std::exp(-0.01f / (0.1f * 0.1f)), 1e-6);
    EXPECT_FLOAT_EQ(adap_similarity(f, s, 0, 2), 1.f);
    s.sigma_albedo = 0.f;  // off
    EXPECT_FLOAT_EQ(adap_similarity(f, s, 0, 1), 1.f);
}

TEST(AdapSelection, RejectsBadSettings) {
    AdapSettings s;
    s.neighbours = 0;
    EXPECT_THROW(select_adap_neighbours(flat_features(), s), std::invalid_argument);
    s = AdapSettings{};
    s.window_radius = 0;
    EXPECT_THROW(select_adap_neighbours(flat_features(), s), std::invalid_argument);
    s = AdapSettings{};
    s.sigma_depth = -1.f;
    EXPECT_THROW(select_adap_neighbours(flat_features(), s), std::invalid_argument);
    EXPECT_THROW(select_adap_neighbours(FeatureImages{}, AdapSettings{}), std::invalid_argument);
}

}  // namespace
}  // namespace gdmlt
