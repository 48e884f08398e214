// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// PixelGraph: nodes are the pixels of a width x height image, each edge (from, to) carries an
// observed RGB difference estimating I(to) - I(from), an optional weight and an optional variance.
// The 4-neighbour lattice is one such graph; ADAP's neighbours (Manzi et al. 2014) are another.
// Replacing the lattice D_x, D_y by a general signed incidence matrix
// D (row e: -1 at from, +1 at to) leaves every screened Poisson and control-variate reconstruction
// unchanged, with L = D^T W D a weighted graph Laplacian.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/image/image.h"

namespace gdmlt::reconstruct {

struct PixelGraph {
    int width = 0;
    int height = 0;

    // Per edge, structure of arrays.
    std::vector<std::int32_t> from;
    std::vector<std::int32_t> to;
    std::vector<float> difference;  // 3 per edge (RGB): I(to) - I(from)
    /// Optional, one per edge (empty = all 1). Non-finite or negative weights drop the edge.
    std::vector<float> weight;
    /// Optional, one per edge (empty = unknown): variance of the difference, for control variates.
    std::vector<float> variance;

    std::size_t node_count() const { return static_cast<std::size_t>(width) * height; }
    std::size_t edge_count() const { return from.size(); }

    /// Appends an edge. `weight` < 0 means "no weight given" (stored as 1 if the graph has
    /// weights). Indices are checked when the solvers compile the graph, not here. Does not
    /// touch `variance`: a caller that uses variances appends one per edge itself.
    void add_edge(std::int32_t from_pixel, std::int32_t to_pixel, float d_r, float d_g, float d_b,
                  float edge_weight = 1.f);
};

/// The 4-neighbour lattice: edges (x,y)->(x+1,y) for every x < width-1, then (x,y)->(x,y+1) for
/// every y < height-1, with zero differences. Pair with set_differences_from_image or fill
/// `difference` directly.
PixelGraph make_lattice_graph(int width, int height);

/// The lattice with the differences of the forward-difference layers dx, dy (RGB, see
/// core/image/gradient_buffers.h for the sign convention). Either layer may be empty (no edges
/// in that direction).
PixelGraph make_lattice_graph(const Image& dx, const Image& dy);

/// Overwrites every edge's difference with the exact difference of `image` (RGB): used by tests
/// and by benchmarks that synthesise inputs from a known image.
void set_differences_from_image(PixelGraph& graph, const Image& image);

}  // namespace gdmlt::reconstruct
