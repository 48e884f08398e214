// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/adap_selection.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>
#include <vector>

namespace gdmlt {
namespace {

bool usable(const Image& image, int width, int height, int channels) {
    return image.width == width && image.height == height && image.channels == channels &&
           !image.pixels.empty();
}

/// Squared distance of two pixels' values of a `channels`-channel image.
float squared_distance(const Image& image, int i, int j) {
    const auto c = static_cast<std::size_t>(image.channels);
    float s = 0.f;
    for (std::size_t k = 0; k < c; ++k) {
        const float d = image.pixels[static_cast<std::size_t>(i) * c + k] -
                        image.pixels[static_cast<std::size_t>(j) * c + k];
        s += d * d;
    }
    return s;
}

/// exp(-max(0, d2 - tau) / sigma^2); sigma <= 0 switches the feature off.
float feature_weight(float distance2, float tau, float sigma) {
    if (!(sigma > 0.f)) return 1.f;
    const float excess = std::max(0.f, distance2 - tau);
    return std::exp(-excess / (sigma * sigma));
}

/// The noise allowance tau: the expected squared difference of two independent noisy means,
/// sum over channels of (var_i + var_j); the variance layers hold the mean over channels.
float noise_allowance(const Image& variance, int channels, int i, int j) {
    if (variance.pixels.empty()) return 0.f;
    return static_cast<float>(channels) * (variance.pixels[static_cast<std::size_t>(i)] +
                                           variance.pixels[static_cast<std::size_t>(j)]);
}

}  // namespace

float adap_similarity(const FeatureImages& f, const AdapSettings& s, int i, int j) {
    const int width = f.albedo.width, height = f.albedo.height;
    float w = 1.f;
    if (usable(f.albedo, width, height, 3))
        w = std::min(w,
                     feature_weight(squared_distance(f.albedo, i, j),
                                    noise_allowance(f.albedo_variance, 3, i, j), s.sigma_albedo));
    if (usable(f.normal, width, height, 3))
        w = std::min(w,
                     feature_weight(squared_distance(f.normal, i, j),
                                    noise_allowance(f.normal_variance, 3, i, j), s.sigma_normal));
    if (usable(f.depth, width, height, 1)) {
        // Relative depth: a wall seen at 10 m and one at 1 m are equally "flat" to the eye.
        const float di = f.depth.pixels[static_cast<std::size_t>(i)];
        const float dj = f.depth.pixels[static_cast<std::size_t>(j)];
        const float scale = std::max(std::abs(di), std::abs(dj));
        if (scale > 0.f) {
            const float rel2 = (di - dj) * (di - dj) / (scale * scale);
            const float tau = noise_allowance(f.depth_variance, 1, i, j) / (scale * scale);
            w = std::min(w, feature_weight(rel2, tau, s.sigma_depth));
        }
    }
    if (usable(f.shape_id, width, height, 1)) {
        const bool same = f.shape_id.pixels[static_cast<std::size_t>(i)] ==
                          f.shape_id.pixels[static_cast<std::size_t>(j)];
        w = std::min(w, feature_weight(same ? 0.f : 1.f, 0.f, s.sigma_shape));
    }
    return w;
}

NeighbourSet select_adap_neighbours(const FeatureImages& f, const AdapSettings& s) {
    if (s.neighbours < 1) throw std::invalid_argument("ADAP: neighbours (K) must be at least 1");
    if (s.window_radius < 1 || s.window_radius > 8)
        throw std::invalid_argument("ADAP: window radius must lie in [1, 8]");
    if (!(s.min_similarity >= 0.f && s.min_similarity <= 1.f))
        throw std::invalid_argument("ADAP: min_similarity must lie in [0, 1]");
    for (const float sigma : {s.sigma_albedo, s.sigma_normal, s.sigma_depth, s.sigma_shape})
        if (!std::isfinite(sigma) || sigma < 0.f)
            throw std::invalid_argument("ADAP: bandwidths must be finite and >= 0 (0 = off)");
    const int width = f.albedo.width, height = f.albedo.height;
    if (!usable(f.albedo, width, height, 3))
        throw std::invalid_argument("ADAP: the albedo feature is required");
    for (const Image* layer : {&f.normal, &f.depth, &f.shape_id, &f.albedo_variance,
                               &f.normal_variance, &f.depth_variance})
        if (!layer->pixels.empty() && (layer->width != width || layer->height != height))
            throw std::invalid_argument("ADAP: feature layers of different sizes");

    // Candidate offsets, nearest first (then by raster order): ties in similarity go to the
    // nearer pixel, whose difference correlates best with its base path.
    std::vector<Vec2i> offsets;
    const int r = s.window_radius;
    for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx)
            if (dx != 0 || dy != 0) offsets.emplace_back(dx, dy);
    std::stable_sort(offsets.begin(), offsets.end(), [](const Vec2i& a, const Vec2i& b) {
        return a.squaredNorm() < b.squaredNorm();
    });

