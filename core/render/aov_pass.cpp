// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/aov_pass.h"

#include <algorithm>
#include <vector>

#include "core/render/pixel_passes.h"
#include "core/sampling/rng.h"

namespace gdmlt {
namespace {

/// Stream family of the AOV pass (derive_stream's first id): not the render's streams.
constexpr std::uint64_t kAovStreams = 0xA0F5;

/// The request's value at `si` (all channels; zero where the ray escaped).
void aov_values(const SurfaceInteraction& si, AovType type, float* out) {
    if (!si.valid()) {
        std::fill(out, out + aov_channels(type).size(), 0.f);
        return;
    }
    const auto put = [&](const auto& v, int n) {
        for (int c = 0; c < n; ++c) out[c] = v[c];
    };
    switch (type) {
        case AovType::Depth:
            // The ray's distance, from the near clip plane where camera rays start (Mitsuba 3's
            // si.t, whose rays start there too).
            out[0] = si.t;
            break;
        case AovType::Position:
            put(si.p, 3);
            break;
        case AovType::Uv:
            put(si.uv, 2);
            break;
        case AovType::GeometricNormal:
            put(si.n_geometric, 3);
            break;
        case AovType::ShadingNormal:
            put(si.shading.n, 3);
            break;
        case AovType::PrimIndex:
            out[0] = static_cast<float>(si.primitive);
            break;
        case AovType::ShapeIndex:
            out[0] = static_cast<float>(si.shape);
            break;
    }
}

}  // namespace

std::vector<ExrLayer> render_aovs(const Scene& scene, const std::vector<AovRequest>& requests,
                                  int spp, std::uint64_t seed, const std::atomic<bool>* cancel) {
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    std::vector<ExrLayer> layers;
    for (const AovRequest& r : requests) {
        const std::vector<std::string> channels = aov_channels(r.type);
        layers.push_back(
            ExrLayer{r.name, channels, Image(width, height, static_cast<int>(channels.size()))});
    }
    std::vector<std::uint32_t> counts(static_cast<std::size_t>(width) * height, 0);
    PixelPassSettings passes;
    passes.spp = std::max(spp, 1);
    passes.seed = derive_stream(seed, kAovStreams);
    run_pixel_passes(
        film, passes, cancel,
        [&](int x, int y, const Vec2f& film_position, IndependentStream& stream) {
            const SurfaceInteraction si = scene.intersect(scene.camera().generate_ray(
                film_position, draw_lens_sample(scene.camera(), stream)));
            // A pixel's samples arrive on one thread: a running mean per pixel.
            const std::uint32_t n = ++counts[static_cast<std::size_t>(y) * width + x];
            for (std::size_t k = 0; k < requests.size(); ++k) {
                float values[3] = {0.f, 0.f, 0.f};
                aov_values(si, requests[k].type, values);
                Image& image = layers[k].image;
                for (int c = 0; c < image.channels; ++c)
                    image(x, y, c) += (values[c] - image(x, y, c)) / static_cast<float>(n);
            }
        },
        [](int) {});
    return layers;
}

}  // namespace gdmlt
