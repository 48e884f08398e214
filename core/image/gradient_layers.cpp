// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/image/gradient_layers.h"

#include <algorithm>
#include <charconv>
#include <limits>
#include <map>
#include <tuple>

#include "core/scene/scene_desc.h"

namespace gdmlt {
namespace {

using Offset = std::pair<int, int>;  // (dy, dx): the canonical order of edge layers

std::string edge_layer_name(const Offset& o) {
    return "edge_" + std::to_string(o.second) + "_" + std::to_string(o.first);
}

/// (dy, dx) of a layer named edge_<dx>_<dy>; false for any other name.
bool parse_edge_layer(const std::string& name, Offset& o) {
    if (name.rfind("edge_", 0) != 0) return false;
    const std::string rest = name.substr(5);
    const auto sep = rest.find('_');
    if (sep == std::string::npos) return false;
    int dx = 0, dy = 0;
    const char* a = rest.data();
    const auto r1 = std::from_chars(a, a + sep, dx);
    const auto r2 = std::from_chars(a + sep + 1, a + rest.size(), dy);
    if (r1.ec != std::errc() || r1.ptr != a + sep || r2.ec != std::errc() ||
        r2.ptr != a + rest.size())
        return false;
    o = {dy, dx};
    return true;
}

const ExrLayer* find_layer(const std::vector<ExrLayer>& layers, const std::string& name) {
    for (const ExrLayer& l : layers)
        if (l.name == name) return &l;
    return nullptr;
}

/// The channels `names` of a layer, in that order.
Image channels_of(const ExrLayer& layer, const std::vector<std::string>& names,
                  const std::string& file) {
    std::vector<std::size_t> index;
    for (const std::string& n : names) {
        const auto it = std::find(layer.channel_names.begin(), layer.channel_names.end(), n);
        if (it == layer.channel_names.end()) {
            std::string list;
            for (const std::string& m : names) list += (list.empty() ? "" : ", ") + m;
            throw InputError(file + ": layer '" + layer.name + "' needs channels " + list);
        }
        index.push_back(static_cast<std::size_t>(it - layer.channel_names.begin()));
    }
    const Image& src = layer.image;
    Image out(src.width, src.height, static_cast<int>(names.size()));
    for (std::size_t i = 0; i < src.pixel_count(); ++i)
        for (std::size_t k = 0; k < index.size(); ++k)
            out.pixels[i * index.size() + k] =
                src.pixels[i * static_cast<std::size_t>(src.channels) + index[k]];
    return out;
}

Image rgb(const ExrLayer& l, const std::string& file) {
    return channels_of(l, {"R", "G", "B"}, file);
}
Image luminance_layer(const ExrLayer& l, const std::string& file) {
    return channels_of(l, {"Y"}, file);
}
/// Variance layers: one channel (the mean over RGB) or one per RGB channel.
Image variance_layer(const ExrLayer& l, const std::string& file) {
    const bool has_y =
        std::find(l.channel_names.begin(), l.channel_names.end(), "Y") != l.channel_names.end();
    if (!has_y && l.channel_names.size() != 3)
        throw InputError(file + ": variance layer '" + l.name + "' needs channel Y or R, G, B");
    return has_y ? luminance_layer(l, file) : rgb(l, file);
}

}  // namespace

std::vector<ExrLayer> gradient_layers(const GradientBuffers& b) {
    const std::vector<std::string> rgb_names = {"R", "G", "B"}, y_names = {"Y"};
    std::vector<ExrLayer> layers;
    const auto add = [&](const std::string& name, const Image& image) {
        if (image.pixels.empty()) return;
        layers.push_back({name, image.channels == 3 ? rgb_names : y_names, image});
    };
    add("primal", b.primal);
    add("dx", b.dx);
    add("dy", b.dy);
    add("very_direct", b.very_direct);
    add("primal_variance", b.primal_variance);
    add("dx_variance", b.dx_variance);
    add("dy_variance", b.dy_variance);
    add("sample_count", b.sample_count);

    // Extra edges: one layer per offset, NaN where a pixel has no edge of that offset.
    const int w = b.primal.width, h = b.primal.height;
    const bool with_variance = b.extra_variances.size() == b.extra_edges.size();
    std::map<Offset, std::pair<Image, Image>> by_offset;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t e = 0; e < b.extra_edges.size(); ++e) {
        const GradientEdge& edge = b.extra_edges[e];
        const Offset o{edge.to / w - edge.from / w, edge.to % w - edge.from % w};
        auto [it, inserted] = by_offset.try_emplace(o);
        if (inserted) {
            it->second.first = Image(w, h, 3, nan);
            if (with_variance) it->second.second = Image(w, h, 1, nan);
        }
        const int x = edge.from % w, y = edge.from / w;
        for (int c = 0; c < 3; ++c)
            it->second.first(x, y, c) = b.extra_differences[3 * e + static_cast<std::size_t>(c)];
        if (with_variance) it->second.second(x, y) = b.extra_variances[e];
    }
    for (const auto& [o, images] : by_offset) {
        add(edge_layer_name(o), images.first);
        add(edge_layer_name(o) + "_variance", images.second);
    }
    return layers;
}

