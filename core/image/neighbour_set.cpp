// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/image/neighbour_set.h"

#include <algorithm>
#include <set>
#include <stdexcept>
#include <utility>

namespace gdmlt {

NeighbourSet NeighbourSet::lattice(int width, int height) {
    NeighbourSet s;
    s.width_ = std::max(width, 0);
    s.height_ = std::max(height, 0);
    for (int y = 0; y < s.height_; ++y)
        for (int x = 0; x + 1 < s.width_; ++x)
            s.edges_.push_back({y * s.width_ + x, y * s.width_ + x + 1});
    for (int y = 0; y + 1 < s.height_; ++y)
        for (int x = 0; x < s.width_; ++x)
            s.edges_.push_back({y * s.width_ + x, (y + 1) * s.width_ + x});
    s.build_links();
    return s;
}

NeighbourSet NeighbourSet::from_edges(int width, int height, std::vector<GradientEdge> edges) {
    NeighbourSet s;
    s.width_ = std::max(width, 0);
    s.height_ = std::max(height, 0);
    const auto n = static_cast<std::int64_t>(s.pixel_count());
    std::set<std::pair<std::int32_t, std::int32_t>> seen;
    for (const GradientEdge& e : edges) {
        if (e.from < 0 || e.to < 0 || e.from >= n || e.to >= n)
            throw std::invalid_argument("neighbour edge index out of range");
        if (e.from == e.to) throw std::invalid_argument("neighbour edge joins a pixel to itself");
        if (!seen.insert({std::min(e.from, e.to), std::max(e.from, e.to)}).second)
            throw std::invalid_argument("neighbour edge listed twice");
    }
    s.edges_ = std::move(edges);
    s.build_links();
    return s;
}

void NeighbourSet::build_links() {
    const std::size_t n = pixel_count();
    std::vector<std::uint32_t> count(n + 1, 0);
    for (const GradientEdge& e : edges_) {
        ++count[static_cast<std::size_t>(e.from)];
        ++count[static_cast<std::size_t>(e.to)];
    }
    first_link_.assign(n + 1, 0);
    for (std::size_t p = 0; p < n; ++p) first_link_[p + 1] = first_link_[p] + count[p];
    links_.assign(first_link_[n], NeighbourLink{});
    edge_links_.assign(edges_.size(), {0, 0});
    std::vector<std::uint32_t> fill(first_link_.begin(), first_link_.end() - 1);
    auto offset_between = [&](std::int32_t a, std::int32_t b) {
        return Vec2i(b % width_ - a % width_, b / width_ - a / width_);
    };
    for (std::size_t e = 0; e < edges_.size(); ++e) {
        const GradientEdge& edge = edges_[e];
        const auto from = static_cast<std::size_t>(edge.from);
        const auto to = static_cast<std::size_t>(edge.to);
        const std::uint32_t at_from = fill[from]++, at_to = fill[to]++;
        links_[at_from] = {offset_between(edge.from, edge.to), static_cast<std::int32_t>(e), true};
        links_[at_to] = {offset_between(edge.to, edge.from), static_cast<std::int32_t>(e), false};
        edge_links_[e] = {at_from, at_to};
    }
    // A fixed order per pixel, independent of how the edges were listed: by offset (+x, -x, +y,
    // -y for the lattice, then any longer offsets).
    auto rank = [](const Vec2i& o) {
        const int kind = o == Vec2i(1, 0)    ? 0
                         : o == Vec2i(-1, 0) ? 1
                         : o == Vec2i(0, 1)  ? 2
                         : o == Vec2i(0, -1) ? 3
                                             : 4;
        return std::tuple(kind, o.y(), o.x());
    };
    max_links_ = 0;
    for (std::size_t p = 0; p < n; ++p) {
        auto begin = links_.begin() + first_link_[p], end = links_.begin() + first_link_[p + 1];
        std::sort(begin, end, [&](const NeighbourLink& a, const NeighbourLink& b) {
            return rank(a.offset) < rank(b.offset);
        });
        max_links_ = std::max<std::size_t>(max_links_, first_link_[p + 1] - first_link_[p]);
        for (std::uint32_t l = first_link_[p]; l < first_link_[p + 1]; ++l)
            edge_links_[static_cast<std::size_t>(links_[l].edge)][links_[l].from_end ? 0 : 1] = l;
    }
}

void store_edge_differences(const NeighbourSet& set, std::span<const RgbD> differences,
                            GradientBuffers& buffers, std::span<const double> variances) {
    if (differences.size() != set.edges().size())
        throw std::invalid_argument("store_edge_differences: one difference per edge expected");
    const bool with_variance = !variances.empty();
    if (with_variance && variances.size() != set.edges().size())
        throw std::invalid_argument("store_edge_differences: one variance per edge expected");
    const int w = set.width(), h = set.height();
    buffers.dx = Image(w, h, 3);
    buffers.dy = Image(w, h, 3);
    buffers.extra_edges.clear();
    buffers.extra_differences.clear();
    buffers.dx_variance = with_variance ? Image(w, h, 1) : Image();
    buffers.dy_variance = with_variance ? Image(w, h, 1) : Image();
    buffers.extra_variances.clear();
    for (std::size_t e = 0; e < set.edges().size(); ++e) {
        const GradientEdge& edge = set.edges()[e];
        const int x = edge.from % w, y = edge.from / w;
        const bool is_dx = edge.to == edge.from + 1 && x + 1 < w;
        const bool is_dy = !is_dx && edge.to == edge.from + w;
        Image* layer = is_dx ? &buffers.dx : is_dy ? &buffers.dy : nullptr;
        for (int c = 0; c < 3; ++c) {
            const auto v = static_cast<float>(differences[e][c]);
            if (layer)
                (*layer)(x, y, c) = v;
            else
                buffers.extra_differences.push_back(v);
        }
        if (!layer) buffers.extra_edges.push_back(edge);
        if (!with_variance) continue;
        const auto v = static_cast<float>(variances[e]);
        if (is_dx)
            buffers.dx_variance(x, y) = v;
        else if (is_dy)
            buffers.dy_variance(x, y) = v;
        else
            buffers.extra_variances.push_back(v);
    }
}

}  // namespace gdmlt
