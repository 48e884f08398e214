// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/image/neighbour_set.h"

#include <algorithm>
#include <set>
#include <stdexcept>
#include <tuple>
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
    // A lattice layer holds its direction only when the set has every edge of it: a zero in a
    // layer means "difference 0", not "no edge" (ADAP drops some lattice edges).
    std::size_t horizontal = 0, vertical = 0;
    const auto unit_kind = [w](const GradientEdge& e) {
        const std::int32_t lo = std::min(e.from, e.to), hi = std::max(e.from, e.to);
        if (hi == lo + 1 && lo % w + 1 < w) return 1;
        if (hi == lo + w) return 2;
        return 0;
    };
    for (const GradientEdge& e : set.edges()) {
        const int kind = unit_kind(e);
        horizontal += kind == 1;
        vertical += kind == 2;
    }
    const bool full_dx = w > 1 && horizontal == static_cast<std::size_t>(w - 1) * h;
    const bool full_dy = h > 1 && vertical == static_cast<std::size_t>(h - 1) * w;
    buffers.dx = full_dx ? Image(w, h, 3) : Image();
    buffers.dy = full_dy ? Image(w, h, 3) : Image();
    buffers.dx_variance = full_dx && with_variance ? Image(w, h, 1) : Image();
    buffers.dy_variance = full_dy && with_variance ? Image(w, h, 1) : Image();
    buffers.extra_edges.clear();
    buffers.extra_differences.clear();
    buffers.extra_variances.clear();
    // Extra edges oriented from the smaller pixel index and ordered by offset (dy, dx), then by
    // `from`: the order in which core/image/gradient_layers.h reads them back from an EXR, so that
    // re-solving a file sees exactly the render's system.
    std::vector<std::size_t> extra;
    for (std::size_t e = 0; e < set.edges().size(); ++e) {
        const GradientEdge& edge = set.edges()[e];
        const int kind = unit_kind(edge);
        Image* layer = kind == 1 && full_dx   ? &buffers.dx
                       : kind == 2 && full_dy ? &buffers.dy
                                              : nullptr;
        if (!layer) {
            extra.push_back(e);
            continue;
        }
        const bool forward = edge.to > edge.from;
        const std::int32_t from = forward ? edge.from : edge.to;
        for (int c = 0; c < 3; ++c) {
            const auto v = static_cast<float>(differences[e][c]);
            (*layer)(from % w, from / w, c) = forward ? v : -v;
        }
        if (with_variance)
            (layer == &buffers.dx ? buffers.dx_variance : buffers.dy_variance)(from % w, from / w) =
                static_cast<float>(variances[e]);
    }
    const auto key = [&](std::size_t e) { return canonical_edge_key(set.edges()[e], w); };
    std::sort(extra.begin(), extra.end(),
              [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
    for (const std::size_t e : extra) {
        const GradientEdge& edge = set.edges()[e];
        const bool forward = edge.to > edge.from;
        buffers.extra_edges.push_back(forward ? edge : GradientEdge{edge.to, edge.from});
        for (int c = 0; c < 3; ++c) {
            const auto v = static_cast<float>(differences[e][c]);
            buffers.extra_differences.push_back(forward ? v : -v);
        }
        if (with_variance) buffers.extra_variances.push_back(static_cast<float>(variances[e]));
    }
}

}  // namespace gdmlt
