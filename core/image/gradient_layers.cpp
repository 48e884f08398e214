// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/image/gradient_layers.h"

#include <stdexcept>

#include "core/scene/scene_desc.h"

namespace gdmlt {
namespace {

const ExrLayer* find_layer(const std::vector<ExrLayer>& layers, const std::string& name) {
    for (const ExrLayer& l : layers)
        if (l.name == name) return &l;
    return nullptr;
}

/// The R,G,B channels of a layer, in that order, as a 3-channel image.
Image rgb_of(const ExrLayer& layer, const std::string& file) {
    int index[3] = {-1, -1, -1};
    const char* names[3] = {"R", "G", "B"};
    for (std::size_t c = 0; c < layer.channel_names.size(); ++c)
        for (int k = 0; k < 3; ++k)
            if (layer.channel_names[c] == names[k]) index[k] = static_cast<int>(c);
    if (index[0] < 0 || index[1] < 0 || index[2] < 0)
        throw InputError(file + ": layer '" + layer.name + "' needs channels R, G, B");
    const Image& src = layer.image;
    Image out(src.width, src.height, 3);
    for (std::size_t i = 0; i < src.pixel_count(); ++i)
        for (int k = 0; k < 3; ++k)
            out.pixels[3 * i + static_cast<std::size_t>(k)] =
                src.pixels[i * static_cast<std::size_t>(src.channels) +
                           static_cast<std::size_t>(index[k])];
    return out;
}

/// A 1-channel layer as is, a 3-channel one as R, G, B (the two forms GradientBuffers allows
/// for variances).
Image one_or_rgb_of(const ExrLayer& layer, const std::string& file) {
    if (layer.image.channels == 1) return layer.image;
    if (layer.image.channels == 3) return rgb_of(layer, file);
    throw InputError(file + ": layer '" + layer.name + "' must have 1 channel or R, G, B");
}

void add_layer(std::vector<ExrLayer>& layers, const char* name, const Image& image) {
    if (image.pixels.empty()) return;
    std::vector<std::string> channels;
    if (image.channels == 1)
        channels = {"Y"};
    else if (image.channels == 3)
        channels = {"R", "G", "B"};
    else
        throw std::invalid_argument(std::string("gradient layer '") + name +
                                    "' must have 1 or 3 channels");
    layers.push_back(ExrLayer{name, std::move(channels), image});
}

}  // namespace

std::vector<ExrLayer> gradient_layers(const GradientBuffers& b) {
    if (!b.extra_edges.empty())
        throw std::invalid_argument("gradient_layers: extra edges have no EXR layer");
    std::vector<ExrLayer> layers;
    add_layer(layers, "primal", b.primal);
    add_layer(layers, "dx", b.dx);
    add_layer(layers, "dy", b.dy);
    add_layer(layers, "very_direct", b.very_direct);
    add_layer(layers, "sample_count", b.sample_count);
    add_layer(layers, "primal_variance", b.primal_variance);
    add_layer(layers, "dx_variance", b.dx_variance);
    add_layer(layers, "dy_variance", b.dy_variance);
    return layers;
}

GradientBuffers gradient_buffers_from_layers(const std::vector<ExrLayer>& layers,
                                             const std::string& file) {
    GradientBuffers b;
    const ExrLayer* primal = find_layer(layers, "primal");
    if (!primal) throw InputError(file + ": no 'primal' layer (is this a gradient-domain render?)");
    b.primal = rgb_of(*primal, file);
    const ExrLayer* dx = find_layer(layers, "dx");
    const ExrLayer* dy = find_layer(layers, "dy");
    if (!dx && !dy) throw InputError(file + ": no 'dx' or 'dy' layer");
    if (dx) b.dx = rgb_of(*dx, file);
    if (dy) b.dy = rgb_of(*dy, file);
    if (const ExrLayer* v = find_layer(layers, "very_direct")) b.very_direct = rgb_of(*v, file);
    if (const ExrLayer* n = find_layer(layers, "sample_count")) b.sample_count = n->image;
    if (const ExrLayer* v = find_layer(layers, "primal_variance"))
        b.primal_variance = one_or_rgb_of(*v, file);
    if (const ExrLayer* v = find_layer(layers, "dx_variance"))
        b.dx_variance = one_or_rgb_of(*v, file);
    if (const ExrLayer* v = find_layer(layers, "dy_variance"))
        b.dy_variance = one_or_rgb_of(*v, file);
    return b;
}

}  // namespace gdmlt
