// SPDX-License-Identifier: GPL-3.0-or-later
#include "tests/support/pixel_difference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/path/bidirectional.h"

namespace gdmlt::test {
namespace {

struct Accumulator {
    double sum = 0.0, sum2 = 0.0;
    int n = 0;
    void add(double v) {
        sum += v;
        sum2 += v * v;
        ++n;
    }
    MeanEstimate estimate() const {
        MeanEstimate e;
        e.mean = sum / n;
        e.standard_error = std::sqrt(std::max(0.0, sum2 / n - e.mean * e.mean) / (n - 1));
        return e;
    }
};

}  // namespace

Path sample_interior_camera_path(const Scene& scene, std::uint64_t key, PathCounters& counters) {
    IndependentStream stream(key);
    const Film& film = scene.camera().film();
    const Vec2f u = stream.next_2d();
    const Vec2f film_position(1.f + u.x() * static_cast<float>(film.width - 2),
                              1.f + u.y() * static_cast<float>(film.height - 2));
    PathSamplerSettings settings;
    settings.max_depth = 8;
    return sample_camera_path(scene, film_position, stream, settings, counters);
}

MeanEstimate gdpt_pixel_difference(const Scene& scene, const mlt::GdptSettings& settings, int xi,
                                   int y, int samples, std::uint64_t seed,
                                   manifold::ShiftCounters& shifts, const Vec2i& offset) {
    PathCounters counters;
    Accumulator acc;
    for (int s = 0; s < samples; ++s) {
        double d = 0.0;
        for (int side = 0; side < 2; ++side) {
            IndependentStream stream(derive_stream(seed, static_cast<std::uint64_t>(side),
                                                   static_cast<std::uint64_t>(s)));
            const Vec2f jitter = stream.next_2d();
            const NeighbourLink link{side == 0 ? offset : Vec2i(-offset), 0, side == 0};
            const Vec2i pixel = Vec2i(xi, y) + (side == 0 ? Vec2i::Zero() : offset);
            mlt::LinkEstimate estimate;
            mlt::sample_gradients(scene,
                                  Vec2f(static_cast<float>(pixel.x()) + jitter.x(),
                                        static_cast<float>(pixel.y()) + jitter.y()),
                                  stream, settings.path, settings.shift, {&link, 1}, {&estimate, 1},
                                  counters, shifts);
            const float difference = luminance(estimate.difference());
            d += side == 0 ? difference : -difference;
        }
        acc.add(d);
    }
    return acc.estimate();
}

BidirectionalDifference bidirectional_pixel_difference(const Scene& scene,
                                                       manifold::ShiftKind shift, int xi, int y,
                                                       int samples, std::uint64_t seed,
                                                       manifold::ShiftCounters& shifts,
                                                       const Vec2i& offset) {
    PathCounters counters;
    PathSamplerSettings path;
    path.max_depth = 8;
    mlt::BidirectionalGradientScratch scratch;
    Accumulator difference, primal[2];
    for (int s = 0; s < samples; ++s) {
        double d = 0.0;
        for (int side = 0; side < 2; ++side) {
            IndependentStream stream(derive_stream(seed, static_cast<std::uint64_t>(side),
                                                   static_cast<std::uint64_t>(s)));
            const Vec2f jitter = stream.next_2d();
            const NeighbourLink link{side == 0 ? offset : Vec2i(-offset), 0, side == 0};
            const Vec2i pixel = Vec2i(xi, y) + (side == 0 ? Vec2i::Zero() : offset);
            mlt::LinkEstimate estimate;
            mlt::BidirectionalGradientSample g;
            mlt::sample_bidirectional_gradients(scene,
                                                Vec2f(static_cast<float>(pixel.x()) + jitter.x(),
                                                      static_cast<float>(pixel.y()) + jitter.y()),
                                                stream, path, shift, {&link, 1}, {&estimate, 1},
                                                nullptr, scratch, g, counters, shifts);
            EXPECT_EQ(g.nonfinite, 0);
            const float value = luminance(estimate.difference());
            d += side == 0 ? value : -value;
            primal[side].add(luminance(g.primal));
        }
        difference.add(d);
    }
    return {difference.estimate(), primal[0].estimate(), primal[1].estimate()};
}

MeanEstimate bdpt_camera_strategies_pixel(const Scene& scene, int x, int y, int samples,
                                          std::uint64_t seed) {
    PathCounters counters;
    BdptSettings settings;
    settings.max_depth = 8;
    settings.rr_depth = std::numeric_limits<int>::max();
    settings.hide_emitters = true;  // paths of one segment: very direct light
    BdptScratch scratch;
    BdptSample sample;
    Accumulator acc;
    for (int s = 0; s < samples; ++s) {
        IndependentStream stream(
            derive_stream(seed, static_cast<std::uint64_t>(x), static_cast<std::uint64_t>(s)));
        const Vec2f jitter = stream.next_2d();
        sample_bdpt(scene,
                    Vec2f(static_cast<float>(x) + jitter.x(), static_cast<float>(y) + jitter.y()),
                    stream, stream, settings, scratch, sample, counters);
        acc.add(luminance(sample.pixel));
    }
    return acc.estimate();
}

MeanEstimate path_traced_pixel(const Scene& scene, const PathSamplerSettings& settings, int x,
                               int y, int samples, std::uint64_t seed) {
    PathCounters counters;
    Accumulator acc;
    for (int s = 0; s < samples; ++s) {
        IndependentStream stream(
            derive_stream(seed, static_cast<std::uint64_t>(x), static_cast<std::uint64_t>(s)));
        const Vec2f jitter = stream.next_2d();
        const Ray ray = scene.camera().generate_ray(
            Vec2f(static_cast<float>(x) + jitter.x(), static_cast<float>(y) + jitter.y()),
            draw_lens_sample(scene.camera(), stream));
        acc.add(luminance(sample_path_radiance(scene, ray, stream, settings, counters)));
    }
    return acc.estimate();
}

}  // namespace gdmlt::test
