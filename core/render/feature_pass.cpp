// SPDX-License-Identifier: GPL-3.0-or-later
#include "core/render/feature_pass.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <array>
#include <vector>

#include "core/render/pixel_passes.h"
#include "core/sampling/rng.h"

namespace gdmlt {
namespace {

/// Stream family of the feature pass (derive_stream's first id), distinct from the render's
/// (seed, pixel, sample) streams: features taken with the render's own random numbers (same
/// jitter, same lobe choices) would carry the same noise as the image they help to filter,
/// and neighbours chosen by them would follow that noise.
constexpr std::uint64_t kFeatureStreams = 0xFEA7;

// Channels of one feature sample, in the order the accumulators keep them.
constexpr int kAlbedoChannel = 0;  // 3 channels
constexpr int kNormalChannel = 3;  // 3 channels
constexpr int kDepthChannel = 6;   // 1 channel
constexpr int kChannelCount = 7;

struct FeatureSample {
    Rgb albedo = Rgb::Zero();
    Vec3f normal = Vec3f::Zero();
    float depth = 0.f;
    int shape = -1;  // -1: escaped
};

/// The features of one camera path: follows delta vertices (along their likelier lobe) up to
/// `max_specular_bounces` times and describes the first other vertex. Three stream dimensions per
/// vertex (lobe, direction), used or not, so that a sample's decisions depend only on its stream.
FeatureSample sample_features(const Scene& scene, const Ray& camera_ray, const Vec3f& camera_end,
                              IndependentStream& stream, int max_specular_bounces,
                              PathCounters& counters) {
    ++counters.paths;
    ++counters.camera_rays;
    Ray ray = camera_ray;
    // The camera ray starts at the near clip plane; the depth is measured from the camera
    // (Camera::camera_end: the pinhole, the lens point, the orthographic ray's origin), so the
    // first segment is measured from there too.
    Vec3f previous_p = camera_end;
    float path_length = 0.f;
    for (int bounce = 0;; ++bounce) {
        if (bounce > 0) ++counters.bounce_rays;
        const SurfaceInteraction si = scene.intersect(ray);
        const float u_lobe = stream.next_1d();
        const Vec2f u_direction = stream.next_2d();
        if (!si.valid()) return FeatureSample{};
        path_length += (si.p - previous_p).norm();
        previous_p = si.p;

        const Vec3f wo_world = -ray.direction;
        const Bsdf& bsdf = scene.bsdf_of(si);
        const bool delta = bsdf.roughness_class_at(si.texture_point()) == RoughnessClass::Delta;
        // One sample serves both purposes: the continuation at a delta vertex, the albedo
        // estimate at the feature vertex. At a delta vertex the walk takes the likelier lobe
        // (u = 1/2 against the Fresnel reflectance: glass refracts unless it reflects more than
        // half, as at grazing angles and under total internal reflection), so that what a pixel
        // sees through glass is a function of where in the pixel its ray starts, not of a coin:
        // with sampled lobes, sample 0's shape id inside a glass sphere was a coin toss between
        // the room reflected and the room refracted, and ADAP's graph there followed the coin.
        const BsdfSample bs = bsdf.sample(si.texture_point(), si.shading.to_local(wo_world),
                                          delta ? 0.5f : u_lobe, u_direction);
        bool feature_vertex = bounce >= max_specular_bounces || !bs.valid() || !delta;
        Vec3f wi_world = Vec3f::Zero();
        if (!feature_vertex) {
            wi_world = si.shading.to_world(bs.wi);
            // The path sampler's light-leak rule (Veach 1997, sec. 5.3): a direction on the
            // wrong side of the geometric surface ends the path there, so it ends the feature
            // walk there too.
            const float side = si.n_geometric.dot(wi_world) * si.n_geometric.dot(wo_world);
            feature_vertex = bs.transmission ? side > 0.f : side < 0.f;
        }
        if (!feature_vertex) {
            ray = spawn_ray(si.p, si.n_geometric, wi_world);
            continue;
        }

        FeatureSample f;
        f.shape = si.shape;
        f.depth = path_length;
        // The side the ray arrived from is decided by the geometric normal (a shading normal
        // may lean across the view direction), so the two sides of a sheet get opposite
        // normals that both face the viewer.
        f.normal = si.n_geometric.dot(wo_world) < 0.f ? Vec3f(-si.shading.n) : si.shading.n;
        const bool emits = scene.shapes()[static_cast<std::size_t>(si.shape)].emitter() >= 0 &&
                           !is_black(scene.emitted(si, wo_world));
        // E[f cos / pdf] over the BSDF's own sampling is the directional albedo; the clamp keeps
        // a rare large weight (a refraction's radiance scaling by the squared relative index,
        // above 1 on leaving glass; a rough lobe's tail) from dominating a few-sample mean. Delta
        // samples are weights too, so a vertex at the bounce limit gets its mirror's or glass's
        // tint.
        if (bs.valid() && !emits && is_finite(bs.weight))
            f.albedo = bs.weight.cwiseMax(0.f).cwiseMin(1.f);
        return f;
    }
}

}  // namespace

FeatureImages render_features(const Scene& scene, const FeatureSettings& settings,
                              const std::atomic<bool>* cancel) {
    const Film& film = scene.camera().film();
    const int width = film.crop_width, height = film.crop_height;
    FeatureImages out;
    out.albedo = Image(width, height, 3);
    out.normal = Image(width, height, 3);
    out.depth = Image(width, height, 1);
    out.shape_id = Image(width, height, 1, -1.f);
    out.albedo_variance = Image(width, height, 1);
    out.normal_variance = Image(width, height, 1);
    out.depth_variance = Image(width, height, 1);

    // Running means (kept in the output images) and sums of squared deviations per channel,
    // updated with Welford's method (Welford 1962): no cancellation between large sums of
    // squares, so a constant feature has exactly zero variance. Float suffices for the few
    // samples of a feature pass and keeps the accumulators at 60 bytes per pixel (7 means,
    // 7 sums, a count).
    Image squared_deviations(width, height, kChannelCount);
    std::vector<std::uint32_t> counts(static_cast<std::size_t>(width) * height, 0);
    tbb::enumerable_thread_specific<PathCounters> counters;

    PixelPassSettings passes;
    passes.spp = std::max(settings.spp, 1);
    passes.seed = derive_stream(settings.seed, kFeatureStreams);
    const int max_specular_bounces = std::max(settings.max_specular_bounces, 0);
    const PixelPassResult done = run_pixel_passes(
        film, passes, cancel,
        [&](int x, int y, const Vec2f& film_position, IndependentStream& stream) {
            const Camera& camera = scene.camera();
            const Vec2f u_lens = draw_lens_sample(camera, stream);
            const Ray ray = camera.generate_ray(film_position, u_lens);
            const FeatureSample f =
                sample_features(scene, ray, camera.camera_end(ray.origin, u_lens), stream,
                                max_specular_bounces, counters.local());
            // A pixel's samples arrive in index order on one thread, so the first to arrive is
            // sample 0.
            const std::uint32_t n = ++counts[static_cast<std::size_t>(y) * width + x];
            if (n == 1) out.shape_id(x, y) = static_cast<float>(f.shape);
            const std::array<float, kChannelCount> values = {
                f.albedo.x(), f.albedo.y(), f.albedo.z(), f.normal.x(),
                f.normal.y(), f.normal.z(), f.depth};
            const std::array<float*, kChannelCount> means = {
                &out.albedo(x, y, 0), &out.albedo(x, y, 1), &out.albedo(x, y, 2),
                &out.normal(x, y, 0), &out.normal(x, y, 1), &out.normal(x, y, 2),
                &out.depth(x, y)};
            for (int c = 0; c < kChannelCount; ++c) {
                float& mean = *means[static_cast<std::size_t>(c)];
                const float value = values[static_cast<std::size_t>(c)];
                const float delta = value - mean;
                mean += delta / static_cast<float>(n);
                squared_deviations(x, y, c) += delta * (value - mean);
            }
        },
        [](int) {});

    // Variance of the mean = unbiased sample variance / n, averaged over a layer's channels.
    const auto variance_of_mean = [&](int x, int y, int first, int channels) {
        const std::uint32_t n = counts[static_cast<std::size_t>(y) * width + x];
        if (n < 2) return 0.f;
        float sum = 0.f;
        for (int c = first; c < first + channels; ++c) sum += squared_deviations(x, y, c);
        return sum / (static_cast<float>(n - 1) * static_cast<float>(n) * channels);
    };
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            out.albedo_variance(x, y) = variance_of_mean(x, y, kAlbedoChannel, 3);
            out.normal_variance(x, y) = variance_of_mean(x, y, kNormalChannel, 3);
            out.depth_variance(x, y) = variance_of_mean(x, y, kDepthChannel, 1);
        }

    out.spp = done.spp_completed;
    out.interrupted = done.interrupted;
    for (const PathCounters& c : counters) out.counters += c;
    return out;
}

}  // namespace gdmlt
