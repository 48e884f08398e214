// SPDX-License-Identifier: GPL-3.0-or-later
#pragma once
// The feature pass of adaptive neighbour selection (ADAP; Manzi et al. 2014, "Improved Sampling
// for Gradient-Domain Metropolis Light Transport"): per-pixel auxiliary images (albedo,
// normal, depth, shape id) and the variance of their per-pixel means, from a few cheap samples
// per pixel, so that a pixel's neighbours can be chosen among pixels with similar features.
//
// The feature vertex is the first vertex along the camera path that is not a smooth mirror or
// glass (RoughnessClass::Delta): at delta surfaces the path follows the likelier lobe (glass
// refracts unless its Fresnel reflectance exceeds 1/2), as the auxiliary buffers of denoisers
// are usually made (Open Image Denoise's documentation, "albedo" and "normal" inputs), so that
// the features of what is seen through a mirror or a window are those of the surface behind
// it, and the same wherever the pixel's samples land on one side of a silhouette.
#include <atomic>
#include <cstdint>

#include "core/image/image.h"
#include "core/path/path_sampler.h"
#include "core/scene/scene.h"

namespace gdmlt {

struct FeatureSettings {
    int spp = 4;  // samples per pixel (at least 1)
    /// The pass derives its own streams from this seed (derive_stream), so a caller may pass
    /// the render's seed without the features replaying the render's first samples.
    std::uint64_t seed = 0;
    /// Delta vertices followed at most; at the limit the last (delta) vertex is the feature
    /// vertex. 0: always the first hit.
    int max_specular_bounces = 8;
};

/// Crop-window-sized images; each pixel is the mean over its samples.
struct FeatureImages {
    /// 3 channels, RGB: one-sample estimate of the directional albedo at the feature vertex
    /// (a BSDF sample's weight f cos / pdf, clamped to [0, 1] per channel). 0 where the path
    /// escaped and on emitters that emit towards the ray (their radiance is emission, which an
    /// albedo does not describe; 0 also sets them apart from reflecting neighbours).
    Image albedo;
    /// 3 channels: world-space shading normal, turned to the side of the surface the ray came
    /// from; the mean is not normalised (its length shrinks where samples disagree).
    Image normal;
    /// 1 channel: path length from the camera position to the feature vertex (the sum of the
    /// segment lengths through mirrors and glass), in scene units.
    Image depth;
    /// 1 channel: index into Scene::shapes() of the shape at the feature vertex of sample 0,
    /// -1 where that path escaped (or the pixel received no sample).
    Image shape_id;
    /// Variance of the per-pixel mean (unbiased sample variance / samples), averaged over the
    /// layer's channels; 0 where a pixel has fewer than two samples (no estimate).
    Image albedo_variance, normal_variance, depth_variance;
    /// Samples every pixel received. After a cancel this may be below the request (even 0):
    /// each pixel is the mean over the samples it did receive.
    int spp = 0;
    bool interrupted = false;
    PathCounters counters;  // camera and bounce rays traced (no shadow rays)
};

/// Renders the feature images with `settings.spp` samples per pixel over all cores (the
/// caller's tbb::global_control applies), deterministic per (seed, pixel, sample) and
/// bit-identical whatever the thread count. `cancel` (optional) is polled per pixel; when it
/// becomes true the pass stops and returns what exists (see FeatureImages::spp).
FeatureImages render_features(const Scene& scene, const FeatureSettings& settings,
                              const std::atomic<bool>* cancel = nullptr);

}  // namespace gdmlt