GradientBuffers gradient_buffers_from_layers(const std::vector<ExrLayer>& layers,
                                             const std::string& file) {
    GradientBuffers b;
    const ExrLayer* primal = find_layer(layers, "primal");
    if (!primal) throw InputError(file + ": no 'primal' layer (is this a gradient-domain render?)");
    b.primal = rgb(*primal, file);
    if (const ExrLayer* l = find_layer(layers, "dx")) b.dx = rgb(*l, file);
    if (const ExrLayer* l = find_layer(layers, "dy")) b.dy = rgb(*l, file);
    if (const ExrLayer* l = find_layer(layers, "very_direct")) b.very_direct = rgb(*l, file);
    if (const ExrLayer* l = find_layer(layers, "primal_variance"))
        b.primal_variance = variance_layer(*l, file);
    if (const ExrLayer* l = find_layer(layers, "dx_variance"))
        b.dx_variance = variance_layer(*l, file);
    if (const ExrLayer* l = find_layer(layers, "dy_variance"))
        b.dy_variance = variance_layer(*l, file);
    if (const ExrLayer* l = find_layer(layers, "sample_count"))
        b.sample_count = luminance_layer(*l, file);

    std::map<Offset, const ExrLayer*> edge_layers;
    for (const ExrLayer& l : layers) {
        Offset o;
        if (parse_edge_layer(l.name, o)) {
            if (!(o.first > 0 || (o.first == 0 && o.second > 0)))
                throw InputError(
                    file + ": layer '" + l.name +
                    "': edge offsets must point forward (dy > 0, or dy = 0 and dx > 0)");
            edge_layers[o] = &l;
        }
    }
    if (b.dx.pixels.empty() && b.dy.pixels.empty() && edge_layers.empty())
        throw InputError(file + ": no difference layer ('dx', 'dy' or 'edge_<dx>_<dy>')");
    const int w = b.primal.width, h = b.primal.height;
    bool all_variances = true;
    for (const auto& [o, l] : edge_layers)
        all_variances = all_variances && find_layer(layers, l->name + "_variance") != nullptr;
    for (const auto& [o, l] : edge_layers) {
        const Image d = rgb(*l, file);
        const ExrLayer* vl = find_layer(layers, l->name + "_variance");
        const Image v = all_variances ? luminance_layer(*vl, file) : Image();
        const auto [dy, dx] = o;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                if (std::isnan(d(x, y, 0))) continue;  // no edge from this pixel
                if (x + dx < 0 || x + dx >= w || y + dy >= h)
                    throw InputError(file + ": layer '" + l->name +
                                     "' has an edge leaving the image at (" + std::to_string(x) +
                                     ", " + std::to_string(y) + ")");
                b.extra_edges.push_back({y * w + x, (y + dy) * w + x + dx});
                for (int c = 0; c < 3; ++c) b.extra_differences.push_back(d(x, y, c));
                if (all_variances) b.extra_variances.push_back(v(x, y));
            }
    }
    return b;
}

}  // namespace gdmlt
