// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// NeighbourSet: which pixels each pixel takes gradients against.
// A set of undirected edges between the pixels of a width x height image, and per pixel the
// list of its links (the offset to the other end and the edge it belongs to). The 4-neighbour
// lattice of G-PT and GDMLT (Lehtinen et al. 2013) is one instance; ADAP's feature-selected
// neighbours (Manzi et al. 2014) another. Integrators read the links of the pixel a base path
// goes through and shift the path by each link's offset; the difference they estimate for an
// edge (from, to) is I(to) - I(from) (core/image/gradient_buffers.h).
//
// The set is frozen before sampling starts: the estimator stays unbiased because which offsets
// a pixel uses never depends on the samples.
#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <tuple>
#include <vector>

#include "core/image/gradient_buffers.h"
#include "core/math/types.h"

namespace gdmlt {

struct NeighbourLink {
    Vec2i offset = Vec2i::Zero();  // to the other end, in pixels
    std::int32_t edge = -1;        // index into NeighbourSet::edges()
    /// True when this pixel is the edge's `from`: a difference sampled here, I(other) - I(this),
    /// enters the edge with a plus sign; at the edge's `to` with a minus sign.
    bool from_end = true;
};

class NeighbourSet {
  public:
    NeighbourSet() = default;

    /// The 4-neighbour lattice: edges (x,y)->(x+1,y) for every x < width-1, then (x,y)->(x,y+1)
    /// for every y < height-1 (the order of reconstruct::make_lattice_graph). Per pixel the
    /// links are +x, -x, +y, -y, those that exist.
    static NeighbourSet lattice(int width, int height);

    /// Any graph: `edges` are undirected pixel pairs (y*width+x); both ends get a link. Throws
    /// std::invalid_argument for an index out of range, a self-loop or a repeated pair.
    static NeighbourSet from_edges(int width, int height, std::vector<GradientEdge> edges);

    int width() const { return width_; }
    int height() const { return height_; }
    std::size_t pixel_count() const { return static_cast<std::size_t>(width_) * height_; }
    const std::vector<GradientEdge>& edges() const { return edges_; }

    /// The links of pixel `pixel` (y*width+x), in a fixed order.
    std::span<const NeighbourLink> links(std::size_t pixel) const {
        return {links_.data() + first_link_[pixel], links_.data() + first_link_[pixel + 1]};
    }
    /// Index of the first link of `pixel` in the flat list of all links (links of one pixel are
    /// consecutive): lets integrators keep per-link sums in one array.
    std::size_t first_link(std::size_t pixel) const { return first_link_[pixel]; }
    std::size_t link_count() const { return links_.size(); }
    /// Flat link indices of an edge's two ends, at `from` and at `to`.
    std::array<std::uint32_t, 2> edge_links(std::size_t edge) const { return edge_links_[edge]; }
    /// The largest number of links of any pixel.
    std::size_t max_links() const { return max_links_; }

  private:
    void build_links();

    int width_ = 0;
    int height_ = 0;
    std::vector<GradientEdge> edges_;
    std::vector<std::uint32_t> first_link_;  // pixel_count + 1 entries
    std::vector<NeighbourLink> links_;
    std::vector<std::array<std::uint32_t, 2>> edge_links_;
    std::size_t max_links_ = 0;
};

/// The canonical order of edges (a function of the edge set alone, so that an EXR round trip
/// keeps it): by offset (dy, then dx) from the smaller pixel index to the larger, then by that
/// pixel. Compare keys with <.
inline std::tuple<int, int, int> canonical_edge_key(const GradientEdge& edge, int width) {
    const std::int32_t from = std::min(edge.from, edge.to), to = std::max(edge.from, edge.to);
    return {to / width - from / width, to % width - from % width, from};
}

/// Writes per-edge differences (RGB, I(to) - I(from), in the order of `set.edges()`) into the
/// buffers: when the set has every edge (x,y)->(x+1,y), they fill dx(x,y) (likewise dy);
/// every other edge goes to extra_edges / extra_differences, oriented from the smaller pixel
/// index and ordered by offset (dy, dx), then by that pixel. dx or dy stays empty when the set
/// lacks some edge of its direction (a 0 in a layer would read as "no change", not "no edge").
/// `variances` (one per edge, the variance of that edge's difference; empty = unknown) go the
/// same way to dx_variance / dy_variance (1 channel) and extra_variances; without them those
/// fields are cleared, so no stale variance outlives its differences.
void store_edge_differences(const NeighbourSet& set, std::span<const RgbD> differences,
                            GradientBuffers& buffers, std::span<const double> variances = {});

}  // namespace gdmlt