    // Each pixel's choice, as undirected pairs (smaller index first) with a count of the ends
    // that chose it (1 or 2).
    const auto index = [width](int x, int y) { return y * width + x; };
    struct Candidate {
        float similarity;
        int order;  // position in `offsets`
        int other;
    };
    // Rows in parallel, each into its own list (the result is sorted below, so it does not
    // depend on the thread count).
    const auto k = static_cast<std::size_t>(s.neighbours);
    std::vector<std::vector<std::pair<std::int32_t, std::int32_t>>> chosen_per_row(
        static_cast<std::size_t>(height));
    tbb::parallel_for(0, height, [&](int y) {
        std::vector<Candidate> candidates;
        candidates.reserve(offsets.size());
        auto& chosen_here = chosen_per_row[static_cast<std::size_t>(y)];
        for (int x = 0; x < width; ++x) {
            const int i = index(x, y);
            candidates.clear();
            for (std::size_t o = 0; o < offsets.size(); ++o) {
                const int xj = x + offsets[o].x(), yj = y + offsets[o].y();
                if (xj < 0 || yj < 0 || xj >= width || yj >= height) continue;
                const int j = index(xj, yj);
                candidates.push_back({adap_similarity(f, s, i, j), static_cast<int>(o), j});
            }
            const std::size_t keep = std::min(k, candidates.size());
            // Similar candidates first, nearest first among them (offsets are sorted by
            // distance); then the rest, most similar first.
            const float threshold = s.min_similarity;
            const auto key = [threshold](const Candidate& c) {
                const bool similar = c.similarity >= threshold;
                return std::tuple(!similar, similar ? 0.f : -c.similarity, c.order);
            };
            std::partial_sort(
                candidates.begin(), candidates.begin() + static_cast<long>(keep), candidates.end(),
                [&](const Candidate& a, const Candidate& b) { return key(a) < key(b); });
            for (std::size_t c = 0; c < keep; ++c)
                chosen_here.emplace_back(std::min(i, candidates[c].other),
                                         std::max(i, candidates[c].other));
        }
    });
    std::vector<std::pair<std::int32_t, std::int32_t>> chosen;
    for (const auto& row : chosen_per_row) chosen.insert(chosen.end(), row.begin(), row.end());
    std::sort(chosen.begin(), chosen.end());
    std::vector<std::pair<std::int32_t, std::int32_t>> pairs;
    for (std::size_t a = 0; a < chosen.size();) {
        std::size_t b = a;
        while (b < chosen.size() && chosen[b] == chosen[a]) ++b;
        if (!s.mutual || b - a >= 2) pairs.push_back(chosen[a]);
        a = b;
    }

    // Every pixel keeps a horizontal and a vertical unit link: the more similar of its two
    // lattice neighbours on each axis when it has neither.
    std::vector<std::uint8_t> has_axis(static_cast<std::size_t>(width) * height, 0);
    const auto mark = [&](std::int32_t a, std::int32_t b) {
        if (b == a + 1 && a % width + 1 < width) {
            has_axis[static_cast<std::size_t>(a)] |= 1;
            has_axis[static_cast<std::size_t>(b)] |= 1;
        } else if (b == a + width) {
            has_axis[static_cast<std::size_t>(a)] |= 2;
            has_axis[static_cast<std::size_t>(b)] |= 2;
        }
    };
    for (const auto& [a, b] : pairs) mark(a, b);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const int i = index(x, y);
            for (int axis = 0; axis < 2; ++axis) {
                if (has_axis[static_cast<std::size_t>(i)] & (1 << axis)) continue;
                const Vec2i step = axis == 0 ? Vec2i(1, 0) : Vec2i(0, 1);
                int best = -1;
                float best_w = -1.f;
                for (const int sign : {1, -1}) {
                    const int xj = x + sign * step.x(), yj = y + sign * step.y();
                    if (xj < 0 || yj < 0 || xj >= width || yj >= height) continue;
                    const int j = index(xj, yj);
                    const float w = adap_similarity(f, s, i, j);
                    if (w > best_w) best_w = w, best = j;
                }
                if (best < 0) continue;  // a one-pixel-wide image has no such neighbour
                const auto pair = std::make_pair(std::min(i, best), std::max(i, best));
                pairs.push_back(pair);
                mark(pair.first, pair.second);
            }
        }
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());

    // Canonical order: by offset (dy, dx), then by `from`.
    std::vector<GradientEdge> edges;
    edges.reserve(pairs.size());
    for (const auto& [a, b] : pairs) edges.push_back({a, b});
    std::sort(edges.begin(), edges.end(), [width](const GradientEdge& a, const GradientEdge& b) {
        return canonical_edge_key(a, width) < canonical_edge_key(b, width);
    });
    return NeighbourSet::from_edges(width, height, std::move(edges));
}

}  // namespace gdmlt
