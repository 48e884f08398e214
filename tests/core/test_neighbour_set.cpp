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

TEST(NeighbourSet, StoresLatticeEdgesInDxDyAndOthersAsExtraEdges) {
    // 3x2: (0,0)->(1,0) is dx(0,0); (1,0)->(1,1) is dy(1,0); (0,0)->(2,1) and the reversed
    // lattice pair (2,0)->(1,0) are extra edges (the latter keeps its own orientation).
    const NeighbourSet set = NeighbourSet::from_edges(3, 2, {{0, 1}, {1, 4}, {0, 5}, {2, 1}});
    const std::vector<RgbD> differences = {RgbD(1, 2, 3), RgbD(4, 5, 6), RgbD(7, 8, 9),
                                           RgbD(10, 11, 12)};
    GradientBuffers b;
    store_edge_differences(set, differences, b);
    EXPECT_EQ(b.dx(0, 0, 2), 3.f);
    EXPECT_EQ(b.dy(1, 0, 0), 4.f);
    float dx_sum = 0.f, dy_sum = 0.f;
    for (float v : b.dx.pixels) dx_sum += v;
    for (float v : b.dy.pixels) dy_sum += v;
    EXPECT_EQ(dx_sum, 6.f);
    EXPECT_EQ(dy_sum, 15.f);
    ASSERT_EQ(b.extra_edges.size(), 2u);
    EXPECT_EQ(b.extra_edges[0], (GradientEdge{0, 5}));
    EXPECT_EQ(b.extra_edges[1], (GradientEdge{2, 1}));
    ASSERT_EQ(b.extra_differences.size(), 6u);
    EXPECT_EQ(b.extra_differences[0], 7.f);
    EXPECT_EQ(b.extra_differences[5], 12.f);
    // No variances given: none kept.
    EXPECT_TRUE(b.dx_variance.pixels.empty());
    EXPECT_TRUE(b.extra_variances.empty());

    // Variances follow their edges, 1 channel, zero where a layer has no edge.
    const std::vector<double> variances = {0.5, 0.25, 0.125, 2.0};
    store_edge_differences(set, differences, b, variances);
    ASSERT_EQ(b.dx_variance.channels, 1);
    ASSERT_EQ(b.dy_variance.channels, 1);
    EXPECT_EQ(b.dx_variance(0, 0), 0.5f);
    EXPECT_EQ(b.dy_variance(1, 0), 0.25f);
    float dxv_sum = 0.f, dyv_sum = 0.f;
    for (float v : b.dx_variance.pixels) dxv_sum += v;
    for (float v : b.dy_variance.pixels) dyv_sum += v;
    EXPECT_EQ(dxv_sum, 0.5f);
    EXPECT_EQ(dyv_sum, 0.25f);
    EXPECT_EQ(b.extra_variances, (std::vector<float>{0.125f, 2.f}));
    // Without variances again: the old ones are cleared, not left beside new differences.
    store_edge_differences(set, differences, b);
    EXPECT_TRUE(b.dy_variance.pixels.empty());
    EXPECT_TRUE(b.extra_variances.empty());
    EXPECT_THROW(store_edge_differences(set, differences, b, std::vector<double>{1.0}),
                 std::invalid_argument);
}

}  // namespace
}  // namespace gdmlt
