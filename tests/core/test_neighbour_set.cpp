// SPDX-License-Identifier: GPL-3.0-or-later
// NeighbourSet: the lattice's links and edges, general edge lists, and where each edge's
// difference is stored.
#include <gtest/gtest.h>

#include <stdexcept>

#include "core/image/neighbour_set.h"

namespace gdmlt {
namespace {

TEST(NeighbourSet, LatticeLinksEveryPixelToItsNeighboursInsideTheImage) {
    const NeighbourSet set = NeighbourSet::lattice(4, 3);
    EXPECT_EQ(set.edges().size(), 3u * 3u + 4u * 2u);
    EXPECT_EQ(set.link_count(), 2 * set.edges().size());
    EXPECT_EQ(set.max_links(), 4u);
    // Corner (0, 0): +x and +y only; interior (1, 1): +x, -x, +y, -y in that order.
    const auto corner = set.links(0);
    ASSERT_EQ(corner.size(), 2u);
    EXPECT_EQ(corner[0].offset, Vec2i(1, 0));
    EXPECT_EQ(corner[1].offset, Vec2i(0, 1));
    const auto interior = set.links(1 * 4 + 1);
    ASSERT_EQ(interior.size(), 4u);
    const Vec2i order[4] = {Vec2i(1, 0), Vec2i(-1, 0), Vec2i(0, 1), Vec2i(0, -1)};
    for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(interior[k].offset, order[k]);
    // Every link points at its edge's other end, with the orientation flag of that end.
    for (std::size_t p = 0; p < set.pixel_count(); ++p)
        for (const NeighbourLink& link : set.links(p)) {
            const GradientEdge& e = set.edges()[static_cast<std::size_t>(link.edge)];
            const auto here = static_cast<std::int32_t>(p);
            EXPECT_EQ(link.from_end ? e.from : e.to, here);
            const std::int32_t other = link.from_end ? e.to : e.from;
            EXPECT_EQ(other, here + link.offset.y() * 4 + link.offset.x());
        }
    // edge_links names the flat index of each end's link.
    for (std::size_t e = 0; e < set.edges().size(); ++e) {
        const auto [at_from, at_to] = set.edge_links(e);
        EXPECT_LT(at_from, set.link_count());
        const std::size_t from = static_cast<std::size_t>(set.edges()[e].from);
        EXPECT_GE(at_from, set.first_link(from));
        EXPECT_LT(at_from, set.first_link(from + 1));
        EXPECT_NE(at_from, at_to);
    }
}

TEST(NeighbourSet, RejectsEdgesOutOfRangeSelfLoopsAndRepeats) {
    EXPECT_THROW(NeighbourSet::from_edges(2, 2, {{0, 4}}), std::invalid_argument);
    EXPECT_THROW(NeighbourSet::from_edges(2, 2, {{1, 1}}), std::invalid_argument);
    EXPECT_THROW(NeighbourSet::from_edges(2, 2, {{0, 3}, {3, 0}}), std::invalid_argument);
    EXPECT_NO_THROW(NeighbourSet::from_edges(2, 2, {{0, 3}, {1, 2}}));
}

TEST(NeighbourSet, StoresAFullLatticeInDxDyAndOtherEdgesInCanonicalOrder) {
    // 3x2 lattice (edges 0..6, listed with the horizontal (1,0)->(2,0) reversed) plus two
    // extra edges listed out of order and one of them reversed: (2,1)->(0,0) = {5, 0} with
    // offset (-2,-1) and (0,0)->(1,1) = {0, 4} with offset (1,1).
    std::vector<GradientEdge> edges = {{0, 1}, {2, 1}, {3, 4}, {4, 5}, {0, 3},
                                       {1, 4}, {2, 5}, {5, 0}, {0, 4}};
    const NeighbourSet set = NeighbourSet::from_edges(3, 2, edges);
    std::vector<RgbD> differences;
    for (int e = 0; e < 9; ++e) differences.emplace_back(e, 10 * e, 100 * e);
    GradientBuffers b;
    store_edge_differences(set, differences, b);
    ASSERT_EQ(b.dx.width, 3);
    ASSERT_EQ(b.dy.width, 3);
    EXPECT_EQ(b.dx(0, 0, 0), 0.f);
    EXPECT_EQ(b.dx(1, 0, 1), -10.f);  // {2, 1} estimates I(1) - I(2): dx(1,0) is its negative
    EXPECT_EQ(b.dx(1, 1, 2), 300.f);
    EXPECT_EQ(b.dy(2, 0, 0), 6.f);
    // Extras oriented from the smaller index, by offset (dy, dx): (0,0)->(2,1) has offset
    // (2, 1), (0,0)->(1,1) has (1, 1), so the latter comes first.
    ASSERT_EQ(b.extra_edges.size(), 2u);
    EXPECT_EQ(b.extra_edges[0], (GradientEdge{0, 4}));
    EXPECT_EQ(b.extra_edges[1], (GradientEdge{0, 5}));
    ASSERT_EQ(b.extra_differences.size(), 6u);
    EXPECT_EQ(b.extra_differences[0], 8.f);
    EXPECT_EQ(b.extra_differences[3], -7.f);  // {5, 0} reversed
    EXPECT_EQ(b.extra_differences[5], -700.f);
}

TEST(NeighbourSet, AnIncompleteLatticeDirectionIsStoredAsExtraEdgesSoNoMissingEdgeReadsAsZero) {
    // 3x2 without the horizontal edge (1,1)->(2,1): a zero there in dx would tell the solver
    // "these pixels are equal". The horizontal edges become extra edges; dy is complete.
    const NeighbourSet set =
        NeighbourSet::from_edges(3, 2, {{2, 5}, {0, 1}, {1, 2}, {3, 4}, {0, 3}, {1, 4}});
    std::vector<RgbD> differences;
    for (int e = 0; e < 6; ++e) differences.emplace_back(e, e, e);
    GradientBuffers b;
    store_edge_differences(set, differences, b);
    EXPECT_TRUE(b.dx.pixels.empty());
    ASSERT_EQ(b.dy.width, 3);
    EXPECT_EQ(b.dy(2, 0, 0), 0.f);
    EXPECT_EQ(b.dy(1, 0, 0), 5.f);
    // Horizontal edges by `from`.
    const std::vector<GradientEdge> expected = {{0, 1}, {1, 2}, {3, 4}};
    EXPECT_EQ(b.extra_edges, expected);
    const std::vector<float> expected_differences = {1, 1, 1, 2, 2, 2, 3, 3, 3};
    EXPECT_EQ(b.extra_differences, expected_differences);
    // No variances given: none kept.
    EXPECT_TRUE(b.dx_variance.pixels.empty());
    EXPECT_TRUE(b.extra_variances.empty());
}

TEST(NeighbourSet, VariancesFollowTheirEdges) {
    // Full 2x2 lattice (dx: {0,1},{2,3}; dy: {0,2},{1,3}) plus the diagonals {0,3} and {2,1}.
    const NeighbourSet set =
        NeighbourSet::from_edges(2, 2, {{0, 1}, {2, 3}, {0, 2}, {1, 3}, {0, 3}, {2, 1}});
    const std::vector<RgbD> differences(6, RgbD(1, 1, 1));
    const std::vector<double> variances = {0.5, 0.25, 0.125, 2.0, 4.0, 8.0};
    GradientBuffers b;
    store_edge_differences(set, differences, b, variances);
    ASSERT_EQ(b.dx_variance.channels, 1);
    ASSERT_EQ(b.dy_variance.channels, 1);
    EXPECT_EQ(b.dx_variance(0, 0), 0.5f);
    EXPECT_EQ(b.dx_variance(0, 1), 0.25f);
    EXPECT_EQ(b.dy_variance(0, 0), 0.125f);
    EXPECT_EQ(b.dy_variance(1, 0), 2.f);
    // Extras in canonical order: {1,2} (offset (-1, 1)) before {0,3} (offset (1, 1)).
    ASSERT_EQ(b.extra_edges, (std::vector<GradientEdge>{{1, 2}, {0, 3}}));
    EXPECT_EQ(b.extra_variances, (std::vector<float>{8.f, 4.f}));
    // Without variances again: the old ones are cleared, not left beside new differences.
    store_edge_differences(set, differences, b);
    EXPECT_TRUE(b.dy_variance.pixels.empty());
    EXPECT_TRUE(b.extra_variances.empty());
    EXPECT_THROW(store_edge_differences(set, differences, b, std::vector<double>{1.0}),
                 std::invalid_argument);
}

}  // namespace
}  // namespace gdmlt
