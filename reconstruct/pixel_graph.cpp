// SPDX-License-Identifier: GPL-3.0-or-later
#include "reconstruct/pixel_graph.h"

#include <stdexcept>

namespace gdmlt::reconstruct {

void PixelGraph::add_edge(std::int32_t from_pixel, std::int32_t to_pixel, float d_r, float d_g,
                          float d_b, float edge_weight) {
    from.push_back(from_pixel);
    to.push_back(to_pixel);
    difference.insert(difference.end(), {d_r, d_g, d_b});
    // Weights are materialised only once someone gives a weight other than 1.
    if (weight.empty() && edge_weight >= 0.f && edge_weight != 1.f)
        weight.assign(from.size() - 1, 1.f);
    if (!weight.empty()) weight.push_back(edge_weight < 0.f ? 1.f : edge_weight);
}

PixelGraph make_lattice_graph(int width, int height) {
    if (width <= 0 || height <= 0) throw std::invalid_argument("make_lattice_graph: empty size");
    PixelGraph g;
    g.width = width;
    g.height = height;
    const std::size_t edges = static_cast<std::size_t>(width - 1) * height +
                              static_cast<std::size_t>(width) * (height - 1);
    g.from.reserve(edges);
    g.to.reserve(edges);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x + 1 < width; ++x) {
            g.from.push_back(y * width + x);
            g.to.push_back(y * width + x + 1);
        }
    for (int y = 0; y + 1 < height; ++y)
        for (int x = 0; x < width; ++x) {
            g.from.push_back(y * width + x);
            g.to.push_back((y + 1) * width + x);
        }
    g.difference.assign(3 * edges, 0.f);
    return g;
}

PixelGraph make_lattice_graph(const Image& dx, const Image& dy) {
    const Image& ref = dx.pixels.empty() ? dy : dx;
    if (ref.pixels.empty()) throw std::invalid_argument("make_lattice_graph: no layers");
    if ((!dx.pixels.empty() && dx.channels != 3) || (!dy.pixels.empty() && dy.channels != 3))
        throw std::invalid_argument("make_lattice_graph: difference layers must be RGB");
    if (!dx.pixels.empty() && !dy.pixels.empty() &&
        (dx.width != dy.width || dx.height != dy.height))
        throw std::invalid_argument("make_lattice_graph: dx and dy differ in size");
    PixelGraph g;
    g.width = ref.width;
    g.height = ref.height;
    const int w = g.width, h = g.height;
    if (!dx.pixels.empty())
        for (int y = 0; y < h; ++y)
            for (int x = 0; x + 1 < w; ++x)
                g.add_edge(y * w + x, y * w + x + 1, dx(x, y, 0), dx(x, y, 1), dx(x, y, 2));
    if (!dy.pixels.empty())
        for (int y = 0; y + 1 < h; ++y)
            for (int x = 0; x < w; ++x)
                g.add_edge(y * w + x, (y + 1) * w + x, dy(x, y, 0), dy(x, y, 1), dy(x, y, 2));
    return g;
}

void set_differences_from_image(PixelGraph& graph, const Image& image) {
    if (image.width != graph.width || image.height != graph.height || image.channels != 3)
        throw std::invalid_argument("set_differences_from_image: image must be RGB, graph size");
    graph.difference.resize(3 * graph.edge_count());
    for (std::size_t e = 0; e < graph.edge_count(); ++e)
        for (std::size_t k = 0; k < 3; ++k)
            graph.difference[3 * e + k] =
                image.pixels[3 * static_cast<std::size_t>(graph.to[e]) + k] -
                image.pixels[3 * static_cast<std::size_t>(graph.from[e]) + k];
}

}  // namespace gdmlt::reconstruct
